"""Spherical obstacles: surface distance, its gradient direction and the inside case (spec 2.1).

Shapes: `q` (N, D) query points, `centres` (K, D), `radii` (K,), D = 2 (circles) or 3 (spheres).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_swarm.guidance.vector_ops import column_mean


@dataclass(frozen=True)
class SurfaceGeometry:
    """Distance of N points to the surfaces of K obstacles: `l` (N, K) surface distance floored at `l_min`
    (spec 2.1 l_eff), `n_o` (N, K, D) unit vector obstacle centre -> point (+last axis, i.e. +z in 3-D, where
    the point sits on the centre)."""

    l: np.ndarray
    n_o: np.ndarray


def centres_at(centres0: np.ndarray, velocities: np.ndarray | None, t: float | np.ndarray) -> np.ndarray:
    """Centres (K, D) of obstacles moving at constant velocity (K, D): c(t) = c0 + v*t (spec 2.1)."""
    centres0 = np.asarray(centres0, dtype=float)
    if velocities is None:
        return centres0
    return centres0 + np.asarray(velocities, dtype=float) * t


def surface_geometry(q: np.ndarray, centres: np.ndarray, radii: np.ndarray, l_min: float) -> SurfaceGeometry:
    """Surface distances and directions of points q (N, D) to obstacles (K, D), (K,) (spec 2.1)."""
    diff = q[:, None, :] - centres[None, :, :]
    dist = np.sqrt(np.einsum("nkd,nkd->nk", diff, diff))
    raw = dist - radii[None, :]
    on_centre = dist == 0.0
    safe = np.where(on_centre, 1.0, dist)
    n_o = diff / safe[..., None]
    if on_centre.any():
        n_o[on_centre] = 0.0
        n_o[on_centre, -1] = 1.0
    return SurfaceGeometry(l=np.maximum(raw, l_min), n_o=n_o)


def squared_distances(q: np.ndarray, points: np.ndarray) -> np.ndarray:
    """|q_i - points_k|^2 (N, K) by one matrix product about the points' centroid, so the cancellation error
    stays near 1e-16 * (extent of the scene)^2; callers recompute exact differences for the pairs that matter.
    NaN rows of q give NaN rows."""
    origin = column_mean(points) if len(points) else 0.0
    a = q - origin
    b = points - origin
    d2 = np.einsum("nd,nd->n", a, a)[:, None] + np.einsum("kd,kd->k", b, b)[None, :] - 2.0 * (a @ b.T)
    return np.maximum(d2, 0.0)


def clearance(q: np.ndarray, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Smallest surface distance (N,) of each point to any obstacle (< 0 inside); +inf without obstacles."""
    if len(radii) == 0:
        return np.full(len(q), np.inf)
    return (np.sqrt(squared_distances(q, centres)) - radii[None, :]).min(axis=1)


def push_out_horizontally(
    points: np.ndarray, centres: np.ndarray, radii: np.ndarray, margin: float
) -> np.ndarray:
    """Points (N, 3) moved horizontally out of every obstacle's sphere grown by `margin` m: a point closer
    than r + margin to a centre (in x, y, at any height the grown sphere covers) goes radially out to that
    circle at its own height (one pass over the obstacles in order). Continuous in the point; (N, 3)."""
    out = np.array(points, dtype=float)
    for c, r in zip(centres, radii, strict=True):
        dz = out[:, 2] - c[2]
        grown = r + margin
        reach_sq = grown * grown - dz * dz
        horiz = out[:, :2] - c[:2]
        dist = np.hypot(horiz[:, 0], horiz[:, 1])
        inside = (reach_sq > 0.0) & (dist * dist < reach_sq)
        if not inside.any():
            continue
        ring = np.sqrt(np.maximum(reach_sq, 0.0))
        direction = np.divide(horiz, dist[:, None], out=np.zeros_like(horiz), where=dist[:, None] > 0.0)
        direction[inside & (dist == 0.0), 0] = 1.0
        out[inside, :2] = c[:2] + direction[inside] * ring[inside, None]
    return out
