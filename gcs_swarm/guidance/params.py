"""Parameter sets of guidance and control (frozen dataclasses, SI units).

Defaults are the spec's values (`docs`: iaapf-smc.md): [paper] where the paper gives
them, [add] rows otherwise. The mission file (gcs_swarm.mission) builds these; the
pure guidance modules only read them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property

G = 9.8  # m/s^2, Table 2


class FieldMethod(Enum):
    """The potential-field laws (FieldParams.method names one by its value)."""

    APF = "apf"  # spec 2, the baseline: quadratic attraction, plain repulsion
    IAAPF = "iaapf"  # spec 3-4: segmented attraction, adaptive repulsion rho^n


@dataclass(frozen=True)
class FieldParams:
    """Potential-field parameters (spec 2-4). Forces are in field units (k_att * m)."""

    method: str = "iaapf"  # "apf" (spec 2, baseline) or "iaapf" (spec 3-4)
    k_att: float = 100.0  # attraction gain (Table 1/6 "k")
    k_rep: float = 1e5  # obstacle repulsion gain (spec 9.1 reproduction default)
    l0: float = 20.0  # m, obstacle influence distance measured from the surface
    d_g: float | None = None  # m, attraction segment boundary; None -> v_max / K_v (spec 3.1)
    n: float = 0.8  # adaptive factor of the obstacle repulsion (Table 2)
    k_uav: float = 5e4  # inter-UAV repulsion gain (spec 11.5)
    n_uav: float = 0.8  # adaptive exponent of the inter-UAV potential (spec 4)
    l_min: float = 0.05  # m, distance floor inside/at an obstacle (spec 2.1)
    rho_eps: float = 1e-3  # m, F*_rep2 is zero closer than this to the goal (spec 3.2)
    obstacle_vertical: float = 0.25  # weight of the vertical obstacle repulsion [add]; 1 = the paper's
    circulation: float = 0.6  # tangential share of an obstacle-ahead repulsion [add]; 0 = the paper's
    # [add] a follower feels an obstacle within its slot's clearance from it less slot_range_margin (m), the
    # slot looked ahead along the follower's own braking path, not less than slot_range_floor (m) nor more
    # than l0 (gcs_swarm.guidance.field.slot_ranges; docs/metrics.md: the floor 10 -> 5 m with the look-ahead
    # took the 80 generated courses at every bound 64 -> 67); false: every vehicle within l0 (the paper's)
    slot_range: bool = True
    slot_range_margin: float = 3.0
    slot_range_floor: float = 5.0

    def __post_init__(self) -> None:
        self.law  # noqa: B018 - refuses an unknown method now
        for name in ("k_att", "l0", "n", "l_min", "rho_eps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"field parameter {name} must be > 0")
        for name in ("k_rep", "k_uav", "circulation", "obstacle_vertical", "slot_range_margin"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"field parameter {name} must be >= 0")
        if not 0 < self.slot_range_floor <= self.l0:
            raise ValueError("field parameter slot_range_floor must lie in (0, l0]")
        if not 0 < self.n_uav < 2:
            raise ValueError("n_uav must lie in (0, 2) so the inter-UAV force stays repulsive (spec 4)")
        if self.d_g is not None and not self.d_g > 0:
            raise ValueError("d_g must be > 0 (or omitted for v_max / K_v)")

    @cached_property
    def law(self) -> FieldMethod:
        """The field law `method` names; ValueError for a name that is none of FieldMethod's."""
        try:
            return FieldMethod(self.method)
        except ValueError:
            names = ", ".join(repr(m.value) for m in FieldMethod)
            raise ValueError(f"field method must be one of {names}, not {self.method!r}") from None


