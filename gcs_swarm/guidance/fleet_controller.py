"""One control tick for the whole fleet: formation targets, potential field, reference generator, position
controller (any `gcs_swarm.guidance.controller.PositionController`: SMC or PID) and thrust/attitude inversion
(spec 5-8).

Everything is local ENU metres, FLU body, rad; arrays have one row per vehicle (N). The ground station calls
`tick` once per control period with the measured state; the returned `Command` rows of active vehicles become
SET_ATTITUDE_TARGET messages (the link converts frames and thrust).

The per-vehicle work of every step is a compiled kernel of the module that owns its law (formation, field,
separation, failsafe_speed, reference, smc, inversion, attitude_slew; swarm_common.jit); `tick` strings them
together and evaluates most transcendental functions (cos, sin, arctan2, arcsin) with numpy between them
(the obstacle repulsion's rho^n and psi_L's atan2 are inside their kernels: libm's, in both modes). With
NUMBA_DISABLE_JIT=1 the same code runs as plain Python and gives the same commands
(tests/gcs_swarm/guidance/test_interpreted_tick.py). `prepare_kernels` compiles, or loads from numba's cache,
every kernel ahead of the first tick.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np

from gcs_swarm.guidance.attitude_slew import slew_step
from gcs_swarm.guidance.capability import NO_BUDGET, AccelBudget, SpeedEnvelope
from gcs_swarm.guidance.column_path import LeaderTrail, column_rows, path_motion
from gcs_swarm.guidance.controller import PositionController
from gcs_swarm.guidance.degradation import stale_verdict
from gcs_swarm.guidance.failsafe_speed import brake_distances, failsafe_speed_caps, speed_caps_from_table
from gcs_swarm.guidance.field import NO_RANGES, attraction, obstacle_repulsion, slot_ranges
from gcs_swarm.guidance.formation import (
    LeaderHeading,
    check_offsets,
    formation_targets,
    leader_course,
    on_slots,
    rotate_to_world,
    slot_positions,
)
from gcs_swarm.guidance.inversion import THRUST_MODES, invert
from gcs_swarm.guidance.leader_path import (
    LeaderModel,
    leader_aim,
    leader_stalls,
    predict_leader_path,
    waypoint_ahead,
)
from gcs_swarm.guidance.leader_wait import TURNING_MARGIN, leader_cap_scale, turn_wait_scale
from gcs_swarm.guidance.params import (
    CapabilityParams,
    DeadGcsParams,
    FieldParams,
    G,
    Limits,
    ReferenceParams,
    ReshapeParams,
    SeparationParams,
    SMCParams,
)
from gcs_swarm.guidance.reference import ReferenceGenerator, default_d_g, no_budgets, paper_literal_reference
from gcs_swarm.guidance.reshape import (
    SAMPLE_STEP_M,
    FormationShaper,
    Route,
    ShapeChange,
    closest_pair_sampled,
    shape_clearance,
    shape_repulsion_range,
)
from gcs_swarm.guidance.route_plan import Detour, detour
from gcs_swarm.guidance.separation import (
    closing_deceleration,
    closing_range,
    closing_speed_caps,
    repulsion_range,
    uav_repulsion,
)
from gcs_swarm.guidance.slot_assignment import closest_approach
from gcs_swarm.guidance.smc import SMCController
from gcs_swarm.guidance.topology import TOPOLOGIES, LeaderRelay, check_adjacency, star_adjacency
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays
from swarm_common.rotations import wrap_pi_float

NO_ROWS = np.zeros((0, 3))
RESHAPE_GAP_M = 1.0  # m beyond D_Emg kept between followers whose slots move in a reshape
OWN_CAP_MIN_SPEED_M_S = 0.5  # m/s: a slower reference has no heading to cap its speed along
PACE_EVENT_SHARE = 0.1  # a new pace event when the followers' cap moves by more than this share
CORNER_TOLERANCE_M = 2.0  # m, how far the leader's route round a gap may stray to bend fewer times
TRAIL_KEEP_MARGIN_M = 50.0  # m of the leader's path kept beyond its column's length (_follow_path)
COURSE_MIN_SPEED = 0.5  # m/s: slower, the leader's course gives no along-track acceleration (_follow_path)
_prepared = False  # every kernel was called once in this process (prepare_kernels)


def prepare_kernels(dead_gcs: DeadGcsParams | None) -> None:
    """What a FleetController needs before its first tick, done ahead (idempotent; both are kept for the
    process): the stopping-distance table of `dead_gcs`'s speed scheduling, and one call of every guidance
    kernel, so that each is compiled, or loaded from numba's cache, now and no tick waits for it.
    gcs_swarm.flight.fly calls it while the embedded simulator starts, before the vehicles arm; every
    FleetController calls it."""
    if dead_gcs is not None and dead_gcs.speed_scheduling:
        failsafe_speed_caps(
            np.zeros((1, 3)), np.zeros((1, 3)), NO_ROWS, np.zeros(0),
            float(dead_gcs.failsafe_timeout_s or 0.0), float(dead_gcs.brake_accel or 0.0), dead_gcs.clearance,
            float(dead_gcs.brake_jerk or 0.0),
        )  # fmt: skip
    global _prepared
    if _prepared:
        return
    _prepared = True
    offsets = np.array([[0.0, 0.0, 0.0], [-5.0, 2.0, 0.0], [-5.0, -2.0, 0.0]])
    pos = offsets + np.array([0.0, 0.0, 10.0])
    obstacle_c, obstacle_r = pos[:1] + 3.0, np.ones(1)
    for mode in ("constant", "formula"):
        ctl = FleetController(
            3, 0, offsets, np.array([[100.0, 0.0, 10.0]]), separation=SeparationParams(mode=mode), z_min=1.0
        )
        ctl.reset(pos, np.zeros((3, 3)), np.zeros(3))
        ctl.tick(0.0, pos, np.ones((3, 3)), np.zeros((3, 3)), obstacle_c, obstacle_r, np.ones(3, dtype=bool))
    shape_clearance(
        offsets[None],
        np.zeros(3, dtype=np.int64),
        np.flatnonzero(offsets[:, 0]),
        pos,
        np.zeros(3),
        obstacle_c,
        obstacle_r,
        *NO_SHAPES,
    )  # reshape
    closest_pair_sampled(pos[None])  # a change of shape's separation, sampled (reshape.closest_pair_in) ...
    closest_approach(offsets, pos)  # ... and exact (slot_assignment)
    assert ctl.heading is not None  # the leader's path flown forward (leader_path: look-ahead, gaps)
    goal = pos[0] + 30.0
    leader_stalls(
        ctl.leader_model, pos[0], np.ones(3), np.zeros(3), ctl.heading, goal, 5.0, obstacle_c, obstacle_r
    )
    table = np.array([0.0, 1.0])  # the failsafe speed scheduling's kernels, on a small table
    brake_distances(table, 7.5, 5.0, 0.002, 2)
    speed_caps_from_table(pos, np.ones((3, 3)), obstacle_c, obstacle_r, 1.0, table, table, *NO_SHAPES)
    alive = np.ones(3, dtype=bool)  # the stale-telemetry rule (degradation.StaleTelemetryMonitor.assess)
    stale_verdict(np.zeros(3), alive, ~alive, pos, np.ones((3, 3)), 0, 1.0, 0.3)


@dataclass(frozen=True)
class Command:
    """Output of one tick. Rows of inactive vehicles are NaN and must not be sent.

    roll_d, pitch_d, yaw_d (N,) rad (FLU body / ENU world, ZYX); thrust_acc (N,) = U1/m in m/s^2 (normalised
    thrust = MOT_THST_HOVER * thrust_acc / g). Diagnostics: ref_pos/ref_vel/ref_acc (N, 3) the SMC's desired
    state, field_force (N, 3) field units, slots (N, 3) formation targets (the leader's row is its current
    waypoint), u (N, 3) limited thrust acceleration, emergency (N,) inside D_Emg of another vehicle,
    psi_leader rad, waypoint_index (the mission waypoint whose leg the leader flies), leader_goal_distance m
    (leader to the point of its route it flies to: its waypoint, or a via point round a gap).
    """

    active: np.ndarray
    roll_d: np.ndarray
    pitch_d: np.ndarray
    yaw_d: np.ndarray
    thrust_acc: np.ndarray
    ref_pos: np.ndarray
    ref_vel: np.ndarray
    ref_acc: np.ndarray
    field_force: np.ndarray
    slots: np.ndarray
    u: np.ndarray
    emergency: np.ndarray
    psi_leader: float
    waypoint_index: int
    leader_goal_distance: float


def _as_array(name: str, value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """`value` as a C-contiguous float array (the kernels take such rows); ValueError if not of `shape`."""
    arr = np.ascontiguousarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    return arr


class FleetController:
    """Leader-follower IAAPF (or APF) guidance with a position controller (SMC or PID) for N vehicles
    (spec 8)."""

    def __init__(
        self,
        n: int,
        leader: int,
        offsets: np.ndarray,
        goal_waypoints: np.ndarray,
        follower_targets: np.ndarray | None = None,
        field: FieldParams | None = None,
        separation: SeparationParams | None = None,
        reference: ReferenceParams | None = None,
        limits: Limits | None = None,
        position_controller: PositionController | None = None,
        adjacency: np.ndarray | None = None,
        topology: str = "broadcast",
        control_dt: float = 0.02,
        thrust_mode: str = "measured",
        g: float = G,
        z_min: float | None = None,
        dead_gcs: DeadGcsParams | None = None,
        reshape: ReshapeParams | None = None,
        pace: CapabilityParams | None = None,
        names: tuple[str, ...] = (),
        shapes: ShapeArrays = NO_SHAPES,
        still_obstacles: ShapeArrays = NO_SHAPES,
    ) -> None:
        """`n` vehicles, `leader` its index; `offsets` (N, 3) leader-frame slots (leader row zero),
        `goal_waypoints` (W, 3) the leader's goals in order, `follower_targets` (N, 3) final destinations g_i
        for the adaptive factor (default g_L + R(psi_L) delta_i, spec 8 step 1), `topology` "broadcast"
        (every follower hears the leader at once) or "relay" (one tick of delay per hop along `adjacency`,
        default the star graph), `position_controller` the control law of step 7 (None: the SMC with the
        spec's gains and `limits`; gcs_swarm.guidance.controller.make_position_controller builds a mission's
        choice), `thrust_mode` "measured" (Eq 36) or "norm" (m|U|), `control_dt` s the nominal tick,
        `dead_gcs` the failsafe speed scheduling (None: off, gcs_swarm.guidance.failsafe_speed), `reshape`
        the deliberate reshaping around obstacles (None or not enabled: the paper's fixed formation,
        gcs_swarm.guidance.reshape), `pace` the leader's cap from its followers' measured drag (None or not
        enabled: v_xy_leader alone, gcs_swarm.guidance.capability), `names` the vehicles' names for events
        (default "vehicle <i+1>"), `shapes` the still cylinders and prisms (spec 2.2) the field, the slots and
        the failsafe speed caps avoid beside the spheres each tick is given, `still_obstacles` every obstacle
        that does not move (spheres included) the leader's route goes round where they close a gap its
        formation cannot fly (reshape.route_round_gaps, gcs_swarm.guidance.route_plan).
        """
        if n < 1 or not 0 <= leader < n:
            raise ValueError(f"leader index {leader} is not a vehicle of a fleet of {n}")
        if topology not in TOPOLOGIES:
            raise ValueError(f"topology must be one of {TOPOLOGIES}, not {topology!r}")
        if thrust_mode not in THRUST_MODES:
            raise ValueError(f"thrust_mode must be one of {THRUST_MODES}, not {thrust_mode!r}")
        if not control_dt > 0:
            raise ValueError("control_dt must be > 0")
        self.n = n
        self.leader = leader
        self.field = field or FieldParams()
        self.separation = separation or SeparationParams()
        self.reference = reference or ReferenceParams()
        self.limits = limits or Limits()
        self.control_dt = control_dt
        self.thrust_mode = thrust_mode
        self.g = g
        self.offsets = check_offsets(offsets, n, leader)
        self.flown_offsets = self.offsets  # (N, 3) the offsets of the latest tick (reshaped or not)
        self.set_goal_waypoints(goal_waypoints)
        self.follower_targets = None if follower_targets is None else self._checked_targets(follower_targets)
        self.shapes = shapes
        self.still_obstacles = still_obstacles
        self.d_g = default_d_g(self.field, self.limits.v_xy, self.reference.k_v)
        self.d_max = repulsion_range(self.separation, self.limits.v_xy, self.limits.a_xy)
        self.closing_accel = closing_deceleration(self.separation, self.limits.tilt_max, g)  # m/s^2, 0: off
        if topology == "relay":
            graph = star_adjacency(n, leader) if adjacency is None else adjacency
            self.delays = check_adjacency(graph, n, leader)
        else:
            self.delays = np.zeros(n, dtype=int)
        self.is_leader = np.arange(n) == leader
        self.v_xy_cap = np.where(self.is_leader, self.limits.v_xy_leader, self.limits.v_xy)
        self.generator = ReferenceGenerator(self.reference, self.limits, self.field.k_att, g, z_min)
        self.position_controller: PositionController = position_controller or SMCController(
            SMCParams(), g, self.limits
        )
        self.tilt_rate_max = np.deg2rad(self.limits.tilt_rate_max_deg)  # rad/s, <= 0: no slew limit
        self.heading_rate_max = float(np.deg2rad(self.reference.heading_rate_max_deg))  # rad/s, psi_L's limit
        self.heading_accel_max = float(np.deg2rad(self.reference.heading_accel_max_deg))  # rad/s^2
        self.heading: LeaderHeading | None = None
        self.last_t: float | None = None  # s, the previous tick's time
        self.relay: LeaderRelay | None = None
        self.speed_scale = 1.0
        self.spacing_scale = 1.0
        self.leader_speed_scale = 1.0  # the leader's cap factor of the latest tick (leader_wait), in (0, 1]
        self.trail: LeaderTrail | None = None  # the leader's path while the formation is a column
        self.trail_leader = -1  # the leader whose path `trail` is
        self.path_pace = math.inf  # m/s, the leader's cap from its column's path (`_follow_path`)
        if dead_gcs is not None and None in (
            dead_gcs.failsafe_timeout_s,
            dead_gcs.brake_accel,
            dead_gcs.brake_jerk,
        ):
            raise ValueError("dead_gcs timeout and stop limits must be set (the mission loader sets them)")
        self.dead_gcs = dead_gcs
        self.reshape = reshape if reshape is not None and reshape.enabled else None
        self.shaper = (
            None
            if self.reshape is None
            else FormationShaper(
                self.reshape, self.offsets, leader, self.separation.d_emg + RESHAPE_GAP_M, hold_m=self.d_g
            )
        )
        self.leader_model = LeaderModel(
            self.generator.config, self.field, float(self.d_g), float(self.reference.brake_accel),
            float(self.reference.waypoint_radius), bool(self.reference.heading_from_route),
            math.radians(self.reference.aim_turn_rate_deg),
        )  # fmt: skip
        self.envelope = (
            None if pace is None or not pace.enabled else SpeedEnvelope(n, pace, self.limits.tilt_max, g)
        )
        self.follower_pace = math.inf  # m/s, the leader's cap from its followers' top speeds (`envelope`)
        if self.shaper is not None and self.envelope is None:
            self.shaper.followers_can_fly(None)
        self.start_pace = math.inf  # m/s, the leader's cap until its followers' drag is measured (`envelope`)
        self.footprint_paced = False  # the shaper's footprint pace holds the leader (`_footprint_event`)
        self.started_in_flight = False  # the leader was faster than the start cap's floor when the formation
        # started (`reset`): its followers are flying already, and the start's cap does not apply
        self.leader_budget = NO_BUDGET  # the leader's acceleration budget from its slowest follower (spec 6b)
        self.assembly_planned = False  # the first tick plans the formation's assembly (`_plan_assembly`)
        self.assembled = False  # every follower has been on its slot (`reset`, kept up to date by `tick`)
        self.events: list[str] = []  # what changed, for the flight's events (`drain_events`)
        self.detours: list[Detour] = []  # legs planned round a gap (`drain_detours`)
        self.names = names if len(names) == n else tuple(f"vehicle {i + 1}" for i in range(n))
        prepare_kernels(dead_gcs)  # now, not in the first formation tick, where it stalled the control loop

    # ----- live changes (operator console) -----

    def set_goal_waypoints(self, goal_waypoints: np.ndarray) -> None:
        """Replace the leader's goal list (W, 3) and restart at its first entry."""
        wp = np.asarray(goal_waypoints, dtype=float)
        if wp.ndim == 1:
            wp = wp[None, :]
        if wp.ndim != 2 or wp.shape[1] != 3 or len(wp) == 0 or not np.isfinite(wp).all():
            raise ValueError(f"goal waypoints must be a non-empty finite (W, 3) array, got shape {wp.shape}")
        self.waypoints = np.ascontiguousarray(wp)  # its rows go to a kernel
        self.waypoint_index = 0
        self.route_points = self.waypoints  # (R, 3) ENU m: the leader's route, via points among its waypoints
        self.route_legs = np.arange(len(wp))  # (R,) the index of the waypoint each route point's leg ends at
        self.route_index = 0  # into route_points: the point the leader flies to
        self.route_stale = True  # the route is rebuilt, and its first leg planned, at the next tick

    def set_goal(self, goal: np.ndarray) -> None:
        """Fly the leader to one new goal (3,); per-follower destinations revert to the default."""
        self.set_goal_waypoints(_as_array("goal", goal, (3,))[None, :])
        self.follower_targets = None

    def set_offsets(self, offsets: np.ndarray) -> None:
        """New leader-frame slot offsets (N, 3), leader row zero: with reshaping on, reached smoothly from
        the offsets flown (gcs_swarm.guidance.reshape) once the flight has begun, else at once."""
        self.offsets = check_offsets(offsets, self.n, self.leader)
        if self.shaper is not None:
            self.shaper.set_nominal(self.offsets, self.leader, self.last_t if self.heading else None)
        else:
            self.flown_offsets = self.offsets

    @property
    def on_last_point(self) -> bool:
        """The leader flies to its last waypoint, no via point of its route before it."""
        return self.route_index == len(self.route_points) - 1

    def _plan_leg(self, t: float, centres: np.ndarray, radii: np.ndarray) -> None:
        """With reshaping and route_round_gaps on, the leg the leader starts now (to the waypoint
        route_points[route_index]) goes round a cluster of still obstacles that closes a gap its formation's
        narrowest shape cannot fly (route_plan.detour), if the leader's own field would stall it in front of
        that gap on the straight leg (leader_path.leader_stalls, among this tick's spheres (K, 3), (K,) m):
        via points go in before the waypoint, and an event says so (spec 6a.8)."""
        if self.shaper is None or self.reshape is None or not self.reshape.route_round_gaps:
            return
        lead, gen = self.leader, self.generator
        goal = self.route_points[self.route_index]
        narrowest = self.shaper.shapes[-1].offsets
        half_width = float(np.max(np.abs(narrowest[:, 1])))
        clearance = self.reshape.gap_clearance_m
        via = detour(gen.p[lead], goal, self.still_obstacles, clearance, half_width, CORNER_TOLERANCE_M)
        if via is None:
            return
        assert self.heading is not None
        cap = float(self.v_xy_cap[lead] * self.speed_scale)
        if not leader_stalls(
            self.leader_model, gen.p[lead], gen.v[lead], gen.a[lead], self.heading, goal, cap, centres, radii,
            self.shapes,
        ):  # fmt: skip
            return
        k = self.route_index
        self.route_points = np.ascontiguousarray(
            np.vstack([self.route_points[:k], via, self.route_points[k:]])
        )
        self.route_legs = np.concatenate(
            [self.route_legs[:k], np.full(len(via), self.route_legs[k]), self.route_legs[k:]]
        )
        self.detours.append(Detour(t, int(self.route_legs[k]), via))
        corners = ", ".join(f"({x:.0f}, {y:.0f})" for x, y in via[:, :2])
        self.events.append(
            f"t={t:.2f} s route: round a gap too narrow for the formation, through {corners} to waypoint "
            f"{self.route_legs[k] + 1}"
        )

    @property
    def follows_path(self) -> bool:
        """The column's slots follow the leader's path this tick (spec 6a.9, `_follow_path`)."""
        return self.trail is not None

    def shape_settled(self, t: float) -> bool:
        """No change of the formation's shape is under way at vehicle time t s (the slots stand still in
        the leader's frame) nor, with reshape.arrive_in_shape, due (a wider shape fits and its way is
        clear): a formation still changing shape, or about to re-form, has not arrived."""
        if self.shaper is None:
            return True
        assert self.reshape is not None
        due = self.reshape.arrive_in_shape and self.shaper.widening_due
        return t >= self.shaper.move.t0 + self.shaper.move.duration and not due

    def set_leader_speed(self, speed: float) -> None:
        """The leader's horizontal speed cap (m/s, > 0, at most limits.v_xy_leader) from now on: a leg's."""
        if not 0.0 < speed <= self.limits.v_xy_leader:
            cap = self.limits.v_xy_leader
            raise ValueError(f"need 0 < speed <= v_xy_leader ({cap:g} m/s), got {speed:g}")
        self.v_xy_cap[self.leader] = speed

    def set_degraded(self, speed_scale: float, spacing_scale: float) -> None:
        """Degraded flight on stale telemetry (gcs_swarm.guidance.degradation): speed caps x speed_scale in
        (0, 1], formation spacing and separation ranges (D_max, D_Emg) x spacing_scale >= 1; 1, 1 = normal."""
        if not (0 < speed_scale <= 1 and spacing_scale >= 1):
            raise ValueError("need 0 < speed_scale <= 1 and spacing_scale >= 1")
        self.speed_scale, self.spacing_scale = float(speed_scale), float(spacing_scale)

    def place_uncommanded(self, row: int, pos: np.ndarray, vel: np.ndarray) -> None:
        """Where vehicle `row`, not commanded this tick (lost), is believed to be: the others repel from
        pos (3,) ENU m moving at vel (3,) m/s, not from its last report (gcs_swarm.guidance.lost_vehicles)."""
        self.last_pos[row] = _as_array("pos", pos, (3,))
        self.last_vel[row] = _as_array("vel", vel, (3,))

    def _closing_caps(self, known: np.ndarray, d_emg: float, s_s: float) -> tuple[np.ndarray, np.ndarray]:
        """(N,) m/s: nobody closes on another faster than it could stop (separation.closing_speed_caps, from
        the measured positions and velocities; `known` (N,) rows have them), short of d_emg m (s_s m in
        formula mode), and the (N,) bool rows capped on a collision course; inf and none when the cap is
        off."""
        if not self.closing_accel > 0.0:
            return np.full(self.n, np.inf), np.zeros(self.n, dtype=bool)
        gap = d_emg if self.separation.mode == "constant" else s_s
        radius = closing_range(gap, self.closing_accel, float(np.max(self.v_xy_cap)))
        return closing_speed_caps(self.last_pos, self.last_vel, known, float(gap), self.closing_accel, radius)

    def speed_caps(self) -> np.ndarray:
        """(N,) m/s: each vehicle's horizontal speed cap before the closing-speed and failsafe caps: v_xy
        (leader v_xy_leader x leader_speed_scale) x the degraded-flight speed_scale; the leader's also within
        the reshape's pace (gcs_swarm.guidance.reshape) and a column's pace along the leader's path
        (`_follow_path`); every vehicle's within what it flies itself at own_tilt_share of its tilt limit
        (`_own_top_speeds`)."""
        cap = self.v_xy_cap * self.speed_scale
        if self.leader_speed_scale < 1.0:
            cap[self.leader] *= self.leader_speed_scale
        if self.shaper is not None:  # [add] the leader gives its followers time to change shape (reshape)
            cap[self.leader] = min(cap[self.leader], self.shaper.pace_cap, self.path_pace)
        if self.follower_pace < cap[self.leader]:  # [add] no faster than the slowest follower (capability)
            cap[self.leader] = self.follower_pace
        if self.start_pace < cap[self.leader]:  # [add] nor, before it is measured, than it flies (capability)
            cap[self.leader] = self.start_pace
        if self.envelope is not None and self.envelope.params.own_tilt_share > 0:  # [add] nor than itself
            cap = np.minimum(cap, self._own_top_speeds())
        return cap

    def _own_top_speeds(self) -> np.ndarray:
        """(N,) m/s: what each vehicle flies at own_tilt_share of its tilt limit against its fitted drag,
        along its reference's horizontal velocity (capability.SpeedEnvelope.top_speeds); inf where the fit is
        not trusted or the reference is slower than OWN_CAP_MIN_SPEED_M_S."""
        assert self.envelope is not None
        v = self.generator.v
        heading = np.arctan2(v[:, 1], v[:, 0])
        caps = self.envelope.top_speeds(heading, self.envelope.params.own_tilt_share)
        moving = np.hypot(v[:, 0], v[:, 1]) >= OWN_CAP_MIN_SPEED_M_S
        return np.where(moving & np.isfinite(caps), np.maximum(caps, 0.0), np.inf)

    def _leader_path_ahead(
        self, speed_cap: float, centres: np.ndarray, radii: np.ndarray, length: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The reshape's look-ahead route (reshape.Route) for `length` m: the leader's path predicted from its
        reference state at up to speed_cap m/s among the obstacles (K, 3), (K,) m and shapes of this tick
        (gcs_swarm.guidance.leader_path)."""
        assert self.heading is not None
        lead, gen = self.leader, self.generator
        return predict_leader_path(
            self.leader_model, gen.p[lead], gen.v[lead], gen.a[lead], self.heading,
            self.route_points[self.route_index :], speed_cap, length, SAMPLE_STEP_M, centres, radii,
            self.shapes, self.aim_bearing, self.leader_budget,
        )  # fmt: skip

    def _follow_path(
        self, offsets: np.ndarray, offset_rate: np.ndarray | None, offset_accel: np.ndarray | None,
        targets: np.ndarray, v_ff: np.ndarray, a_ff: np.ndarray,
    ) -> None:  # fmt: skip
        """[add] Spec 6a.9: while the offsets flown (N, 3) make a column (column_path.column_rows), each
        column follower's slot is on the leader's path (`trail`, begun when the column formed), spaced from
        its neighbours by the chords their distances astern differ by (LeaderTrail.behind). Its feed-forwards
        are those of a point moving along the path there (column_path.path_motion) at the leader's
        horizontal speed plus the slot's own rate along the column (offset_rate, leader frame m/s), speeding
        up as the leader along its course plus offset_accel, and turning as the leader turned there:
        targets, v_ff, a_ff (N, 3) ENU are changed in place in their horizontal components, the vertical
        ones stay the leader's. The leader's pace (`path_pace`, m/s) is then what lets every slot go round
        the bends ahead of it with at most path_turn_accel_m_s2, braking at pace_decel_m_s2
        (LeaderTrail.pace); inf when not a column. The leader's position is the one measured now (the relay
        delay of spec 6 applies to the rigid slots only)."""
        assert self.reshape is not None and self.heading is not None
        rows = column_rows(offsets)
        if self.shaper is not None:
            self.shaper.bent = None
        if rows is None:
            self.trail, self.path_pace = None, math.inf
            return
        lead, scale = self.leader, self.spacing_scale
        lags = -offsets[rows, 0] * scale  # m astern
        p_lead, v_lead = self.last_pos[lead], self.last_vel[lead, :2]
        keep = float(lags.max()) + TRAIL_KEEP_MARGIN_M
        a_lead = self.generator.a[lead, :2]
        if self.trail is None or self.trail_leader != lead:
            self.trail, self.trail_leader = LeaderTrail(p_lead, v_lead, a_lead, self.heading.psi, keep), lead
        self.trail.keep_m = max(self.trail.keep_m, keep)
        self.trail.record(p_lead, v_lead, a_lead)
        points, v_then, a_then, arcs = self.trail.behind(p_lead, v_lead, a_lead, lags)
        speed = float(np.hypot(v_lead[0], v_lead[1]))
        accel = float(a_lead @ v_lead) / speed if speed > COURSE_MIN_SPEED else 0.0
        along_v = speed + (np.zeros(len(rows)) if offset_rate is None else offset_rate[rows, 0] * scale)
        along_a = accel + (np.zeros(len(rows)) if offset_accel is None else offset_accel[rows, 0] * scale)
        targets[rows, :2] = points
        if self.shaper is not None:  # where a change of shape starts from: these slots, in the leader's frame
            bent = offsets.copy()
            away = np.zeros((len(rows), 3))
            away[:, :2] = (points - p_lead[:2]) / scale
            bent[rows, :2] = rotate_to_world(away, -self.heading.psi)[:, :2]  # world -> leader frame
            self.shaper.bent = bent
        v_ff[rows, :2], a_ff[rows, :2] = path_motion(v_then, a_then, along_v, along_a)
        turn, brake = self.reshape.path_turn_accel_m_s2, self.reshape.pace_decel_m_s2
        self.path_pace = self.trail.pace(p_lead, v_lead, a_lead, arcs, turn, brake)

    def _standing_offsets(self, t: float, p_lead: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where the followers in the formation stand now relative to the leader at p_lead (3,) ENU m and
        heading psi_L, (N, 3) leader-frame m before the degraded widening, and their rate in that turning
        frame (N, 3) m/s (FormationShaper.decide's `standing`); the offsets flown at t s and their rate for
        the leader's row and the rows out of the formation or without a position."""
        assert self.shaper is not None and self.heading is not None
        flown, flown_rate, _ = self.shaper.flown(t)
        psi, turn = self.heading.psi, self.heading.rate
        here = rotate_to_world(self.last_pos - p_lead, -psi) / self.spacing_scale  # world -> leader frame
        relative = rotate_to_world(self.last_vel - self.last_vel[self.leader], -psi) / self.spacing_scale
        rate = relative - turn * np.stack([-here[:, 1], here[:, 0], np.zeros(self.n)], axis=1)
        known = np.isfinite(here).all(axis=1) & np.any(flown != 0.0, axis=1)
        return np.where(known[:, None], here, flown), np.where(known[:, None], rate, flown_rate)

    def _plan_assembly(self, t: float, p_lead: np.ndarray, goal: np.ndarray) -> None:
        """[add] Spec 6a.4: a formation that has not assembled when it starts assembles along a planned move
        from where its followers stand and at the rate they fly (`_standing_offsets`) to the mission's shape,
        as any change of shape before assembly does, instead of each follower pursuing a slot that stands
        elsewhere (gap-6: a follower crossing 7.5 m at 4.8 m/s overshot its slot by 2.1 m and turned 97 deg
        at 2.2 m/s, a cusp); its spacing scale starts at theirs. Only where that move takes at most
        reshape.assembly_move_max_s: followers farther off fly to their slots at their own speed, quicker
        than a slot may move; where the move into the mission's shape is longer but one into a narrower
        candidate is not, into the widest such (FormationShaper.assemble_from), widened once assembled as
        any narrowed formation is. Once, at the first tick with the leader's state (t s, p_lead (3,) ENU
        m); an event says which.

        With heading_from_route, each shape's move is planned first with psi_L turned to the direction from
        the leader to the point it flies to, `goal` (3,) ENU m (unless the leader is already in flight or
        within d_g of it), and taken so if it is short enough: the formation is formed facing its route, so
        that psi_L does not swing the slots round the leader while they move (gap-12: the leader's yaw 18 deg
        off its first leg; psi_L turned when the leader reached heading_min_speed, 3 s in, and swung a slot
        17 m astern across its follower's way, a cusp). Else that shape's move is planned with psi_L the
        leader's yaw, before any narrower shape is tried (real PX4 SIH starts 53 deg off its goal: turned,
        the move into its shape would take 11.4 s; unturned it takes 8.4 s).
        Once the move is taken the formation has assembled (its followers stand on the slots of the moment),
        so a change decided in the same tick is planned as one after assembly is (spec 6a.4)."""
        assert self.shaper is not None and self.reshape is not None and self.heading is not None
        self.assembly_planned = True
        if self.assembled:
            return
        to_goal = goal[:2] - p_lead[:2]
        yaw = self.heading.psi
        frames = [yaw]
        if self.reference.heading_from_route and not self.started_in_flight and np.hypot(*to_goal) > self.d_g:
            frames.insert(0, math.atan2(to_goal[1], to_goal[0]))  # facing the route, preferred
        starts = []
        for psi in frames:
            self.heading.psi = psi
            starts.append(self._standing_offsets(t, p_lead))
        taken, duration = self.shaper.assemble_from(starts, t)
        self.heading.psi = yaw if taken is None else frames[taken]
        turn = math.degrees(wrap_pi_float(self.heading.psi - yaw))
        if abs(turn) >= 1.0:
            self.events.append(f"t={t:.2f} s formation faces its route: psi_L turned {turn:+.0f} deg")
        if taken is not None:
            self.assembled = True
            self.events.append(f"t={t:.2f} s formation assembles along a planned move of {duration:.1f} s")
        else:
            self.events.append(
                f"t={t:.2f} s followers fly to their slots on their own (a planned move would take "
                f"{duration:.1f} s, over assembly_move_max_s {self.reshape.assembly_move_max_s:g} s)"
            )

    def _footprint_event(self, t: float) -> None:
        """An event where the shaper's footprint pace (spec 6a.10) starts holding the leader, with its cap,
        and where it lets go."""
        assert self.shaper is not None
        cap = self.shaper.footprint_cap
        if math.isfinite(cap) and not self.footprint_paced:
            self.events.append(
                f"t={t:.2f} s pace: leader held to {cap:.1f} m/s, where its path leaves the "
                f"{self.shaper.shape_name} room"
            )
        elif not math.isfinite(cap) and self.footprint_paced:
            self.events.append(f"t={t:.2f} s pace: leader's footprint pace off")
        self.footprint_paced = math.isfinite(cap)

    def drain_events(self) -> list[str]:
        """The guidance's events since the last call (pace changes) as "t=... s ..." lines; the changes of
        shape come apart, from `drain_shape_changes`."""
        out, self.events = self.events, []
        return out

    def drain_detours(self) -> list[Detour]:
        """The legs planned round a gap (route_plan) since the last call, oldest first."""
        out, self.detours = self.detours, []
        return out

    def drain_shape_changes(self) -> list[ShapeChange]:
        """The formation's changes of shape (reshape) since the last call, oldest first."""
        if self.shaper is None:
            return []
        out, self.shaper.changes = self.shaper.changes, []
        return out

    def _update_pace(self, t: float, vel: np.ndarray, att: np.ndarray, active: np.ndarray) -> None:
        """Feed the followers' telemetry to the drag fits; when they change, the leader's cap (spec 6b) and an
        event when it binds, leaves off, or moves by PACE_EVENT_SHARE."""
        assert self.envelope is not None and self.heading is not None
        if not self.envelope.update(t, vel, att, active):
            return
        followers = active & ~self.is_leader
        cap = self.envelope.leader_cap(self.heading.psi, followers)
        if self.shaper is not None:
            self.shaper.followers_can_fly(cap)
        nominal = float(self.v_xy_cap[self.leader])
        was = self.follower_pace
        self.follower_pace = cap
        binds, bound = cap < nominal, was < nominal
        if binds and (not bound or abs(cap - was) > PACE_EVENT_SHARE * was):
            slowest = self.envelope.slowest(self.heading.psi, followers)
            assert slowest is not None  # a finite cap comes from a trusted fit
            self.events.append(
                f"t={t:.2f} s pace: leader capped at {cap:.1f} m/s, what {self.names[slowest]} flies at "
                f"{self.envelope.params.tilt_share:.0%} tilt against its measured drag "
                f"{self.envelope.drag[slowest]:.2f} 1/s"
            )
        elif bound and not binds:
            self.follower_pace = math.inf
            self.events.append(f"t={t:.2f} s pace: every follower can fly the leader's {nominal:.1f} m/s")
        if not binds:
            self.follower_pace = math.inf
        budget = self.envelope.accel_budget(self.heading.psi, followers)
        if budget != self.leader_budget:
            if math.isinf(budget.budget) != math.isinf(self.leader_budget.budget):
                self.events.append(self._budget_event(t, budget, followers))
            self.leader_budget = budget

    def _update_start_pace(
        self, t: float, vel: np.ndarray, active: np.ndarray, offset_rate: np.ndarray | None
    ) -> None:
        """The leader's cap until its active followers' drag is measured (capability.SpeedEnvelope.start_cap,
        spec 6b), from their measured vel (N, 3) m/s and their slots' own rate (N, 3) leader-frame m/s (None:
        the slots stand still in the leader's frame), and an event when it ends."""
        assert self.envelope is not None and self.heading is not None
        forward = np.zeros(self.n) if offset_rate is None else offset_rate[:, 0] * self.spacing_scale
        followers = active & ~self.is_leader
        cap = self.envelope.start_cap(vel, self.heading.psi, forward, followers, self._start_cap_floor())
        if math.isinf(cap) and not math.isinf(self.start_pace):
            self.events.append(f"t={t:.2f} s pace: every follower's drag measured, the start's cap is off")
        self.start_pace = cap

    def _start_cap_floor(self) -> float:
        """m/s: the start's cap never holds the leader under this (psi_L turns above heading_min_speed only),
        nor applies to a formation whose leader is faster than this when it starts (spec 6b)."""
        return TURNING_MARGIN * self.reference.heading_min_speed

    def _budget_event(self, t: float, budget: AccelBudget, followers: np.ndarray) -> str:
        """The event line of the leader's acceleration budget starting (from the slowest of the (N,) bool
        followers) or ending (no follower's fit trusted)."""
        assert self.envelope is not None and self.heading is not None
        if math.isinf(budget.budget):
            return f"t={t:.2f} s pace: leader's acceleration free again (no follower's drag fit trusted)"
        slowest = self.envelope.slowest(self.heading.psi, followers)
        assert slowest is not None
        share = self.envelope.params.accel_tilt_share
        return (
            f"t={t:.2f} s pace: leader accelerates within what {self.names[slowest]} can at {share:.0%} tilt "
            f"against its measured drag {budget.drag:.2f} 1/s"
        )

    def _checked_targets(self, targets: np.ndarray) -> np.ndarray:
        arr = _as_array("follower_targets", targets, (self.n, 3))
        if not np.isfinite(arr).all():
            raise ValueError("follower_targets must be finite")
        return arr

    # ----- control -----

    def reset(self, pos: np.ndarray, vel: np.ndarray, yaw: np.ndarray, att: np.ndarray | None = None) -> None:
        """Start from the measured state: references at (pos, vel) (N, 3), psi_L = the leader's yaw (rad),
        tilt commands at the measured roll and pitch (`att` (N, 3) roll, pitch, yaw; None: level)."""
        pos = _as_array("pos", pos, (self.n, 3))
        vel = _as_array("vel", vel, (self.n, 3))
        yaw = _as_array("yaw", yaw, (self.n,))
        att = np.zeros((self.n, 3)) if att is None else _as_array("att", att, (self.n, 3))
        self.roll_cmd, self.pitch_cmd = att[:, 0].copy(), att[:, 1].copy()  # rad, the slewed tilt commands
        known = np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1)
        if not known[self.leader] or not np.isfinite(yaw[self.leader]):
            raise ValueError(f"reset needs a finite state of the leader (vehicle {self.leader})")
        self.last_pos = np.where(known[:, None], pos, np.nan)
        self.last_vel = np.where(known[:, None], vel, 0.0)
        self.was_active = known.copy()
        self.last_t = None
        # every follower has been within ASSEMBLED_M of its slot (on_slots; kept up to date by `tick`)
        slots = slot_positions(pos[self.leader], yaw[self.leader], self.flown_offsets * self.spacing_scale)
        self.assembled = on_slots(pos, slots, known & ~self.is_leader)
        self.assembly_planned = False  # the first tick plans the formation's assembly (`_plan_assembly`)
        self.started_in_flight = bool(np.hypot(*vel[self.leader, :2]) > self._start_cap_floor())
        self.start_pace = math.inf  # (the next tick sets the start's cap again where it applies)
        self.footprint_paced = False
        self.generator.reset(self.last_pos, self.last_vel)
        self.position_controller.reset(self.n)
        rate = self.heading_rate_max
        ref = self.reference
        self.heading = LeaderHeading(
            yaw[self.leader],
            ref.heading_min_speed,
            rate,
            self.d_g,
            accel_max=self.heading_accel_max,
            filter_s=ref.heading_filter_s,
            gain=ref.heading_gain,
        )
        self.aim_bearing = math.nan  # rad, the leader's aim (leader_aim); none yet
        self.relay = LeaderRelay(self.delays, self._leader_state())

    def _leader_state(self) -> np.ndarray:
        assert self.heading is not None
        p, v = self.last_pos[self.leader], self.last_vel[self.leader]
        a = self.generator.a[self.leader]
        return np.concatenate([p, v, [self.heading.psi, self.heading.rate], a])

    def _tick_dt(self, t: float) -> float:
        """Time since the previous tick; the nominal period on the first tick or after a gap or jump."""
        dt = self.control_dt if self.last_t is None else t - self.last_t
        self.last_t = t
        return dt if 0.0 < dt <= 5.0 * self.control_dt else self.control_dt

    def _check_tick_inputs(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        att: np.ndarray,
        obstacles_c: np.ndarray,
        obstacles_r: np.ndarray,
        active: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Shapes and finiteness of one tick's inputs, as float/bool arrays; ValueError naming the problem."""
        pos = _as_array("pos", pos, (self.n, 3))
        vel = _as_array("vel", vel, (self.n, 3))
        att = _as_array("att", att, (self.n, 3))
        active = np.asarray(active, dtype=bool)
        if active.shape != (self.n,):
            raise ValueError(f"active must have shape ({self.n},), got {active.shape}")
        obstacles_c = np.ascontiguousarray(obstacles_c, dtype=float).reshape(-1, 3)
        obstacles_r = np.ascontiguousarray(obstacles_r, dtype=float).reshape(-1)
        if len(obstacles_c) != len(obstacles_r):
            raise ValueError(f"{len(obstacles_c)} obstacle centres but {len(obstacles_r)} radii")
        if not (
            np.isfinite(obstacles_c).all() and np.isfinite(obstacles_r).all() and (obstacles_r >= 0).all()
        ):
            raise ValueError("obstacle centres must be finite and radii finite and >= 0")
        state_ok = np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1) & np.isfinite(att).all(axis=1)
        bad = np.flatnonzero(active & ~state_ok)
        if len(bad):
            raise ValueError(f"non-finite state for active vehicle(s) {', '.join(map(str, bad))}")
        return pos, vel, att, obstacles_c, obstacles_r, active

    def tick(
        self,
        t: float,
        pos: np.ndarray,
        vel: np.ndarray,
        att: np.ndarray,
        obstacles_c: np.ndarray,
        obstacles_r: np.ndarray,
        active: np.ndarray,
    ) -> Command:
        """One control step at vehicle time t (s) from measured pos/vel (N, 3), att (N, 3) roll, pitch, yaw,
        obstacles (K, 3), (K,) at time t, and the (N,) mask of vehicles to command (spec 8 steps 1-7)."""
        if self.heading is None or self.relay is None:
            raise RuntimeError("FleetController.reset must be called before tick")
        pos, vel, att, centres, radii, active = self._check_tick_inputs(
            pos, vel, att, obstacles_c, obstacles_r, active
        )
        dt = self._tick_dt(t)
        if self.envelope is not None:  # [add] what the followers can fly, from their telemetry (capability)
            self._update_pace(t, vel, att, active)
        returning = active & ~self.was_active
        self.last_pos[active] = pos[active]
        self.last_vel[active] = vel[active]
        self.was_active = active.copy()
        if returning.any():
            self.generator.reset_rows(returning, pos, vel)
            self.position_controller.reset_rows(returning)
            self.roll_cmd[returning], self.pitch_cmd[returning] = att[returning, 0], att[returning, 1]

        # Leader goal and heading (spec 6 [add]); the heading follows the leader's reference velocity.
        lead = self.leader
        p_lead = self.last_pos[lead]
        new_leg = self.route_stale
        if self.route_stale:  # from the waypoint flown to, no via points yet
            self.route_points, self.route_legs = self.waypoints, np.arange(len(self.waypoints))
            self.route_index, self.route_stale = self.waypoint_index, False
        v_ref, aim_rate = self.generator.v[lead], math.radians(self.reference.aim_turn_rate_deg)
        self.route_index, goal_dist = waypoint_ahead(
            self.route_points, self.route_index, p_lead, v_ref[0], v_ref[1], self.reference.waypoint_radius,
            aim_rate, float(self.d_g),
        )  # fmt: skip
        new_leg |= int(self.route_legs[self.route_index]) != self.waypoint_index
        self.waypoint_index = int(self.route_legs[self.route_index])
        if new_leg:  # [add] round a gap the formation cannot fly (route_plan)
            self._plan_leg(t, centres, radii)
            goal_dist = float(np.linalg.norm(self.route_points[self.route_index] - p_lead))
        goal = self.route_points[self.route_index]
        aim, self.aim_bearing = leader_aim(p_lead, goal, self.aim_bearing, aim_rate * dt, self.d_g)
        course = leader_course(self.generator.v[lead, :2], p_lead, goal, self.reference.heading_from_route)
        sweep_max, sweep_accel = self.reference.heading_sweep_max, self.reference.heading_sweep_accel
        if (sweep_max > 0.0 or sweep_accel > 0.0) and not self.follows_path:  # [add] the farthest slot swings
            # at most this fast, and speeds its swing up at most this hard (not a column following the
            # leader's path: its slots do not swing)
            flown = self.flown_offsets
            reach = float(np.max(np.hypot(flown[:, 0], flown[:, 1]))) * self.spacing_scale
            per_reach = 1.0 / reach if reach > 0.0 else np.inf  # 1/m
            if sweep_max > 0.0:
                self.heading.rate_max = min(self.heading_rate_max, sweep_max * per_reach)
            if sweep_accel > 0.0 and self.heading_accel_max > 0.0:  # (0: psi_L's rate steps, spec 6)
                self.heading.accel_max = min(self.heading_accel_max, sweep_accel * per_reach)
        self.heading.update(course, goal_dist, dt)
        ref = self.reference
        offsets, offset_rate, offset_accel, shrink = self.offsets, None, None, 1.0
        if self.shaper is not None:  # [add] deliberate reshaping around obstacles (reshape)
            assert self.reshape is not None
            if not self.assembly_planned:
                self._plan_assembly(t, p_lead, goal)
            cap_now = float(self.v_xy_cap[lead] * self.speed_scale)
            predicted = partial(self._leader_path_ahead, cap_now, centres, radii)

            def predicted_at(speed_cap: float) -> Route:
                return partial(self._leader_path_ahead, speed_cap, centres, radii)

            standing = None if self.assembled else partial(self._standing_offsets, t, p_lead)
            self.shaper.decide(
                t, p_lead, self.heading.psi, self.route_points[self.route_index :], cap_now,
                float(np.hypot(*self.last_vel[lead, :2])), centres, radii, self.shapes,
                route=predicted if self.reshape.predict_path else None,
                assembled=self.assembled, standing=standing,
                route_at=predicted_at if self.reshape.predict_path and self.reshape.footprint_pace else None,
            )  # fmt: skip
            offsets, offset_rate, offset_accel = self.shaper.flown(t)
            shrink = self.shaper.scale(t)
            self._footprint_event(t)
        self.flown_offsets = offsets
        start_cap_on = self.envelope is not None and self.envelope.params.start_lead_m_s > 0
        if start_cap_on and not self.started_in_flight:  # [add] no faster than followers not yet measured fly
            self._update_start_pace(t, vel, active, offset_rate)
        if ref.leader_wait_m > 0.0:  # [add] the leader waits for followers behind their slots (leader_wait)
            self.leader_speed_scale = leader_cap_scale(
                self.last_pos, lead, offsets * self.spacing_scale, self.heading.psi,
                active & ~self.is_leader, ref.leader_wait_m, ref.leader_wait_span_m, ref.leader_wait_floor,
            )  # fmt: skip
        if ref.turn_wait_deg > 0.0:  # [add] at a corner of its route the leader waits for the formation to
            # turn (not on its first leg, while the formation assembles, nor near its goal: psi_L holds there)
            at_corner = self.route_index > 0 and goal_dist > self.d_g
            cap = float(self.v_xy_cap[lead] * self.speed_scale)
            turn_scale = turn_wait_scale(p_lead, goal, self.heading.psi, at_corner, ref, cap)
            waited = self.leader_speed_scale if ref.leader_wait_m > 0.0 else 1.0
            self.leader_speed_scale = min(waited, turn_scale)

        # Step 1: targets from the leader state each vehicle has heard (relay delay, spec 6).
        self.relay.push(self._leader_state())
        heard = self.relay.read()
        psi_l = heard[:, 6]
        destinations = NO_ROWS if self.follower_targets is None else self.follower_targets
        cos_l, sin_l = np.cos(psi_l), np.sin(psi_l)
        targets, v_ff, a_ff, dest = formation_targets(
            heard, cos_l, sin_l, offsets, float(self.spacing_scale), centres, radii, float(ref.slot_margin),
            int(lead), goal, self.waypoints[self.waypoint_index], destinations, *self.shapes,
        )  # fmt: skip
        if not self.assembled:  # [add] the formation has assembled once every follower reached its slot
            self.assembled = on_slots(pos, targets, active & ~self.is_leader)
        for motion, ff in ((offset_rate, v_ff), (offset_accel, a_ff)):  # the slots' own motion, leader frame
            if motion is not None and motion.any():
                scaled = motion * self.spacing_scale
                ff[:, 0] += scaled[:, 0] * cos_l - scaled[:, 1] * sin_l
                ff[:, 1] += scaled[:, 0] * sin_l + scaled[:, 1] * cos_l
                ff[:, 2] += scaled[:, 2]
        if self.reshape is not None and self.reshape.column_follows_path:  # [add] spec 6a.9 (column_path)
            self._follow_path(offsets, offset_rate, offset_accel, targets, v_ff, a_ff)
        gen = self.generator
        literal = ref.paper_literal & ~self.is_leader
        if ref.paper_literal:
            gen.reset_rows(literal & active, pos, vel)

        wide = self.spacing_scale
        sep = self.separation
        d_emg, s_s = (sep.d_emg, sep.s_s) if wide == 1.0 else (sep.d_emg * wide, sep.s_s * wide)
        known = np.asarray(np.isfinite(self.last_pos).all(axis=1))
        closing_caps, on_course = self._closing_caps(known, d_emg, s_s)
        # Step 6 (leash) then step 2: the field at the reference points (obstacles along their braking paths);
        # the other vehicles repel from where they are (or were). [add] A vehicle closing on another faster
        # than its closing-speed cap allows, on a course that would pass within d_emg + 1 m, has its reference
        # held closing_leash_m from it, so that the cap brakes the vehicle and not only a reference up to the
        # leash ahead of it.
        leash = np.full(self.n, float(ref.leash))
        leash[on_course] = min(float(ref.leash), sep.closing_leash_m)
        ahead = gen.leash_and_lookahead(pos, active, leash)
        p_r = gen.p
        fp = self.field
        ranges = NO_RANGES
        if fp.slot_range:  # [add] a follower on a slot clear of an obstacle is not pushed off it (field)
            followers = active & ~self.is_leader
            ranges = slot_ranges(
                targets, ahead - p_r, followers, centres, radii, *self.shapes, fp.l0, fp.slot_range_margin,
                fp.slot_range_floor,
            )  # fmt: skip
        f_obs = obstacle_repulsion(p_r, ahead, dest, centres, radii, fp, shapes=self.shapes, ranges=ranges)
        d_max = self.d_max * wide
        if shrink < 1.0:  # a tighter shape: its neighbours are not repelled out of their slots
            assert self.reshape is not None and self.shaper is not None
            spacing, tightest = self.shaper.spacing, self.reshape.min_spacing_m
            d_max = shape_repulsion_range(self.d_max, spacing, shrink, tightest) * wide
        f_uav, emergency = uav_repulsion(
            p_r, self.last_pos, self.last_vel, known, gen.v, float(ref.brake_accel), self.field, d_max,
            sep.mode == "formula", min(d_emg, d_max), sep.a_e, s_s,
        )  # fmt: skip
        # [add] spec 4: D_Emg also where the vehicles are. A vehicle at its tilt limit lags its reference by
        # up to the leash, so two vehicles can close within D_Emg while each reference stays clear of the
        # other (slow airframe, legs2-3: 1.54 m, no emergency). Such a vehicle takes the pair forces there.
        f_here, near = uav_repulsion(
            self.last_pos, self.last_pos, self.last_vel, known, self.last_vel, 0.0, self.field, d_max,
            sep.mode == "formula", min(d_emg, d_max), sep.a_e, s_s,
        )  # fmt: skip
        lagging = near & ~emergency
        f_uav[lagging] = f_here[lagging]
        emergency |= near
        pulled = targets.copy()  # the leader's attraction and stopping curve pull toward its aim (spec 8a.10)
        pulled[lead] = aim
        force = attraction(p_r, pulled, self.field, self.d_g) + f_obs + f_uav

        # Steps 3-5 (or the paper-literal follower reference)
        speed_cap = np.minimum(self.speed_caps(), closing_caps)
        if self.dead_gcs is not None and self.dead_gcs.speed_scheduling:
            fs = self.dead_gcs
            caps = failsafe_speed_caps(
                pos, vel, centres, radii, float(fs.failsafe_timeout_s or 0.0), float(fs.brake_accel or 0.0),
                fs.clearance, float(fs.brake_jerk or 0.0), self.shapes,
            )  # fmt: skip
            speed_cap = np.minimum(speed_cap, caps)
        budgets = no_budgets(self.n)
        budgets[lead] = self.leader_budget
        x_d, xd_dot, xd_ddot = gen.step(force, v_ff, speed_cap, dt, active, a_ff, pulled, emergency, budgets)
        if ref.paper_literal:
            lit = paper_literal_reference(targets, v_ff, f_obs + f_uav, self.field.k_att, self.field.l0)
            for arr, lit_arr in zip((x_d, xd_dot, xd_ddot), lit, strict=True):
                arr[literal] = lit_arr[literal]

        # Step 7: position control, inversion, tilt slew
        u = self.position_controller(x_d, xd_dot, xd_ddot, pos, vel, dt)
        if self.thrust_mode == "measured":
            cmd = invert(u, att[:, 2], self.limits, self.g, att[:, 0], att[:, 1])
        else:
            cmd = invert(u, att[:, 2], self.limits, self.g)
        self.roll_cmd, self.pitch_cmd = slew_step(
            cmd.roll, cmd.pitch, self.roll_cmd, self.pitch_cmd, float(self.tilt_rate_max * dt), active
        )
        off = ~active if not active.all() else None

        def masked(fresh: np.ndarray) -> np.ndarray:
            """`fresh` (an array of this tick's own) with NaN in the rows not commanded."""
            if off is not None:
                fresh[off] = np.nan
            return fresh

        return Command(
            active=active, roll_d=masked(self.roll_cmd.copy()), pitch_d=masked(self.pitch_cmd.copy()),
            yaw_d=masked(psi_l.copy()), thrust_acc=masked(cmd.thrust_acc), ref_pos=x_d, ref_vel=xd_dot,
            ref_acc=xd_ddot, field_force=force, slots=targets, u=masked(cmd.u_limited),
            emergency=emergency & active, psi_leader=self.heading.psi, waypoint_index=self.waypoint_index,
            leader_goal_distance=goal_dist,
        )  # fmt: skip
