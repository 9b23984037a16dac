"""The mission file as written, as strict pydantic models: every key, its type, range and default
(docs/mission-schema.md). Validation turns the first mistake into a `MissionError` "file:line: field:
sentence", the line found through `yaml_tree` from pydantic's error location.

Strict: a number must be a YAML number (an integer is taken as a float; a quoted "10", `true`, `.inf` and
`.nan` are refused), a whole number an integer, a flag true or false, text a string. Unknown keys are refused
with a "did you mean". A section written as null (`run:`) is the same as leaving it out. Rules that relate
several keys (one leader, placements, ...) are `gcs_swarm.mission.checks`; turning the file into a `Mission`
is `gcs_swarm.mission.loader`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import operator
import re
import typing
from collections.abc import Callable, Mapping
from typing import Annotated, Any, ClassVar

from pydantic import (
    AfterValidator,
    AliasPath,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    GetCoreSchemaHandler,
    PlainValidator,
    Tag,
    ValidationError,
    WrapValidator,
    create_model,
    model_validator,
)
from pydantic_core import ErrorDetails, PydanticCustomError, core_schema
from pydantic_core.core_schema import ValidatorFunctionWrapHandler

from gcs_swarm.guidance.controller import CONTROLLERS
from gcs_swarm.guidance.params import (
    CapabilityParams,
    DeadGcsParams,
    FieldParams,
    Limits,
    PIDParams,
    ReferenceParams,
    ReshapeParams,
    SeparationParams,
    SMCParams,
    TelemetryParams,
)
from gcs_swarm.link.command_mode import StepDown
from gcs_swarm.mission.yaml_tree import Node, loc_path
from swarm_common.radio_presets import RADIO_PRESETS, RADIO_RANGES

DEFAULT_ORIGIN = (-35.363261, 149.165230, 584.0)  # ArduPilot SITL's CMAC field, Canberra
NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}"
NAME_HINT = "expected a name of letters, digits, '_', '.' or '-' (at most 64, no spaces)"
MAX_LINK_DELAY_MS = 10000.0  # the simulator's limit (sitl-sim --link-delay-ms)


def describe(value: object) -> str:
    """How a YAML value reads in an error message."""
    if value is None:
        return "nothing (null)"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, float):
        return f"the number {value:g}"
    if isinstance(value, int):
        digits = str(value)
        return f"the number {digits}" if len(digits) <= 20 else f"a {len(digits)}-digit number"
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"the text {shown!r}"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    return "a mapping"


def _refuse(message: str, at: tuple[str | int, ...] = ()) -> PydanticCustomError:
    """A validation error whose sentence is `message`; `at` is the key path, below the value being validated,
    that the sentence is about."""
    return PydanticCustomError("mission", "{message}", {"message": message, "at": at})


# ---------------------------------------------------------------- value types (Annotated metadata)


def _bound(x: float) -> str:
    return str(x) if isinstance(x, int) else f"{x:g}"


_COMPARISONS: tuple[tuple[str, str, Callable[[Any, Any], bool]], ...] = (
    ("gt", ">", operator.gt),
    ("ge", ">=", operator.ge),
    ("lt", "<", operator.lt),
    ("le", "<=", operator.le),
)


@dataclasses.dataclass(frozen=True)
class Range:
    """Bounds of a number (`gt`/`lt` strict, `ge`/`le` inclusive) and its unit, as the error names them."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    unit: str = ""

    def problem(self, x: float) -> str | None:
        """The sentence saying how `x` breaks the bounds, or None when it keeps them."""
        unit = f" {self.unit}" if self.unit else ""
        got = describe(x) if isinstance(x, int) else f"{x:g}"
        for name, symbol, holds in _COMPARISONS:
            bound = getattr(self, name)
            if bound is not None and not holds(x, bound):
                return f"must be {symbol} {_bound(bound)}{unit}, got {got}"
        return None

    def __get_pydantic_core_schema__(
        self, source: Any, handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        def check(x: float) -> float:
            problem = self.problem(x)
            if problem:
                raise _refuse(problem)
            return x

        return core_schema.no_info_after_validator_function(check, handler(source))


def text(pattern: str | None = None, hint: str = "") -> AfterValidator:
    """Non-empty text, optionally matching `pattern` (then `hint` says what is expected)."""

    def check(value: str) -> str:
        if not value.strip():
            raise _refuse("must not be empty")
        if pattern is not None and not re.fullmatch(pattern, value):
            raise _refuse(f"{hint}, got {describe(value)}")
        return value

    return AfterValidator(check)


def one_of(*options: str) -> PlainValidator:
    """One of the `options` (exact spelling), with a "did you mean" for a near miss."""

    def check(value: object) -> str:
        if isinstance(value, str) and value in options:
            return value
        listed = ", ".join(repr(o) for o in options)
        close = difflib.get_close_matches(value, options, n=1) if isinstance(value, str) else []
        suggestion = f"; did you mean {close[0]!r}?" if close else ""
        raise _refuse(f"expected one of {listed}, got {describe(value)}{suggestion}")

    return PlainValidator(check)


def _vector(value: object, validate: ValidatorFunctionWrapHandler) -> object:
    """A list of exactly three finite numbers [x, y, z]."""
    if not isinstance(value, list) or len(value) != 3:
        got = str(len(value)) if isinstance(value, list) else describe(value)
        raise _refuse(f"expected 3 numbers, got {got}")
    return validate(value)


def _forever(value: object, validate: ValidatorFunctionWrapHandler) -> object:
    """Seconds, or `inf` / `.inf`: for good."""
    if value == "inf" or value == math.inf:
        return math.inf
    if isinstance(value, str):
        raise _refuse(f"expected seconds or inf (for good), got {describe(value)}")
    return validate(value)


Vec = Annotated[list[float], WrapValidator(_vector)]
OptionalVec = Vec | None  # null: not given


def _horizontal(value: object, validate: ValidatorFunctionWrapHandler) -> object:
    """A list of exactly two finite numbers [x, y] (m ENU, horizontal)."""
    if not isinstance(value, list) or len(value) != 2:
        got = str(len(value)) if isinstance(value, list) else describe(value)
        raise _refuse(f"expected 2 numbers [x, y] or a mapping {{lat: .., lon: ..}}, got {got}")
    return validate(value)


Vec2 = Annotated[list[float], WrapValidator(_horizontal)]


def pair(bounds: Range = Range()) -> WrapValidator:
    """Two numbers [low, high], each within `bounds` and low <= high, read as a tuple (low, high)."""

    def check(value: object, validate: ValidatorFunctionWrapHandler) -> object:
        if not isinstance(value, list | tuple) or len(value) != 2:
            raise _refuse(f"expected two numbers [low, high], got {describe(value)}")
        low, high = validate(tuple(value))
        problem = bounds.problem(low) or bounds.problem(high)
        if problem:
            raise _refuse(problem)
        if low > high:
            raise _refuse(f"low {low:g} is above high {high:g}")
        return (low, high)

    return WrapValidator(check)


@dataclasses.dataclass(frozen=True)
class Params:
    """A params dataclass of `gcs_swarm.guidance.params` read from a mapping of its fields; keys not given
    keep the values of `default` (None: the class's own defaults), nested dataclasses are nested mappings.
    `skip` keys are allowed beside the fields and left to another schema field. The dataclass's own ValueError
    (e.g. SMC k1*c1 <= 1/4) is blamed on the key whose value (set after those before it) breaks it first."""

    default: Any = None
    skip: tuple[str, ...] = ()

    def __get_pydantic_core_schema__(
        self, source: Any, handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        default = source() if self.default is None else self.default
        names = [f.name for f in dataclasses.fields(default)]
        hints = typing.get_type_hints(type(default))
        fields: dict[str, Any] = {key: (Any, None) for key in self.skip}
        for name in names:
            value = getattr(default, name)
            if dataclasses.is_dataclass(value):
                fields[name] = (Annotated[hints[name], Params(value)], value)
            elif hints[name] is str:
                fields[name] = (Annotated[str, text()], value)
            else:
                fields[name] = (hints[name], value)
        section = create_model(f"{type(default).__name__}Section", __base__=Section, **fields)

        def build(data: object, validate: ValidatorFunctionWrapHandler) -> object:
            given = validate(data)
            values = {name: getattr(given, name) for name in names}
            try:
                return type(default)(**values)
            except ValueError as exc:
                order = list(data) if isinstance(data, dict) else []
                raise _refuse(str(exc), _breaking_key(default, values, order)) from None

        return core_schema.no_info_wrap_validator_function(build, handler.generate_schema(section))


def _breaking_key(default: Any, values: dict[str, Any], order: list[str]) -> tuple[str, ...]:
    """(key,) of the given key (in file order) at which the dataclass first refuses when the given values are
    set on the defaults one by one; () when no key is given (then the section is to blame)."""
    trial = {name: getattr(default, name) for name in values}
    for key in (k for k in order if k in values):
        trial[key] = values[key]
        try:
            type(default)(**trial)
        except ValueError:
            return (key,)
    return ()


# ---------------------------------------------------------------- sections


class Section(BaseModel):
    """A mapping of the mission file: strict types, every key known; null reads as empty (all defaults)."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True, allow_inf_nan=False)
    null_is_empty: ClassVar[bool] = True
    moved_keys: ClassVar[dict[str, str]] = {}  # keys that belong in another section -> that section

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if data is None and cls.null_is_empty:
            return {}
        if not isinstance(data, dict):
            raise _refuse(f"expected a mapping of keys to values, got {describe(data)}")
        allowed = [
            f.validation_alias if isinstance(f.validation_alias, str) else name
            for name, f in cls.model_fields.items()
            if not isinstance(f.validation_alias, AliasPath)
        ]
        for key in data:
            if key in allowed:
                continue
            if key in cls.moved_keys:
                raise _refuse(f"unknown key here; it belongs under '{cls.moved_keys[key]}'", (key,))
            close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
            if close:
                raise _refuse(f"unknown key; did you mean {close[0]!r}?", (key,))
            raise _refuse(f"unknown key (allowed here: {', '.join(allowed)})", (key,))
        return data


class Entry(Section):
    """A mapping that is a list item or a required value: null is a mistake, not an empty mapping."""

    null_is_empty: ClassVar[bool] = False


ZERO = [0.0, 0.0, 0.0]


def _form(value: object) -> str:
    """Which form a position is written in: a mapping is geographic, anything else ENU metres. The tags are
    left out of error locations (`_where`)."""
    return "<geo>" if isinstance(value, dict) else "<enu>"


Height = Annotated[float, Range(ge=-500, le=20000, unit="m")]


class GeoPoint(Entry):
    """A position in latitude/longitude (WGS-84 deg), converted to ENU about the origin at load time
    (gcs_swarm.mission.geodesy): `alt` m above the origin or `amsl` m above mean sea level, at most one; a
    ground start may give neither (on the ground, z = 0)."""

    lat: Annotated[float, Range(ge=-90, le=90, unit="deg")]
    lon: Annotated[float, Range(ge=-180, le=180, unit="deg")]
    alt: Height | None = None
    amsl: Height | None = None

    @model_validator(mode="after")
    def _one_height(self) -> GeoPoint:
        if self.alt is not None and self.amsl is not None:
            both = "give alt (m above the origin) or amsl (m above mean sea level), not both"
            raise _refuse(both, ("amsl",))
        return self


class GeoVertex(Entry):
    """A horizontal point in latitude/longitude (WGS-84 deg): a vertex of a fence or a footprint."""

    lat: Annotated[float, Range(ge=-90, le=90, unit="deg")]
    lon: Annotated[float, Range(ge=-180, le=180, unit="deg")]


# a position: [x, y, z] m ENU, or {lat, lon, alt | amsl}; a vertex: [x, y] m ENU, or {lat, lon}
Position = Annotated[Annotated[Vec, Tag("<enu>")] | Annotated[GeoPoint, Tag("<geo>")], Discriminator(_form)]
Vertex = Annotated[Annotated[Vec2, Tag("<enu>")] | Annotated[GeoVertex, Tag("<geo>")], Discriminator(_form)]


class MetaSection(Section):
    name: Annotated[str, text(NAME_PATTERN, NAME_HINT)] = ""  # "": from the file name
    description: Annotated[str, text()] = ""


class OriginSection(Section):
    lat: Annotated[float, Range(ge=-90, le=90, unit="deg")]
    lon: Annotated[float, Range(ge=-180, le=180, unit="deg")]
    alt: Annotated[float, Range(ge=-500, le=9000, unit="m")] = 0.0


class StartEntry(Entry):
    position: Position
    velocity: Vec = ZERO
    yaw_deg: Annotated[float, Range(ge=-360, le=360, unit="deg")] = 0.0


class VehicleEntry(Entry):
    name: Annotated[str, text(NAME_PATTERN, NAME_HINT)] = ""  # "": uav<i+1>
    connection: Annotated[str, text()] = ""  # "": udpout:127.0.0.1:<base_port + i>
    role: Annotated[str, one_of("leader", "follower")] = "follower"
    sysid: Annotated[int, Range(ge=1, le=254)] = 0  # 0: learned from the vehicle's HEARTBEAT
    slot: OptionalVec = None
    start: StartEntry
    target: Position | None = None
    # auto: from the vehicle's HEARTBEAT.autopilot; ardupilot | px4: speak that dialect whatever it says
    autopilot: Annotated[str, one_of("auto", "ardupilot", "px4")] = "auto"


class FormationSection(Section):
    shape: Annotated[str, one_of("v", "line", "column", "grid", "offsets")] = "v"
    spacing: Annotated[float, Range(gt=0, unit="m")] = 10.0
    angle_deg: Annotated[float, Range(gt=0, le=90, unit="deg")] = 45.0
    altitude: Annotated[float, Range(gt=0, unit="m")] = 10.0
    topology: Annotated[str, one_of("broadcast", "relay")] = "broadcast"
    adjacency: list[list[int]] | None = None
    assign_slots: bool = True


class LegFormation(Section):
    """What a leg changes of the formation (the rest as the mission's `formation`)."""

    shape: Annotated[str, one_of("v", "line", "column", "grid")] | None = None  # None: the leg before's
    spacing: Annotated[float, Range(gt=0, unit="m")] | None = None  # None: the leg before's


class LegEntry(Entry):
    """One leg of the route (model.Leg): its waypoints and what it flies differently from the leg before."""

    name: Annotated[str, text()] = ""  # names it in events and the report ("": legs[<i>])
    waypoints: list[Position]
    formation: LegFormation = LegFormation()
    altitude: Annotated[float, Range(gt=0, unit="m")] | None = None  # every waypoint's height; None: theirs
    speed: Annotated[float, Range(gt=0, unit="m/s")] | None = None  # the leader's cap; None: the leg before's


class ObstacleEntry(Entry):
    center: Position
    radius: Annotated[float, Range(gt=0, unit="m")]
    velocity: Vec = ZERO


class WindSection(Section):
    """Steady wind plus turbulence, for the simulator."""

    speed: Annotated[float, Range(ge=0, le=100, unit="m/s")] = 0.0
    # the direction the wind blows FROM, compass degrees (0 = north, 90 = east), read into 0..360
    direction_deg: Annotated[
        float, Range(ge=-360, le=360, unit="deg"), AfterValidator(lambda deg: deg % 360.0)
    ] = 0.0
    turbulence: Annotated[float, Range(ge=0, le=50, unit="m/s")] = 0.0  # standard deviation of the gusts


class OutageEntry(Entry):
    vehicle: Any = None  # a vehicle's name (checks.py); not given: every vehicle
    start_s: Annotated[float, Range(ge=0, unit="s")]
    duration_s: Annotated[float, Range(gt=0, unit="s (or inf: for good)"), WrapValidator(_forever)]


Probability = Annotated[float, Range(ge=0, le=1)]
Delay = Annotated[float, Range(ge=0, le=MAX_LINK_DELAY_MS, unit="ms")]


def _radio_range(key: str) -> Range:
    """The accepted range of a radio figure (swarm_common.radio_presets.RADIO_RANGES) as a Range."""
    low, high, unit = RADIO_RANGES[key]
    return Range(ge=low, le=high, unit=unit)


class StepDownSection(Section):
    """When the command mode steps down in flight (link.command_mode.StepDown, docs/command-modes.md)."""

    enabled: bool = StepDown.enabled  # false: the mode chosen before take-off is flown to the end
    # telemetry older than this plus one report period at a window's end is queueing on the air
    queue_age_s: Annotated[float, Range(gt=0, le=5, unit="s")] = StepDown.queue_age_s
    # a vehicle's downlink degraded this long (whole seconds: windows of 1 s) steps the fleet down
    after_s: Annotated[int, Range(ge=1, le=60, unit="s")] = StepDown.after_s


class LinkSection(Section):
    loss: Probability = 0.0
    dup: Probability = 0.0
    corrupt: Probability = 0.0
    reorder: Probability = 0.0
    delay_ms: Delay = 0.0
    jitter_ms: Delay = 0.0
    from_s: Annotated[float, Range(ge=0, unit="s")] = 0.0
    outages: list[OutageEntry] | None = None
    # the radio under every link (docs/radio.md): a preset and any of its figures overridden (null: the
    # preset's); checks.py applies radio_spec's rule that overrides need a preset or capacity_bps
    radio: Annotated[str, one_of(*RADIO_PRESETS)] | None = None
    capacity_bps: Annotated[float, _radio_range("capacity_bps")] | None = None
    bits_per_byte: Annotated[float, _radio_range("bits_per_byte")] | None = None
    overhead_bytes: Annotated[int, _radio_range("overhead_bytes")] | None = None
    overhead_us: Annotated[float, _radio_range("overhead_us")] | None = None
    half_duplex: bool | None = None
    shared: bool | None = None
    buffer_bytes: Annotated[int, _radio_range("buffer_bytes")] | None = None
    radio_status: bool | None = None
    # the ground station's budget per vehicle link, both ways together (docs/mission-schema.md; link.link_use)
    budget_bps: Annotated[float, Range(gt=0, unit="bit/s")] | None = None
    # how the ground station commands the vehicles: auto (from the budget), attitude or position
    # (docs/command-modes.md; link.command_mode)
    command_mode: Annotated[str, one_of("auto", "attitude", "position")] = "auto"
    step_down: StepDownSection = StepDownSection()  # the in-flight step down (link.command_mode)


class _Heights(Entry):
    """A shape between two heights, m above the origin."""

    name: Annotated[str, text()] = ""  # names it in messages ("" : its place in the list)
    bottom: Height = 0.0
    top: Height

    @model_validator(mode="after")
    def _top_above_bottom(self) -> _Heights:
        if self.top <= self.bottom:
            raise _refuse(f"must be above bottom ({self.bottom:g} m), got {self.top:g} m", ("top",))
        return self


class PrismEntry(_Heights):
    """A vertical prism (a building): a footprint polygon between bottom and top."""

    polygon: list[Vertex]


class CylinderEntry(_Heights):
    """A vertical cylinder (a tree, a mast): a centre and radius between bottom and top."""

    center: Vertex
    radius: Annotated[float, Range(gt=0, unit="m")]


class WorldSection(Section):
    obstacles: list[ObstacleEntry] | None = None
    prisms: list[PrismEntry] | None = None  # buildings, avoided (spec 2.2)
    cylinders: list[CylinderEntry] | None = None  # trees and masts, avoided (spec 2.2)
    # site files merged into the mission (paths relative to the mission file; gcs_swarm.mission.imports)
    imports: list[Annotated[str, text()]] = Field(default=[], validation_alias="import")
    wind: WindSection = WindSection()
    link: LinkSection = LinkSection()


class ControlSection(Section):
    controller: Annotated[str, one_of(*CONTROLLERS)] = "smc"
    smc: Annotated[SMCParams, Params()] = SMCParams()
    pid: Annotated[PIDParams, Params()] = PIDParams()


class ExclusionEntry(Entry):
    """An exclusion zone of the fence: a polygon, or a circle (center and radius)."""

    name: Annotated[str, text()] = ""  # names it in messages ("" : its place in the list)
    polygon: list[Vertex] | None = None
    center: Vertex | None = None
    radius: Annotated[float, Range(gt=0, unit="m")] | None = None

    @model_validator(mode="after")
    def _one_shape(self) -> ExclusionEntry:
        circle = self.center is not None or self.radius is not None
        if self.polygon is not None and circle:
            raise _refuse("give 'polygon' or a circle ('center' and 'radius'), not both", ("polygon",))
        if self.polygon is None and (self.center is None or self.radius is None):
            missing = "radius" if self.center is not None else "center"
            raise _refuse(
                f"'{missing}' is missing: give 'polygon' (vertices) or 'center' and 'radius' (a circle)",
                (missing,),
            )
        return self


class GeofenceSection(Section):
    radius: Annotated[float, Range(gt=0, unit="m")] = 2000.0
    max_alt: float = 300.0  # above safety.min_altitude (checks.py)
    polygon: list[Vertex] | None = None  # the inclusion polygon (enforced by the command guard)
    exclusions: list[ExclusionEntry] | None = None  # no-fly zones (enforced by the command guard)
    upload: bool = False  # also upload polygon and exclusions to the autopilots (flight.geofence)


class SafetySection(Section):
    separation: Annotated[SeparationParams, Params()] = SeparationParams()
    min_altitude: Annotated[float, Range(ge=0, unit="m")] = 2.0
    geofence: GeofenceSection = GeofenceSection()
    rally: list[Position] | None = None  # rally points: uploaded, RTL returns to them (flight.geofence)
    collision_radius: Annotated[float, Range(gt=0, unit="m")] = 0.175
    gcs_failsafe: Annotated[str, one_of("brake", "land", "rtl", "off")] = "land"
    telemetry: Annotated[TelemetryParams, Params()] = TelemetryParams()
    dead_gcs: Annotated[DeadGcsParams, Params()] = DeadGcsParams()


class SimulatorSection(Section):
    """The simulator the ground station starts for this mission (when `embedded`)."""

    embedded: bool = True
    time_mode: Annotated[str, one_of("lockstep", "realtime", "speedup")] = "lockstep"
    # lockstep frames before the answer to a frame takes effect
    lockstep_delay_frames: Annotated[int, Range(ge=0, le=1, unit="frames")] = 1
    # us each side of a lockstep exchange polls for the other's packets, then blocks
    lockstep_spin_us: Annotated[float, Range(ge=0, le=20000, unit="us")] = 1000.0
    speedup: Annotated[float, Range(gt=0, le=10000)] = 1.0  # simulated seconds per wall second ("speedup")
    seed: Annotated[int, Range(ge=0, le=2**32 - 1)] = 0
    # physics rate, >= run.control_rate_hz (checks.py)
    rate_hz: Annotated[float, Range(le=100000, unit="Hz")] = 1000.0
    base_port: Annotated[int, Range(ge=1024, le=65535)] = 14540  # vehicle i listens on base_port + i
    # the persona of vehicles whose `autopilot` is auto (a vehicle's explicit autopilot wins)
    autopilot: Annotated[str, one_of("ardupilot", "px4")] = "ardupilot"


FORWARD_HINT = "a connection string such as udpout:127.0.0.1:14550"
FORWARD_PATTERN = r"(udpout|udpin|udp|tcp):[^:\s]+:\d{1,5}|serial:\S+|/dev/\S+"


class RunSection(Section):
    control_rate_hz: Annotated[float, Range(gt=0, le=1000, unit="Hz")] = 50.0
    time_limit_s: Annotated[float, Range(gt=0, unit="s")] = 300.0
    goal_tolerance_m: Annotated[float, Range(gt=0, unit="m")] = 1.0
    hold_s: Annotated[float, Range(ge=0, unit="s")] = 2.0
    airborne_start: bool = False
    takeoff_timeout_s: Annotated[float, Range(gt=0, unit="s")] = 60.0
    preflight_timeout_s: Annotated[float, Range(gt=0, unit="s")] = 60.0
    land_timeout_s: Annotated[float, Range(gt=0, unit="s")] = 300.0
    leader_takeover_timeout_s: Annotated[float, Range(gt=0, unit="s")] = 30.0
    simulator: SimulatorSection = SimulatorSection()
    signing_key_file: Annotated[str, text()] = ""  # "": none
    keep_params: bool = False
    # other ground stations watching through this one (docs/watching-with-qgc.md); forward_rw: may command
    forward: list[Annotated[str, text(FORWARD_PATTERN, FORWARD_HINT)]] = []
    forward_rw: bool = False


class PlannerSection(Section):
    dimensions: Annotated[int, Range(ge=2, le=3)] = 3
    dt: Annotated[float, Range(gt=0, unit="s")] = 0.01  # below time_limit_s (checks.py)
    time_limit_s: Annotated[float, Range(gt=0, unit="s")] = 60.0
    speed: Annotated[float, Range(gt=0, unit="m/s")] = 0.0  # 0: limits.v_xy_leader
    goal_radius: Annotated[float, Range(gt=0, unit="m")] = 0.5
    step: Annotated[str, one_of("proportional", "constant")] = "proportional"
    start: Position | None = None


class MissionFile(Section):
    """The whole file. `goal`, `waypoints`, `legs` count as given when in `model_fields_set` (checks.py)."""

    moved_keys: ClassVar[dict[str, str]] = {
        "obstacles": "world",
        "wind": "world",
        "separation": "safety",
        "simulator": "run",
    }

    mission: MetaSection = MetaSection()
    origin: OriginSection = OriginSection(lat=DEFAULT_ORIGIN[0], lon=DEFAULT_ORIGIN[1], alt=DEFAULT_ORIGIN[2])
    vehicles: list[VehicleEntry]
    formation: FormationSection = FormationSection()
    goal: Position = ZERO
    waypoints: list[Position] = []
    legs: list[LegEntry] = []  # [add] the route as legs (model.Leg); instead of goal or waypoints
    world: WorldSection = WorldSection()
    guidance: Annotated[FieldParams, Params(skip=("reference", "reshape", "pace"))] = FieldParams()
    reference: Annotated[ReferenceParams, Params()] = Field(
        ReferenceParams(), validation_alias=AliasPath("guidance", "reference")
    )
    reshape: Annotated[ReshapeParams, Params()] = Field(
        ReshapeParams(), validation_alias=AliasPath("guidance", "reshape")
    )
    pace: Annotated[CapabilityParams, Params()] = Field(
        CapabilityParams(), validation_alias=AliasPath("guidance", "pace")
    )
    control: ControlSection = ControlSection()
    limits: Annotated[Limits, Params()] = Limits()
    safety: SafetySection = SafetySection()
    run: RunSection = RunSection()
    planner: PlannerSection = PlannerSection()


# ---------------------------------------------------------------- pydantic errors -> sentences

_EXPECTED = {
    "float_type": "a number",
    "finite_number": "a finite number",
    "int_type": "a whole number",
    "bool_type": "true or false",
    "string_type": "text",
    "list_type": "a list",
}


def _sentence(error: ErrorDetails) -> str:
    kind, value = error["type"], error["input"]
    if kind == "missing":
        return "required key is missing"
    if kind == "float_type" and isinstance(value, int) and not isinstance(value, bool):
        return "the number is too large"
    if kind in _EXPECTED:
        return f"expected {_EXPECTED[kind]}, got {describe(value)}"
    return str(error.get("ctx", {}).get("message", error["msg"]))


def _where(error: ErrorDetails) -> tuple[str | int, ...]:
    """The key path of the error, without the tags of a position's form (`_form`)."""
    loc = (*error["loc"], *error.get("ctx", {}).get("at", ()))
    return tuple(step for step in loc if not (isinstance(step, str) and step in ("<enu>", "<geo>")))


def validate_file(root: Node) -> MissionFile:
    """The mapping (`root`, from `yaml_tree.parse_yaml`) validated; MissionError at the first mistake."""
    try:
        return MissionFile.model_validate(root.plain())
    except ValidationError as exc:
        error = exc.errors()[0]
        raise root.at(_where(error)).error(_sentence(error)) from None


def error_sentence(exc: ValidationError) -> str:
    """The first mistake pydantic found, as "path: sentence" ("sentence" for the whole document)."""
    error = exc.errors()[0]
    path = loc_path(_where(error))
    return f"{path}: {_sentence(error)}" if path else _sentence(error)


def settings_problem(settings: Mapping[str, object]) -> str | None:
    """What is wrong with mission-file keys given by dotted path ({"control.smc.xy.disturbance_gain": 0.5},
    as a variant of a mission sets them): "path: sentence" as a mission file holding them would be told, or
    None. Only the keys given are checked; rules across keys run when the derived mission file is loaded."""
    document: dict[str, Any] = {}
    for path, value in settings.items():
        *sections, key = path.split(".")
        section = document
        for name in sections:
            section = section.setdefault(name, {})
        section[key] = value
    try:
        MissionFile.model_validate(document)
    except ValidationError as exc:
        for error in exc.errors():
            if error["type"] != "missing":
                return f"{loc_path(_where(error))}: {_sentence(error)}"
    return None
