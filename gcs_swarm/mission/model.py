"""What a mission file describes, as frozen dataclasses (local ENU metres, seconds; degrees where `_deg`).

Vectors are read-only float numpy arrays of shape (3,). Equality compares arrays by value, so two loads of the
same file compare equal. The loader (`gcs_swarm.mission.loader`) is the only code that builds these from text.
Sections the file gives as they are used (the simulator, the wind) are the schema's frozen models.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

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
from gcs_swarm.mission.schema import SimulatorSection, WindSection


def frozen_vector(values: Any) -> np.ndarray:
    """A read-only float64 copy of `values` (any shape)."""
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and np.array_equal(a, b)
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


class _ValueEquality:
    """Field-by-field equality that compares numpy arrays by value (dataclass eq would raise on them)."""

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(
            _same(getattr(self, f.name), getattr(other, f.name))
            for f in dataclasses.fields(self)  # type: ignore[arg-type]
        )

    __hash__ = None  # type: ignore[assignment]  # arrays are unhashable


@dataclasses.dataclass(frozen=True, eq=False)
class Obstacle(_ValueEquality):
    """A sphere (a circle in 2-D planning) moving at constant velocity (spec 2.1): c(t) = c0 + v*t."""

    center: np.ndarray  # (3,) m, ENU, at t = 0
    radius: float  # m
    velocity: np.ndarray  # (3,) m/s, ENU

    def center_at(self, t: float) -> np.ndarray:
        """Centre (3,) in m at mission time t in s."""
        return self.center + self.velocity * t


@dataclasses.dataclass(frozen=True, eq=False)
class Zone(_ValueEquality):
    """An exclusion zone of the fence, horizontal m ENU: a polygon, or a circle (center, radius)."""

    name: str  # as the mission names it, or its key path ("safety.geofence.exclusions[1]")
    polygon: np.ndarray | None  # (K, 2) m, vertices in order, not closed; None: a circle
    center: np.ndarray | None  # (2,) m, the circle's centre; None: a polygon
    radius: float  # m, the circle's radius; 0.0 for a polygon


@dataclasses.dataclass(frozen=True, eq=False)
class Fence(_ValueEquality):
    """The site fence beside the radius cylinder of `SafetySpec` (safety.geofence): the inclusion polygon the
    vehicles stay inside and the zones they stay out of, horizontal m ENU, at every height."""

    polygon: np.ndarray | None = None  # (K, 2) m, vertices in order, not closed; None: no polygon
    exclusions: tuple[Zone, ...] = ()
    upload: bool = False  # also install it on the autopilots (gcs_swarm.flight.geofence)


@dataclasses.dataclass(frozen=True, eq=False)
class Prism(_ValueEquality):
    """A vertical prism (a building): a footprint polygon between two heights, m ENU."""

    name: str  # as the mission names it, or its key path ("world.prisms[0]")
    footprint: np.ndarray  # (K, 2) m, vertices in order, not closed
    bottom: float  # m above the origin
    top: float  # m above the origin, > bottom


@dataclasses.dataclass(frozen=True, eq=False)
class Cylinder(_ValueEquality):
    """A vertical cylinder (a tree, a mast) between two heights, m ENU."""

    name: str  # as the mission names it, or its key path ("world.cylinders[0]")
    center: np.ndarray  # (2,) m
    radius: float  # m
    bottom: float  # m above the origin
    top: float  # m above the origin, > bottom


@dataclasses.dataclass(frozen=True)
class Leg:
    """One leg of the leader's route [add] (issue 37, mission key `legs`): from where the leg before ended
    (the leader's start, for the first) through Mission.waypoints[first:] up to the next leg's `first`,
    flown in its own formation at its own speed. Every field is resolved at load: a leg that does not set one
    keeps the leg before's (the first: the mission's `formation` and `limits.v_xy_leader`)."""

    name: str  # as the mission names it, or its key path ("legs[1]")
    first: int  # index into Mission.waypoints of the leg's first waypoint
    shape: str  # formation shape flown on the leg: "v" | "line" | "column" | "grid" | "offsets"
    spacing: float  # m between neighbouring slots
    speed: float  # m/s, the leader's horizontal speed cap on the leg
    altitude: float | None  # m above the origin every waypoint of the leg is at; None: their own heights


def leg_at(legs: tuple[Leg, ...], waypoint_index: int) -> int:
    """Index of the leg whose waypoints include Mission.waypoints[waypoint_index] (0 without legs)."""
    return max((k for k, leg in enumerate(legs) if leg.first <= waypoint_index), default=0)


@dataclasses.dataclass(frozen=True, eq=False)
class StartState(_ValueEquality):
    """Where the simulator spawns a vehicle (ENU m, m/s); yaw_deg counter-clockwise from East (spec 1.1)."""

    position: np.ndarray  # (3,) m
    velocity: np.ndarray  # (3,) m/s
    yaw_deg: float


@dataclasses.dataclass(frozen=True)
class OutageSpec:
    """No packet crosses a vehicle's link (None: every vehicle's) for duration_s simulated s from start_s."""

    vehicle: int | None  # index in vehicle order (the simulator's vehicle number), None: every vehicle
    start_s: float  # s, simulated time
    duration_s: float  # s, > 0; math.inf: for good


@dataclasses.dataclass(frozen=True)
class LinkSpec:
    """Radio-link faults the simulator applies to every vehicle's link, both directions (docs/sitl.md)."""

    loss: float = 0.0  # probability a packet is lost
    delay_ms: float = 0.0  # one-way delay, simulated ms
    jitter_ms: float = 0.0  # extra delay uniform in 0..jitter_ms
    dup: float = 0.0  # probability a packet is delivered twice
    corrupt: float = 0.0  # probability one byte is flipped
    reorder: float = 0.0  # probability a packet is held back 60 ms more
    from_s: float = 0.0  # s, the rates above act from this simulated time on
    outages: tuple[OutageSpec, ...] = ()
    # the radio under every link (docs/radio.md): a swarm_common.radio_presets name (None: unlimited
    # capacity), then any of its figures overridden (None: the preset's), combined by radio_spec
    radio: str | None = None
    capacity_bps: float | None = None  # bit/s
    bits_per_byte: float | None = None  # bit times on the air per byte
    overhead_bytes: int | None = None  # bytes the radio adds to each packet
    overhead_us: float | None = None  # us of air time per packet besides its bytes
    half_duplex: bool | None = None
    shared: bool | None = None  # the whole swarm on one medium
    buffer_bytes: int | None = None  # each transmitting radio's buffer, bytes (0: one second of capacity)
    radio_status: bool | None = None  # the ground radio sends RADIO_STATUS once a second
    # bit/s of MAVLink bytes each vehicle's link carries for the ground station, up and down together (None:
    # no budget); going over it is an event (gcs_swarm.link.link_use)
    budget_bps: float | None = None
    command_mode: str = "auto"  # auto (from the budget) | attitude | position (gcs_swarm.link.command_mode)
    step_down: StepDown = StepDown()  # when the command mode steps down in flight (link.command_mode)


