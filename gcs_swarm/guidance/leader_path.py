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

Shapes: positions (3,) or (P, 3) ENU m; headings rad; distances m.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from gcs_swarm.guidance.field import attraction, obstacle_repulsion
from gcs_swarm.guidance.formation import LeaderHeading, leader_course
from gcs_swarm.guidance.params import FieldParams
from gcs_swarm.guidance.reference import ReferenceConfig, leash_and_lookahead, reference_step
from gcs_swarm.guidance.reshape import route_samples
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays

PREDICT_DT_S = 0.1  # s, the prediction's step
# steps allowed per metre asked at the speed cap, and at least MIN_STEPS: a leader slowed by its field or
# stopping at its goal covers less than `length` and the prediction ends there
STEP_ALLOWANCE = 2.0
MIN_STEPS = 20
STOPPED_M_S = 0.05  # m/s: a leader this slow at its last waypoint has arrived
STALL_PROGRESS_M = 1.0  # m: a leader that comes no closer to its goal than this ...
STALL_S = 6.0  # s: ... for this long, far from it, is held by its field (leader_stalls)


def waypoint_ahead(waypoints: np.ndarray, index: int, p: np.ndarray, radius: float) -> tuple[int, float]:
    """The leader's waypoint (spec 6 [add]): the index into waypoints (W, 3) it flies to from p (3,) ENU m,
    moving on from `index` to the next once within `radius` m (never past the last), and its distance m."""
    distance = float(np.linalg.norm(waypoints[index] - p))
    if distance < radius and index < len(waypoints) - 1:
        index += 1
        distance = float(np.linalg.norm(waypoints[index] - p))
    return index, distance


@dataclass(frozen=True)
class LeaderModel:
    """What the prediction flies: the leader's reference settings (ReferenceGenerator.config), its field,
    the attraction's segment boundary d_g m, the braking look-ahead's deceleration m/s^2 (0: at the point),
    the waypoint switch radius m and whether psi_L follows the route (ReferenceParams)."""

    config: ReferenceConfig
    field: FieldParams
    d_g: float
    brake_accel: float
    waypoint_radius: float
    heading_from_route: bool


def leader_steps(
    model: LeaderModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, heading: LeaderHeading,
    waypoints: np.ndarray, speed_cap: float, steps: int, centres: np.ndarray, radii: np.ndarray,
    shapes: ShapeArrays = NO_SHAPES,
) -> Iterator[tuple[np.ndarray, float, float, int, float]]:  # fmt: skip
    """The leader's reference flown forward from p, v, a (3,) (ENU m, m/s, m/s^2) and heading (not changed: a
    copy is flown) through the waypoints (W, 3) at up to speed_cap m/s among spheres centres (K, 3), radii
    (K,) and `shapes`, for at most `steps` steps of PREDICT_DT_S: after each, its position (3,), horizontal
    speed m/s, the formation's heading psi_L rad, the index of the waypoint it flies to and its distance m;
    the steps end early once it has stopped at its last waypoint."""
    psi = copy.deepcopy(heading)
    ps, vs, accel = (np.array(x, dtype=float).reshape(1, 3) for x in (p, v, a))
    rows, evasive, zero = np.ones(1, dtype=bool), np.zeros(1, dtype=bool), np.zeros((1, 3))
    cap = np.array([float(speed_cap)])
    index, last = 0, len(waypoints) - 1
    for _ in range(steps):
        index, distance = waypoint_ahead(waypoints, index, ps[0], model.waypoint_radius)
        goal = waypoints[index]
        goal_row = goal.reshape(1, 3)
        ahead = leash_and_lookahead(ps, vs, ps, rows, math.inf, model.brake_accel)
        force = attraction(ps, goal_row, model.field, model.d_g)
        force += obstacle_repulsion(ps, ahead, goal_row, centres, radii, model.field, shapes=shapes)
        psi.update(leader_course(vs[0, :2], ps[0], goal, model.heading_from_route), distance, PREDICT_DT_S)
        accel, ps, vs = reference_step(
            ps, vs, accel, force, zero, zero, goal_row, cap, rows, evasive, PREDICT_DT_S, *model.config
        )
        speed = float(np.hypot(vs[0, 0], vs[0, 1]))
        yield ps[0].copy(), speed, psi.psi, index, distance
        if index == last and speed < STOPPED_M_S and distance < model.d_g:
            return


def predict_leader_path(
    model: LeaderModel, p: np.ndarray, v: np.ndarray, a: np.ndarray, heading: LeaderHeading,
    waypoints: np.ndarray, speed_cap: float, length: float, step_m: float, centres: np.ndarray,
    radii: np.ndarray, shapes: ShapeArrays = NO_SHAPES,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The leader's path (`leader_steps`) from its reference state p, v, a (3,)
    and heading through the waypoints (W, 3) still ahead at up to speed_cap m/s, among spheres centres (K, 3),
    radii (K,) and `shapes`, for `length` m of horizontal travel (where the leader stops short, on along the
    straight route: module docstring): points (P, 3), the formation's heading there (P,) rad and their travel
    from p (P,) m, one every step_m, the first p itself with the present heading."""
    track, courses, travel, index = [np.array(p, dtype=float)], [heading.psi], [0.0], 0
    steps = max(MIN_STEPS, math.ceil(STEP_ALLOWANCE * length / (max(speed_cap, 1.0) * PREDICT_DT_S)))
    flight = leader_steps(model, p, v, a, heading, waypoints, speed_cap, steps, centres, radii, shapes)
    for point, _, psi, heading_to, _ in flight:
        index = heading_to  # the waypoint the path goes on from if it stops short
        track.append(point)
        courses.append(psi)
        travel.append(travel[-1] + float(np.hypot(*(track[-1][:2] - track[-2][:2]))))
        if travel[-1] >= length:
            break
    if travel[-1] < length:  # stopped short: on along the straight route (from its end, the waypoints left)
        rest, rest_courses, rest_travel = route_samples(
            track[-1], courses[-1], waypoints[index:], length - travel[-1], model.d_g
        )
        track.extend(rest[1:])
        courses.extend(rest_courses[1:])
        travel.extend(travel[-1] + rest_travel[1:])
    headings = np.unwrap(np.array(courses))
    return resample(np.array(track), headings, np.array(travel), min(length, travel[-1]), step_m)


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
    steps = max(MIN_STEPS, math.ceil(STEP_ALLOWANCE * length / (max(speed_cap, 1.0) * PREDICT_DT_S)))
    goal_row = np.asarray(goal, dtype=float).reshape(1, 3)
    closest, held_s = math.inf, 0.0
    for _, _, _, _, distance in leader_steps(
        model, p, v, a, heading, goal_row, speed_cap, steps, centres, radii, shapes
    ):
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
