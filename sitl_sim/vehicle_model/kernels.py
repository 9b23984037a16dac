"""Fused numba kernel advancing N quadrotors nsteps: attitude control, mixing, motors, rigid body, ground.

A scalar transcription of the numpy reference (sitl_sim.vehicle_model.attitude_control and
FleetDynamics._step_numpy in sitl_sim.vehicle_model.dynamics); tests/sitl_sim/vehicle_model/test_dynamics.py
checks that both agree, so change them together.
Vehicles are independent, so each one is advanced all nsteps in a row with its state in registers.
Importing this module requires numba; sitl_sim.vehicle_model.dynamics only imports it for the numba backend.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sitl_sim.vehicle_model.airframe import QuadParams
from sitl_sim.vehicle_model.attitude_control import (
    MOTOR_PITCH_SIGN,
    MOTOR_ROLL_SIGN,
    MOTOR_YAW_SIGN,
    AttitudeGains,
)

# Packed parameter vectors (float64), indices below.
P_MASS, P_G, P_IXX, P_IYY, P_IZZ, P_ARM_XY = range(6)
P_YAW_COEF, P_F_MAX, P_MOTOR_ALPHA, P_DRAG_LIN, P_DRAG_ROT, P_DT = range(6, 12)
# Gains: angle P (3), accel max (3), rate max (3), rate P (3), I (3), D (3), I limit (3), D filter alpha.
C_ANGLE_P, C_ACCEL_MAX, C_RATE_MAX, C_KP, C_KI, C_KD, C_I_MAX, C_D_ALPHA = 0, 3, 6, 9, 12, 15, 18, 21

_ROLL = MOTOR_ROLL_SIGN.copy()
_PITCH = MOTOR_PITCH_SIGN.copy()
_YAW = MOTOR_YAW_SIGN.copy()


def pack_physics(params: QuadParams, dt: float) -> np.ndarray:
    """Airframe parameters and step dt (s) as the kernel's float64 vector."""
    return np.array(
        [
            params.mass,
            params.g,
            params.ixx,
            params.iyy,
            params.izz,
            params.arm * math.sqrt(0.5),
            params.yaw_coef,
            params.f_max,
            math.exp(-dt / params.motor_tau),
            params.drag_lin,
            params.drag_rot,
            dt,
        ]
    )


def pack_gains(gains: AttitudeGains, dt: float) -> np.ndarray:
    """Attitude gains as the kernel's float64 vector (D filter alpha for step dt)."""
    return np.concatenate(
        (
            gains.angle_p,
            gains.accel_max,
            gains.rate_max,
            gains.rate_p,
            gains.rate_i,
            gains.rate_d,
            gains.i_max,
            [gains.d_alpha(dt)],
        )
    ).astype(np.float64)


@njit(cache=True, inline="always")
def _sqrt_controller(error: float, p: float, accel_max: float) -> float:
    linear_dist = accel_max / (p * p)
    magnitude = abs(error)
    if magnitude > linear_dist:
        return math.copysign(math.sqrt(2.0 * accel_max * max(magnitude - 0.5 * linear_dist, 0.0)), error)
    return p * error


