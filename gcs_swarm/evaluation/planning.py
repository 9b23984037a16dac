"""The `plan` subcommand's logic: the leader's kinematic path through a mission's obstacles (spec 5.1, 11.3),
its JSON figures (spec 10 definitions) and an optional plot.

`mission` is a `gcs_swarm.mission.Mission`; only these attributes are read: goal, obstacles (.center,
.radius, .velocity), cylinders and prisms (spec 2.2), field (FieldParams), reference (ReferenceParams),
planner (.start, .dimensions, .dt, .time_limit_s, .speed, .goal_radius, .step) and
vehicles[leader_index].start.position.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from gcs_swarm.evaluation import figures
from gcs_swarm.evaluation.planner import PlannerSettings, PlanResult, plan_path
from gcs_swarm.guidance.params import FieldMethod
from swarm_common.obstacle_shapes import pack_shapes

METHODS = tuple(law.value for law in FieldMethod)
JSON_KEYS = (
    "reached",
    "time_s",
    "path_length_m",
    "min_clearance_m",
    "oscillation_time_s",
    "heading_reversals",
)


def plan_mission(mission: Any, method: str) -> PlanResult:
    """Plan the leader's path with `method` "apf" or "iaapf" in the mission's 2-D (x, y) or 3-D world.

    The segment boundary d_g defaults to planner speed / K_v (spec 3.1) unless the field sets it.
    """
    if method not in METHODS:
        raise ValueError(f"plan method must be one of {', '.join(METHODS)}, not {method!r}")
    cfg = mission.planner
    dim = int(cfg.dimensions)
    if dim not in (2, 3):
        raise ValueError(f"planner dimensions must be 2 or 3, not {cfg.dimensions!r}")
    start = cfg.start if cfg.start is not None else mission.vehicles[mission.leader_index].start.position
    obstacles = list(mission.obstacles)
    centres = np.array([np.asarray(o.center, dtype=float)[:dim] for o in obstacles]).reshape(-1, dim)
    radii = np.array([float(o.radius) for o in obstacles])
    speeds = [
        np.zeros(dim) if o.velocity is None else np.asarray(o.velocity, dtype=float)[:dim] for o in obstacles
    ]
    velocities = np.array(speeds).reshape(-1, dim) if any(np.any(v != 0.0) for v in speeds) else None
    fp = dataclasses.replace(mission.field, method=method)
    d_g = fp.d_g if fp.d_g is not None else cfg.speed / mission.reference.k_v
    settings = PlannerSettings(
        dt=cfg.dt,
        time_limit_s=cfg.time_limit_s,
        speed=cfg.speed,
        goal_radius=cfg.goal_radius,
        step=cfg.step,
        k_v=mission.reference.k_v,
    )
    goal = np.asarray(mission.goal, dtype=float)[:dim]
    # the cylinders and prisms (spec 2.2); a 2-D world is the plane z = 0, where they stand from -inf to
    # inf (their footprints, as the spheres are their circles)
    low, high = (-math.inf, math.inf) if dim == 2 else (None, None)
    shapes = pack_shapes(
        cylinders=[(c.center, c.radius, low or c.bottom, high or c.top) for c in mission.cylinders],
        prisms=[(p.footprint, low or p.bottom, high or p.top) for p in mission.prisms],
    )
    return plan_path(
        np.asarray(start, dtype=float)[:dim], goal, centres, radii, velocities, fp, d_g, settings, shapes
    )


def _finite_or_none(x: float | None, digits: int = 3) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), digits)


def plan_json(result: PlanResult) -> dict[str, Any]:
    """The figures printed by `plan --json` (keys `JSON_KEYS`; time_s null if not reached, clearance null
    without obstacles)."""
    return {
        "reached": bool(result.reached),
        "time_s": _finite_or_none(result.time_s),
        "path_length_m": _finite_or_none(result.path_length_m),
        "min_clearance_m": _finite_or_none(result.min_clearance_m),
        "oscillation_time_s": _finite_or_none(result.oscillation_time_s),
        "heading_reversals": int(result.heading_reversals),
    }


def draw_plan(
    ax: Any, results_by_method: Mapping[str, PlanResult], obstacles: Iterable[Any], title: str
) -> None:
    """Draw a top view (x East, y North) of planned paths, obstacles (.center, .radius at t = 0) and
    start/goal on a matplotlib Axes."""
    import matplotlib.pyplot as plt

    for obs in obstacles:
        c = np.asarray(obs.center, dtype=float)
        ax.add_patch(plt.Circle((c[0], c[1]), float(obs.radius), color="0.6", alpha=0.6))
    first = None
    for method, res in results_by_method.items():
        first = first or res
        state = f"reached {res.time_s:.1f} s" if res.reached else "not reached"
        ax.plot(res.path[:, 0], res.path[:, 1], lw=1.5, label=f"{method.upper()} ({state})")
    if first is not None:
        ax.plot(*first.start[:2], "ks", label="start")
        ax.plot(*first.goal[:2], "r*", ms=12, label="goal")
    ax.set_aspect("equal")
    ax.set(title=title, xlabel="x East (m)", ylabel="y North (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")


def plot_plan(
    results_by_method: Mapping[str, PlanResult], obstacles: Iterable[Any], path_png: str | os.PathLike[str]
) -> bool:
    """Save the top view of `draw_plan` as a PNG at `path_png`. Returns False (writing nothing) when
    matplotlib, the optional `plot` extra, is not installed."""
    plt = figures.pyplot()
    if plt is None:
        return False
    fig, ax = plt.subplots(figsize=(7, 6))
    draw_plan(ax, results_by_method, obstacles, "planned path")
    fig.tight_layout()
    fig.savefig(path_png, dpi=120)
    plt.close(fig)
    return True
