"""Generated families of obstacle courses: worlds nobody tuned for, to test that a formation keeps its shape
(issue 36; docs/metrics.md "Generated courses").

`course(family, seed)` is the mission data (a dict, as YAML would load it) of one course; the same (family,
seed) gives the same course on every machine. Each seed draws the fleet (3 to 9 vehicles in a V, a line or a
grid, 8 to 12 m apart) and the weather (calm on even seeds, 2 to 6 m/s of wind with gusts on odd ones); the
family decides the route and the obstacles:

- `slalom`: one straight leg of 180 to 240 m past five spheres alternating left and right, 3 to 9 m from the
  route;
- `gap`: one leg through a gap between two large spheres, 8 m wide up to 0.8 times the formation's width, then
  a sphere near the route;
- `legs2`, `legs3`: two or three legs of 100 to 160 m with turns of 30 to 100 degrees, two spheres near each.

The vehicles start in a launch grid behind the leader (rows of four, 6 m apart), facing the first leg, so that
the formation has to assemble: hovering at the formation altitude (the default, which spares each flight its
climb) or on the ground. Everything else is the mission defaults
(docs/mission-schema.md). Positions are local ENU metres.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gcs_swarm.guidance.formation import formation_offsets, rotate_to_world

FAMILIES = ("slalom", "gap", "legs2", "legs3")
SHAPES = ("v", "line", "grid")
ALTITUDE_M = 10.0
LAUNCH_SPACING_M = 6.0  # m between launch spots
LAUNCH_ROW = 4  # spots per launch row
KEEP_OUT_M = 6.0  # m beyond an obstacle's radius kept free around starts, waypoints and final slots


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _launch_grid(n: int, heading: float) -> np.ndarray:
    """(n, 2) ENU m: the leader at the origin, the others in rows of LAUNCH_ROW behind it, facing heading."""
    spots = np.zeros((n, 2))
    for k in range(1, n):
        row, col = divmod(k - 1, LAUNCH_ROW)
        back = -(row + 1) * LAUNCH_SPACING_M
        side = ((LAUNCH_ROW - 1) / 2.0 - col) * LAUNCH_SPACING_M
        spots[k] = rotate_to_world(np.array([[back, side, 0.0]]), heading)[0, :2]
    return spots


def _route(family: str, rng: np.random.Generator, heading: float) -> np.ndarray:
    """(W, 2) ENU m: the leader's waypoints after the start at the origin."""
    if family in ("slalom", "gap"):
        return (rng.uniform(180.0, 240.0) * _unit(heading))[None, :]
    legs = 2 if family == "legs2" else 3
    points, here, course = [], np.zeros(2), heading
    for leg in range(legs):
        if leg:
            course += math.radians(rng.uniform(30.0, 100.0)) * rng.choice([-1.0, 1.0])
        here = here + rng.uniform(100.0, 160.0) * _unit(course)
        points.append(here)
    return np.array(points)


def _beside(a: np.ndarray, b: np.ndarray, along: float, cross: float) -> np.ndarray:
    """The point `along` (fraction) of the way from a to b, `cross` m to the left of it."""
    d = b - a
    u = d / np.linalg.norm(d)
    return a + along * d + cross * np.array([-u[1], u[0]])


def _obstacles(
    family: str, rng: np.random.Generator, route: np.ndarray, width: float
) -> list[tuple[np.ndarray, float]]:
    """(centre (2,), radius m) of the course's spheres; `width` m the formation's lateral extent."""
    points = np.vstack([np.zeros((1, 2)), route])
    out: list[tuple[np.ndarray, float]] = []
    if family == "slalom":
        side = rng.choice([-1.0, 1.0])
        for k, along in enumerate(np.linspace(0.3, 0.85, 5)):
            cross = side * (-1.0) ** k * rng.uniform(3.0, 9.0)
            out.append(
                (
                    _beside(points[0], points[1], along + rng.uniform(-0.03, 0.03), cross),
                    rng.uniform(2.5, 4.0),
                )
            )
    elif family == "gap":
        gap = rng.uniform(8.0, max(8.5, 0.8 * width))
        radius = rng.uniform(6.0, 10.0)
        shift = rng.uniform(-0.25, 0.25) * gap  # the gap's centre off the straight route
        along = rng.uniform(0.4, 0.55)
        for side in (-1.0, 1.0):
            out.append((_beside(points[0], points[1], along, shift + side * (gap / 2.0 + radius)), radius))
        cross = rng.choice([-1.0, 1.0]) * rng.uniform(3.0, 8.0)
        out.append((_beside(points[0], points[1], rng.uniform(0.75, 0.85), cross), rng.uniform(2.5, 4.0)))
    else:
        for a, b in zip(points[:-1], points[1:], strict=True):
            for along in (rng.uniform(0.3, 0.45), rng.uniform(0.6, 0.75)):
                cross = rng.choice([-1.0, 1.0]) * rng.uniform(2.0, 9.0)
                out.append((_beside(a, b, along, cross), rng.uniform(2.5, 4.0)))
    return out


