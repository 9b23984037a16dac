"""The leader's path ahead, predicted by flying its own reference forward through the same field [add]
(docs/iaapf-smc-spec.md section 6a.2).

The reshape's look-ahead (gcs_swarm.guidance.reshape) asks where every slot will pass. Along the straight
route through the waypoints, the answer is wrong wherever the leader itself meets an obstacle: its own
repulsion (l0 = 20 m) swerves it metres off the route long before it gets there (the quickstart's leader
passes 16 m right of the line to its goal), so the formation is checked where it will not fly, finds that
no shape fits, and changes shape only once the obstacle is close. Here the leader's reference (spec 8 steps
2-5: attraction to its waypoint, the obstacles' repulsion along its braking path, the jerk-limited shaping,
its speed cap) is integrated forward from its present state alone, without the other vehicles, every
PREDICT_DT_S, and the formation's heading psi_L with it (formation.leader_course, LeaderHeading); the path is
resampled every `step_m` of horizontal travel. Obstacles are taken where they are now. Where the predicted
leader stops short of the length asked (at its goal, or stalled where its attraction and an obstacle's
repulsion balance, as in front of a gap between two large obstacles, which the real leader leaves seconds
later), the path goes on along the straight route from there (reshape.route_samples): a look-ahead that
ended at the stall would find no obstacle beyond it, and a formation narrowed for the gap would widen in
front of it.

The stepping is one compiled kernel (`leader_flight`, swarm_common.jit) over the laws the tick itself calls,
each written once: the waypoint switch (`waypoint_ahead`, within `switch_radius`), the leader's aim at its
waypoint (`leader_aim`, spec 8a.10), the braking look-ahead and the reference step
(reference.py), the field (field.attraction_force, field.obstacle_repulsion_force) and psi_L
(formation.leader_course, formation.heading_step); with NUMBA_DISABLE_JIT=1 the same code runs as plain
Python and gives the same path (tests/gcs_swarm/guidance/test_leader_path.py).

Shapes: positions (3,) or (P, 3) ENU m; headings rad; distances m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from gcs_swarm.guidance.capability import NO_BUDGET, AccelBudget
from gcs_swarm.guidance.field import (
    NO_RANGES,
    attraction_config,
    attraction_force,
    obstacle_repulsion_force,
    repulsion_config,
)
from gcs_swarm.guidance.formation import LeaderHeading, heading_step, leader_course
from gcs_swarm.guidance.params import FieldParams
from gcs_swarm.guidance.reference import ReferenceConfig, leash_and_lookahead, reference_step
from gcs_swarm.guidance.reshape import route_samples
from swarm_common.jit import kernel
from swarm_common.numpy_rules import norm3
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays
from swarm_common.rotations import wrap_pi_float

PREDICT_DT_S = 0.1  # s, the prediction's step
# steps allowed per metre asked at the speed cap, and at least MIN_STEPS: a leader slowed by its field or
# stopping at its goal covers less than `length` and the prediction ends there
STEP_ALLOWANCE = 2.0
MIN_STEPS = 20
STOPPED_M_S = 0.05  # m/s: a leader this slow at its last waypoint has arrived
STALL_PROGRESS_M = 1.0  # m: a leader that comes no closer to its goal than this ...
STALL_S = 6.0  # s: ... for this long, far from it, is held by its field (leader_stalls)


@kernel
def switch_radius(
    waypoints: np.ndarray, index: int, vx: float, vy: float, radius: float, aim_turn_rate: float, most: float
) -> float:
    """m: how near the leader moves on from waypoint `index` of waypoints (W, 3) ENU m to the next (spec 8a.10
    [add]; `waypoint_ahead` asks): `radius`, or with an aim turning at aim_turn_rate rad/s > 0 (`leader_aim`)
    at a corner, where the arc the leader flies at its reference speed (vx, vy) m/s (radius speed / rate)
    meets the next leg, so that it flies by on an arc round the corner instead of beyond it: the tangent
    length (speed / rate) tan(theta / 2) of a turn by theta (the angle between that velocity and the next
    leg), at most `most` m, never under `radius`. `radius` itself at the last waypoint."""
    last = waypoints.shape[0] - 1
    if aim_turn_rate <= 0.0 or index >= last:
        return radius
    leg_x = waypoints[index + 1, 0] - waypoints[index, 0]
    leg_y = waypoints[index + 1, 1] - waypoints[index, 1]
    leg, speed = np.hypot(leg_x, leg_y), np.hypot(vx, vy)
    if leg <= 0.0 or speed <= 0.0:
        return radius
    cos_turn = min(max((vx * leg_x + vy * leg_y) / (leg * speed), -1.0), 1.0)
    tangent = speed / aim_turn_rate * math.tan(0.5 * math.acos(cos_turn))
    return max(radius, min(tangent, most))


@kernel
def waypoint_ahead(
    waypoints: np.ndarray, index: int, p: np.ndarray, vx: float, vy: float, radius: float,
    aim_turn_rate: float, most: float,
) -> tuple[int, float]:  # fmt: skip
    """The leader's waypoint (spec 6 [add]): the index into waypoints (W, 3) it flies to from p (3,) ENU m,
    moving on from `index` to the next once within `switch_radius` of it (never past the last), and its
    distance m; the leader's reference velocity (vx, vy) m/s, its aim's turn rate rad/s and the switch radius
    `radius` and `most` m go to `switch_radius`. Compiled: the tick calls it, and so does `leader_flight`."""
    distance = norm3(waypoints[index, 0] - p[0], waypoints[index, 1] - p[1], waypoints[index, 2] - p[2])
    within = switch_radius(waypoints, index, vx, vy, radius, aim_turn_rate, most)
    if distance < within and index < waypoints.shape[0] - 1:
        index += 1
        distance = norm3(waypoints[index, 0] - p[0], waypoints[index, 1] - p[1], waypoints[index, 2] - p[2])
    return index, distance


@kernel
def leader_aim(
    p: np.ndarray, goal: np.ndarray, bearing: float, max_turn: float, hold_distance: float
) -> tuple[np.ndarray, float]:
    """Where the leader's attraction pulls it (spec 8a.10 [add]: a fly-by corner): its waypoint goal (3,) ENU
    m as seen from p (3,) along a bearing (rad, from East) that turns at most max_turn rad toward the true one
    from `bearing`, its value at the previous step, at the waypoint's own horizontal distance and height; the
    waypoint itself (and its true bearing) when max_turn <= 0, when `bearing` is not finite (no previous
    step), within hold_distance m of it, where the attraction steers the leader onto its goal, or once the
    bearing has caught up with the true one (the waypoint exactly, not to rounding). Returns the
    aim (3,) and its bearing rad in [-pi, pi). Compiled: the tick calls it, and so does `leader_flight`."""
    to_x, to_y = goal[0] - p[0], goal[1] - p[1]
    across = np.hypot(to_x, to_y)
    true = math.atan2(to_y, to_x)
    aim = goal.copy()
    if max_turn <= 0.0 or not math.isfinite(bearing) or across <= hold_distance:
        return aim, true
    turn = wrap_pi_float(true - bearing)
    if abs(turn) <= max_turn:  # caught up: the waypoint itself, exactly
        return aim, true
    turned = wrap_pi_float(bearing + min(max(turn, -max_turn), max_turn))
    aim[0], aim[1] = p[0] + across * math.cos(turned), p[1] + across * math.sin(turned)
    return aim, turned


@dataclass(frozen=True)
class LeaderModel:
    """What the prediction flies: the leader's reference settings (ReferenceGenerator.config), its field,
    the attraction's segment boundary d_g m, the braking look-ahead's deceleration m/s^2 (0: at the point),
    the waypoint switch radius m, whether psi_L follows the route and how fast its aim turns, rad/s
    (`leader_aim`; 0: off) (ReferenceParams)."""

    config: ReferenceConfig
    field: FieldParams
    d_g: float
    brake_accel: float
    waypoint_radius: float
    heading_from_route: bool
    aim_turn_rate: float = 0.0


class LeaderSteps(NamedTuple):
    """The leader's reference flown forward (`leader_steps`), one row per step of PREDICT_DT_S (S steps)."""

    positions: np.ndarray  # (S, 3) ENU m, after each step
    speeds: np.ndarray  # (S,) m/s, horizontal
    headings: np.ndarray  # (S,) rad, the formation's heading psi_L, in [-pi, pi)
    waypoints: np.ndarray  # (S,) int, the index of the waypoint flown to during the step
    distances: np.ndarray  # (S,) m, the distance to that waypoint at the step's start
    travel: np.ndarray  # (S,) m, the horizontal path length from the start