@dataclass(frozen=True)
class SeparationParams:
    """Inter-UAV ranges (spec 4, Eqs 17 and 20)."""

    mode: str = "constant"  # "constant" (Table 2) or "formula" (Eq 17 / Eq 20)
    d_max: float = 10.0  # m, constant mode
    d_emg: float = 3.0  # m, constant mode
    t_r: float = 0.2  # s, reaction time (formula mode)
    s_s: float = 1.0  # m, safe distance (formula mode)
    a_e: float = 10.0  # m/s^2, emergency deceleration (formula mode)
    # m/s^2 [add]: a vehicle's speed is capped so that it closes on any other vehicle no faster than it could
    # stop, at this deceleration, 1 m outside d_emg (separation.closing_speed_caps): the repulsion alone let a
    # follower catching up at 20 m/s run into one slowing ahead of it (1.29 m in the nine-UAV V). 0 = off
    closing_brake_accel: float = 2.0
    # [add] ... but at most this share of g tan(limits.tilt_max_deg), the horizontal acceleration the tilt
    # limit allows (separation.closing_deceleration): with 2 m/s^2 a V assembling on a 15 deg tilt limit
    # passed 1.3 m from its leader, on 11 deg 0.9 m (g tan 11 deg is 1.9 m/s^2). 0.3 leaves 35 deg's 2 m/s^2
    # as it is. 0 = no such bound
    closing_brake_tilt_share: float = 0.3
    # m [add]: while a vehicle's closing-speed cap binds (it closes faster than the cap allows) and the pair,
    # flying on, would pass within d_emg + 1 m (separation.closing_speed_caps), its reference is held this
    # close to it (spec 8 step 6's leash, which is reference.leash otherwise), so the cap brakes the vehicle
    # itself: a vehicle at its tilt limit trails its reference by up to the 5 m leash and would fly on at
    # full tilt toward a reference that has already slowed (17 deg tilt limit: 2.34 m, under D_Emg)
    closing_leash_m: float = 1.0

    def __post_init__(self) -> None:
        if not self.closing_brake_accel >= 0:
            raise ValueError("closing_brake_accel must be >= 0 (0 turns the closing-speed cap off)")
        if not self.closing_leash_m >= 0:
            raise ValueError("closing_leash_m must be >= 0")
        if not 0 <= self.closing_brake_tilt_share <= 1:
            raise ValueError("closing_brake_tilt_share must lie in [0, 1] (0: no bound by the tilt limit)")
        if self.mode not in ("constant", "formula"):
            raise ValueError(f"separation mode must be 'constant' or 'formula', not {self.mode!r}")
        for name in ("d_max", "d_emg", "a_e"):
            if not getattr(self, name) > 0:
                raise ValueError(f"separation parameter {name} must be > 0")
        for name in ("t_r", "s_s"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"separation parameter {name} must be >= 0")


@dataclass(frozen=True)
class SMCAxisGains:
    """Gains of one SMC channel (spec 7.1, paper Eqs 29-50)."""

    c1: float
    k1: float
    k2: float
    k3: float
    xi1: float = 0.5
    xi2: float = 1.5
    disturbance_gain: float = 0.0  # 1/s, k_d of the estimate d_hat_dot = k_d s [add]; 0 = off (paper Eq 49)
    disturbance_max: float = 4.0  # m/s^2, clamp of |d_hat| (xy: of its horizontal norm) [add]

    def __post_init__(self) -> None:
        if not (self.c1 > 0 and self.k1 > 0 and self.k2 >= 0 and self.k3 >= 0):
            raise ValueError("SMC gains need c1 > 0, k1 > 0, k2 >= 0, k3 >= 0")
        if not self.k1 * self.c1 > 0.25:  # spec 7.2: P positive definite iff k1*c1 > 1/4
            raise ValueError(f"SMC stability condition k1*c1 > 1/4 violated (k1*c1 = {self.k1 * self.c1:g})")
        if not 0 < self.xi1 < 1 < self.xi2 < 2:
            raise ValueError("SMC exponents need 0 < xi1 < 1 < xi2 < 2")
        if not self.disturbance_gain >= 0:
            raise ValueError("disturbance_gain must be >= 0 (0 turns the disturbance estimate off)")
        if not self.disturbance_max > 0:
            raise ValueError("disturbance_max must be > 0")


@dataclass(frozen=True)
class SMCParams:
    """Sliding-mode position controller (spec 7.3 gains, 7.4 boundary layer, per-channel disturbance
    estimate [add] in gcs_swarm.guidance.smc)."""

    # xy: the disturbance estimate on [add] (disturbance_gain 1/s): without integral action a 3.6-5 m/s wind
    # holds the leader 1.05-1.7 m off its goal for good (4 of 50 quickstart Monte Carlo worlds never arrived)
    xy: SMCAxisGains = field(default_factory=lambda: SMCAxisGains(0.8, 1.5, 0.3, 0.05, disturbance_gain=1.0))
    z: SMCAxisGains = field(default_factory=lambda: SMCAxisGains(1.0, 2.0, 0.5, 0.1))
    boundary_layer: float = 0.0  # m/s, Phi of sat(s/Phi); 0 = off (sgn, as in the paper)
    # [add] horizontal drag adaptation (gcs_swarm.guidance.smc): U += c_hat v_xy, c_hat_dot = gamma s . v_xy,
    # gamma in 1/m^2; 0 = off (the paper's Eq 49). Removes most of the trail behind a moving slot without an
    # integrator that must unwind at the stop
    drag_adaptation: float = 0.01
    drag_max: float = 1.5  # 1/s, c_hat kept within [0, drag_max]

    def __post_init__(self) -> None:
        if self.boundary_layer < 0:
            raise ValueError("boundary_layer must be >= 0 (0 turns it off)")
        if not (self.drag_adaptation >= 0 and self.drag_max > 0):
            raise ValueError("need drag_adaptation >= 0 (0: off) and drag_max > 0")


