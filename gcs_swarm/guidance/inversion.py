"""From thrust acceleration U = (U_x, U_y, U_z) and yaw to roll, pitch and collective thrust (spec 5,
paper Eqs 22-25, 36), with the command limits in the spec's order.

Angles in rad, ENU world / FLU body, ZYX Euler (spec 1.1); thrust as U1/m in m/s^2 (mass-free; the link
scales it to the vehicle's normalised thrust). Shapes: U (N, 3), angles (N,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gcs_swarm.guidance.params import G, Limits
from gcs_swarm.guidance.vector_ops import row_norms

THRUST_MODES = ("measured", "norm")


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


def limit_thrust_vector(u: np.ndarray, limits: Limits, g: float = G) -> np.ndarray:
    """Spec 5 limits 1-2: U_z >= uz_min_g g, then shorten U_xy to U_z tan(tilt_max) keeping its direction."""
    out = np.array(u, dtype=float)
    out[:, 2] = np.maximum(out[:, 2], limits.uz_min_g * g)
    u_xy = np.hypot(out[:, 0], out[:, 1])
    cap = out[:, 2] * np.tan(limits.tilt_max)
    over = u_xy > cap
    out[over, :2] *= (cap[over] / u_xy[over])[:, None]
    return out


def invert(
    u: np.ndarray,
    yaw: np.ndarray,
    limits: Limits,
    g: float = G,
    measured_roll: np.ndarray | None = None,
    measured_pitch: np.ndarray | None = None,
) -> AttitudeThrust:
    """Limited U -> (roll_d, pitch_d, U1/m) for the measured yaw (spec 5, Eqs 23-25).

    Thrust: with measured roll/pitch given, Eq 36 `U_z / (cos phi cos theta)` (the cosine product floored at
    cos(tilt_max)), else `|U|`; then capped at thrust_max_g * g (limit 3).
    """
    ul = limit_thrust_vector(u, limits, g)
    cy, sy = np.cos(yaw), np.sin(yaw)
    norm = row_norms(ul)
    pitch = np.arctan2(ul[:, 0] * cy + ul[:, 1] * sy, ul[:, 2])
    roll = np.arcsin(np.clip((ul[:, 0] * sy - ul[:, 1] * cy) / norm, -1.0, 1.0))
    if measured_roll is None or measured_pitch is None:
        thrust = norm
    else:
        tilt_cos = np.maximum(np.cos(measured_roll) * np.cos(measured_pitch), np.cos(limits.tilt_max))
        thrust = ul[:, 2] / tilt_cos
    thrust = np.minimum(thrust, limits.thrust_max_g * g)
    return AttitudeThrust(roll=roll, pitch=pitch, thrust_acc=thrust, u_limited=ul)