def _clear_of(
    points: np.ndarray, obstacles: list[tuple[np.ndarray, float]]
) -> list[tuple[np.ndarray, float]]:
    """The obstacles that keep KEEP_OUT_M beyond their radius from every point (K, 2)."""
    return [(c, r) for c, r in obstacles if np.min(np.linalg.norm(points - c, axis=1)) > r + KEEP_OUT_M]


def course(family: str, seed: int, airborne: bool = True) -> dict[str, Any]:
    """The mission data of course `seed` of `family` (module docstring); `airborne`: the vehicles start
    hovering over their launch spots at the formation altitude (run.airborne_start), else on the ground.
    ValueError for an unknown family."""
    if family not in FAMILIES:
        raise ValueError(f"course family must be one of {', '.join(FAMILIES)}, not {family!r}")
    rng = np.random.default_rng([FAMILIES.index(family), seed])
    n = int(rng.integers(3, 10))
    shape = str(rng.choice(SHAPES))
    spacing = float(rng.uniform(8.0, 12.0))
    heading = float(rng.uniform(-math.pi, math.pi))
    offsets = formation_offsets(shape, n - 1, spacing)
    width = float(np.ptp(np.concatenate([[0.0], offsets[:, 1]])))
    route = _route(family, rng, heading)
    obstacles = _obstacles(family, rng, route, width)
    starts = _launch_grid(n, heading)
    last_course = heading if len(route) == 1 else math.atan2(*(route[-1] - route[-2])[::-1])
    finals = route[-1] + rotate_to_world(offsets, last_course)[:, :2]
    obstacles = _clear_of(np.vstack([starts, route, finals]), obstacles)
    yaw_deg = round(math.degrees(heading), 2)
    vehicles: list[dict[str, Any]] = [
        {
            "name": f"uav{i + 1}",
            **({"role": "leader"} if i == 0 else {}),
            "start": {
                "position": [round(float(x), 3) for x in (*starts[i], ALTITUDE_M if airborne else 0.0)],
                "yaw_deg": yaw_deg,
            },
        }
        for i in range(n)
    ]
    windy = seed % 2 == 1
    wind = {
        "speed": round(float(rng.uniform(2.0, 6.0)), 2) if windy else 0.0,
        "direction_deg": round(float(rng.uniform(0.0, 360.0)), 1),
        "turbulence": 0.3 if windy else 0.0,
    }
    length = float(np.sum(np.linalg.norm(np.diff(np.vstack([np.zeros((1, 2)), route]), axis=0), axis=1)))
    waypoints = [[round(float(x), 3) for x in (*p, ALTITUDE_M)] for p in route]
    return {
        "mission": {
            "name": f"course-{family}-{seed}",
            "description": f"generated course {family} seed {seed}: {n} vehicles in a {shape}, "
            f"{len(obstacles)} obstacles, wind {wind['speed']:g} m/s",
        },
        "vehicles": vehicles,
        "formation": {"shape": shape, "spacing": round(spacing, 3), "altitude": ALTITUDE_M},
        "waypoints": waypoints,
        "world": {
            "obstacles": [
                {"center": [round(float(c[0]), 3), round(float(c[1]), 3), ALTITUDE_M], "radius": round(r, 3)}
                for c, r in obstacles
            ],
            "wind": wind,
        },
        "run": {
            "time_limit_s": round(60.0 + length / 3.0),
            "airborne_start": airborne,
            "simulator": {"seed": seed},
        },
    }