@dataclass(frozen=True)
class PIDParams:
    """Baseline PID position controller (acceleration output, same interface as the SMC)."""

    kp_xy: float = 1.2
    ki_xy: float = 0.05
    kd_xy: float = 2.3
    kp_z: float = 2.0
    ki_z: float = 0.1
    kd_z: float = 3.0
    i_limit: float = 2.0  # m/s^2, anti-windup clamp of the integral term

    def __post_init__(self) -> None:
        for name in ("kp_xy", "ki_xy", "kd_xy", "kp_z", "ki_z", "kd_z", "i_limit"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"PID gain {name} must be >= 0")


@dataclass(frozen=True)
class Limits:
    """Motion and command limits (Table 2 and spec 5 [add])."""

    v_xy_leader: float = 10.0  # m/s, leader cap below the followers' (spec 8 step 3)
    v_xy: float = 20.0  # m/s
    v_z: float = 20.0  # m/s
    a_xy: float = 20.0  # m/s^2
    a_z: float = 15.0  # m/s^2
    tilt_max_deg: float = 35.0  # deg, spec 5 limit 2
    tilt_rate_max_deg: float = 115.0  # deg/s (2 rad/s), slew limit of the commanded tilt [add]; 0 = none
    thrust_max_g: float = 2.0  # U1_max / (m g), spec 5 limit 3
    uz_min_g: float = 0.3  # U_z >= uz_min_g * g, spec 5 limit 1

    def __post_init__(self) -> None:
        for name in ("v_xy_leader", "v_xy", "v_z", "a_xy", "a_z", "thrust_max_g", "uz_min_g"):
            if not getattr(self, name) > 0:
                raise ValueError(f"limit {name} must be > 0")
        if not self.tilt_rate_max_deg >= 0:
            raise ValueError("tilt_rate_max_deg must be >= 0 (0: no slew limit)")
        if not 0 < self.tilt_max_deg < 80:
            raise ValueError("tilt_max_deg must lie in (0, 80)")
        if not self.uz_min_g < 1 < self.thrust_max_g:
            raise ValueError("need uz_min_g < 1 < thrust_max_g so hover is commandable")

    @property
    def tilt_max(self) -> float:
        """Tilt limit in rad."""
        return math.radians(self.tilt_max_deg)


