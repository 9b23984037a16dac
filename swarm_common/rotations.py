"""Angles and quaternions, vectorised: leading dimensions broadcast, the last axis holds the components (3 for
ZYX Euler angles `(roll, pitch, yaw)` rad, 4 for quaternions `(w, x, y, z)`). Frame-agnostic: the caller says
which frames a quaternion maps between (gcs_swarm.link.frames, sitl_sim's attitude controller)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from swarm_common.jit import kernel_with

FloatArray = NDArray[np.float64]


def wrap_pi(angle: ArrayLike) -> FloatArray:
    """Angle(s) in rad wrapped to [-pi, pi)."""
    return np.asarray((np.asarray(angle, dtype=float) + math.pi) % (2.0 * math.pi) - math.pi, dtype=float)


@kernel_with("float64(float64)")  # compiled (or loaded) at import; callable from Python and kernels
def wrap_pi_float(angle: float) -> float:
    """`wrap_pi` of one angle in plain floats (the same bits: Python's float %, which numba compiles with the
    same rule, is numpy's remainder)."""
    return (float(angle) + math.pi) % (2.0 * math.pi) - math.pi


@kernel_with("float64(float64)")  # compiled (or loaded) at import: Python callers never wait for the JIT
def yaw_ned_enu(yaw: float) -> float:
    """A yaw (heading) in rad between the two world frames, either way: NED (clockwise from North) <-> ENU
    (counter-clockwise from East), wrap_pi(pi/2 - yaw) in [-pi, pi); the map is its own inverse (spec 1.1).
    The one spelling of this conversion: compiled, and callable from Python and from other kernels."""
    return ((0.5 * math.pi - yaw) + math.pi) % (2.0 * math.pi) - math.pi


def euler_to_quaternion(euler: ArrayLike) -> FloatArray:
    """ZYX Euler `(roll, pitch, yaw)` (..., 3) rad -> quaternion `(w, x, y, z)` (..., 4); R = Rz Ry Rx."""
    a = np.asarray(euler, dtype=float) * 0.5
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ),
        axis=-1,
    )


def quaternion_to_euler(q: ArrayLike) -> FloatArray:
    """Quaternion `(w, x, y, z)` (..., 4), any norm > 0 -> ZYX Euler `(roll, pitch, yaw)` rad (..., 3)."""
    a = np.asarray(q, dtype=float)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    w, x, y, z = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack((roll, pitch, yaw), axis=-1)


def quaternion_multiply(p: ArrayLike, q: ArrayLike) -> FloatArray:
    """Hamilton product `p * q` of quaternions `(w, x, y, z)`, shapes broadcast over (..., 4)."""
    a, b = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
    w1, x1, y1, z1 = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    w2, x2, y2, z2 = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    return np.stack(
        (
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ),
        axis=-1,
    )
