"""Kinematic point-mass planner (spec 5.1 / 11.3): follow the APF or IAAPF field from start to goal.

Step rule per sample: "proportional" `v = F/|F| * min(speed, |F|/k_att * K_v)` or "constant"
`v = speed * F/|F|`.
2-D or 3-D by the length of `start`. Obstacles may move at constant velocity. The field is the flight's own
(gcs_swarm.guidance.field, 3-D): a 2-D world is its z = 0 plane, with the [add] circulation off (the plane
has no "horizontal side" of its own to pass on).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_swarm.evaluation import metrics
from gcs_swarm.guidance.field import attraction, obstacle_repulsion
from gcs_swarm.guidance.obstacles import centres_at
from gcs_swarm.guidance.params import FieldParams
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays

STEP_RULES = ("proportional", "constant")
NO_ROWS, NO_RADII = np.zeros((0, 3)), np.zeros(0)


@dataclass(frozen=True)
class PlannerSettings:
    """dt s, time_limit_s s, speed m/s (cap or constant), goal_radius m, step rule, K_v 1/s, hold_s s (the
    reached-with-hold time of spec 10, simulated past the first entry)."""

    dt: float = 0.01
    time_limit_s: float = 60.0
    speed: float = 15.0
    goal_radius: float = 0.5
    step: str = "proportional"
    k_v: float = 1.0
    hold_s: float = 2.0

    def __post_init__(self) -> None:
        if self.step not in STEP_RULES:
            raise ValueError(f"planner step must be one of {STEP_RULES}, not {self.step!r}")
        for name in ("dt", "time_limit_s", "speed", "goal_radius", "k_v"):
            if not getattr(self, name) > 0:
                raise ValueError(f"planner {name} must be > 0")
        if self.hold_s < 0:
            raise ValueError("planner hold_s must be >= 0")


@dataclass(frozen=True)
class PlanResult:
    """The path (T, D) m at `times` (T,) s, and the figures of spec 10 over the approach (up to `time_s`
    when reached, else the whole run): reached, time_s (None if not reached), path_length_m,
    min_clearance_m (inf without obstacles), collision, oscillation_time_s, heading_reversals;
    final_distance_m to the goal at the end."""

    method: str
    start: np.ndarray
    goal: np.ndarray
    path: np.ndarray
    times: np.ndarray
    reached: bool
    time_s: float | None
    path_length_m: float
    min_clearance_m: float
    collision: bool
    oscillation_time_s: float
    heading_reversals: int
    final_distance_m: float


def plan_path(
    start: np.ndarray,
    goal: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    velocities: np.ndarray | None,
    fp: FieldParams,
    d_g: float,
    settings: PlannerSettings,
    shapes: ShapeArrays = NO_SHAPES,
) -> PlanResult:
    """Run the point mass from start (D,) to goal (D,) through obstacles (K, D), (K,), moving at velocities
    (K, D) or static (None), and the still cylinders and prisms `shapes` (spec 2.2; a 2-D world is the plane
    z = 0), under the field `fp` (its `method` selects APF or IAAPF), segment boundary d_g m.

    Stops after the goal has been held for `settings.hold_s` or at the time limit.
    """
    start = np.asarray(start, dtype=float)
    goal = np.asarray(goal, dtype=float)
    dim = start.shape[0]
    if dim not in (2, 3) or goal.shape != (dim,):
        raise ValueError(f"start and goal must both be 2-D or 3-D points, got {start.shape} and {goal.shape}")
    centres = np.asarray(centres, dtype=float).reshape(-1, dim)
    radii = np.asarray(radii, dtype=float).reshape(-1)
    steps = int(round(settings.time_limit_s / settings.dt))
    path = np.empty((steps + 1, dim))
    path[0] = start
    q = np.zeros((1, 3))
    q[0, :dim] = start
    goal_3d = np.zeros((1, 3))
    goal_3d[0, :dim] = goal
    centres_3d = np.zeros((len(radii), 3))
    circulation = None if dim == 3 else 0.0
    hold_steps = int(round(settings.hold_s / settings.dt))
    inside_for = -1
    last = steps
    for k in range(steps):
        centres_3d[:, :dim] = centres_at(centres, velocities, k * settings.dt)
        repulsion = obstacle_repulsion(q, q, goal_3d, centres_3d, radii, fp, circulation, shapes)
        force = (attraction(q, goal_3d, fp, d_g) + repulsion)[:, :dim]
        size = float(np.linalg.norm(force))
        if size > 0.0:
            speed = settings.speed
            if settings.step == "proportional":
                speed = min(speed, size / fp.k_att * settings.k_v)
            q[:, :dim] = q[:, :dim] + force * (speed * settings.dt / size)
        path[k + 1] = q[0, :dim]
        inside_for = inside_for + 1 if np.linalg.norm(path[k + 1] - goal) <= settings.goal_radius else -1
        if inside_for >= hold_steps:
            last = k + 1
            break
    path = path[: last + 1]
    times = np.arange(last + 1) * settings.dt
    dist = np.linalg.norm(path - goal, axis=1)
    t_reach = metrics.reach_time(times, dist, settings.goal_radius, settings.hold_s)
    approach = len(times) if t_reach is None else int(np.searchsorted(times, t_reach)) + 1
    vel = np.diff(path[:approach], axis=0) / settings.dt
    t_osc, reversals = metrics.oscillation(times[1:approach], vel)
    if velocities is None:
        track = centres
    else:
        track = centres_at(centres[None], np.reshape(velocities, (1, -1, dim)), times[:approach, None, None])
    clear, collided = metrics.min_obstacle_clearance(path[:approach, None, :], track, radii, l_arm=0.0)
    if shapes.number:
        path_3d = np.zeros((approach, 1, 3))
        path_3d[:, 0, :dim] = path[:approach]
        shape_clear, shape_hit = metrics.min_obstacle_clearance(path_3d, NO_ROWS, NO_RADII, 0.0, shapes)
        clear, collided = min(clear, shape_clear), collided or shape_hit
    return PlanResult(
        method=fp.method,
        start=start,
        goal=goal,
        path=path,
        times=times,
        reached=t_reach is not None,
        time_s=t_reach,
        path_length_m=metrics.path_length(path[:approach]),
        min_clearance_m=clear,
        collision=collided,
        oscillation_time_s=t_osc,
        heading_reversals=reversals,
        final_distance_m=float(dist[-1]),
    )