@dataclasses.dataclass(frozen=True, eq=False)
class World(_ValueEquality):
    """What the simulator needs from a mission."""

    origin: tuple[float, float, float]  # lat deg, lon deg, alt m AMSL of the local ENU origin
    starts: tuple[StartState, ...]  # in vehicle order (vehicle i has sysid i + 1 in the simulator)
    obstacles: tuple[Obstacle, ...]
    wind: WindSection  # steady wind and gusts for the simulator (schema.py)
    link: LinkSpec = LinkSpec()
    # in vehicle order, the autopilot each simulated vehicle behaves as: "ardupilot" | "px4" (empty: all
    # "ardupilot")
    autopilots: tuple[str, ...] = ()
    prisms: tuple[Prism, ...] = ()  # still buildings the simulator's collision check sees (world.prisms)
    cylinders: tuple[Cylinder, ...] = ()  # still trees and masts (world.cylinders)


@dataclasses.dataclass(frozen=True, eq=False)
class VehicleSpec(_ValueEquality):
    """One vehicle of the fleet."""

    name: str
    connection: str  # pymavlink connection string, e.g. "udpout:127.0.0.1:14541"
    role: str  # "leader" | "follower"
    sysid: int | None  # None: taken from the vehicle's HEARTBEAT
    slot: (
        np.ndarray | None
    )  # (3,) m, explicit offset in the leader's heading frame (FLU); None: from the shape
    start: StartState
    target: np.ndarray | None  # (3,) m ENU, a follower's own final destination g_i (spec 8 step 1)
    autopilot: str = "auto"  # "auto" (HEARTBEAT.autopilot decides) | "ardupilot" | "px4"


