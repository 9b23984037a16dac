"""The shared world: spherical obstacles moving at constant velocity, still cylinders and prisms (trees,
masts, buildings: swarm_common.obstacle_shapes), and collision detection (ENU metres).

Collisions are swept: between two autopilot ticks every vehicle and obstacle is taken to move in a straight
line, and the closest approach over the interval is tested, so a fast vehicle cannot tunnel through a thin
gap between two samples. A vehicle collides with an obstacle when it comes within FUSELAGE_RADIUS of the
obstacle's surface, and with another vehicle when the two centres come within 2 * FUSELAGE_RADIUS.
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.approach import segment_min_norm
from swarm_common.jit import kernel
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays, segment_nearest, surface

FUSELAGE_RADIUS = 0.175  # m (the paper's arm length, Table 2)


class Obstacles:
    """K spheres: centres at t = 0 (K,3) m, radii (K,) m, velocities (K,3) m/s; centre(t) = c0 + v t; and
    `shapes`, S still cylinders and prisms (spec 2.2), numbered K .. K + S - 1 after the spheres."""

    def __init__(
        self, centers: np.ndarray, radii: np.ndarray, velocities: np.ndarray, shapes: ShapeArrays = NO_SHAPES
    ) -> None:
        self.shapes = shapes
        self.centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        self.velocities = np.asarray(velocities, dtype=float).reshape(-1, 3)
        if not (len(self.centers) == len(self.radii) == len(self.velocities)):
            raise ValueError("obstacle centres, radii and velocities must have the same length")

    def at(self, t: float) -> np.ndarray:
        """(K,3) centres at simulated time t (s)."""
        return self.centers + self.velocities * t


@kernel
def swept_hits(
    pos0: np.ndarray, pos1: np.ndarray, c0: np.ndarray, c1: np.ndarray, radii: np.ndarray, ignore: np.ndarray,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Per vehicle: first obstacle hit (N,) and first vehicle hit (N,), -1 for none (find_collisions). The
    spheres (K) are numbered first, then the packed shapes kinds, params, vertices: a vehicle hits one when
    the point of its step's segment nearest the shape's surface (obstacle_shapes.segment_nearest) is within
    FUSELAGE_RADIUS of it."""
    n, k = pos0.shape[0], c0.shape[0]
    obstacle_hit = np.full(n, -1, dtype=np.int64)
    vehicle_hit = np.full(n, -1, dtype=np.int64)
    for i in range(n):
        if ignore[i]:
            continue
        for j in range(k):
            reach = segment_min_norm(
                pos0[i, 0] - c0[j, 0], pos0[i, 1] - c0[j, 1], pos0[i, 2] - c0[j, 2],
                pos1[i, 0] - c1[j, 0], pos1[i, 1] - c1[j, 1], pos1[i, 2] - c1[j, 2],
            )  # fmt: skip
            if reach <= radii[j] + FUSELAGE_RADIUS:
                obstacle_hit[i] = j
                break
        for s in range(kinds.shape[0] if obstacle_hit[i] < 0 else 0):
            a0, a1, a2 = pos0[i, 0], pos0[i, 1], pos0[i, 2]
            b0, b1, b2 = pos1[i, 0], pos1[i, 1], pos1[i, 2]
            step = math.sqrt((b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2)
            if surface(a0, a1, a2, s, kinds, params, vertices)[0] - step > FUSELAGE_RADIUS:
                continue  # the distance is 1-Lipschitz: no point of the step comes nearer
            f = segment_nearest(a0, a1, a2, b0, b1, b2, s, kinds, params, vertices)
            l = surface(
                a0 + f * (b0 - a0), a1 + f * (b1 - a1), a2 + f * (b2 - a2), s, kinds, params, vertices
            )[0]
            if l <= FUSELAGE_RADIUS:
                obstacle_hit[i] = k + s
                break
        for j in range(i + 1, n):
            if ignore[j]:
                continue
            reach = segment_min_norm(
                pos0[i, 0] - pos0[j, 0], pos0[i, 1] - pos0[j, 1], pos0[i, 2] - pos0[j, 2],
                pos1[i, 0] - pos1[j, 0], pos1[i, 1] - pos1[j, 1], pos1[i, 2] - pos1[j, 2],
            )  # fmt: skip
            if reach <= 2.0 * FUSELAGE_RADIUS:
                if vehicle_hit[i] < 0:
                    vehicle_hit[i] = j
                if vehicle_hit[j] < 0:
                    vehicle_hit[j] = i
    return obstacle_hit, vehicle_hit


def find_collisions(
    pos0: np.ndarray, pos1: np.ndarray, obstacles: Obstacles, t0: float, t1: float, ignore: np.ndarray
) -> list[tuple[int, str]]:
    """Vehicles that collided while moving from pos0 to pos1 (N,3) during [t0, t1]: (index, what it hit).

    ignore (N,) bool: vehicles already crashed (not tested, and not obstacles for the others either: debris
    on the ground is not tracked). Vehicle indices in the text are 0-based like the CLI's vehicle numbers.
    An obstacle hit is reported before a vehicle hit.
    """
    obstacle_hit, vehicle_hit = swept_hits(
        pos0, pos1, obstacles.at(t0), obstacles.at(t1), obstacles.radii, np.asarray(ignore, dtype=np.bool_),
        *obstacles.shapes,
    )  # fmt: skip
    hits = []
    for i in np.flatnonzero((obstacle_hit >= 0) | (vehicle_hit >= 0)):
        what = f"obstacle {obstacle_hit[i]}" if obstacle_hit[i] >= 0 else f"vehicle {vehicle_hit[i]}"
        hits.append((int(i), f"collision with {what}"))
    return hits