@dataclass(frozen=True)
class ReferenceParams:
    """Reference generator that closes IAAPF onto the SMC (spec 8)."""

    k_v: float = 1.0  # 1/s, velocity per (field / k_att) metre
    tau_v: float = 0.5  # s, velocity-tracking time constant
    leash: float = 5.0  # m, max distance of the reference point from the vehicle
    heading_min_speed: float = 3.0  # m/s, psi_L updates only above this reference speed (spec 6)
    heading_rate_max_deg: float = 30.0  # deg/s, rate limit of psi_L (spec 6)
    heading_accel_max_deg: float = (
        20.0  # deg/s^2, how fast the turn rate of psi_L may change [add]; 0 = steps
    )
    heading_filter_s: float = (
        1.0  # s, time constant of the leader velocity low-pass psi_L follows [add]; 0 = off
    )
    heading_gain: float = 1.0  # 1/s, turn rate of psi_L per rad of course error, small errors [add]
    # [add] psi_L follows the direction from the leader to its current waypoint instead of its velocity's
    # course, so the formation does not swing its tail when the leader swerves round an obstacle
    heading_from_route: bool = True
    # [add] m/s: the formation turns no faster than lets its farthest slot swing round the leader at this
    # speed (rate <= heading_sweep_max / farthest slot distance), so a long formation keeps up in a turn;
    # 0 = off (only heading_rate_max_deg)
    heading_sweep_max: float = 4.0
    # [add] m/s^2: psi_L's turn rate changes no faster than lets its farthest slot speed up or slow down its
    # swing round the leader at this (turn acceleration <= heading_sweep_accel / farthest slot distance, and
    # <= heading_accel_max_deg), so the tail of a long column is not flung sideways when a turn starts, stops
    # or reverses (docs/metrics.md: on the 80 generated courses slot error max <= 6 m on 62 against 49);
    # 0 = off (only heading_accel_max_deg)
    heading_sweep_accel: float = 4.0
    paper_literal: bool = False  # spec 8 option: x_d = slot + K_f * sum F_rep
    waypoint_radius: float = 5.0  # m, the leader moves on to its next goal waypoint within this distance
    jerk_max: float = (
        5.0  # m/s^3, horizontal jerk of the reference (ArduPilot shaping) [add]; 0 = spec step 4
    )
    jerk_max_z: float = 10.0  # m/s^3, vertical jerk of the reference [add]
    stop_accel: float = (
        3.0  # m/s^2, approach speed to the attraction target capped at sqrt(2 a d) [add]; 0 = off
    )
    slot_margin: float = 0.0  # m, slots closer than this to an obstacle surface are moved out [add]; 0 = off
    evasive_jerk_max: float = 40.0  # m/s^3, jerk of a reference in an emergency separation (full tilt) [add]
    accel_xy_max: float = 4.0  # m/s^2, horizontal acceleration of the shaped reference (jerk_max > 0) [add]
    brake_accel: float = (
        1.5  # m/s^2, obstacle field felt at the braking point v|v|/(2 a) ahead [add]; 0 = off
    )
    # [add] the leader waits for its followers (gcs_swarm.guidance.leader_wait): its speed cap falls once the
    # worst follower is more than leader_wait_m (m) from its slot, linearly over leader_wait_span_m (m) down
    # to leader_wait_floor x v_xy_leader; 0 = off (the paper's leader ignores its followers)
    leader_wait_m: float = 0.0
    leader_wait_span_m: float = 5.0
    leader_wait_floor: float = 0.2
    # [add] at a corner of its route the leader waits for the formation to turn (guidance.leader_wait): its
    # speed cap falls once psi_L lags the direction to its waypoint by more than turn_wait_deg, linearly over
    # turn_wait_span_deg down to turn_wait_floor x its cap, never under 1.25 x heading_min_speed (or psi_L
    # stops turning); 0 = off
    turn_wait_deg: float = 20.0
    turn_wait_span_deg: float = 30.0
    turn_wait_floor: float = 0.4
    # [add] deg/s: the leader's aim at its waypoint turns at most this fast (spec 8a.10, leader_aim), so at a
    # corner of its route it flies by on a curve instead of braking into a turn on the spot; 0 = off
    aim_turn_rate_deg: float = 30.0

    def __post_init__(self) -> None:
        for name in ("k_v", "tau_v", "leash", "heading_rate_max_deg", "waypoint_radius", "accel_xy_max"):
            if not getattr(self, name) > 0:
                raise ValueError(f"reference parameter {name} must be > 0")
        if self.heading_min_speed < 0:
            raise ValueError("heading_min_speed must be >= 0")
        if not self.heading_sweep_max >= 0:
            raise ValueError("heading_sweep_max must be >= 0 (0 turns it off)")
        if not self.heading_sweep_accel >= 0:
            raise ValueError("heading_sweep_accel must be >= 0 (0 turns it off)")
        if not (self.heading_accel_max_deg >= 0 and self.heading_filter_s >= 0 and self.heading_gain > 0):
            raise ValueError("need heading_accel_max_deg >= 0, heading_filter_s >= 0 and heading_gain > 0")
        if not self.slot_margin >= 0:
            raise ValueError("slot_margin must be >= 0 (0 turns it off)")
        if not self.stop_accel >= 0:
            raise ValueError("stop_accel must be >= 0 (0 turns the stopping curve off)")
        if not (self.jerk_max >= 0 and self.jerk_max_z > 0):
            raise ValueError("jerk_max must be >= 0 (0: unshaped, spec 8 step 4) and jerk_max_z > 0")
        if not (self.leader_wait_m >= 0 and self.leader_wait_span_m > 0 and 0 < self.leader_wait_floor <= 1):
            raise ValueError(
                "need leader_wait_m >= 0 (0: off), leader_wait_span_m > 0 and 0 < leader_wait_floor <= 1"
            )
        if not (self.turn_wait_deg >= 0 and self.turn_wait_span_deg > 0 and 0 < self.turn_wait_floor <= 1):
            raise ValueError(
                "need turn_wait_deg >= 0 (0: off), turn_wait_span_deg > 0 and 0 < turn_wait_floor <= 1"
            )
        if not self.aim_turn_rate_deg >= 0:
            raise ValueError("aim_turn_rate_deg must be >= 0 (0: off)")