@njit(cache=True)
def advance(
    nsteps, phys, ctl, pos, vel, quat, omega, motor, landed, crashed, accel_out,
    quat_t, rate_ff, thrust_sp, motors_on, rate_mode, rate_cmd, integ, d_state, prev_err, wind,
):  # fmt: skip
    """Advance all vehicles nsteps; state and controller arrays are updated in place (shapes: FleetState)."""
    mass, g, dt = phys[P_MASS], phys[P_G], phys[P_DT]
    inertia = np.array([phys[P_IXX], phys[P_IYY], phys[P_IZZ]])
    arm_xy, yaw_coef, f_max = phys[P_ARM_XY], phys[P_YAW_COEF], phys[P_F_MAX]
    alpha, drag_lin, drag_rot = phys[P_MOTOR_ALPHA], phys[P_DRAG_LIN], phys[P_DRAG_ROT]
    inv_4d = 1.0 / (4.0 * arm_xy)
    weight = mass * g
    d_alpha = ctl[C_D_ALPHA]
    rate_sp = np.empty(3)
    err = np.empty(3)
    torque = np.empty(3)
    rp = np.empty(4)
    yaw = np.empty(4)
    diff = np.empty(4)
    f_cmd = np.empty(4)
    w_dot = np.empty(3)

    for i in range(pos.shape[0]):
        for _ in range(nsteps):
            qw, qx, qy, qz = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
            active = motors_on[i] and not crashed[i]

            # --- angle loop (attitude_control.angle_rate_demand) or rate-only command
            if rate_mode[i]:
                for k in range(3):
                    rate_sp[k] = rate_cmd[i, k]
            else:
                tw, tx, ty, tz = quat_t[i, 0], quat_t[i, 1], quat_t[i, 2], quat_t[i, 3]
                ew = qw * tw + qx * tx + qy * ty + qz * tz  # conj(q) * q_target
                ex = qw * tx - qx * tw - qy * tz + qz * ty
                ey = qw * ty + qx * tz - qy * tw - qz * tx
                ez = qw * tz - qx * ty + qy * tx - qz * tw
                n = math.hypot(ew, ez)
                if n < 1e-12:
                    cw, cz = 1.0, 0.0
                else:
                    cw, cz = ew / n, ez / n
                sx = ex * cw - ey * cz
                sy = ey * cw + ex * cz
                h = math.hypot(ex, ey)
                factor = 2.0 * math.atan2(h, n) / h if h > 1e-12 else 2.0
                sign = -1.0 if cw < 0.0 else 1.0
                err[0] = sx * factor
                err[1] = sy * factor
                err[2] = 2.0 * math.atan2(cz * sign, cw * sign)
                for k in range(3):
                    r = _sqrt_controller(err[k], ctl[C_ANGLE_P + k], ctl[C_ACCEL_MAX + k]) + rate_ff[i, k]
                    rate_sp[k] = min(max(r, -ctl[C_RATE_MAX + k]), ctl[C_RATE_MAX + k])

            # --- rate PID (attitude_control.rate_pid)
            reset = landed[i] or not active
            for k in range(3):
                e = rate_sp[k] - omega[i, k]
                d_raw = (e - prev_err[i, k]) / dt
                if reset:
                    integ[i, k] = 0.0
                    d_state[i, k] = 0.0
                else:
                    d_state[i, k] = d_state[i, k] + d_alpha * (d_raw - d_state[i, k])
                    i_lim = ctl[C_I_MAX + k]
                    integ[i, k] = min(max(integ[i, k] + ctl[C_KI + k] * e * dt, -i_lim), i_lim)
                prev_err[i, k] = e
                torque[k] = ctl[C_KP + k] * e + integ[i, k] + ctl[C_KD + k] * d_state[i, k]
                if landed[i]:
                    torque[k] = 0.0

            # --- mixer (attitude_control.mix_x_quad) and motor lag
            if active:
                rp_hi, rp_lo = -np.inf, np.inf
                for j in range(4):
                    rp[j] = (_ROLL[j] * torque[0] + _PITCH[j] * torque[1]) * inv_4d
                    rp_hi, rp_lo = max(rp_hi, rp[j]), min(rp_lo, rp[j])
                rp_span = rp_hi - rp_lo
                yaw_scale = 1.0
                if rp_span > f_max:
                    for j in range(4):
                        rp[j] = rp[j] * (f_max / rp_span)
                    yaw_scale = 0.0
                for j in range(4):
                    yaw[j] = _YAW[j] * torque[2] * (0.25 / yaw_coef)
                if yaw_scale > 0.0:
                    for a in range(4):
                        for b in range(4):
                            dy = yaw[a] - yaw[b]
                            if dy > 0.0:
                                yaw_scale = min(yaw_scale, (f_max - (rp[a] - rp[b])) / dy)
                    yaw_scale = max(yaw_scale, 0.0)
                d_hi, d_lo = -np.inf, np.inf
                for j in range(4):
                    diff[j] = rp[j] + yaw[j] * yaw_scale
                    d_hi, d_lo = max(d_hi, diff[j]), min(d_lo, diff[j])
                per_motor = min(max(0.25 * thrust_sp[i], -d_lo), f_max - d_hi)
                for j in range(4):
                    f_cmd[j] = min(max(per_motor + diff[j], 0.0), f_max)
            else:
                for j in range(4):
                    f_cmd[j] = 0.0
            thrust = 0.0
            tau_x, tau_y, tau_z = 0.0, 0.0, 0.0
            for j in range(4):
                f = 0.0 if crashed[i] else f_cmd[j] + (motor[i, j] - f_cmd[j]) * alpha
                motor[i, j] = f
                thrust += f
                tau_x += f * _ROLL[j]
                tau_y += f * _PITCH[j]
                tau_z += f * _YAW[j]
            tau_x *= arm_xy
            tau_y *= arm_xy
            tau_z *= yaw_coef

            # --- rigid body (FleetDynamics._step_numpy)
            if landed[i] and thrust > weight:
                landed[i] = False
            if landed[i]:
                for k in range(3):
                    vel[i, k] = 0.0
                    omega[i, k] = 0.0
                    accel_out[i, k] = 0.0
                continue
            ax_t = 2.0 * (qw * qy + qx * qz)  # R e3, the thrust axis in the world
            ay_t = 2.0 * (qy * qz - qw * qx)
            az_t = 1.0 - 2.0 * (qx * qx + qy * qy)
            k_drag = drag_lin / mass
            a_x = ax_t * (thrust / mass) - k_drag * (vel[i, 0] - wind[i, 0])
            a_y = ay_t * (thrust / mass) - k_drag * (vel[i, 1] - wind[i, 1])
            a_z = az_t * (thrust / mass) - k_drag * (vel[i, 2] - wind[i, 2]) - g
            wx, wy, wz = omega[i, 0], omega[i, 1], omega[i, 2]
            lx, ly, lz = inertia[0] * wx, inertia[1] * wy, inertia[2] * wz
            w_dot[0] = (tau_x - (wy * lz - wz * ly) - drag_rot * wx) / inertia[0]
            w_dot[1] = (tau_y - (wz * lx - wx * lz) - drag_rot * wy) / inertia[1]
            w_dot[2] = (tau_z - (wx * ly - wy * lx) - drag_rot * wz) / inertia[2]
            vel[i, 0] += a_x * dt
            vel[i, 1] += a_y * dt
            vel[i, 2] += a_z * dt
            for k in range(3):
                pos[i, k] += vel[i, k] * dt
                omega[i, k] += w_dot[k] * dt
            accel_out[i, 0], accel_out[i, 1], accel_out[i, 2] = a_x, a_y, a_z

            # q * exp(omega dt / 2) (dynamics.integrate_attitude)
            wx, wy, wz = omega[i, 0], omega[i, 1], omega[i, 2]
            rate = math.sqrt(wx * wx + wy * wy + wz * wz)
            half = 0.5 * rate * dt
            scale = 0.5 * dt * (1.0 - half * half / 6.0) if half < 1e-6 else math.sin(half) / rate
            dw, dx, dy_, dz = math.cos(half), wx * scale, wy * scale, wz * scale
            nw = qw * dw - qx * dx - qy * dy_ - qz * dz
            nx = qw * dx + qx * dw + qy * dz - qz * dy_
            ny = qw * dy_ - qx * dz + qy * dw + qz * dx
            nz = qw * dz + qx * dy_ - qy * dx + qz * dw
            norm = math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
            nw, nx, ny, nz = nw / norm, nx / norm, ny / norm, nz / norm

            # --- ground plane z = 0
            if pos[i, 2] < 0.0:
                pos[i, 2] = 0.0
                vel[i, 2] = max(vel[i, 2], 0.0)
                if thrust * az_t <= weight:
                    landed[i] = True
                    for k in range(3):
                        vel[i, k] = 0.0
                        omega[i, k] = 0.0
                        accel_out[i, k] = 0.0
                    yaw_angle = math.atan2(2.0 * (nw * nz + nx * ny), 1.0 - 2.0 * (ny * ny + nz * nz))
                    nw, nx, ny, nz = math.cos(0.5 * yaw_angle), 0.0, 0.0, math.sin(0.5 * yaw_angle)
            quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3] = nw, nx, ny, nz


