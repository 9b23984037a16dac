"""Speed scheduling for a ground station that may die at any moment [add] (docs/reliability.md, "When the
ground station dies").

If the ground station stops, a vehicle flies on: up to GUID_TIMEOUT on its last attitude target, then level
at constant altitude without braking, until its GCS failsafe (FS_GCS_TIMEOUT after the last ground-station
heartbeat) puts it in BRAKE. Bounded from above (drag ignored), it covers `v T + D(v)` along its current
course: T = FS_GCS_TIMEOUT and D(v) the distance ArduCopter's BRAKE needs to stop from v
(`brake_distance`). So the horizontal speed of each vehicle is capped at the largest v for which that
distance, plus a clearance, fits before the first obstacle its course meets (inf if it meets none).

BRAKE does not stop at a constant deceleration: AC_PosControl shapes the stop (AP_Math control.cpp
shape_vel_accel, BRAKE_MODE_DECEL_RATE a = 7.5 m/s^2, PSC_JERK_XY j = 5 m/s^3): the deceleration ramps up
at j and then, below a^2 / j = 11.25 m/s, follows k v with k = j / a, an exponential decay of time constant
1.5 s. From 10 m/s that is about 20 m, not the 6.7 m of v^2 / 2a (a real ArduCopter SITL quad stopped from
10.1 m/s in 20.4 m; the sitl-sim vehicle follows the same shaping: sitl_sim.vehicle_model.position_control
.brake_shaping_step).

Shapes: pos, vel (N, 3) ENU m, m/s; centres (K, 3), radii (K,) m.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import numpy as np

from gcs_swarm.guidance.shaping import shape_vel_accel

# The compiled stopping-distance table (numba, extra "fast"): 0.3 s instead of numpy's 1.1 s at every mission
# start, where the ground station builds it before its first formation tick; the same bits
# (test_failsafe_speed.py). None: numpy.
compiled_brake_distances: Callable[[np.ndarray, float, float, float, int], np.ndarray] | None
try:
    from gcs_swarm.guidance.shaping_kernels import brake_distances as compiled_brake_distances
except ImportError:  # pragma: no cover - numba not installed
    compiled_brake_distances = None

SPEED_TABLE_MAX = 60.0  # m/s, the largest speed of the stopping-distance table (beyond: extrapolated)


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


def brake_distance(speed: np.ndarray | float, accel: float, jerk: float) -> np.ndarray:
    """m: horizontal distance ArduCopter's BRAKE needs to stop from `speed` m/s (module docstring), for the
    shaping's acceleration limit `accel` m/s^2 and jerk limit `jerk` m/s^3; the vehicle's own tracking lag is
    not included (about 0.2 s of travel at the start speed on the real SITL quad)."""
    speeds, distances = _brake_table(float(accel), float(jerk))
    v = np.asarray(speed, dtype=float)
    slope = (distances[-1] - distances[-2]) / (speeds[-1] - speeds[-2])
    return np.where(
        v <= speeds[-1], np.interp(v, speeds, distances), distances[-1] + slope * (v - speeds[-1])
    )


@lru_cache(maxsize=8)
def _brake_table(accel: float, jerk: float) -> tuple[np.ndarray, np.ndarray]:
    """(speeds, stopping distances) of the BRAKE shaping integrated at 2 ms for start speeds 0 to
    SPEED_TABLE_MAX: the ground station's own ArduPilot shaping (`shaping.shape_vel_accel`, AP_Math
    shape_vel_accel) driving each speed to zero, never through it (update_vel_accel's limit)."""
    if not (accel > 0 and jerk > 0):
        raise ValueError("accel and jerk must be > 0")
    speeds = np.linspace(0.0, SPEED_TABLE_MAX, 601)
    dt = 0.002
    steps = int((SPEED_TABLE_MAX / accel + 27.0 * accel / jerk) / dt)
    if compiled_brake_distances is not None:
        return speeds, compiled_brake_distances(speeds, accel, jerk, dt, steps)
    v, a, x = speeds.copy(), np.zeros_like(speeds), np.zeros_like(speeds)
    zero = np.zeros_like(speeds)
    for _ in range(steps):
        if not (v > 0.0).any():
            break
        a = np.where(v > 0.0, shape_vel_accel(zero, zero, v, a, accel, jerk, dt), 0.0)
        v = np.maximum(v + a * dt, 0.0)
        x += v * dt
    return speeds, x


def failsafe_speed_caps(
    pos: np.ndarray,
    vel: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    reaction_s: float,
    brake_accel: float,
    clearance: float,
    brake_jerk: float = 5.0,
) -> np.ndarray:
    """(N,) m/s horizontal speed caps (module docstring); inf where the course is clear. `reaction_s` T s
    (FS_GCS_TIMEOUT), `brake_accel` m/s^2 and `brake_jerk` m/s^3 the BRAKE shaping's limits, `clearance` m."""
    d = distance_along_course(pos, vel, centres, radii, clearance)
    speeds, distances = _brake_table(float(brake_accel), float(brake_jerk))
    total = speeds * reaction_s + distances  # increasing in the speed: invert it by interpolation
    cap = np.interp(np.where(np.isfinite(d), d, 0.0), total, speeds)
    return np.where(np.isfinite(d), cap, np.inf)
