"""The last guard before attitude commands reach the vehicles: whatever the guidance computed, what goes out
stays within the vehicles' limits (defence in depth; the guidance already limits tilt and thrust, spec 5).

Rules, per vehicle row, cheap vectorised numpy:
- a non-finite row (roll, pitch, yaw or thrust) becomes level at the vehicle's measured yaw with hover thrust;
- tilt (angle of the body z axis from vertical, acos(cos r cos p)) <= tilt_max: if steeper, roll and pitch
  are scaled down together to hypot(r, p) = tilt_max (spherical Pythagoras: the tilt is then <= tilt_max);
- thrust in [0, min(1, hover * thrust_max_g)] (normalised, GUID_OPTIONS bit 3);
- outside the geofence radius: a tilt that accelerates further out is replaced by level, unless it only
  brakes (given the velocity): the vehicle is moving inward, the tilt opposes its velocity (a . v < 0) and
  points outward no more steeply than straight braking does (a_r / |a| <= -v_r / |v|), so it slows the
  vehicle down without steering it outward; above the fence ceiling thrust <= hover; below the minimum
  altitude thrust >= hover (never accelerate down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
TILT_SLACK = 1e-9  # rad: the guidance's own limit, met to rounding, is left untouched


@dataclass(frozen=True)
class CommandLimits:
    """Vehicle limits in the units of the guard: rad, normalised thrust multiples, metres above the origin."""

    tilt_max: float  # rad
    thrust_max_g: float  # maximum collective thrust / weight
    min_altitude: float  # m (ENU z)
    geofence_radius: float  # m, horizontal, around the origin
    geofence_max_alt: float  # m (ENU z)


def guard_attitude_commands(
    roll: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    thrust: FloatArray,
    pos: FloatArray,
    measured_yaw: FloatArray,
    hover: FloatArray,
    limits: CommandLimits,
    vel: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """(roll, pitch, yaw, thrust, changed): the (N,) commands made safe, and which rows were changed.

    roll, pitch, yaw: (N,) rad body FLU in world ENU; thrust, hover: (N,) normalised; pos: (N,3) ENU m
    (NaN rows skip the position rules); measured_yaw: (N,) rad (fallback heading of a non-finite row);
    vel: (N,3) ENU m/s, lets a vehicle outside the fence brake (None, or a NaN row: no outward tilt at all).
    """
    r, p, y, t = (np.array(a, dtype=float) for a in (roll, pitch, yaw, thrust))
    hover = np.asarray(hover, dtype=float)
    bad = ~(np.isfinite(r) & np.isfinite(p) & np.isfinite(y) & np.isfinite(t))
    if bad.any():
        r[bad], p[bad], t[bad] = 0.0, 0.0, hover[bad]
        y[bad] = np.nan_to_num(np.asarray(measured_yaw, dtype=float)[bad])
    # Each rule below is skipped when no row meets its condition (most ticks): the same result, fewer calls.
    too_steep = np.arccos(np.clip(np.cos(r) * np.cos(p), -1.0, 1.0)) > limits.tilt_max + TILT_SLACK
    if too_steep.any():
        scale = np.where(too_steep, limits.tilt_max / np.maximum(np.hypot(r, p), 1e-12), 1.0)
        r, p = r * scale, p * scale
    x_e, y_n, z_u = (np.asarray(pos, dtype=float)[:, k] for k in range(3))
    with np.errstate(invalid="ignore"):
        outside = np.hypot(x_e, y_n) >= limits.geofence_radius  # NaN rows: False
        outward = outside
        if outside.any():
            # horizontal thrust direction of ZYX (yaw, pitch, roll): Rz(yaw) (sin p cos r, -sin r)
            h1, h2 = np.sin(p) * np.cos(r), -np.sin(r)
            a_e, a_n = np.cos(y) * h1 - np.sin(y) * h2, np.sin(y) * h1 + np.cos(y) * h2
            outward = outside & (a_e * x_e + a_n * y_n > 0)
            if vel is not None:
                outward &= ~_braking(a_e, a_n, x_e, y_n, np.asarray(vel, dtype=float))
            r[outward], p[outward] = 0.0, 0.0
        high, low = z_u >= limits.geofence_max_alt, z_u <= limits.min_altitude
        if high.any():
            t = np.where(high, np.minimum(t, hover), t)
        if low.any():
            t = np.where(low, np.maximum(t, hover), t)
    t = np.clip(t, 0.0, np.minimum(1.0, hover * limits.thrust_max_g))
    changed = bad | too_steep | outward | (t != np.asarray(thrust, dtype=float))
    return r, p, y, t, changed


def _braking(
    a_e: FloatArray, a_n: FloatArray, x_e: FloatArray, y_n: FloatArray, vel: FloatArray
) -> NDArray[np.bool_]:
    """(N,) the horizontal acceleration direction (a_e, a_n) only brakes the horizontal velocity: it opposes
    the velocity and its outward part, relative to its size, is at most that of -v (which needs v inward)."""
    v_e, v_n = vel[:, 0], vel[:, 1]
    opposes = a_e * v_e + a_n * v_n < 0
    # a_r / |a| <= -v_r / |v|, both sides times |a| |v| |x| (|x| > 0 outside the fence)
    a_out, v_out = a_e * x_e + a_n * y_n, v_e * x_e + v_n * y_n
    not_steeper = a_out * np.hypot(v_e, v_n) <= -v_out * np.hypot(a_e, a_n)
    return opposes & not_steeper
