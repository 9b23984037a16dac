"""ArduCopter-like position/velocity/altitude controllers, vectorised over N vehicles (world ENU, SI units).

Cascade as AC_PosControl: position error -> sqrt controller -> velocity demand (speed limited) -> velocity PI
-> acceleration demand -> thrust vector (spec 5 inversion: U = a + g e3, tilt limited altitude first) ->
attitude target and collective as a fraction of full thrust (hover fraction * |U| / g, MOT_THST_HOVER).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sitl_sim.attitude_control import quat_from_euler, sqrt_controller

ACCEL_Z_MAX = 2.5  # m/s^2, vertical acceleration of the sqrt shaping (PILOT_ACCEL_Z 250 cm/s^2)
I_MAX_XY = 2.0  # m/s^2, horizontal velocity integrator limit
I_MAX_Z = 4.0  # m/s^2, vertical velocity integrator limit (covers a MOT_THST_HOVER off by 40 %)
MIN_UP_ACCEL = 0.3  # fraction of g: U_z floor, no free-fall commands (spec 5, limit 1)


@dataclass
class PositionGains:
    """Per-vehicle gains and limits, each (N,): P in 1/s, I in 1/s^2, speeds m/s, accel m/s^2, tilt rad."""

    pos_xy_p: np.ndarray
    pos_z_p: np.ndarray
    vel_xy_p: np.ndarray
    vel_xy_i: np.ndarray
    vel_z_p: np.ndarray
    vel_z_i: np.ndarray
    speed_xy: np.ndarray
    speed_up: np.ndarray
    speed_dn: np.ndarray
    accel_xy: np.ndarray
    tilt_max: np.ndarray


def velocity_demand(
    pos: np.ndarray, pos_sp: np.ndarray, vel_ff: np.ndarray, gains: PositionGains
) -> np.ndarray:
    """(N,3) velocity demand m/s: feed-forward plus sqrt-shaped position correction, speed limited.

    pos_sp (N,3) may hold NaN per component: no position control on that axis (horizontal x/y together).
    """
    error = np.where(np.isnan(pos_sp), 0.0, pos_sp - pos)
    dist = np.hypot(error[:, 0], error[:, 1])
    speed = np.minimum(sqrt_controller(dist, gains.pos_xy_p, gains.accel_xy), gains.speed_xy)
    scale = np.where(dist > 1e-9, speed / np.where(dist > 1e-9, dist, 1.0), 0.0)
    vel = vel_ff.copy()
    vel[:, :2] += error[:, :2] * scale[:, None]
    vel[:, 2] += sqrt_controller(error[:, 2], gains.pos_z_p, ACCEL_Z_MAX)
    horizontal = np.hypot(vel[:, 0], vel[:, 1])
    limit = np.where(horizontal > gains.speed_xy, gains.speed_xy / np.maximum(horizontal, 1e-9), 1.0)
    vel[:, :2] *= limit[:, None]
    vel[:, 2] = np.clip(vel[:, 2], -gains.speed_dn, gains.speed_up)
    return vel


def accel_demand(
    vel: np.ndarray,
    vel_sp: np.ndarray,
    acc_ff: np.ndarray,
    integrator: np.ndarray,
    active: np.ndarray,
    gains: PositionGains,
    dt: float,
) -> np.ndarray:
    """(N,3) acceleration demand m/s^2 of the velocity PI; integrator (N,3) updated in place.

    active (N,3) bool: axes under velocity control this tick; the others have their integrator cleared.
    """
    error = vel_sp - vel
    ki = np.stack((gains.vel_xy_i, gains.vel_xy_i, gains.vel_z_i), axis=1)
    kp = np.stack((gains.vel_xy_p, gains.vel_xy_p, gains.vel_z_p), axis=1)
    i_new = np.clip(
        integrator + ki * error * dt, [-I_MAX_XY, -I_MAX_XY, -I_MAX_Z], [I_MAX_XY, I_MAX_XY, I_MAX_Z]
    )
    integrator[:] = np.where(active, i_new, 0.0)
    return acc_ff + kp * error + integrator


def attitude_from_accel(
    accel: np.ndarray, yaw: np.ndarray, tilt_max: np.ndarray, g: float
) -> tuple[np.ndarray, np.ndarray]:
    """Attitude target (N,4) FLU->ENU and thrust in units of g (N,) for acceleration demands (N,3), yaw (N,) rad.

    Spec 5, paper Eqs 23-25: U = a + g e3 with U_z >= 0.3 g and the tilt limited by shortening U_xy.
    """
    u = accel + np.array([0.0, 0.0, g])
    u[:, 2] = np.maximum(u[:, 2], MIN_UP_ACCEL * g)
    horizontal = np.hypot(u[:, 0], u[:, 1])
    allowed = u[:, 2] * np.tan(tilt_max)
    shrink = np.where(horizontal > allowed, allowed / np.maximum(horizontal, 1e-9), 1.0)
    u[:, :2] *= shrink[:, None]
    norm = np.linalg.norm(u, axis=1)
    cy, sy = np.cos(yaw), np.sin(yaw)
    pitch = np.arctan2(u[:, 0] * cy + u[:, 1] * sy, u[:, 2])
    roll = np.arcsin(np.clip((u[:, 0] * sy - u[:, 1] * cy) / norm, -1.0, 1.0))
    return quat_from_euler(roll, pitch, yaw), norm / g
