"""The last guard before attitude commands reach the vehicles: whatever the guidance computed, what goes out
stays within the vehicles' limits (defence in depth; the guidance already limits tilt and thrust, spec 5).

Rules, per vehicle row (one compiled loop over the vehicles):
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

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.link.autopilots.thrust import nan_to_num
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip, maximum, minimum

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
    r, p, y, t, h, heading = (
        np.ascontiguousarray(a, dtype=np.float64) for a in (roll, pitch, yaw, thrust, hover, measured_yaw)
    )
    x = np.ascontiguousarray(pos, dtype=np.float64)
    v = np.full_like(x, np.nan) if vel is None else np.ascontiguousarray(vel, dtype=np.float64)
    # numpy's own arccos: on AVX-512 machines it differs from the C library's acos in the last bit for
    # about one value in ten, and numpy's is the one the guard has always used
    with np.errstate(invalid="ignore"):
        tilt = np.arccos(np.clip(np.cos(r) * np.cos(p), -1.0, 1.0))
    bounds = (
        float(limits.tilt_max),
        float(limits.thrust_max_g),
        float(limits.min_altitude),
        float(limits.geofence_radius),
        float(limits.geofence_max_alt),
    )
    return _guard(r, p, y, t, tilt, x, v, heading, h, bounds, TILT_SLACK)  # type: ignore[no-any-return]


@kernel
def _guard(
    roll: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    thrust: np.ndarray,
    commanded_tilt: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    measured_yaw: np.ndarray,
    hover: np.ndarray,
    limits: tuple[float, float, float, float, float],
    tilt_slack: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """guard_attitude_commands, one loop over the N vehicles; commanded_tilt (N,) rad: arccos(cos roll cos
    pitch) of the commands; `limits`: CommandLimits' fields in order."""
    tilt_max, thrust_max_g, min_altitude, geofence_radius, geofence_max_alt = limits
    n = roll.shape[0]
    r_out, p_out, y_out, t_out = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    changed = np.empty(n, dtype=np.bool_)
    for i in range(n):
        r, p, y, t = roll[i], pitch[i], yaw[i], thrust[i]
        bad = not (math.isfinite(r) and math.isfinite(p) and math.isfinite(y) and math.isfinite(t))
        if bad:
            r, p, t = 0.0, 0.0, hover[i]
            y = nan_to_num(measured_yaw[i])
        steep = not bad and commanded_tilt[i] > tilt_max + tilt_slack  # a bad row is level: tilt 0
        if steep:
            scale = tilt_max / maximum(math.hypot(r, p), 1e-12)
            r, p = r * scale, p * scale
        x_e, y_n, z_u = pos[i, 0], pos[i, 1], pos[i, 2]
        outward = False
        if math.hypot(x_e, y_n) >= geofence_radius:
            # horizontal thrust direction of ZYX (yaw, pitch, roll): Rz(yaw) (sin p cos r, -sin r)
            h1, h2 = math.sin(p) * math.cos(r), -math.sin(r)
            a_e = math.cos(y) * h1 - math.sin(y) * h2
            a_n = math.sin(y) * h1 + math.cos(y) * h2
            if a_e * x_e + a_n * y_n > 0:
                # it only brakes: it opposes the velocity and its outward part, relative to its size, is at
                # most that of -v (a_r / |a| <= -v_r / |v|, both sides times |a| |v| |x|)
                v_e, v_n = vel[i, 0], vel[i, 1]
                opposes = a_e * v_e + a_n * v_n < 0
                a_out, v_out = a_e * x_e + a_n * y_n, v_e * x_e + v_n * y_n
                not_steeper = a_out * math.hypot(v_e, v_n) <= -v_out * math.hypot(a_e, a_n)
                outward = not (opposes and not_steeper)
        if outward:
            r, p = 0.0, 0.0
        if z_u >= geofence_max_alt:
            t = minimum(t, hover[i])
        if z_u <= min_altitude:
            t = maximum(t, hover[i])
        t = clip(t, 0.0, minimum(1.0, hover[i] * thrust_max_g))
        r_out[i], p_out[i], y_out[i], t_out[i] = r, p, y, t
        changed[i] = bad or steep or outward or t != thrust[i]
    return r_out, p_out, y_out, t_out, changed
