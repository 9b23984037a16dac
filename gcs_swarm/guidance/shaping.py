"""Jerk-limited shaping of a velocity demand into a smooth acceleration, vectorised over vehicles.

A port of ArduPilot's command shaping (libraries/AP_Math/control.cpp: `sqrt_controller`,
`shape_accel`, `shape_accel_xy`, `shape_vel_accel`, `shape_vel_accel_xy`), the field's proven way to turn a
jumping velocity demand into an acceleration that changes at most `jerk_max` m/s^3 and never overshoots:
the correction acceleration is linear in the velocity error near the target and follows the square-root
braking curve sqrt(2 J |error|) farther out, so it can always be ramped back to zero in time.

Shapes: horizontal vectors (N, 2), vertical scalars (N,); SI units (m/s, m/s^2, m/s^3, s).
"""

from __future__ import annotations

import math

import numpy as np

CORNER_ACCELERATION_RATIO = 1.0 / math.sqrt(2.0)  # control.cpp: lateral share kept for cross-track correction


def sqrt_controller(
    error: np.ndarray, p: np.ndarray | float, second_order_limit: np.ndarray | float, dt: float
) -> np.ndarray:
    """Correction rate (N,) for errors (N,): `p * error` near zero, `sqrt(2 L (|e| - L / (2 p^2)))` beyond
    `L / p^2` (L = second_order_limit), never more than |error| / dt (control.cpp `sqrt_controller`).
    `p` and `L` are scalars or (N,) arrays; L <= 0 means no second-order limit (linear)."""
    error = np.asarray(error, dtype=float)
    p = np.asarray(p, dtype=float)
    limit = np.asarray(second_order_limit, dtype=float)
    size = np.abs(error)
    linear = error * p
    two_limit = 2.0 * np.maximum(limit, 0.0)  # 2 L, no second-order limit below 0
    p_sq = p * p
    linear_dist = np.divide(limit, p_sq, out=np.full(size.shape, np.inf), where=p_sq > 0.0)
    beyond = np.maximum(size - 0.5 * linear_dist, 0.0)
    direction = np.sign(error)
    rate = np.where(size > linear_dist, direction * np.sqrt(two_limit * beyond), linear)
    no_gain = p == 0.0
    if no_gain.any():
        rate = np.where(no_gain, direction * np.sqrt(two_limit * size), rate)
    no_limit = limit <= 0.0
    if no_limit.any():
        rate = np.where(no_limit, linear, rate)
    if dt > 0.0:
        bound = size / dt
        rate = np.clip(rate, -bound, bound)
    return rate


def sqrt_controller_scalar(error: float, p: float, second_order_limit: float, dt: float) -> float:
    """`sqrt_controller` of one error, in plain float operations: the same bits, numpy's rules for NaN and
    signed zeros included (np.maximum, np.sign, np.clip); tests/gcs_swarm/guidance/test_smoothing.py. For
    the per-tick scalars (the leader's heading), where numpy's per-call cost is most of the work, and
    compiled as it is into shaping_kernels (so it calls nothing but math)."""
    size = abs(error)
    linear = error * p
    limit = second_order_limit
    two_limit = 2.0 * (limit if (limit > 0.0 or limit != limit) else 0.0)  # np.maximum(limit, 0)
    p_sq = p * p
    linear_dist = limit / p_sq if p_sq > 0.0 else math.inf
    direction = 1.0 if error > 0.0 else (-1.0 if error < 0.0 else (0.0 if error == 0.0 else error))  # np.sign
    if limit <= 0.0:
        rate = linear
    elif p == 0.0:
        rate = direction * math.sqrt(two_limit * size)
    elif size > linear_dist:
        beyond = size - 0.5 * linear_dist
        rate = direction * math.sqrt(two_limit * (beyond if (beyond > 0.0 or beyond != beyond) else 0.0))
    else:
        rate = linear
    if (
        dt > 0.0 and rate == rate
    ):  # np.clip(rate, -bound, bound): NaN wins, then max with -bound, min with bound
        bound = size / dt
        rate = rate if rate > -bound else -bound
        rate = rate if rate < bound else bound
    return rate


