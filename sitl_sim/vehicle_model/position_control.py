"""ArduCopter-like position/velocity/altitude control of one vehicle (world ENU, SI units).

Cascade as AC_PosControl: position error -> sqrt controller -> velocity demand (speed limited) -> velocity PI
-> acceleration demand -> thrust vector (spec 5 inversion: U = a + g e3, tilt limited altitude first) ->
attitude target and collective in units of g (times MOT_THST_HOVER = fraction of full thrust).
Scalar functions over one vehicle, compiled (swarm_common.jit), called from the autopilot's outer loop.
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.jit import kernel
from swarm_common.shaping import sqrt_controller

ACCEL_Z_MAX = 2.5  # m/s^2, vertical acceleration of the sqrt shaping (PILOT_ACCEL_Z 250 cm/s^2)
I_MAX_XY = 2.0  # m/s^2, horizontal velocity integrator limit
I_MAX_Z = 4.0  # m/s^2, vertical velocity integrator limit (covers a MOT_THST_HOVER off by 40 %)
MIN_UP_ACCEL = 0.3  # fraction of g: U_z floor, no free-fall commands (spec 5, limit 1)


@kernel
def velocity_demand(
    pos: np.ndarray,
    pos_sp: np.ndarray,
    vel_ff: np.ndarray,
    p_xy: float,
    p_z: float,
    accel_xy: float,
    speed_xy: float,
    speed_up: float,
    speed_dn: float,
) -> tuple[float, float, float]:
    """Velocity demand (m/s) from position (3,), target (3,) and feed-forward (3,); NaN target components
    switch position control off on that axis (x and y together). Horizontal speed <= speed_xy, vertical in
    [-speed_dn, speed_up]."""
    vx, vy, vz = vel_ff[0], vel_ff[1], vel_ff[2]
    if not math.isnan(pos_sp[0]):
        ex, ey = pos_sp[0] - pos[0], pos_sp[1] - pos[1]
        dist = math.hypot(ex, ey)
        if dist > 1e-9:
            speed = min(sqrt_controller(dist, p_xy, accel_xy, 0.0), speed_xy)
            vx += ex * speed / dist
            vy += ey * speed / dist
    if not math.isnan(pos_sp[2]):
        vz += sqrt_controller(pos_sp[2] - pos[2], p_z, ACCEL_Z_MAX, 0.0)
    horizontal = math.hypot(vx, vy)
    if horizontal > speed_xy:
        vx *= speed_xy / horizontal
        vy *= speed_xy / horizontal
    return vx, vy, min(max(vz, -speed_dn), speed_up)


@kernel
def velocity_pi(
    error: float, integrator: float, kp: float, ki: float, i_max: float, dt: float
) -> tuple[float, float]:
    """(acceleration demand, new integrator) of one velocity PI axis."""
    integrator = min(max(integrator + ki * error * dt, -i_max), i_max)
    return kp * error + integrator, integrator


@kernel
def attitude_from_accel(
    ax: float, ay: float, az: float, yaw: float, tilt_max: float, g: float
) -> tuple[float, float, float, float, float]:
    """(qw, qx, qy, qz, thrust in g) for an acceleration demand (m/s^2, ENU) at heading yaw (rad, ENU).

    Spec 5, paper Eqs 23-25: U = a + g e3 with U_z >= 0.3 g and the tilt limited by shortening U_xy;
    quaternion body FLU -> world ENU of R = Rz(yaw) Ry(pitch) Rx(roll).
    """
    uz = max(az + g, MIN_UP_ACCEL * g)
    horizontal = math.hypot(ax, ay)
    allowed = uz * math.tan(tilt_max)
    if horizontal > allowed:
        ax *= allowed / horizontal
        ay *= allowed / horizontal
    norm = math.sqrt(ax * ax + ay * ay + uz * uz)
    cy, sy = math.cos(yaw), math.sin(yaw)
    pitch = math.atan2(ax * cy + ay * sy, uz)
    roll = math.asin(min(max((ax * sy - ay * cy) / norm, -1.0), 1.0))
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    ch, sh = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (
        ch * cp * cr + sh * sp * sr,
        ch * cp * sr - sh * sp * cr,
        ch * sp * cr + sh * cp * sr,
        sh * cp * cr - ch * sp * sr,
        norm / g,
    )


@kernel
def brake_shaping_step(
    nav_pos: np.ndarray,
    nav_vel: np.ndarray,
    nav_acc: np.ndarray,
    accel_max: float,
    jerk_max: float,
    dt: float,
) -> None:
    """One step of ArduCopter's BRAKE stop, in place on the (3,) target position/velocity/acceleration (ENU;
    horizontal axes only): AC_PosControl::input_vel_accel_NE with a zero velocity input, i.e. AP_Math
    shape_vel_accel_xy + shape_accel_xy (control.cpp): correction acceleration = sqrt_controller(-vel,
    jerk/accel, jerk) capped at accel_max, reached at no more than jerk_max, then integrated into the target.

    Below accel_max^2 / jerk_max (11.25 m/s with BRAKE_MODE_DECEL_RATE 7.5 m/s^2 and PSC_JERK_XY 5 m/s^3) the
    target's speed decays exponentially with time constant accel_max / jerk_max (1.5 s): a real ArduCopter
    SITL quad stopped from 10.1 m/s in 20.4 m this way (this shaping alone: 20.7 m).
    """
    vx, vy = nav_vel[0], nav_vel[1]
    speed = math.hypot(vx, vy)
    if speed < 1e-6 and math.hypot(nav_acc[0], nav_acc[1]) < 1e-6:
        nav_vel[0] = nav_vel[1] = nav_acc[0] = nav_acc[1] = 0.0
        return
    want = 0.0
    if speed > 1e-6:
        want = min(sqrt_controller(speed, jerk_max / accel_max, jerk_max, 0.0), accel_max) / speed
    dax, day = -vx * want - nav_acc[0], -vy * want - nav_acc[1]  # towards the correction acceleration
    step = math.hypot(dax, day)
    if step > jerk_max * dt:
        dax *= jerk_max * dt / step
        day *= jerk_max * dt / step
    nav_acc[0] += dax
    nav_acc[1] += day
    new_vx, new_vy = vx + nav_acc[0] * dt, vy + nav_acc[1] * dt
    if new_vx * vx + new_vy * vy <= 0.0:  # stopped: never reverse (update_vel_accel's limit)
        new_vx = new_vy = nav_acc[0] = nav_acc[1] = 0.0
    nav_vel[0], nav_vel[1] = new_vx, new_vy
    nav_pos[0] += new_vx * dt
    nav_pos[1] += new_vy * dt
