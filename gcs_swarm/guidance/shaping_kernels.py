"""Compiled twin of the reference generator's jerk-limited step 4: the numpy `shape_vel_accel_xy` (columns
x, y) and `shape_vel_accel` (column z) of gcs_swarm.guidance.shaping, as ReferenceGenerator._acceleration
calls them, transcribed to one scalar loop over vehicles; and of the BRAKE stopping-distance table that
gcs_swarm.guidance.failsafe_speed integrates with the same shaping (`brake_distances`).

A small fleet pays numpy's per-call overhead about 150 times per tick in this stage; the loop pays one call.
Every operation is the numpy code's IEEE operation in the same order, and the helpers below reproduce
numpy's rules for NaN and signed zeros (np.maximum, np.clip, np.sign), so the results are the same bits
(but for the sign of a NaN where two NaNs meet: which one x86 returns depends on the operand order the
compiler picks): tests/gcs_swarm/guidance/test_shaping_kernels.py and test_failsafe_speed.py pin them equal,
so change both together.
No fastmath (it would reorder and contract operations); error_model "numpy" makes x / 0 inf or NaN, as in
numpy. Compiled at import for the signatures below (cache=True: later imports load it from numba's cache),
so no tick waits for the JIT. Importing this module requires numba (extra "fast"); reference.py falls back
to the numpy functions without it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_swarm.guidance.shaping import CORNER_ACCELERATION_RATIO, sqrt_controller_scalar

_scalar = njit(cache=True, error_model="numpy", inline="always")  # helpers, inlined into the kernel


@_scalar
def _maximum(a: float, b: float) -> float:
    """np.maximum of two floats: NaN if either is, else the larger; b when they compare equal (+-0)."""
    return a if (a > b or a != a) else b


@_scalar
def _clip(x: float, lo: float, hi: float) -> float:
    """np.clip of a float between bounds given per row (arrays): NaN if any argument is (x's, else lo's,
    else hi's); hi when they compare equal (+-0)."""
    if x != x:
        return x
    if lo != lo:
        return lo
    bounded_below = x if x > lo else lo
    return bounded_below if bounded_below < hi else hi


@_scalar
def _clip_to_scalars(x: float, lo: float, hi: float) -> float:
    """np.clip of a float between bounds that are scalars (numpy's constant-bound loop): NaN if any argument
    is (lo's, else hi's, else x's); x itself when it compares equal to a bound (+-0)."""
    if lo != lo:
        return lo
    if hi != hi:
        return hi
    if x != x:
        return x
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


@_scalar
def _sign(x: float) -> float:
    """np.sign of a float: -1, 0 or 1, NaN for NaN."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return x


_sqrt_controller = _scalar(sqrt_controller_scalar)  # shaping.sqrt_controller for one error


@_scalar
def _limit_scale(x: float, y: float, limit: float) -> float:
    """shaping.limit_length's factor for (x, y): limit / |(x, y)| when longer than limit, else 1."""
    length = math.hypot(x, y)
    return limit / length if length > limit else 1.0


@_scalar
def _shape_vel_accel_xy(
    vx: float, vy: float, ax_in: float, ay_in: float, vel_x: float, vel_y: float,
    acc_x: float, acc_y: float, accel_max: float, jerk_max: float, dt: float,
) -> tuple[float, float]:  # fmt: skip
    """shaping.shape_vel_accel_xy for one vehicle: demand (vx, vy), feed-forward (ax_in, ay_in), state
    (vel_x, vel_y), (acc_x, acc_y); returns the next acceleration (x, y)."""
    kpa = jerk_max / accel_max
    ex = vx - vel_x
    ey = vy - vel_y
    length = math.hypot(ex, ey)  # sqrt_controller_xy
    rate = _sqrt_controller(length, kpa, jerk_max, dt)
    scale = rate / length if length > 0.0 else 0.0
    tx = ex * scale
    ty = ey * scale
    speed_in = math.hypot(vx, vy)
    ux = vx / speed_in if speed_in > 0.0 else 0.0
    uy = vy / speed_in if speed_in > 0.0 else 0.0
    along = 0.0 + ux * tx + uy * ty  # np.einsum's sum starts at 0 (so -0 becomes +0)
    cx = tx - ux * along
    cy = ty - uy * along
    cross_sq = 0.0 + cx * cx + cy * cy
    if speed_in == 0.0 or along * along <= cross_sq:
        s = _limit_scale(tx, ty, accel_max)
        tx = tx * s
        ty = ty * s
    else:
        s = _limit_scale(cx, cy, CORNER_ACCELERATION_RATIO * accel_max)
        cx = cx * s
        cy = cy * s
        along_max = math.sqrt(_maximum(accel_max * accel_max - (0.0 + cx * cx + cy * cy), 0.0))
        along = _clip(along, -along_max, along_max)
        tx = cx + ux * along
        ty = cy + uy * along
    tx = tx + ax_in
    ty = ty + ay_in
    s = _limit_scale(tx, ty, accel_max)
    dx = tx * s - acc_x
    dy = ty * s - acc_y
    s = _limit_scale(dx, dy, jerk_max * dt)
    return acc_x + dx * s, acc_y + dy * s


@_scalar
def _shape_vel_accel(
    v_in: float, a_in: float, vel: float, acc: float, accel_max: float, jerk_max: float, dt: float
) -> float:
    """shaping.shape_vel_accel for one vehicle, with accel_max a scalar and jerk_max an (N,) array in the
    numpy call (the two select different np.clip loops)."""
    kpa = jerk_max / accel_max
    target = _clip_to_scalars(_sqrt_controller(v_in - vel, kpa, jerk_max, dt), -accel_max, accel_max)
    target = _clip_to_scalars(target + a_in, -accel_max, accel_max)
    jerk_step = jerk_max * dt
    return acc + _clip(target - acc, -jerk_step, jerk_step)


@njit(
    "float64[:, ::1](float64[:, :], float64[:, :], float64[:, :], float64[:, :],"
    " float64[::1], float64[::1], float64, float64[::1], float64)",
    cache=True,
    error_model="numpy",
)
def shape_reference_acceleration(
    v_cmd: np.ndarray,
    a_ff: np.ndarray,
    vel: np.ndarray,
    accel: np.ndarray,
    accel_xy: np.ndarray,
    jerk_xy: np.ndarray,
    accel_z: float,
    jerk_z: np.ndarray,
    dt: float,
) -> np.ndarray:
    """Next reference acceleration (N, 3) m/s^2 toward the velocity demand v_cmd (N, 3) m/s from the state
    vel, accel (N, 3), with the feed-forward a_ff (N, 3): horizontally shape_vel_accel_xy with the limits
    accel_xy, jerk_xy (N,), vertically shape_vel_accel with accel_z (scalar) and jerk_z (N,); dt s.
    The compiled twin of those two numpy calls in ReferenceGenerator._acceleration."""
    n = v_cmd.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        out[i, 0], out[i, 1] = _shape_vel_accel_xy(
            v_cmd[i, 0], v_cmd[i, 1], a_ff[i, 0], a_ff[i, 1], vel[i, 0], vel[i, 1],
            accel[i, 0], accel[i, 1], accel_xy[i], jerk_xy[i], dt,
        )  # fmt: skip
        out[i, 2] = _shape_vel_accel(v_cmd[i, 2], a_ff[i, 2], vel[i, 2], accel[i, 2], accel_z, jerk_z[i], dt)
    return out


@njit("float64[::1](float64[::1], float64, float64, float64, int64)", cache=True, error_model="numpy")
def brake_distances(speeds: np.ndarray, accel: float, jerk: float, dt: float, steps: int) -> np.ndarray:
    """(S,) m: the distance each start speed of `speeds` (S,) m/s covers until the BRAKE shaping (accel
    m/s^2, jerk m/s^3) brings it to rest, integrated at dt s for at most `steps` steps. The compiled twin of
    the numpy loop in failsafe_speed._brake_table, which calls shaping.shape_vel_accel with scalar limits
    (so every clip here is numpy's constant-bound loop) and stops a speed once it reaches zero."""
    out = np.empty(speeds.shape[0])
    kpa = jerk / accel
    jerk_step = jerk * dt
    for i in range(speeds.shape[0]):
        v = speeds[i]
        a = 0.0
        x = 0.0
        for _ in range(steps):
            if not v > 0.0:  # at rest: the numpy loop's a = 0, v = 0 from here on add nothing to x
                break
            target = _clip_to_scalars(_sqrt_controller(0.0 - v, kpa, jerk, dt), -accel, accel)
            target = _clip_to_scalars(target + 0.0, -accel, accel)
            a = a + _clip_to_scalars(target - a, -jerk_step, jerk_step)
            v = _maximum(v + a * dt, 0.0)
            if x + v * dt == x:  # a <= target <= 0 throughout: v never grows, so x will not change again
                break
            x += v * dt
        out[i] = x
    return out
