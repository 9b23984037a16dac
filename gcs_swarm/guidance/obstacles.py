"""Spherical obstacles: moving centres and surface distance (spec 2.1), and the push of a formation slot out
of an obstacle, sphere, cylinder or prism (compiled, for the tick's formation kernel).

Shapes: `q` (N, D) query points, `centres` (K, D), `radii` (K,), D = 2 (circles) or 3 (spheres); cylinders
and prisms packed as swarm_common.obstacle_shapes.ShapeArrays (kinds, params, vertices).
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.jit import kernel
from swarm_common.numpy_rules import maximum
from swarm_common.obstacle_shapes import footprint_distance


def centres_at(centres0: np.ndarray, velocities: np.ndarray | None, t: float | np.ndarray) -> np.ndarray:
    """Centres (K, D) of obstacles moving at constant velocity (K, D): c(t) = c0 + v*t (spec 2.1)."""
    centres0 = np.asarray(centres0, dtype=float)
    if velocities is None:
        return centres0
    return centres0 + np.asarray(velocities, dtype=float) * t


def surface_distance(q: np.ndarray, centres: np.ndarray, radii: np.ndarray, l_min: float) -> np.ndarray:
    """Surface distances (N, K) of points q (N, D) to obstacles (K, D), (K,), floored at `l_min` (spec 2.1
    l_eff)."""
    diff = q[:, None, :] - centres[None, :, :]
    return np.maximum(np.sqrt(np.einsum("nkd,nkd->nk", diff, diff)) - radii[None, :], l_min)


@kernel
def push_out_horizontally(
    x: float, y: float, z: float, centres: np.ndarray, radii: np.ndarray, margin: float
) -> tuple[float, float]:
    """The point (x, y, z) moved horizontally out of every obstacle's sphere grown by `margin` m: a point
    closer than r + margin to a centre (in x, y, at any height the grown sphere covers) goes radially out to
    that circle at its own height (one pass over the obstacles in order; a point on the centre's vertical
    goes out along +x). Continuous in the point; returns the new (x, y)."""
    for k in range(radii.shape[0]):
        dz = z - centres[k, 2]
        grown = radii[k] + margin
        reach_sq = grown * grown - dz * dz
        h0, h1 = x - centres[k, 0], y - centres[k, 1]
        dist = np.hypot(h0, h1)
        if reach_sq > 0.0 and dist * dist < reach_sq:
            ring = math.sqrt(maximum(reach_sq, 0.0))
            if dist > 0.0:
                d0, d1 = h0 / dist, h1 / dist
            else:
                d0, d1 = 1.0, 0.0
            x, y = centres[k, 0] + d0 * ring, centres[k, 1] + d1 * ring
    return x, y


@kernel
def push_out_of_shapes(
    x: float, y: float, z: float, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, margin: float
) -> tuple[float, float]:
    """The point (x, y, z) moved horizontally out of every cylinder and prism (packed, spec 2.2) grown by
    `margin` m, as push_out_horizontally does for spheres: the grown shape's cross-section at height z is
    the footprint grown by margin beside the walls, by sqrt(margin^2 - v^2) at v m above the roof or below the
    floor; a point with footprint distance h (obstacle_shapes.footprint_distance, < 0 inside) short of that
    goes along the footprint's outward normal at its nearest point by the difference (one pass over the
    shapes in order; a point on a cylinder's axis goes out along +x). Returns the new (x, y)."""
    for k in range(kinds.shape[0]):
        row = params[k]
        v = maximum(row[4] - z, z - row[5])  # m beyond the roof or floor, <= 0 between them
        if v >= margin:
            continue
        ring = margin if v <= 0.0 else math.sqrt(margin * margin - v * v)
        h, nx, ny = footprint_distance(x, y, kinds[k], row, vertices)
        if h < ring:
            x, y = x + (ring - h) * nx, y + (ring - h) * ny
    return x, y
