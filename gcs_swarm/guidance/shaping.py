"""Jerk-limited shaping of a velocity demand into a smooth acceleration, one vehicle at a time.

A port of ArduPilot's command shaping (libraries/AP_Math/control.cpp: `shape_vel_accel`,
`shape_vel_accel_xy` with limit_total_accel, then `shape_accel` / `shape_accel_xy`), the field's proven way
to turn a jumping velocity demand into an acceleration that changes at most `jerk_max` m/s^3 and never
overshoots: the correction acceleration is linear in the velocity error near the target and follows the
square-root braking curve sqrt(2 J |error|) farther out (swarm_common.shaping.sqrt_controller), so it can
always be ramped back to zero in time.

Scalars in and out (m/s, m/s^2, m/s^3, s); compiled (swarm_common.jit), called from the reference
generator's kernel (gcs_swarm.guidance.reference) and the BRAKE stopping table (failsafe_speed).
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip, clip_to_scalars, maximum
from swarm_common.shaping import sqrt_controller

CORNER_ACCELERATION_RATIO = 1.0 / math.sqrt(2.0)  # control.cpp: lateral share kept for cross-track correction


@kernel
def _limit_scale(x: float, y: float, limit: float) -> float:
    """The factor that shortens (x, y) to at most `limit`: limit / |(x, y)| when longer, else 1."""
    length = np.hypot(x, y)
    return limit / length if length > limit else 1.0


@kernel
def shape_vel_accel_xy(
    vx: float, vy: float, ax_in: float, ay_in: float, vel_x: float, vel_y: float,
    acc_x: float, acc_y: float, accel_max: float, jerk_max: float, dt: float,
) -> tuple[float, float]:  # fmt: skip
    """Next horizontal acceleration (x, y) that drives the velocity (vel_x, vel_y) toward the demand
    (vx, vy) with the feed-forward (ax_in, ay_in), the correction within `accel_max` and the change from
    (acc_x, acc_y) within `jerk_max * dt`. When the demand has a direction, up to 1/sqrt(2) of `accel_max`
    is reserved for the cross-track part, so that a turn is not starved by the along-track acceleration
    (ArduPilot's corner rule)."""
    kpa = jerk_max / accel_max
    ex = vx - vel_x
    ey = vy - vel_y
    length = np.hypot(ex, ey)  # control.cpp sqrt_controller of a vector: along the error
    rate = sqrt_controller(length, kpa, jerk_max, dt)
    scale = rate / length if length > 0.0 else 0.0
    tx = ex * scale
    ty = ey * scale
    speed_in = np.hypot(vx, vy)
    ux = vx / speed_in if speed_in > 0.0 else 0.0
    uy = vy / speed_in if speed_in > 0.0 else 0.0
    along = 0.0 + ux * tx + uy * ty
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
        along_max = math.sqrt(maximum(accel_max * accel_max - (0.0 + cx * cx + cy * cy), 0.0))
        along = clip(along, -along_max, along_max)
        tx = cx + ux * along
        ty = cy + uy * along
    tx = tx + ax_in
    ty = ty + ay_in
    s = _limit_scale(tx, ty, accel_max)
    dx = tx * s - acc_x
    dy = ty * s - acc_y
    s = _limit_scale(dx, dy, jerk_max * dt)
    return acc_x + dx * s, acc_y + dy * s


@kernel
def shape_vel_accel(
    v_in: float, a_in: float, vel: float, acc: float, accel_max: float, jerk_max: float, dt: float
) -> float:
    """One axis: the next acceleration toward the velocity demand `v_in` from the state (vel, acc), with the
    feed-forward `a_in`, the total within +-accel_max and changing at most `jerk_max * dt` per step."""
    kpa = jerk_max / accel_max
    target = clip_to_scalars(sqrt_controller(v_in - vel, kpa, jerk_max, dt), -accel_max, accel_max)
    target = clip_to_scalars(target + a_in, -accel_max, accel_max)
    jerk_step = jerk_max * dt
    return acc + clip(target - acc, -jerk_step, jerk_step)