@njit(cache=True)
def store_targets(
    quat_sp, rate_ff, thrust_sp, motors_on, tilt_max, current_quat, hover, thrust_max, default_tilt,
    out_quat, out_rate_ff, out_thrust, out_motors_on, out_sanitised,
):  # fmt: skip
    """Sanitise, normalise and tilt-limit new targets into the out_* arrays (FleetDynamics.set_targets)."""
    for i in range(quat_sp.shape[0]):
        w, x, y, z = quat_sp[i, 0], quat_sp[i, 1], quat_sp[i, 2], quat_sp[i, 3]
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        bad_quat = not math.isfinite(norm) or norm < 1e-6
        if bad_quat:
            w, x, y, z = current_quat[i, 0], current_quat[i, 1], current_quat[i, 2], current_quat[i, 3]
        else:
            w, x, y, z = w / norm, x / norm, y / norm, z / norm
        tilt_lim = tilt_max[i]
        bad_tilt = not math.isfinite(tilt_lim)
        if bad_tilt:
            tilt_lim = default_tilt
        tilt_lim = min(max(tilt_lim, 0.0), math.pi)
        # attitude_control.limit_tilt: q = swing * twist, shorten the swing
        n = math.hypot(w, z)
        if n < 1e-12:
            cw, cz = 1.0, 0.0
        else:
            cw, cz = w / n, z / n
        h = math.hypot(x, y)
        tilt = 2.0 * math.atan2(h, n)
        if tilt > tilt_lim:
            half = 0.5 * tilt_lim
            scale = math.sin(half) / (h if h > 0.0 else 1.0)
            sx, sy, sw = (x * cw - y * cz) * scale, (y * cw + x * cz) * scale, math.cos(half)
            w, x, y, z = sw * cw, sx * cw + sy * cz, sy * cw - sx * cz, sw * cz
        out_quat[i, 0], out_quat[i, 1], out_quat[i, 2], out_quat[i, 3] = w, x, y, z
        bad_rate = False
        for k in range(3):
            if not math.isfinite(rate_ff[i, k]):
                bad_rate = True
        for k in range(3):
            out_rate_ff[i, k] = 0.0 if bad_rate else rate_ff[i, k]
        thrust = thrust_sp[i]
        bad_thrust = not math.isfinite(thrust)
        if bad_thrust:
            thrust = hover
        out_thrust[i] = min(max(thrust, 0.0), thrust_max)
        out_motors_on[i] = motors_on[i]
        out_sanitised[i] = bad_quat or bad_rate or bad_thrust or bad_tilt