@dataclass(frozen=True)
class TelemetryParams:
    """How old a vehicle's position telemetry may get, and what the ground station does as it ages [add]
    (docs/reliability.md). A vehicle's age is its newest time_boot_ms minus that of its latest position."""

    predict_s: float = 0.3  # s, up to this age the vehicle is flown on its predicted state pos + vel * age
    hold_s: float = 1.0  # s, older: the vehicle brakes and holds on its own autopilot until fresh again
    lost_s: float = 3.0  # s without any packet: the vehicle is declared lost and the rest re-form
    degraded_speed: float = 0.5  # speed caps x this while any live vehicle is older than predict_s
    degraded_spacing: float = 1.5  # formation spacing and separation ranges x this, likewise
    recover_s: float = 2.0  # s every live vehicle must stay within predict_s before degraded mode ends
    lost_radius: float = 3.0  # m, a lost vehicle's predicted position is avoided as a sphere of this radius,
    lost_radius_growth: float = 0.5  # m/s growing this fast after its last report (the prediction's error)
    lost_radius_max: float = 15.0  # m, up to this

    def __post_init__(self) -> None:
        if not 0 <= self.predict_s < self.hold_s < self.lost_s:
            raise ValueError("telemetry ages need 0 <= predict_s < hold_s < lost_s")
        if not 0 < self.degraded_speed <= 1:
            raise ValueError("degraded_speed must lie in (0, 1]")
        if not 1 <= self.degraded_spacing <= 5:
            raise ValueError("degraded_spacing must lie in [1, 5]")
        if not self.recover_s >= 0:
            raise ValueError("recover_s must be >= 0")
        if not (0 < self.lost_radius <= self.lost_radius_max and self.lost_radius_growth >= 0):
            raise ValueError("need 0 < lost_radius <= lost_radius_max and lost_radius_growth >= 0")


