"""From thrust acceleration U = (U_x, U_y, U_z) and yaw to roll, pitch and collective thrust (spec 5,
paper Eqs 22-25, 36), with the command limits in the spec's order; compiled (swarm_common.jit) up to the
inverse trigonometry, which `invert` evaluates with numpy.

Angles in rad, ENU world / FLU body, ZYX Euler (spec 1.1); thrust as U1/m in m/s^2 (mass-free; the link
scales it to the vehicle's normalised thrust). Shapes: U (N, 3), angles (N,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_swarm.guidance.params import G, Limits
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip_to_scalars, maximum, minimum, norm3

THRUST_MODES = ("measured", "norm")
NO_VALUES = np.zeros(0)


@dataclass(frozen=True)
class AttitudeThrust:
    """Roll, pitch (N,) rad, thrust_acc = U1/m (N,) m/s^2, and the limited U (N, 3) they realise."""

    roll: np.ndarray
    pitch: np.ndarray
    thrust_acc: np.ndarray
    u_limited: np.ndarray


def thrust_vector(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray, thrust_acc: np.ndarray) -> np.ndarray:
    """U = (U1/m) R e3, (N, 3) (spec 5, Eqs 21-22 with the corrected y row)."""
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    axis = np.stack([cr * sp * cy + sr * sy, cr * sp * sy - sr * cy, cr * cp], axis=-1)
    return thrust_acc[..., None] * axis


@kernel
def limited_thrust(
    u0: float, u1: float, u2: float, uz_floor: float, tan_tilt: float
) -> tuple[float, float, float]:
    """Spec 5 limits 1-2 on one U (m/s^2): U_z >= uz_floor, then U_xy shortened to U_z tan(tilt_max) keeping
    its direction."""
    z = maximum(u2, uz_floor)
    u_xy = np.hypot(u0, u1)
    cap = z * tan_tilt
    if u_xy > cap:
        scale = cap / u_xy
        return u0 * scale, u1 * scale, z
    return u0, u1, z


@kernel
def inversion_terms(
    u: np.ndarray, cos_yaw: np.ndarray, sin_yaw: np.ndarray, uz_floor: float, tan_tilt: float,
    tilt_cos: np.ndarray, cos_tilt_max: float, thrust_cap: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """`invert` up to its inverse trigonometry: the limited U (N, 3), the arctan2 numerator
    U_x cos psi + U_y sin psi (N,) (its denominator is U_z), the arcsin argument
    (U_x sin psi - U_y cos psi) / |U| clipped to [-1, 1] (N,), and the thrust U1/m (N,): Eq 36
    U_z / max(tilt_cos, cos_tilt_max) from tilt_cos = cos phi cos theta of the measured attitude (N,), or |U|
    when tilt_cos is empty; at most thrust_cap (limit 3)."""
    n = u.shape[0]
    ul = np.empty((n, 3))
    pitch_num = np.empty(n)
    roll_arg = np.empty(n)
    thrust = np.empty(n)
    for i in range(n):
        l0, l1, l2 = limited_thrust(u[i, 0], u[i, 1], u[i, 2], uz_floor, tan_tilt)
        ul[i, 0], ul[i, 1], ul[i, 2] = l0, l1, l2
        norm = norm3(l0, l1, l2)
        pitch_num[i] = l0 * cos_yaw[i] + l1 * sin_yaw[i]
        roll_arg[i] = clip_to_scalars((l0 * sin_yaw[i] - l1 * cos_yaw[i]) / norm, -1.0, 1.0)
        t = l2 / maximum(tilt_cos[i], cos_tilt_max) if tilt_cos.shape[0] else norm
        thrust[i] = minimum(t, thrust_cap)
    return ul, pitch_num, roll_arg, thrust


def invert(
    u: np.ndarray,
    yaw: np.ndarray,
    limits: Limits,
    g: float = G,
    measured_roll: np.ndarray | None = None,
    measured_pitch: np.ndarray | None = None,
) -> AttitudeThrust:
    """Limited U (N, 3) -> (roll_d, pitch_d, U1/m) for the measured yaw (N,) (spec 5, Eqs 23-25).

    Thrust: with measured roll/pitch (N,) given, Eq 36 `U_z / (cos phi cos theta)` (the cosine product
    floored at cos(tilt_max)), else `|U|`; then capped at thrust_max_g * g (limit 3).
    """
    if measured_roll is None or measured_pitch is None:
        tilt_cos = NO_VALUES
    else:
        tilt_cos = np.cos(measured_roll) * np.cos(measured_pitch)
    ul, pitch_num, roll_arg, thrust = inversion_terms(
        np.ascontiguousarray(u), np.cos(yaw), np.sin(yaw), float(limits.uz_min_g * g),
        float(np.tan(limits.tilt_max)), tilt_cos, float(np.cos(limits.tilt_max)),
        float(limits.thrust_max_g * g),
    )  # fmt: skip
    pitch = np.arctan2(pitch_num, ul[:, 2])
    roll = np.arcsin(roll_arg)
    return AttitudeThrust(roll=roll, pitch=pitch, thrust_acc=thrust, u_limited=ul)
