"""Which autopilot each simulated vehicle impersonates: the persona base class and the registry of personas.

The physics, the attitude controller and the shared outer loop (sitl_sim.autopilot.copter.Autopilot,
sitl_sim.autopilot.outer_loop) are the same for every vehicle. Whatever differs per autopilot is asked of the
vehicle's persona: its default ready delay and telemetry rates, its parameter table (names, encoding, the
mirrors of its parameters into the shared loop's columns), its HEARTBEAT, its pre-arm verdict, its rules
around each tick of the shared loop (failsafes, auto-disarm, takeoff limits), and its landing descent profile.
One module per persona: ArduCopter's in sitl_sim.autopilot.arducopter, PX4's in sitl_sim.autopilot.px4 (and
their MAVLink surfaces in sitl_sim.network.commands / .px4_commands, chosen by sitl_sim.network.surfaces).

A persona class answers the fleet-wide questions asked before the autopilot exists (class attributes and
class methods); an instance holds the persona's own state for its vehicles of one Autopilot (`rows`) and
plays its rules. The registry knows every persona by its `--autopilot` name and refuses any other name:
there is no silent default persona.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from sitl_sim.autopilot.outer_loop import DESCENT_TWO_SPEED
from sitl_sim.autopilot.params import ParamSpec, ParamTable

if TYPE_CHECKING:
    from sitl_sim.autopilot.copter import Autopilot


class Persona:
    """An autopilot's behaviour over the shared autopilot `ap`, for its vehicles `rows` (N,) bool.

    Subclasses set the class attributes and override the methods whose behaviour differs; the defaults here
    are "no rules of its own" (nothing before or after the shared loop, no parameters of its own).
    """

    name: ClassVar[str] = ""  # the `--autopilot` name
    ready_delay_s: ClassVar[float] = 0.0  # default simulated s from boot to the position estimate
    default_rates_hz: ClassVar[Mapping[int, float]] = {}  # MAVLink message id -> Hz on a new link (0: off)
    bytewise_params: ClassVar[bool] = False  # PARAM_VALUE integers bytewise (else as float values)
    shows_shared_params: ClassVar[bool] = True  # the shared (ArduCopter-named) table is its parameter surface
    reports_ekf_status: ClassVar[bool] = False  # sends ardupilotmega's EKF_STATUS_REPORT
    # the shared loop's landing descent (outer_loop.DESCENT_*) and, for DESCENT_INTERPOLATED, the parameters
    # it reads (outer_loop.Descent documents the order) and its two constants
    descent_profile: ClassVar[int] = DESCENT_TWO_SPEED
    descent_params: ClassVar[tuple[str, ...]] = ()
    descent_accel_down: ClassVar[float] = 0.0  # m/s^2
    descent_range_max: ClassVar[float] = 0.0  # m, the height a range finder measures up to
    # own parameter -> (the shared loop's column it drives, scale); shared columns hidden and held fixed
    mirrors: ClassVar[Mapping[str, tuple[str, float]]] = {}
    hidden_fixed: ClassVar[Mapping[str, float]] = {}

    def __init__(self, ap: Autopilot, rows: np.ndarray) -> None:
        self.ap = ap
        self.rows = np.asarray(rows, dtype=bool)

    # --- before the fleet exists ----------------------------------------------------------------------------

    @classmethod
    def param_specs(cls, hover_fraction: float) -> tuple[ParamSpec, ...]:
        """The parameters of its own, beyond the shared table (hover_fraction: MOT_THST_HOVER's default)."""
        return ()

    @classmethod
    def shows(cls, spec: ParamSpec, own: tuple[ParamSpec, ...], shared: bool) -> bool:
        """Whether its vehicles list `spec` (one of its `own` parameters, or of the shared table when
        `shared`): its own parameters, the simulator's SIM_*, and the shared table when that is its
        surface."""
        return spec in own or spec.name.startswith("SIM_") or (shared and cls.shows_shared_params)

    @classmethod
    def configure(cls, table: ParamTable, rows: np.ndarray) -> None:
        """Its vehicles' hidden shared columns, from its own parameters (mirrors) or fixed (hidden_fixed)."""
        for name, (column, scale) in cls.mirrors.items():
            own = table.values[rows, table.column_index(name)]
            table.values[rows, table.column_index(column)] = own * scale
        for name, value in cls.hidden_fixed.items():
            table.values[rows, table.column_index(name)] = value

    @classmethod
    def parameter_set(cls, table: ParamTable, i: int, name: str) -> None:
        """Vehicle i's parameter `name` was set: a mirrored one drives its shared column at once."""
        if name in cls.mirrors:
            column, scale = cls.mirrors[name]
            table.values[i, table.column_index(column)] = table.value(i, name) * scale

    # --- over the fleet -------------------------------------------------------------------------------------

    def heartbeat(self, i: int) -> tuple[int, int, int, int]:
        """(autopilot, base_mode, custom_mode, system_status) of vehicle i's HEARTBEAT."""
        raise NotImplementedError

    def prearm_ok(self, i: int) -> bool:
        """SYS_STATUS's pre-arm check bit: vehicle i would arm now."""
        raise NotImplementedError

    def before_loop(self, t: float, dt: float) -> None:
        """Its rules before the shared loop's tick at simulated time t (s) covering dt (s)."""

    def after_loop(self, t: float, events: np.ndarray) -> None:
        """Its rules after the shared loop's tick; events (N,): the loop's outer_loop.EVENT_* per vehicle."""


def persona_classes() -> dict[str, type[Persona]]:
    """Every persona by its `--autopilot` name."""
    from sitl_sim.autopilot.arducopter import ArduCopter  # noqa: PLC0415 - the persona modules import this one
    from sitl_sim.autopilot.px4 import Px4  # noqa: PLC0415

    return {persona.name: persona for persona in (ArduCopter, Px4)}


def persona_named(name: str) -> type[Persona]:
    """The persona called `name`; ValueError (a one-line reason) for a name no persona has."""
    personas = persona_classes()
    if name not in personas:
        raise ValueError(f"--autopilot {name!r} is not one of {', '.join(personas)}")
    return personas[name]


def parse_autopilots(text: str, vehicles: int) -> tuple[str, ...]:
    """`--autopilot` text -> one persona name per vehicle: a single name applies to all, a comma list gives
    one per vehicle. Raises ValueError (a one-line reason) for an unknown name or a wrong count."""
    names = tuple(part.strip().lower() for part in text.split(","))
    for name in names:
        persona_named(name)
    if len(names) == 1:
        return names * vehicles
    if len(names) != vehicles:
        raise ValueError(f"--autopilot lists {len(names)} autopilots for {vehicles} vehicles")
    return names


def fleet_personas(names: tuple[str, ...], vehicles: int) -> tuple[type[Persona], ...]:
    """The persona of each of `vehicles` vehicles from their names (() : ArduCopter for all)."""
    return tuple(persona_named(name) for name in names) if names else (persona_named("ardupilot"),) * vehicles


def fleet_params(
    shared: tuple[ParamSpec, ...], hover_fraction: float, personas: tuple[type[Persona], ...]
) -> ParamTable:
    """One parameter table for a fleet whose vehicle i is personas[i]: the `shared` specs (the shared loop's
    columns, in ArduCopter's names and units) plus every persona's own (whether or not the fleet has one);
    each vehicle lists what its persona shows, and its hidden shared columns follow its persona's values
    (Persona.configure)."""
    kinds = tuple(persona_classes().values())
    own = {kind: kind.param_specs(hover_fraction) for kind in kinds}
    specs = tuple(sorted(shared + tuple(s for kind in kinds for s in own[kind]), key=lambda spec: spec.name))
    is_shared = [spec in shared for spec in specs]
    shown = {
        kind: [kind.shows(spec, own[kind], flag) for spec, flag in zip(specs, is_shared, strict=True)]
        for kind in kinds
    }
    visible = np.array([shown[kind] for kind in personas])
    table = ParamTable(len(personas), specs, {}, visible)
    for kind in kinds:
        kind.configure(table, np.flatnonzero([persona is kind for persona in personas]))
    return table