@dataclass(frozen=True)
class ReshapeParams:
    """Deliberate reshaping of the formation where obstacles leave it too little room [add]
    (gcs_swarm.guidance.reshape; docs/iaapf-smc-spec.md section 6a): the formation narrows (its spacing
    scaled down to `min_spacing_m`) or falls into a column while every slot would pass closer than
    `clearance_m` to an obstacle along the look-ahead, and re-forms when the wider shape fits again."""

    enabled: bool = True  # false: the paper's fixed formation (each follower avoids on its own repulsion)
    # m between every slot and an obstacle surface along the look-ahead: a slot within about 10 m of a surface
    # lies in the strong part of the obstacle's repulsion (l0 = 20 m), which holds its follower metres off it
    # (docs/metrics.md, slot error against slot clearance)
    clearance_m: float = 10.0
    lookahead_s: float = 6.0  # s of leader travel at its speed cap checked ahead, plus committed travel ...
    lookahead_min_m: float = 30.0  # m, ... but at least this far
    # the look-ahead follows the leader's path predicted by flying its reference forward through the field
    # (gcs_swarm.guidance.leader_path); false: the straight route through its waypoints
    predict_path: bool = True
    # while the shape flown does not fit the look-ahead and no other is taken, the leader slows to the
    # fastest of 0.8, 0.6 and 0.4 x its cap at which its predicted path leaves that shape room (spec
    # 6a.10); needs predict_path
    footprint_pace: bool = True
    # m, the tightest spacing a narrowed formation or column flies: D_Emg (3 m) plus 2 m of slot error on
    # each of two neighbours before they are in an emergency separation
    min_spacing_m: float = 7.0
    steps: int = 3  # spacings tried between the mission's and min_spacing_m
    column: bool = True  # may fall into a column (line astern) when no narrowed shape fits
    speed_m_s: float = 6.0  # m/s, fastest a slot moves relative to the leader while the shape changes
    # m/s, fastest a slot moves relative to the leader in a widening the leader spends mostly at its goal (it
    # stops there before half the change is over, so a slot's rate is then its follower's own speed), at most
    # the slowest follower's measured top speed less 1.5 m/s (gcs_swarm.guidance.capability); not under
    # speed_m_s. Such a change accelerates its slots at up to accel_m_s2 + pace_decel_m_s2: the leader no
    # longer brakes. A column restoring its shape at the goal brings its tail 40-50 m forward (reshape, spec
    # 6a.4)
    goal_speed_m_s: float = 9.0
    # m, the closest two slots (the leader's among them) may pass in a change for the slots to take the
    # quickest way (straight, rather than along then across): min_spacing_m less the 1 m by which a tighter
    # shape's neighbours repel (reshape.RESHAPE_CUSHION_M), so the quicker way does not push its
    # followers out of their slots
    move_gap_m: float = 6.0
    # m/s^2, hardest a slot accelerates relative to the leader in a change: with pace_decel_m_s2, within the
    # reference's accel_xy_max (4 m/s^2)
    accel_m_s2: float = 2.0
    # m/s^2, hardest the slots brake the rate they had when a change starts while they still move (one
    # change taking over from another, or a change from where unassembled followers fly): the move carries
    # that rate on and brings it to rest within this (reshape.SlotMove), so no slot's velocity jumps
    settle_accel_m_s2: float = 4.0
    # s: a formation that has not assembled when it starts is carried into its shape along a planned move
    # from where its followers stand when that move takes at most this long (no follower then pursues a slot
    # standing elsewhere and overshoots it); farther, each follower flies to its slot at its own speed, which
    # is quicker than a slot may move (followers starting hundreds of metres away: paper_nine_9). The
    # issue's assembly bound (reshape, spec 6a.4); 0: always by pursuit
    assembly_move_max_s: float = 10.0
    # m/s^2, fastest the leader's pace cap falls while the shape changes (the followers brake with it)
    pace_decel_m_s2: float = 1.5
    restore_after_s: float = 1.5  # s a wider shape must keep fitting before the formation widens to it
    # a wider shape that does not fit where the leader is may still be taken when it fits from where the
    # leader will be once the move to it is over (flying on at its speed, the route straight meanwhile) and
    # the way there keeps clearance_m + 1 m: a column passing its last obstacle opens out behind it instead
    # of after it has left it a formation's length behind (reshape, spec 6a.3). False: from where it is now
    widen_after_move: bool = True
    # the formation has not arrived while a wider shape fits and the way to it is not found blocked (it
    # re-forms at the goal when the mission's shape fits there and its way is clear, instead of ending the
    # flight as a column); false: arrival waits only for a change of shape under way (reshape, spec 6a.3)
    arrive_in_shape: bool = True
    # deg between the turns about the leader tried at the goal, where the leader hovers with psi_L held: a
    # formation whose shape does not fit beside the obstacles there settles in the widest candidate that
    # fits, least turned (reshape, spec 6a.3: on two generated courses a column's tail stood beside the last
    # obstacle, its followers held off their slots until the time limit); 0: never turned
    goal_turn_step_deg: float = 15.0
    # the leader's route goes round clusters of still obstacles that close a gap narrower than
    # 2 x gap_clearance_m plus the narrowest shape's width (gcs_swarm.guidance.route_plan): with the field's
    # defaults a leader's reference stalls in front of a 12 m gap between two spheres of 6-10 m and passes a
    # 14 m one (tests/gcs_swarm/guidance/test_route_plan.py)
    route_round_gaps: bool = True
    gap_clearance_m: float = 7.0  # m
    decide_every_s: float = 0.2  # s between decisions
    # while the formation is a column, its slots follow the leader's path instead of its heading
    # (gcs_swarm.guidance.column_path), and the leader flies no faster than lets every slot go round the
    # bends ahead of it with at most path_turn_accel_m_s2 of centripetal acceleration (braking for them at
    # pace_decel_m_s2): a follower reaching a bend faster than it can turn would overshoot it. Off by
    # default: on the generated courses it keeps long columns on their slots round corners but arrives on
    # fewer courses and later (docs/metrics.md, "A column that follows the leader's path")
    column_follows_path: bool = False
    path_turn_accel_m_s2: float = 2.0  # m/s^2, half the reference's accel_xy_max: the rest for tracking

    def __post_init__(self) -> None:
        if not (self.clearance_m >= 0 and self.lookahead_s > 0 and self.lookahead_min_m >= 0):
            raise ValueError("need clearance_m >= 0, lookahead_s > 0 and lookahead_min_m >= 0")
        if not (self.min_spacing_m > 0 and self.speed_m_s > 0 and self.steps >= 1 and self.move_gap_m > 0):
            raise ValueError("need min_spacing_m > 0, speed_m_s > 0, steps >= 1 and move_gap_m > 0")
        if not self.goal_speed_m_s >= self.speed_m_s:
            raise ValueError("need goal_speed_m_s >= speed_m_s")
        if not (self.pace_decel_m_s2 > 0 and self.accel_m_s2 > 0 and self.settle_accel_m_s2 > 0):
            raise ValueError("need pace_decel_m_s2 > 0, accel_m_s2 > 0 and settle_accel_m_s2 > 0")
        if not self.gap_clearance_m >= 0:
            raise ValueError("need gap_clearance_m >= 0")
        if not (self.restore_after_s >= 0 and self.decide_every_s > 0 and self.assembly_move_max_s >= 0):
            raise ValueError("need restore_after_s >= 0, decide_every_s > 0 and assembly_move_max_s >= 0")
        if not self.path_turn_accel_m_s2 > 0:
            raise ValueError("need path_turn_accel_m_s2 > 0")
        if not 0 <= self.goal_turn_step_deg <= 180:
            raise ValueError("need 0 <= goal_turn_step_deg <= 180")