@dataclasses.dataclass(frozen=True, eq=False)
class FormationSpec(_ValueEquality):
    """Formation shape and communication topology (spec 6)."""

    shape: str  # "v" | "line" | "column" | "grid" | "offsets"
    spacing: float  # m
    angle_deg: float  # V half-angle
    altitude: float  # m above the origin: take-off and formation altitude
    topology: str  # "broadcast" | "relay"
    adjacency: np.ndarray | None  # (N, N) 0/1 ints in vehicle order; A[i, j] = 1: vehicle i hears vehicle j
    # [add] slots the mission does not pin (no vehicle sets `slot` or `target`) go to followers by least total
    # travel at every (re-)formation; False: in vehicle order
    assign_slots: bool = True


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """How a mission is flown."""

    control_rate_hz: float
    time_limit_s: float
    goal_tolerance_m: float
    hold_s: float
    airborne_start: bool
    takeoff_timeout_s: float
    preflight_timeout_s: float  # s to wait for every vehicle's position estimate and pre-arm health
    land_timeout_s: float  # s to wait, after LAND, until every vehicle has disarmed
    # s the others hold after the leader was taken over, in `gcs-swarm run`, before they land
    leader_takeover_timeout_s: float
    simulator: SimulatorSection  # the embedded simulator, as the file gives it (schema.py)
    signing_key_file: Path | None = None  # MAVLink 2 signing key (64 hex chars); relative to the mission file
    keep_params: bool = False  # leave the parameters the run set (GUID_OPTIONS, FS_GCS_*, ...) as flown
    forward: tuple[str, ...] = ()  # connection strings of ground stations watching through this one
    forward_rw: bool = False  # the forwards may command the vehicles (else read-only)


@dataclasses.dataclass(frozen=True)
class SafetySpec:
    """Separation, altitude floor, geofence (a cylinder around the origin), the GCS-loss failsafe and how the
    ground station treats ageing telemetry (docs/reliability.md)."""

    separation: SeparationParams
    min_altitude: float  # m above the origin
    geofence_radius: float  # m, horizontal, around the origin
    geofence_max_alt: float  # m above the origin
    collision_radius: float  # m, vehicle radius for collision checks (Table 2 arm length)
    gcs_failsafe: str  # "brake" | "land" | "rtl" | "off"
    telemetry: TelemetryParams = TelemetryParams()
    dead_gcs: DeadGcsParams = DeadGcsParams()


@dataclasses.dataclass(frozen=True, eq=False)
class PlannerSpec(_ValueEquality):
    """The kinematic point-mass planner of `gcs-swarm plan` (spec 9.1, 11.3)."""

    dimensions: int  # 2 (x, y only) or 3
    dt: float  # s
    time_limit_s: float
    speed: float  # m/s cap
    goal_radius: float  # m
    step: str  # "proportional" | "constant" (spec 11.3)
    start: np.ndarray | None  # (3,) m; None: the leader's start position


@dataclasses.dataclass(frozen=True, eq=False)
class Mission(_ValueEquality):
    """A validated mission file."""

    name: str
    description: str
    path: Path
    origin: tuple[float, float, float]  # lat deg, lon deg, alt m AMSL
    vehicles: tuple[VehicleSpec, ...]
    formation: FormationSpec
    goal: np.ndarray  # (3,) m ENU, the leader's final goal (= waypoints[-1])
    waypoints: tuple[np.ndarray, ...]  # leader waypoints, ending at the goal
    obstacles: tuple[Obstacle, ...]
    wind: WindSection  # steady wind and gusts for the simulator (schema.py)
    link: LinkSpec
    field: FieldParams
    reference: ReferenceParams
    reshape: ReshapeParams  # [add] deliberate reshaping around obstacles (guidance.reshape)
    controller: str  # "smc" | "pid"
    smc: SMCParams
    pid: PIDParams
    limits: Limits
    safety: SafetySpec
    run: RunSpec
    planner: PlannerSpec
    # [add] the leader's pace from what its followers can fly (guidance.pace)
    pace: CapabilityParams = dataclasses.field(default_factory=CapabilityParams)
    # [add] the site (issue 37): the fence, buildings and trees (avoided: spec 2.2); rally points (RTL's)
    fence: Fence = dataclasses.field(default_factory=Fence)
    prisms: tuple[Prism, ...] = ()
    cylinders: tuple[Cylinder, ...] = ()
    rally: tuple[np.ndarray, ...] = ()  # (3,) m ENU each, rally points
    # [add] the route as legs, each in its own formation and speed (issue 37); () when written as `goal` or
    # `waypoints` (one leg in the mission's formation)
    legs: tuple[Leg, ...] = ()

    @property
    def leader_index(self) -> int:
        """Index of the leader in `vehicles`."""
        return next(i for i, v in enumerate(self.vehicles) if v.role == "leader")

    def world(self) -> World:
        """The simulator's view of this mission."""
        return World(
            origin=self.origin,
            starts=tuple(v.start for v in self.vehicles),
            obstacles=self.obstacles,
            wind=self.wind,
            link=self.link,
            autopilots=tuple(
                self.run.simulator.autopilot if v.autopilot == "auto" else v.autopilot for v in self.vehicles
            ),
            prisms=self.prisms,
            cylinders=self.cylinders,
        )
