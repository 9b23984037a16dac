"""Speed scheduling for a ground station that may die at any moment [add] (docs/reliability.md, "When the
ground station dies").

If the ground station stops, a vehicle flies on: up to GUID_TIMEOUT on its last attitude target, then level
at constant altitude without braking, until its GCS failsafe (FS_GCS_TIMEOUT after the last ground-station
heartbeat) brakes it. Bounded from above, it covers `v T + v^2 / (2 a)` along its current course
(T = FS_GCS_TIMEOUT, a the failsafe's braking deceleration). So the horizontal speed of each vehicle is capped
at the largest v for which that distance, plus a clearance, fits before the first obstacle its course meets:

    v_cap = a (sqrt(T^2 + 2 d / a) - T),   d = (distance along the course to the obstacle's sphere grown by
                                                 the clearance), v_cap = inf if the course meets none.

Shapes: pos, vel (N, 3) ENU m, m/s; centres (K, 3), radii (K,) m.
"""

from __future__ import annotations

import numpy as np


def distance_along_course(
    pos: np.ndarray, vel: np.ndarray, centres: np.ndarray, radii: np.ndarray, clearance: float
) -> np.ndarray:
    """(N,) m: how far each vehicle can go along its horizontal course (the direction of vel's x, y; at its
    altitude) before it enters an obstacle's sphere grown by `clearance` (at its altitude: the circle of that
    sphere's cross-section); 0 if already inside one; inf if the course meets none or the vehicle hovers."""
    n = len(pos)
    out = np.full(n, np.inf)
    speed = np.hypot(vel[:, 0], vel[:, 1])
    moving = speed > 1e-6
    if not len(radii) or not moving.any():
        return out
    direction = np.zeros((n, 2))
    direction[moving] = vel[moving, :2] / speed[moving, None]
    rel = centres[None, :, :2] - pos[:, None, :2]  # (N, K, 2) vehicle -> centre
    dz = pos[:, None, 2] - centres[None, :, 2]
    grown_sq = (radii[None, :] + clearance) ** 2 - dz * dz  # squared radius of the cross-section circle
    along = np.einsum("nkd,nd->nk", rel, direction)
    miss_sq = np.einsum("nkd,nkd->nk", rel, rel) - along * along  # squared distance of centre from the ray
    half_chord_sq = grown_sq - miss_sq
    inside = np.einsum("nkd,nkd->nk", rel, rel) < grown_sq
    hit = (grown_sq > 0.0) & (half_chord_sq >= 0.0) & (along > 0.0)
    entry = np.where(hit, along - np.sqrt(np.maximum(half_chord_sq, 0.0)), np.inf)
    entry = np.where(inside & (grown_sq > 0.0), 0.0, entry)
    out[moving] = entry[moving].min(axis=1)
    return out


def failsafe_speed_caps(
    pos: np.ndarray,
    vel: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    reaction_s: float,
    brake_accel: float,
    clearance: float,
) -> np.ndarray:
    """(N,) m/s horizontal speed caps (module docstring); inf where the course is clear. `reaction_s` T s,
    `brake_accel` a m/s^2, `clearance` m."""
    d = distance_along_course(pos, vel, centres, radii, clearance)
    a, t = brake_accel, reaction_s
    with np.errstate(invalid="ignore"):
        cap = a * (np.sqrt(t * t + 2.0 * d / a) - t)
    return np.where(np.isfinite(d), cap, np.inf)