def sqrt_controller_xy(
    error: np.ndarray, p: np.ndarray | float, second_order_limit: np.ndarray | float, dt: float
) -> np.ndarray:
    """Vector form (N, 2): `sqrt_controller` of |error| along the error's direction (control.cpp)."""
    length = np.hypot(error[:, 0], error[:, 1])
    rate = sqrt_controller(length, p, second_order_limit, dt)
    scale = np.divide(rate, length, out=np.zeros_like(length), where=length > 0.0)
    return error * scale[:, None]


def limit_length(vec: np.ndarray, limit: np.ndarray | float) -> np.ndarray:
    """Vectors (N, 2) shortened to at most `limit` (N,) or scalar, keeping their direction."""
    length = np.hypot(vec[:, 0], vec[:, 1])
    scale = np.divide(limit, length, out=np.ones_like(length), where=length > limit)
    return vec * scale[:, None]


def shape_vel_accel_xy(
    vel_input: np.ndarray,
    accel_input: np.ndarray,
    vel: np.ndarray,
    accel: np.ndarray,
    accel_max: np.ndarray | float,
    jerk_max: np.ndarray | float,
    dt: float,
) -> np.ndarray:
    """Next horizontal acceleration (N, 2) that drives `vel` (N, 2) toward `vel_input` (N, 2) with the
    feed-forward `accel_input` (N, 2), the correction within `accel_max` and the change from `accel` within
    `jerk_max * dt` (control.cpp `shape_vel_accel_xy` with limit_total_accel, then `shape_accel_xy`).

    When the demand has a direction, up to 1/sqrt(2) of `accel_max` is reserved for the cross-track part,
    so that a turn is not starved by the along-track acceleration (ArduPilot's corner rule). Limits are
    scalars or (N,) arrays (per vehicle)."""
    accel_max = np.asarray(accel_max, dtype=float)
    jerk_max = np.asarray(jerk_max, dtype=float)
    kpa = jerk_max / accel_max
    target = sqrt_controller_xy(vel_input - vel, kpa, jerk_max, dt)
    speed_in = np.hypot(vel_input[:, 0], vel_input[:, 1])
    unit = np.divide(vel_input, speed_in[:, None], out=np.zeros_like(vel_input), where=speed_in[:, None] > 0)
    along = np.einsum("nd,nd->n", unit, target)
    cross = target - unit * along[:, None]
    cross_sq = np.einsum("nd,nd->n", cross, cross)
    simple = (speed_in == 0.0) | (along * along <= cross_sq)
    cross = limit_length(cross, CORNER_ACCELERATION_RATIO * accel_max)
    along_max = np.sqrt(np.maximum(accel_max * accel_max - np.einsum("nd,nd->n", cross, cross), 0.0))
    cornered = cross + unit * np.clip(along, -along_max, along_max)[:, None]
    target = np.where(simple[:, None], limit_length(target, accel_max), cornered)
    target = limit_length(target + accel_input, accel_max)
    return accel + limit_length(target - accel, jerk_max * dt)


def shape_vel_accel(
    vel_input: np.ndarray,
    accel_input: np.ndarray,
    vel: np.ndarray,
    accel: np.ndarray,
    accel_max: np.ndarray | float,
    jerk_max: np.ndarray | float,
    dt: float,
) -> np.ndarray:
    """One axis (N,): next acceleration toward `vel_input`, total within +-accel_max and changing at most
    `jerk_max * dt` per step (control.cpp `shape_vel_accel` with symmetric limits and limit_total_accel).
    Limits are scalars or (N,) arrays."""
    accel_max = np.asarray(accel_max, dtype=float)
    jerk_max = np.asarray(jerk_max, dtype=float)
    kpa = jerk_max / accel_max
    target = np.clip(sqrt_controller(vel_input - vel, kpa, jerk_max, dt), -accel_max, accel_max)
    target = np.clip(target + accel_input, -accel_max, accel_max)
    jerk_step = jerk_max * dt
    return accel + np.clip(target - accel, -jerk_step, jerk_step)
