"""Leader-follower formation geometry (spec 6, paper Eqs 26-29) and the leader heading (spec 6 [add]).

Offsets `delta_i = (d_x, d_y, d_z)` are in the leader heading frame (x forward, y left, z up), one row per
vehicle, the leader's row zero. Functions broadcast over leading axes: `p_L` (..., 3), `psi_L` (...,),
offsets (N, 3) -> (..., N, 3).
"""

from __future__ import annotations

import math

import numpy as np

from gcs_swarm.guidance.obstacles import push_out_horizontally, push_out_of_shapes
from gcs_swarm.guidance.slot_assignment import AssignmentRule, assign_moves
from swarm_common.jit import kernel
from swarm_common.rotations import wrap_pi, wrap_pi_float
from swarm_common.shaping import sqrt_controller

SHAPES = ("line", "v", "column", "grid")


def formation_offsets(shape: str, n_followers: int, spacing: float, angle_deg: float = 45.0) -> np.ndarray:
    """Leader-frame slot offsets (n_followers, 3) of a named shape for followers k = 1..n_followers (place
    them in the rows of the non-leader vehicles, in index order; the leader's offset is zero).

    line: abreast, alternating right/left (`(0, s r L, 0)`); v: wedge behind the leader with half-angle
    `angle_deg`, `(-r L cos a, s r L sin a, 0)` with row r = ceil(k/2) and side s = (-1)^k (spec 6 (b));
    column: `(-k L, 0, 0)`; grid: rows of ceil(sqrt(n_followers)) centred behind the leader, `L` apart.
    """
    if shape not in SHAPES:
        raise ValueError(f"formation shape must be one of {', '.join(SHAPES)}, not {shape!r}")
    if n_followers < 0:
        raise ValueError("the number of followers must be >= 0")
    if not spacing > 0:
        raise ValueError("formation spacing must be > 0")
    k = np.arange(1, n_followers + 1, dtype=float)
    row = np.ceil(k / 2.0)
    side = np.where(k % 2 == 1, -1.0, 1.0)
    out = np.zeros((n_followers, 3))
    if shape == "line":
        out[:, 1] = side * row * spacing
    elif shape == "v":
        a = math.radians(angle_deg)
        out[:, 0] = -row * spacing * math.cos(a)
        out[:, 1] = side * row * spacing * math.sin(a)
    elif shape == "column":
        out[:, 0] = -k * spacing
    else:
        cols = max(1, math.ceil(math.sqrt(n_followers)))
        m = np.arange(n_followers)
        out[:, 0] = -(1 + m // cols) * spacing
        out[:, 1] = ((cols - 1) / 2.0 - m % cols) * spacing
    return out


def check_offsets(offsets: np.ndarray, n: int, leader: int) -> np.ndarray:
    """Validate explicit offsets: finite, shape (N, 3), leader row zero. Returns them as a float array."""
    arr = np.ascontiguousarray(offsets, dtype=float)
    if arr.shape != (n, 3):
        raise ValueError(f"formation offsets must have shape ({n}, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("formation offsets must be finite numbers")
    if np.any(arr[leader] != 0.0):
        raise ValueError(f"the leader's offset (row {leader}) must be zero, got {arr[leader].tolist()}")
    return arr


def rotate_to_world(offsets: np.ndarray, psi: np.ndarray | float) -> np.ndarray:
    """Leader-frame offsets (..., N, 3) rotated about z by psi (...,) rad into world ENU, (..., N, 3) (spec 6,
    Eqs 26-27)."""
    offsets, psi = np.asarray(offsets, dtype=float), np.asarray(psi, dtype=float)[..., None]
    c, s = np.cos(psi), np.sin(psi)
    out = np.empty(np.broadcast_shapes(offsets.shape, psi.shape + (3,)))
    out[..., 0] = offsets[..., 0] * c - offsets[..., 1] * s
    out[..., 1] = offsets[..., 0] * s + offsets[..., 1] * c
    out[..., 2] = offsets[..., 2]
    return out


# m: a formation has assembled once every follower is this close to its slot: the controller's rule (until
# then a change of shape keeps its slots farthest apart, reshape) and the report's assembly (flight_quality)
ASSEMBLED_M = 2.0


def on_slots(pos: np.ndarray, slots: np.ndarray, rows: np.ndarray) -> bool:
    """Whether every one of the (N,) bool `rows` stands within ASSEMBLED_M of its slot: positions and slots
    (N, 3) ENU m."""
    return bool(np.all(np.linalg.norm(pos[rows] - slots[rows], axis=1) <= ASSEMBLED_M))


def slot_positions(p_leader: np.ndarray, psi_leader: np.ndarray | float, offsets: np.ndarray) -> np.ndarray:
    """Slots X_i^s (..., N, 3) from the leader position (..., 3) and heading (...,) (spec 6, Eqs 26-28)."""
    return np.asarray(p_leader, dtype=float)[..., None, :] + rotate_to_world(offsets, psi_leader)


@kernel
def formation_targets(
    heard: np.ndarray, cos_psi: np.ndarray, sin_psi: np.ndarray, offsets: np.ndarray, spacing: float,
    centres: np.ndarray, radii: np.ndarray, slot_margin: float, lead: int, goal: np.ndarray,
    destination: np.ndarray, follower_targets: np.ndarray, kinds: np.ndarray, params: np.ndarray,
    vertices: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Spec 8 step 1 for every vehicle from the leader state it heard (N, 11) (p (3), v (3), psi, psi rate,
    a (3)) and cos, sin of that psi (N,); offsets (N, 3) in the leader frame, scaled by `spacing`:

    - the slot X_i^s = p_L + R(psi_L) delta_i (N, 3) (spec 6, Eqs 26-28); [add] with slot_margin > 0 moved
      horizontally out of the spheres (obstacles.push_out_horizontally), then out of the cylinders and prisms
      packed as kinds, params, vertices (obstacles.push_out_of_shapes), so a follower is not torn between its
      slot's attraction and an obstacle's repulsion; the leader's row is its goal (3,);
    - the velocity feed-forward v_L + psi_L_dot z x R(psi_L) delta_i (N, 3);
    - [add] the acceleration feed-forward a_L minus the centripetal psi_L_dot^2 R(psi_L) delta_i (horizontal)
      (N, 3): followers accelerate with the leader; both feed-forwards zero in the leader's row;
    - the adaptive factor's destinations (N, 3): destination + R(psi_L) delta_i, or `follower_targets`
      (N, 3) when it has rows; the leader's row its goal. `destination` (3,) is the goal itself, or, while
      the leader flies to a via point round a gap (spec 6a.8), the waypoint that leg ends at: the followers'
      rho, and with it their repulsion, does not jump at each via point."""
    n = heard.shape[0]
    targets = np.empty((n, 3))
    v_ff = np.empty((n, 3))
    a_ff = np.empty((n, 3))
    dest = np.empty((n, 3))
    for i in range(n):
        c, s = cos_psi[i], sin_psi[i]
        o0, o1, o2 = offsets[i, 0] * spacing, offsets[i, 1] * spacing, offsets[i, 2] * spacing
        w0, w1, w2 = o0 * c - o1 * s, o0 * s + o1 * c, o2  # R(psi_L) delta_i
        rate = heard[i, 7]
        targets[i, 0], targets[i, 1], targets[i, 2] = heard[i, 0] + w0, heard[i, 1] + w1, heard[i, 2] + w2
        v_ff[i, 0] = heard[i, 3] + -rate * w1
        v_ff[i, 1] = heard[i, 4] + rate * w0
        v_ff[i, 2] = heard[i, 5] + 0.0
        rate_sq = rate * rate
        a_ff[i, 0] = heard[i, 8] - rate_sq * w0
        a_ff[i, 1] = heard[i, 9] - rate_sq * w1
        a_ff[i, 2] = heard[i, 10] - rate_sq * 0.0
        if follower_targets.shape[0] == 0:
            dest[i, 0], dest[i, 1], dest[i, 2] = destination[0] + w0, destination[1] + w1, destination[2] + w2
        else:
            dest[i, 0], dest[i, 1], dest[i, 2] = (
                follower_targets[i, 0],
                follower_targets[i, 1],
                follower_targets[i, 2],
            )
        if slot_margin > 0.0:
            targets[i, 0], targets[i, 1] = push_out_horizontally(
                targets[i, 0], targets[i, 1], targets[i, 2], centres, radii, slot_margin
            )
            targets[i, 0], targets[i, 1] = push_out_of_shapes(
                targets[i, 0], targets[i, 1], targets[i, 2], kinds, params, vertices, slot_margin
            )
    for d in range(3):
        targets[lead, d] = goal[d]
        v_ff[lead, d] = 0.0
        a_ff[lead, d] = 0.0
        dest[lead, d] = goal[d]
    return targets, v_ff, a_ff, dest


def leader_frame_offsets(p: np.ndarray, p_leader: np.ndarray, psi_leader: np.ndarray | float) -> np.ndarray:
    """Measured offsets (..., N, 3) of positions p (..., N, 3) in the leader heading frame (spec 6, Eq 29
    corrected: the transpose rotation, by -psi_leader)."""
    return rotate_to_world(p - np.asarray(p_leader, dtype=float)[..., None, :], -np.asarray(psi_leader))


def assign_slots(
    pos: np.ndarray,
    p_leader: np.ndarray,
    psi_leader: float,
    offsets: np.ndarray,
    movable: np.ndarray,
    min_gap: float,
) -> tuple[np.ndarray, AssignmentRule]:
    """Offsets (N, 3) with the slots of the `movable` (N,) bool vehicles permuted among them so that the
    longest straight move from a vehicle's position (N, 3) to its slot (at the leader's position (3,) and
    heading psi rad) is least, the moves not crossing and keeping min_gap m between vehicles
    (gcs_swarm.guidance.slot_assignment) [add], and the rule that decided. Rows with a non-finite position
    keep their slot."""
    out = np.array(offsets, dtype=float)
    rows = np.flatnonzero(np.asarray(movable, dtype=bool) & np.isfinite(pos).all(axis=1))
    if len(rows) < 2:
        return out, AssignmentRule.BOTTLENECK
    slots = slot_positions(p_leader, psi_leader, out[rows])
    order, rule = assign_moves(pos[rows], slots, min_gap)
    out[rows] = offsets[rows[order]]
    return out, rule


@kernel
def leader_course(
    v_ref_xy: np.ndarray, p_leader: np.ndarray, goal: np.ndarray, from_route: bool
) -> tuple[float, float]:
    """The course (x, y) m/s that psi_L steers to (`heading_step`): the leader's reference velocity v_ref_xy
    (2,), or with `from_route` [add] the direction from p_leader (3,) to its waypoint goal (3,) ENU m at that
    speed (the velocity itself at the waypoint). Compiled: the tick calls it, and so does the leader's
    predicted path (gcs_swarm.guidance.leader_path) from its kernel."""
    to_x, to_y = goal[0] - p_leader[0], goal[1] - p_leader[1]
    across = np.hypot(to_x, to_y)
    if from_route and across > 0.0:
        scale = np.hypot(v_ref_xy[0], v_ref_xy[1]) / across
        return to_x * scale, to_y * scale
    return v_ref_xy[0], v_ref_xy[1]


@kernel
def heading_step(
    psi: float, rate: float, filtered: bool, fx: float, fy: float, vx: float, vy: float, distance: float,
    dt: float, min_speed: float, rate_max: float, hold_distance: float, accel_max: float, filter_s: float,
    gain: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """One step of dt s of psi_L (spec 6 [add]; LeaderHeading documents the law) from its heading psi rad,
    turn rate rad/s and low-passed course (fx, fy) m/s (`filtered`: there is one yet), toward the course
    (vx, vy) m/s (`leader_course`) of a leader `distance` m from its goal; the settings are LeaderHeading's
    (min_speed m/s, rate_max rad/s, hold_distance m, accel_max rad/s^2, filter_s s, gain 1/s). Returns the
    new psi rad in [-pi, pi), its rate rad/s and the low-passed course (x, y) m/s. Plain float arithmetic,
    compiled: the tick's LeaderHeading.update and the leader's predicted path (gcs_swarm.guidance.leader_path)
    call it."""
    if filtered and filter_s > 0.0:
        k = dt / (filter_s + dt)
        vx, vy = fx + (vx - fx) * k, fy + (vy - fy) * k
    steering = np.hypot(vx, vy) > min_speed and distance > hold_distance
    error = wrap_pi_float(math.atan2(vy, vx) - psi) if steering else 0.0
    if accel_max <= 0.0:
        turn = error / dt
    else:
        turn = sqrt_controller(error, gain, accel_max, dt)
    turn = min(max(turn, -rate_max), rate_max)
    if accel_max > 0.0:
        step = accel_max * dt
        turn = min(max(turn, rate - step), rate + step)
    if not steering and accel_max <= 0.0:
        turn = 0.0
    return wrap_pi_float(psi + turn * dt), turn, vx, vy


class LeaderHeading:
    """psi_L: course of the leader's reference velocity, held when slow or near the goal (spec 6 [add]). The
    formation rotates with it and every vehicle's yaw is commanded to it.

    [add] Smoothing, so that the slot frame swings neither with every swerve of the leader nor in steps:
    the course is taken from the reference velocity low-passed with time constant `filter_s`, and psi_L
    follows it with ArduPilot's angle shaping (swarm_common.shaping.sqrt_controller): turn rate at
    most `rate_max`, changing at most `accel_max` rad/s^2. `accel_max` = 0 and `filter_s` = 0 give the
    spec's plain rate limit (the rate steps between -rate_max and +rate_max). The law is `heading_step`."""

    def __init__(
        self,
        psi: float,
        min_speed: float,
        rate_max: float,
        hold_distance: float,
        accel_max: float = 0.0,
        filter_s: float = 0.0,
        gain: float = 1.0,
    ) -> None:
        """`min_speed` m/s, `rate_max` rad/s, `hold_distance` m (d_g), `accel_max` rad/s^2, `filter_s` s,
        `gain` 1/s: turn rate per rad of course error in the linear region of the shaping."""
        self.psi = float(wrap_pi(psi))
        self.rate = 0.0
        self.min_speed = min_speed
        self.rate_max = rate_max
        self.hold_distance = hold_distance
        self.accel_max = accel_max
        self.filter_s = filter_s
        self.gain = gain
        self.v_filtered: tuple[float, float] | None = None  # m/s, the low-passed (x, y)

    def settings(self) -> tuple[float, float, float, float, float, float]:
        """`heading_step`'s settings, its last parameters in order: min_speed, rate_max, hold_distance,
        accel_max, filter_s, gain (as floats)."""
        return (
            float(self.min_speed), float(self.rate_max), float(self.hold_distance), float(self.accel_max),
            float(self.filter_s), float(self.gain),
        )  # fmt: skip

    def update(self, v_ref_xy: np.ndarray | tuple[float, float], distance_to_goal: float, dt: float) -> float:
        """Advance psi_L by one step of dt s (`heading_step`) toward the course v_ref_xy (2,) m/s
        (`leader_course`) of a leader distance_to_goal m from its goal; returns psi_L rad."""
        filtered = self.v_filtered is not None
        fx, fy = self.v_filtered if self.v_filtered is not None else (0.0, 0.0)
        self.psi, self.rate, vx, vy = heading_step(
            self.psi, self.rate, filtered, fx, fy, float(v_ref_xy[0]), float(v_ref_xy[1]),
            float(distance_to_goal), float(dt), *self.settings(),
        )  # fmt: skip
        self.v_filtered = (vx, vy)
        return self.psi
