"""The shared world: spherical obstacles moving at constant velocity, and collision detection (ENU metres).

Collisions are swept: between two autopilot ticks every vehicle and obstacle is taken to move in a straight
line, and the closest approach over the interval is tested, so a fast vehicle cannot tunnel through a thin
gap between two samples. A vehicle collides with an obstacle when it comes within FUSELAGE_RADIUS of the
obstacle's surface, and with another vehicle when the two centres come within 2 * FUSELAGE_RADIUS.
"""

from __future__ import annotations

import numpy as np

FUSELAGE_RADIUS = 0.175  # m (the paper's arm length, Table 2)


class Obstacles:
    """K spheres: centres at t = 0 (K,3) m, radii (K,) m, velocities (K,3) m/s; centre(t) = c0 + v t."""

    def __init__(self, centers: np.ndarray, radii: np.ndarray, velocities: np.ndarray) -> None:
        self.centers = np.asarray(centers, dtype=float).reshape(-1, 3)
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        self.velocities = np.asarray(velocities, dtype=float).reshape(-1, 3)
        if not (len(self.centers) == len(self.radii) == len(self.velocities)):
            raise ValueError("obstacle centres, radii and velocities must have the same length")

    def __len__(self) -> int:
        return len(self.radii)

    def at(self, t: float) -> np.ndarray:
        """(K,3) centres at simulated time t (s)."""
        return self.centers + self.velocities * t


def closest_approach(rel0: np.ndarray, rel1: np.ndarray) -> np.ndarray:
    """Minimum norm of the segment rel0 -> rel1 (..., 3), for relative positions moving linearly."""
    delta = rel1 - rel0
    length2 = np.einsum("...k,...k->...", delta, delta)
    s = np.clip(-np.einsum("...k,...k->...", rel0, delta) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    return np.linalg.norm(rel0 + s[..., None] * delta, axis=-1)


def find_collisions(
    pos0: np.ndarray, pos1: np.ndarray, obstacles: Obstacles, t0: float, t1: float, ignore: np.ndarray
) -> list[tuple[int, str]]:
    """Vehicles that collided while moving from pos0 to pos1 (N,3) during [t0, t1]: (index, what it hit).

    ignore (N,) bool: vehicles already crashed (not tested, and not obstacles for the others either: debris
    on the ground is not tracked). Vehicle indices in the text are 0-based like the CLI's vehicle numbers.
    """
    hits: dict[int, str] = {}
    live = np.flatnonzero(~ignore)
    if len(obstacles) and len(live):
        c0, c1 = obstacles.at(t0), obstacles.at(t1)
        rel0 = pos0[live, None, :] - c0[None, :, :]
        rel1 = pos1[live, None, :] - c1[None, :, :]
        touching = closest_approach(rel0, rel1) <= obstacles.radii[None, :] + FUSELAGE_RADIUS
        for a, k in zip(*np.nonzero(touching), strict=True):
            hits.setdefault(int(live[a]), f"collision with obstacle {int(k)}")
    if len(live) > 1:
        a, b = np.triu_indices(len(live), k=1)
        rel0 = pos0[live[a]] - pos0[live[b]]
        rel1 = pos1[live[a]] - pos1[live[b]]
        for pair in np.flatnonzero(closest_approach(rel0, rel1) <= 2.0 * FUSELAGE_RADIUS):
            i, j = int(live[a[pair]]), int(live[b[pair]])
            hits.setdefault(i, f"collision with vehicle {j}")
            hits.setdefault(j, f"collision with vehicle {i}")
    return sorted(hits.items())
