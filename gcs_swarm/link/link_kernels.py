"""Compiled twins of what the link computes for the whole fleet on every telemetry tick, one scalar loop over
the N vehicles instead of a dozen or more small numpy calls each:

- the two frame conversions (gcs_swarm.link.frames): positions geodetic -> ENU when telemetry arrives,
  attitude targets Euler FLU/ENU -> quaternion NED/FRD when commands leave. For 6 vehicles 25 -> 2 us and
  23 -> 1 us (timeit);
- the test whether a complete telemetry frame is in (lockstep.take_new_frame), 12 -> 0.6 us, made two or
  three times per tick.

What that does to a flight's tick: BENCHMARKS.md, 2026-11-27 (20:00 UTC).

Same results as the numpy functions (frames.geodetic_to_enu, which is pymap3d.geodetic2enu's arithmetic,
frames.attitude_target_quaternion, lockstep.take_new_frame), bit for bit: every operation is the numpy code's
IEEE operation in the same order, and the sines, cosines and hypot are the C library's, which numpy's float64
ufuncs also call (tests/gcs_swarm/link/test_frames.py and test_fleet_lockstep.py compare them).
No fastmath (it would reorder and contract); error_model "numpy" (no exceptions on x / 0). `warm_up` calls
each once (Fleet.connect), so that no tick waits for numba to compile them or load them from its cache.
Importing requires numba (extra "fast"); frames and lockstep fall back to numpy without it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_kernel = njit(cache=True, error_model="numpy")


_RAD_PER_DEG = math.pi / 180.0  # numpy.radians(x) = x * (pi / 180)


@_kernel
def geodetic_rows_to_enu(
    geodetic: np.ndarray,
    a2: float,
    a: float,
    b: float,
    b_over_a2: float,
    origin_terms: tuple[float, ...],
) -> np.ndarray:
    """(N, 3) lat deg, lon deg, alt m -> (N, 3) ENU m around the origin whose `origin_terms` are (x0, y0, z0
    ECEF m, cos lat0, sin lat0, cos lon0, sin lon0) (frames._enu_origin_terms); the ellipsoid's semimajor
    axis `a` m, its square `a2`, semiminor axis `b` m and (b / a)^2 as pymap3d computes them."""
    x0, y0, z0, cos_lat0, sin_lat0, cos_lon0, sin_lon0 = origin_terms
    n = geodetic.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        lat = geodetic[i, 0] * _RAD_PER_DEG
        lon = geodetic[i, 1] * _RAD_PER_DEG
        alt = geodetic[i, 2]
        cos_lat, sin_lat = math.cos(lat), math.sin(lat)
        # pymap3d.ecef.geodetic2ecef
        prime = a2 / math.hypot(a * cos_lat, b * sin_lat)  # radius of curvature of the prime vertical
        x = (prime + alt) * cos_lat * math.cos(lon)
        y = (prime + alt) * cos_lat * math.sin(lon)
        z = (prime * b_over_a2 + alt) * sin_lat
        # pymap3d.ecef.uvw2enu of the offset from the origin
        u, v, w = x - x0, y - y0, z - z0
        t = cos_lon0 * u + sin_lon0 * v
        out[i, 0] = -sin_lon0 * u + cos_lon0 * v
        out[i, 1] = -sin_lat0 * t + cos_lat0 * w
        out[i, 2] = cos_lat0 * t + sin_lat0 * w
    return out


@_kernel
def attitude_target_quaternions(euler_flu_enu: np.ndarray) -> np.ndarray:
    """(N, 3) roll, pitch, yaw rad (body FLU in world ENU) -> (N, 4) quaternions (w, x, y, z) world NED ->
    body FRD: frames.attitude_enu_to_ned (roll, -pitch, wrap_pi(pi/2 - yaw)), then rotations.
    euler_to_quaternion."""
    n = euler_flu_enu.shape[0]
    out = np.empty((n, 4))
    for i in range(n):
        yaw_ned = ((0.5 * math.pi - euler_flu_enu[i, 2]) + math.pi) % (2.0 * math.pi) - math.pi
        r, p, y = euler_flu_enu[i, 0] * 0.5, -euler_flu_enu[i, 1] * 0.5, yaw_ned * 0.5
        cr, sr = math.cos(r), math.sin(r)
        cp, sp = math.cos(p), math.sin(p)
        cy, sy = math.cos(y), math.sin(y)
        out[i, 0] = cr * cp * cy + sr * sp * sy
        out[i, 1] = sr * cp * cy - cr * sp * sy
        out[i, 2] = cr * sp * cy + sr * cp * sy
        out[i, 3] = cr * cp * sy - sr * sp * cy
    return out


@_kernel
def take_new_frame(
    alive: np.ndarray, position_ms: np.ndarray, frame_ms: np.ndarray, tick_ms: np.ndarray
) -> bool:
    """lockstep.take_new_frame_numpy, compiled: the same answer and the same tick_ms afterwards."""
    n = alive.shape[0]
    last_tick = np.int64(-1)
    any_alive = False
    for i in range(n):
        if alive[i] and (not any_alive or tick_ms[i] > last_tick):
            last_tick = tick_ms[i]
            any_alive = True
    if not any_alive:
        return False
    for i in range(n):
        expected = alive[i] or (frame_ms[i] >= 0 and frame_ms[i] >= last_tick and tick_ms[i] >= last_tick)
        if expected and not max(position_ms[i], frame_ms[i]) > tick_ms[i]:
            return False
    for i in range(n):
        if alive[i] or (frame_ms[i] >= 0 and frame_ms[i] >= last_tick and tick_ms[i] >= last_tick):
            tick_ms[i] = max(position_ms[i], frame_ms[i])
    return True


def warm_up() -> None:
    """Call every kernel once with the argument types the link gives it (compiles them, or loads them from
    numba's cache: tens of ms once numba is loaded), so that no tick waits for the JIT."""
    rows = np.zeros((2, 3))
    geodetic_rows_to_enu(rows, 1.0, 1.0, 1.0, 1.0, (0.0,) * 7)
    attitude_target_quaternions(rows)
    times = np.zeros(2, dtype=np.int64)
    take_new_frame(np.ones(2, dtype=np.bool_), times, times, times.copy())