@dataclass(frozen=True)
class CapabilityParams:
    """The leader's pace from what its followers can fly, measured from their telemetry in flight [add]
    (gcs_swarm.guidance.capability; docs/iaapf-smc-spec.md section 6b): the leader cruises no faster than the
    slowest follower flies at `tilt_share` of the tilt limit against its fitted drag and the wind, and
    accelerates no harder than `accel_tilt_share` of it leaves that follower at the leader's speed; no
    vehicle's reference flies faster than that vehicle itself does at `own_tilt_share`."""

    enabled: bool = True  # false: the leader's cap is limits.v_xy_leader alone (the paper)
    # share of the tilt limit a follower spends to keep the leader's cruise; the rest is for catching up
    tilt_share: float = 0.7
    memory_s: float = 20.0  # s, time constant over which old samples are forgotten
    sample_s: float = 0.2  # s between samples (acceleration from the change of velocity over one)
    min_samples: float = 25.0  # samples (forgotten count) before a fit is trusted ...
    min_spread_m_s: float = 1.5  # m/s ... and RMS spread of the velocities it saw
    # share of the tilt limit's horizontal thrust that the leader's acceleration and the drag at its speed may
    # take of that follower (capability.AccelBudget); 1: the tilt limit itself; 0: no acceleration budget
    accel_tilt_share: float = 1.0
    # share of the tilt limit at which a vehicle's reference may fly against that vehicle's own fitted drag;
    # the rest is left for steering (0: no such cap)
    own_tilt_share: float = 0.9
    # m/s: until a follower's drag has been measured (its fit has min_samples and min_spread_m_s), the leader
    # flies no faster than lets that follower's slot run ahead of it by more than this along psi_L, never
    # under 1.25 x heading_min_speed: a follower still hovering is not left behind by a leader cruising at a
    # speed it may not reach (real PX4 SIH: 9-12 m slot errors in the first 10 s). Not for a formation that
    # starts with its leader faster than that floor (its followers fly already). 0: no such cap
    # (docs/metrics.md, "The start: no faster than the followers fly")
    start_lead_m_s: float = 2.0

    def __post_init__(self) -> None:
        if not self.start_lead_m_s >= 0:
            raise ValueError("start_lead_m_s must be >= 0 (0 turns the start's cap off)")
        if not 0 < self.tilt_share <= 1:
            raise ValueError("tilt_share must lie in (0, 1]")
        if not (self.memory_s > 0 and self.sample_s > 0):
            raise ValueError("need memory_s > 0 and sample_s > 0")
        if not (self.min_samples >= 3 and self.min_spread_m_s > 0):
            raise ValueError("need min_samples >= 3 and min_spread_m_s > 0")
        if not (self.accel_tilt_share == 0 or self.tilt_share <= self.accel_tilt_share <= 1):
            raise ValueError("accel_tilt_share must be 0 (off) or lie in [tilt_share, 1]")
        if not (self.own_tilt_share == 0 or self.tilt_share <= self.own_tilt_share <= 1):
            raise ValueError("own_tilt_share must be 0 (off) or lie in [tilt_share, 1]")


FENCE_ACTIONS = ("brake", "land", "rtl", "report")  # safety.dead_gcs.fence.action -> FENCE_ACTION 4, 2, 1, 0


@dataclass(frozen=True)
class FenceParams:
    """The autopilots' own geofence around the mission's static obstacles [add] (docs/reliability.md "The
    ground station dies"; gcs_swarm.flight.geofence): each obstacle the formation can meet is uploaded as an
    exclusion circle of radius obstacle (its cross-section at the formation's altitudes) + collision radius +
    `margin_m`, so that a vehicle heading into it stops by itself even with no ground station."""

    # off by default: normal flight passes obstacles closer than a braking margin in some missions (4 m in
    # the nine-UAV paper mission), where the fence would stop vehicles mid-mission (docs/reliability.md)
    enabled: bool = False  # upload the circles, set FENCE_TYPE 4, FENCE_ACTION, FENCE_ENABLE 1 in preflight
    # m added beyond the vehicle's collision radius: ArduCopter's BRAKE stops in about 1.5 s x speed + 1.3 m
    # (sitl-sim; ArduCopter SITL 20.4 m from 10.1 m/s), so 10 m stops a vehicle that enters at 5.5 m/s
    margin_m: float = 10.0
    action: str = "brake"  # FENCE_ACTION: brake (4, Brake or Land) | land (2) | rtl (1) | report (0)

    def __post_init__(self) -> None:
        if not self.margin_m >= 0:
            raise ValueError("margin_m must be >= 0")
        if self.action not in FENCE_ACTIONS:
            raise ValueError(f"action must be one of {', '.join(FENCE_ACTIONS)}, not {self.action!r}")