@kernel
def leader_flight(
    p: np.ndarray, v: np.ndarray, a: np.ndarray, psi: float, rate: float, filtered: bool, fx: float,
    fy: float, min_speed: float, rate_max: float, hold_distance: float, accel_max: float, filter_s: float,
    gain: float, waypoints: np.ndarray, speed_cap: float, steps: int, length: float, centres: np.ndarray,
    radii: np.ndarray, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, k_att: float,
    d_g: float, segmented: bool, l0: float, l_min: float, adaptive: bool, k_rep: float, n_exp: float,
    rho_eps: float, circulation: float, obstacle_vertical: float, brake_accel: float, waypoint_radius: float,
    from_route: bool, aim_bearing: float, aim_turn_rate: float, budgets: np.ndarray, ref_gain: float,
    v_z: float, stop_accel: float, k_v: float, jerk_max: float, has_z_min: bool, z_min: float,
    jerk_max_z: float, a_z: float, tau_v: float, a_xy_max: float, a_xy_evasive: float, jerk_xy_evasive: float,
    jerk_z_evasive: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:  # fmt: skip
    """The leader's reference (spec 8 steps 2-5) flown forward alone from p, v, a (3,) (ENU m, m/s, m/s^2)
    with psi_L's state psi rad, rate rad/s, low-passed course (fx, fy) m/s (`filtered`: there is one) and
    settings (`heading_step`'s), through the waypoints (W, 3) from the first (`waypoint_ahead` from
    waypoint_radius m) at up to speed_cap m/s, among spheres centres (K, 3), radii
    (K,) and the shapes packed as kinds, params, vertices, for at most `steps` steps of PREDICT_DT_S. The
    field's settings are AttractionConfig's (k_att .. segmented) and RepulsionConfig's (l0 ..
    obstacle_vertical), the braking look-ahead's deceleration brake_accel m/s^2, `from_route` psi_L's course
    (`leader_course`), the aim's bearing rad at the start (NaN: none yet) and turn rate rad/s (`leader_aim`),
    its acceleration budget (1, 4) (`reference_step`'s budgets), the rest ReferenceConfig's (its `gain` as
    ref_gain). Each step: the waypoint and the aim at it, the field at the reference (the obstacles along its
    braking path), psi_L, then the reference step.

    Returns the arrays of LeaderSteps, `steps` rows each, and the number S of rows filled: the steps end
    early after the one whose horizontal travel reaches `length` m, or once the leader has stopped
    (slower than STOPPED_M_S within d_g m of its last waypoint)."""
    positions = np.empty((steps, 3))
    speeds = np.empty(steps)
    headings = np.empty(steps)
    indices = np.empty(steps, dtype=np.int64)
    distances = np.empty(steps)
    travel = np.empty(steps)
    ps, vs, accel = np.empty((1, 3)), np.empty((1, 3)), np.empty((1, 3))
    goal, aimed = np.empty((1, 3)), np.empty((1, 3))
    for d in range(3):
        ps[0, d], vs[0, d], accel[0, d] = p[d], v[d], a[d]
    rows, evasive, zero = np.ones(1, dtype=np.bool_), np.zeros(1, dtype=np.bool_), np.zeros((1, 3))
    cap = np.full(1, speed_cap)
    index, last, covered, count = 0, waypoints.shape[0] - 1, 0.0, 0
    no_leash = np.full(ps.shape[0], math.inf)  # the predicted reference is its own vehicle
    for step in range(steps):
        index, distance = waypoint_ahead(
            waypoints, index, ps[0], vs[0, 0], vs[0, 1], waypoint_radius, aim_turn_rate, d_g
        )
        aim, aim_bearing = leader_aim(ps[0], waypoints[index], aim_bearing, aim_turn_rate * PREDICT_DT_S, d_g)
        for d in range(3):
            goal[0, d], aimed[0, d] = waypoints[index, d], aim[d]
        ahead = leash_and_lookahead(ps, vs, ps, rows, no_leash, brake_accel)
        force = attraction_force(ps, aimed, k_att, d_g, segmented) + obstacle_repulsion_force(
            ps, ahead, goal, centres, radii, kinds, params, vertices, NO_RANGES, l0, l_min, adaptive, k_rep,
            n_exp, rho_eps, circulation, obstacle_vertical,
        )  # fmt: skip
        course_x, course_y = leader_course(vs[0, :2], ps[0], goal[0], from_route)
        psi, rate, fx, fy = heading_step(
            psi, rate, filtered, fx, fy, course_x, course_y, distance, PREDICT_DT_S, min_speed, rate_max,
            hold_distance, accel_max, filter_s, gain,
        )  # fmt: skip
        filtered = True
        was_x, was_y = ps[0, 0], ps[0, 1]
        accel, ps, vs = reference_step(
            ps, vs, accel, force, zero, zero, aimed, cap, rows, evasive, budgets, PREDICT_DT_S, ref_gain, v_z,
            stop_accel, k_v, jerk_max, has_z_min, z_min, jerk_max_z, a_z, tau_v, a_xy_max, a_xy_evasive,
            jerk_xy_evasive, jerk_z_evasive,
        )  # fmt: skip
        speed = np.hypot(vs[0, 0], vs[0, 1])
        covered += np.hypot(ps[0, 0] - was_x, ps[0, 1] - was_y)
        for d in range(3):
            positions[step, d] = ps[0, d]
        speeds[step], headings[step], indices[step] = speed, psi, index
        distances[step], travel[step] = distance, covered
        count = step + 1
        if covered >= length or (index == last and speed < STOPPED_M_S and distance < d_g):
            break
    return positions, speeds, headings, indices, distances, travel, count


def leader_steps(
    model: LeaderModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, heading: LeaderHeading,
    waypoints: np.ndarray, speed_cap: float, steps: int, length: float, centres: np.ndarray,
    radii: np.ndarray, shapes: ShapeArrays = NO_SHAPES, aim_bearing: float = math.nan,
    budget: AccelBudget = NO_BUDGET,
) -> LeaderSteps:  # fmt: skip
    """The leader's reference flown forward (`leader_flight`) from p, v, a (3,) (ENU m, m/s, m/s^2), psi_L
    as `heading` stands (not changed), its aim's bearing rad (`leader_aim`; NaN: none yet) and its
    acceleration budget (capability.AccelBudget, held as it is now) through the
    waypoints (W, 3) at up to speed_cap m/s among spheres centres (K, 3), radii (K,) and `shapes`, for at
    most `steps` steps of PREDICT_DT_S, ending after the step whose horizontal travel reaches `length` m
    (math.inf: no such end) or once it has stopped at its last waypoint."""
    fx, fy = heading.v_filtered if heading.v_filtered is not None else (0.0, 0.0)
    p, v, a = (np.ascontiguousarray(x, dtype=float).reshape(3) for x in (p, v, a))
    start = (p, v, a, float(heading.psi), float(heading.rate), heading.v_filtered is not None, fx, fy)
    course = (np.ascontiguousarray(waypoints, dtype=float), float(speed_cap), int(steps), float(length))
    obstacles = (np.ascontiguousarray(centres, dtype=float), np.ascontiguousarray(radii, dtype=float))
    leader = (
        float(model.brake_accel), float(model.waypoint_radius), bool(model.heading_from_route),
        float(aim_bearing), float(model.aim_turn_rate), np.array([budget], dtype=float),
    )  # fmt: skip
    args = (
        *start, *heading.settings(), *course, *obstacles, *shapes, *attraction_config(model.field, model.d_g),
        *repulsion_config(model.field), *leader, *model.config,
    )  # fmt: skip
    *arrays, count = leader_flight(*args)
    return LeaderSteps(*(x[:count] for x in arrays))


def _step_budget(length: float, speed_cap: float) -> int:
    """Steps allowed for `length` m at up to speed_cap m/s: STEP_ALLOWANCE times the time at the cap, and
    at least MIN_STEPS."""
    return max(MIN_STEPS, math.ceil(STEP_ALLOWANCE * length / (max(speed_cap, 1.0) * PREDICT_DT_S)))


def predict_leader_path(
    model: LeaderModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, heading: LeaderHeading,
    waypoints: np.ndarray, speed_cap: float, length: float, step_m: float, centres: np.ndarray,
    radii: np.ndarray, shapes: ShapeArrays = NO_SHAPES, aim_bearing: float = math.nan,
    budget: AccelBudget = NO_BUDGET,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The leader's path (`leader_steps`) from its reference state p, v, a (3,), heading, aim's bearing rad
    (`leader_aim`; NaN: none yet) and acceleration budget (capability.AccelBudget) through the waypoints
    (W, 3) still ahead at up to speed_cap m/s, among spheres centres (K, 3), radii (K,) and `shapes`, for
    `length` m of horizontal travel (where the leader stops short, on along the straight route: module
    docstring): points (P, 3), the formation's heading there (P,) rad and their travel from p (P,) m, one
    every step_m, the first p itself with the present heading."""
    steps = _step_budget(length, speed_cap)
    flight = leader_steps(
        model, p, v, a, heading, waypoints, speed_cap, steps, length, centres, radii, shapes, aim_bearing,
        budget,
    )  # fmt: skip
    track = np.vstack([np.asarray(p, dtype=float).reshape(1, 3), flight.positions])
    courses = np.concatenate([[heading.psi], flight.headings])
    travel = np.concatenate([[0.0], flight.travel])
    if travel[-1] < length:  # stopped short: on along the straight route (from its end, the waypoints left)
        index = int(flight.waypoints[-1]) if len(flight.waypoints) else 0
        rest, rest_courses, rest_travel = route_samples(
            track[-1], courses[-1], waypoints[index:], length - travel[-1], model.d_g
        )
        track = np.vstack([track, rest[1:]])
        courses = np.concatenate([courses, rest_courses[1:]])
        travel = np.concatenate([travel, travel[-1] + rest_travel[1:]])
    return resample(track, np.unwrap(courses), travel, min(length, travel[-1]), step_m)


def leader_stalls(
    model: LeaderModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, heading: LeaderHeading, goal: np.ndarray,
    speed_cap: float, centres: np.ndarray, radii: np.ndarray, shapes: ShapeArrays = NO_SHAPES,
) -> bool:  # fmt: skip
    """Whether the leader, flown forward (`leader_steps`) from p, v, a (3,) and heading to goal (3,) at up to
    speed_cap m/s among the obstacles, is held on the way: for STALL_S its distance to the goal, still more
    than d_g m, comes no STALL_PROGRESS_M closer than it has been (held where its attraction and the
    repulsion balance, at rest or swinging to and fro), within STEP_ALLOWANCE times the time the straight
    line takes at speed_cap."""
    length = float(np.hypot(*(np.asarray(goal)[:2] - np.asarray(p)[:2])))
    goal_row = np.asarray(goal, dtype=float).reshape(1, 3)
    flight = leader_steps(
        model, p, v, a, heading, goal_row, speed_cap, _step_budget(length, speed_cap), math.inf, centres,
        radii, shapes,
    )  # fmt: skip
    closest, held_s = math.inf, 0.0
    for distance in flight.distances.tolist():
        if distance < closest - STALL_PROGRESS_M:
            closest, held_s = distance, 0.0
        else:
            held_s += PREDICT_DT_S
        if held_s >= STALL_S and distance > model.d_g:
            return True
    return False


def resample(
    track: np.ndarray, courses: np.ndarray, travel: np.ndarray, length: float, step_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The points (P, 3), headings (P,) rad and travel (P,) m of a track (T, 3) with its unwrapped headings
    (T,) and non-decreasing travel (T,) m, interpolated every step_m up to `length` m (and at 0)."""
    at = np.arange(0.0, length + 1e-9, step_m)
    points = np.stack([np.interp(at, travel, track[:, k]) for k in range(3)], axis=1)
    return points, np.interp(at, travel, courses), at
