"""Compiled twins of what the link computes for the whole fleet on every telemetry tick, one scalar loop over
the N vehicles instead of a dozen or more small numpy calls each:

- the two frame conversions (gcs_swarm.link.frames): positions geodetic -> ENU when telemetry arrives,
  attitude targets Euler FLU/ENU -> quaternion NED/FRD when commands leave. For 6 vehicles 25 -> 2 us and
  23 -> 1 us (timeit);
- the test whether a complete telemetry frame is in (lockstep.take_new_frame), 12 -> 0.6 us, made two or
  three times per tick;
- the send step of a formation tick (gcs_swarm.link.attitude_commands): thrust for ArduCopter from the
  guidance's collective acceleration, then the final command guard, 45 -> 10 us (timeit, 6 vehicles).

What that does to a flight's tick: BENCHMARKS.md, 2026-11-27 (20:00 UTC).

Same results as the numpy functions (frames.geodetic_to_enu, which is pymap3d.geodetic2enu's arithmetic,
frames.attitude_target_quaternion, lockstep.take_new_frame, attitude_commands.attitude_commands_numpy), bit
for bit: every operation is the numpy code's IEEE operation in the same order, and the sines, cosines and
hypot are the C library's, which numpy's float64 ufuncs also call (tests/gcs_swarm/link/test_frames.py,
test_fleet_lockstep.py and test_attitude_commands.py compare them). Not numpy's arccos, which on AVX-512
machines is its own and differs from the C library's acos in the last bit for about one value in ten: the
send step's tilt comes from numpy.
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
_FLOAT_MAX = float(np.finfo(np.float64).max)  # numpy.nan_to_num's value for +inf


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


@_kernel
def _clip(x: float, low: float, high: float) -> float:
    """numpy.clip of one float64 between scalar bounds, numpy's vector loop (x NaN: x; a NaN bound: NaN;
    x equal to a bound, as -0.0 to 0.0: x)."""
    if x != x:
        return x
    if low != low:
        return low
    if high != high:
        return high
    if x < low:
        return low
    if x > high:
        return high
    return x


@_kernel
def _clip_to_array_bound(x: float, low: float, high: float) -> float:
    """numpy.clip of one float64 whose upper bound is an array's element, numpy's generic loop, which
    differs from the vector loop only in signed zeros: x equal to a bound gives the bound."""
    if x != x:
        return x
    m = x if x > low else low
    if m != m:
        return m
    return m if m < high else high


@_kernel
def _minimum(a: float, b: float) -> float:
    """numpy.minimum of two float64: a NaN wins; of equal values (signed zeros) the second."""
    return a if (a < b or a != a) else b


@_kernel
def _maximum(a: float, b: float) -> float:
    """numpy.maximum of two float64: a NaN wins; of equal values (signed zeros) the second."""
    return a if (a > b or a != a) else b


@_kernel
def _nan_to_num(x: float) -> float:
    """numpy.nan_to_num of one float64: NaN -> 0, +-inf -> the largest finite float of its sign."""
    if x != x:
        return 0.0
    if x == math.inf:
        return _FLOAT_MAX
    if x == -math.inf:
        return -_FLOAT_MAX
    return x


@_kernel
def attitude_commands(
    roll: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    thrust_acc: np.ndarray,
    commanded_tilt: np.ndarray,
    att: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    hover: np.ndarray,
    boost: np.ndarray,
    g: float,
    limits: tuple[float, float, float, float, float],
    tilt_slack: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """attitude_commands.attitude_commands_numpy in one loop over the N vehicles: (roll, pitch, yaw, thrust,
    changed), each (N,). `commanded_tilt` (N,) rad: numpy's arccos(clip(cos roll cos
    pitch, -1, 1)) of the commands (see the module doc); `limits`: tilt_max, thrust_max_g, min_altitude,
    geofence_radius, geofence_max_alt (command_limits.CommandLimits)."""
    tilt_max, thrust_max_g, min_altitude, geofence_radius, geofence_max_alt = limits
    n = roll.shape[0]
    r_out, p_out, y_out, t_out = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    changed = np.empty(n, dtype=np.bool_)
    for i in range(n):
        # autopilots.ardupilot.unboosted_thrust, numpy.nan_to_num, autopilots.ardupilot.thrust_from_acc
        acc = thrust_acc[i]
        if boost[i]:
            cos_tilt = _clip(math.cos(att[i, 0]) * math.cos(att[i, 1]), 0.1, 1.0)
            if not math.isfinite(cos_tilt):
                cos_tilt = 1.0
            acc = acc * cos_tilt
        t_in = _clip(hover[i] * _nan_to_num(acc) / g, 0.0, 1.0)
        # command_limits.guard_attitude_commands
        r, p, y, t = roll[i], pitch[i], yaw[i], t_in
        bad = not (math.isfinite(r) and math.isfinite(p) and math.isfinite(y) and math.isfinite(t))
        if bad:
            r, p, t = 0.0, 0.0, hover[i]
            y = _nan_to_num(att[i, 2])
        steep = not bad and commanded_tilt[i] > tilt_max + tilt_slack  # a bad row is level: tilt 0
        if steep:
            scale = tilt_max / _maximum(math.hypot(r, p), 1e-12)
            r, p = r * scale, p * scale
        x_e, y_n, z_u = pos[i, 0], pos[i, 1], pos[i, 2]
        outward = False
        if math.hypot(x_e, y_n) >= geofence_radius:
            h1, h2 = math.sin(p) * math.cos(r), -math.sin(r)
            a_e = math.cos(y) * h1 - math.sin(y) * h2
            a_n = math.sin(y) * h1 + math.cos(y) * h2
            if a_e * x_e + a_n * y_n > 0:
                v_e, v_n = vel[i, 0], vel[i, 1]
                opposes = a_e * v_e + a_n * v_n < 0
                a_out, v_out = a_e * x_e + a_n * y_n, v_e * x_e + v_n * y_n
                not_steeper = a_out * math.hypot(v_e, v_n) <= -v_out * math.hypot(a_e, a_n)
                outward = not (opposes and not_steeper)
        if outward:
            r, p = 0.0, 0.0
        if z_u >= geofence_max_alt:
            t = _minimum(t, hover[i])
        if z_u <= min_altitude:
            t = _maximum(t, hover[i])
        t = _clip_to_array_bound(t, 0.0, _minimum(1.0, hover[i] * thrust_max_g))
        r_out[i], p_out[i], y_out[i], t_out[i] = r, p, y, t
        changed[i] = bad or steep or outward or t != t_in
    return r_out, p_out, y_out, t_out, changed


def warm_up() -> None:
    """Call every kernel once with the argument types the link gives it (compiles them, or loads them from
    numba's cache: tens of ms once numba is loaded), so that no tick waits for the JIT."""
    rows = np.zeros((2, 3))
    geodetic_rows_to_enu(rows, 1.0, 1.0, 1.0, 1.0, (0.0,) * 7)
    attitude_target_quaternions(rows)
    times = np.zeros(2, dtype=np.int64)
    take_new_frame(np.ones(2, dtype=np.bool_), times, times, times.copy())
    row = np.zeros(2)
    attitude_commands(
        row, row, row, row, row, rows, rows, rows, row, np.ones(2, dtype=np.bool_), 9.8, (1.0,) * 5, 0.0
    )