# How each GCS-failsafe action stops a vehicle at speed (m/s^2, m/s^3): the limits of ArduCopter's shaped
# stop, each checked against a real ArduCopter SITL quad from 10.1 m/s (docs/reliability.md "How a vehicle
# stops").
# brake: BRAKE, BRAKE_MODE_DECEL_RATE 7.5 and PSC_JERK_XY 5 (20.4 m); land: LAND's loiter braking,
# LOIT_BRK_ACCEL 2.5 and LOIT_BRK_JERK 5 (23.7 m); rtl first stops like a loiter too; off never stops at all
# (the speed scheduling then bounds nothing, and assumes the gentlest of these).
STOP_SHAPING: dict[str, tuple[float, float]] = {
    "brake": (7.5, 5.0),
    "land": (2.5, 5.0),
    "rtl": (2.5, 5.0),
    "off": (2.5, 5.0),
}


@dataclass(frozen=True)
class DeadGcsParams:
    """What the vehicles do if the ground station dies, and the speed scheduling that keeps it safe [add]
    (docs/reliability.md "When the ground station dies"; the action itself is safety.gcs_failsafe)."""

    # s an ArduCopter flies its last attitude target before it levels and holds its altitude; s a PX4 flies
    # its last OFFBOARD target before the failsafe (safety.gcs_failsafe) takes it out of OFFBOARD for good
    # (PX4's default 1 s, so a ground-station stall shorter than that does not end the flight); and s without
    # the ground station before the GCS failsafe, >= telemetry.lost_s so that an outage the fleet rides out
    # fires none (None: telemetry.lost_s, filled in by the mission loader). Each autopilot's dialect turns
    # them into its parameters and says which values it accepts (gcs_swarm.link.autopilots)
    guided_timeout_s: float = 0.5
    offboard_loss_timeout_s: float = 1.0
    failsafe_timeout_s: float | None = None
    # m/s^2 and m/s^3, acceleration and jerk limits of the failsafe's shaped stop (failsafe_speed
    # .brake_distances); None: the failsafe action's own (STOP_SHAPING; the mission loader fills them in)
    brake_accel: float | None = None
    brake_jerk: float | None = None
    clearance: float = 3.0  # m, kept between the point a vehicle would stop at and an obstacle's surface
    speed_scheduling: bool = True  # cap each vehicle's speed so that it stops short of what its course meets
    fence: FenceParams = FenceParams()  # the autopilots' geofence around the obstacles (FenceParams)

    def __post_init__(self) -> None:
        if self.brake_accel is not None and not self.brake_accel > 0:
            raise ValueError("brake_accel must be > 0")
        if self.brake_jerk is not None and not 1.0 <= self.brake_jerk <= 50.0:
            raise ValueError("brake_jerk must lie in 1..50 m/s^3 (PSC_JERK_XY 1..20, LOIT_BRK_JERK 5..50)")
        if not self.clearance >= 0:
            raise ValueError("clearance must be >= 0")


# [add] values that turn every smoothing and safety addition off, leaving the method as the spec states it
# (sections 3-8): the `paper` variant of `gcs-swarm compare` flies these, and tests of the plain equations use
# them. Keys are mission-file paths.
PAPER_PLAIN: dict[str, dict[str, float]] = {
    "guidance": {"circulation": 0.0, "obstacle_vertical": 1.0, "slot_range": False},
    "guidance.reference": {
        "jerk_max": 0.0,
        "brake_accel": 0.0,
        "stop_accel": 0.0,
        "heading_accel_max_deg": 0.0,
        "heading_filter_s": 0.0,
        "heading_from_route": False,
        "heading_sweep_max": 0.0,
        "heading_sweep_accel": 0.0,
        "turn_wait_deg": 0.0,
        "aim_turn_rate_deg": 0.0,
    },
    "limits": {"tilt_rate_max_deg": 0.0},
    "control.smc": {"drag_adaptation": 0.0},
    "control.smc.xy": {"disturbance_gain": 0.0},
    "safety.separation": {"closing_brake_accel": 0.0},
    "guidance.reshape": {"enabled": False},
    "guidance.pace": {"enabled": False},
}


def paper_plain_field(**changes: float | str) -> FieldParams:
    """FieldParams with the [add] terms off (PAPER_PLAIN), plus `changes`."""
    return FieldParams(**{**PAPER_PLAIN["guidance"], **changes})  # type: ignore[arg-type]


def paper_plain_reference(**changes: float | bool) -> ReferenceParams:
    """ReferenceParams with the [add] shaping off (PAPER_PLAIN), plus `changes`."""
    return ReferenceParams(**{**PAPER_PLAIN["guidance.reference"], **changes})  # type: ignore[arg-type]
