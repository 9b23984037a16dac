"""Vectorised 6-DOF quadrotor fleet: motors, rigid body, drag, wind, ground contact, attitude control.

Model (spec 5 as a real rigid body [fix/add]; Table 2 and Table 6 values): world ENU with z up, body FLU,
attitude quaternion [w, x, y, z] body -> world (spec 1.1).

    m dv/dt   = R e3 * sum(f_i) - m g e3 - drag_lin (v - wind)
    I dw/dt   = tau(f) - w x (I w) - drag_rot w          (body rates, gyroscopic term included)
    dq/dt     = q * (0, w) / 2                             (integrated exactly for constant w over a step)
    df_i/dt   = (f_cmd,i - f_i) / motor_tau                (discretised exactly: exp(-dt/tau))

X-quad torques from thrusts in ArduCopter's motor order (see attitude_control.MOTOR_*_SIGN): roll/pitch arm
= arm/sqrt(2); yaw reaction torque = (k_D/k_T) * f_i (Table 6: thrust k_T w^2, torque k_D w^2).
Semi-implicit Euler: velocity and rates first, then position and attitude with the new ones; quaternion
renormalised every step. Stable at 1 kHz and 250 Hz.

Ground (plane z = 0): a vehicle never sinks below it. Touching down with vertical thrust <= weight makes it
`landed` (velocity and rates zeroed, attitude levelled keeping yaw, attitude loop relaxed); it lifts off when
total thrust exceeds its weight. Crashed vehicles have their motors off (they fall and lie on the ground).

`advance` is the one implementation of this step, compiled (swarm_common.jit): per vehicle and physics step
the attitude controller (sitl_sim.vehicle_model.attitude_control), the motor lag, the rigid body and the
ground; FleetDynamics holds the arrays and calls it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from sitl_sim.vehicle_model.airframe import QuadParams
from sitl_sim.vehicle_model.attitude_control import (
    MOTOR_PITCH_SIGN,
    MOTOR_ROLL_SIGN,
    MOTOR_YAW_SIGN,
    AttitudeGains,
    attitude_error,
    euler_from_quat,
    level_quat,
    limit_tilt,
    mix_x_quad,
    rate_pid_axis,
)
from swarm_common.jit import kernel
from swarm_common.shaping import sqrt_controller

DEFAULT_TILT_MAX = math.radians(30.0)  # ArduCopter ANGLE_MAX default, 3000 cdeg


class StepPhysics(NamedTuple):
    """The airframe (QuadParams) for a physics step of dt s, as the compiled step `advance` takes it."""

    mass: float  # kg
    g: float  # m/s^2
    ixx: float  # kg m^2, principal inertias (body FLU)
    iyy: float
    izz: float
    arm_xy: float  # m, roll/pitch lever of each motor: arm / sqrt(2)
    yaw_coef: float  # m, reaction torque per newton of thrust (k_d / k_t)
    f_max: float  # N, one motor's maximum thrust
    motor_alpha: float  # exp(-dt / motor_tau): the motor lag's decay over one step
    drag_lin: float  # N per m/s of air-relative velocity
    drag_rot: float  # N m per rad/s of body rate
    dt: float  # s, the physics step

    @classmethod
    def of(cls, params: QuadParams, dt: float) -> StepPhysics:
        """The airframe `params` for a step of dt s."""
        return cls(
            params.mass, params.g, params.ixx, params.iyy, params.izz, params.arm * math.sqrt(0.5),
            params.yaw_coef, params.f_max, math.exp(-dt / params.motor_tau), params.drag_lin, params.drag_rot,
            dt,
        )  # fmt: skip


class FleetState:
    """State of N vehicles as plain arrays, mutated in place by FleetDynamics.

    pos (N,3) ENU m; vel (N,3) ENU m/s; quat (N,4) [w,x,y,z] body FLU -> world ENU; omega (N,3) body FLU
    rad/s; motor (N,4) current motor thrusts N (ArduCopter motor order); landed, crashed (N,) bool.
    Mutate the arrays in place (state.pos[i] = ...), do not rebind them: the numba kernel expects
    C-contiguous float64/bool arrays of these shapes.
    """

    def __init__(
        self,
        pos: np.ndarray,
        vel: np.ndarray,
        quat: np.ndarray,
        omega: np.ndarray,
        motor: np.ndarray,
        landed: np.ndarray,
        crashed: np.ndarray,
    ) -> None:
        n = len(pos)
        self.pos = _float_array(pos, (n, 3), "pos")
        self.vel = _float_array(vel, (n, 3), "vel")
        self.quat = _float_array(quat, (n, 4), "quat")
        self.omega = _float_array(omega, (n, 3), "omega")
        self.motor = _float_array(motor, (n, 4), "motor")
        self.landed = _bool_array(landed, n, "landed")
        self.crashed = _bool_array(crashed, n, "crashed")
        # (N,3) world acceleration of the last step, m/s^2 (zero while landed; IMU-style outputs)
        self.world_accel = np.zeros((n, 3))

    @classmethod
    def at_rest(
        cls,
        pos: np.ndarray,
        yaw: np.ndarray,
        vel: np.ndarray | None = None,
        params: QuadParams | None = None,
    ) -> FleetState:
        """Level vehicles at pos (N,3) with yaw (N,) rad and velocity vel (N,3) (default zero).

        A vehicle is landed when pos z <= 0 and its velocity is zero (z is clamped to the ground); every other
        vehicle starts airborne with its motors at hover thrust of `params` (default QuadParams()).
        """
        params = params or QuadParams()
        pos = _float_array(pos, (len(np.atleast_2d(pos)), 3), "pos").copy()
        n = len(pos)
        yaw = np.broadcast_to(np.asarray(yaw, dtype=float), (n,))
        vel = np.zeros((n, 3)) if vel is None else _float_array(vel, (n, 3), "vel").copy()
        landed = (pos[:, 2] <= 0.0) & ~np.any(vel != 0.0, axis=1)
        pos[:, 2] = np.maximum(pos[:, 2], 0.0)
        motor = np.where(landed[:, None], 0.0, params.mass * params.g / 4.0) * np.ones((n, 4))
        return cls(pos, vel, level_quat(yaw), np.zeros((n, 3)), motor, landed, np.zeros(n, dtype=bool))

    def euler(self) -> np.ndarray:
        """(N,3) roll, pitch, yaw (ZYX, rad, spec 1.1)."""
        return euler_from_quat(self.quat)


class FleetDynamics:
    """N quadrotors with their attitude controllers, advanced together at rate_hz.

    Targets (set_targets / set_rate_targets) are held until the next call, as an autopilot outer loop at
    100-400 Hz would hold them; at first they hold the initial `state` (hover if airborne, idle if landed).
    """

    def __init__(
        self,
        n: int,
        params: QuadParams = QuadParams(),  # noqa: B008 - frozen dataclass, safe as a default
        rate_hz: float = 1000.0,
        attitude_gains: AttitudeGains | None = None,
        state: FleetState | None = None,
    ) -> None:
        if not (isinstance(n, int | np.integer) and n >= 1):
            raise ValueError(f"vehicle count n must be an integer >= 1, not {n!r}")
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"physics rate_hz must be a finite number > 0, not {rate_hz!r}")
        self.n = int(n)
        self.params = params
        self.gains = attitude_gains or AttitudeGains()
        self.dt = 1.0 / float(rate_hz)
        self._targets_quat = np.zeros((self.n, 4))
        self._rate_ff = np.zeros((self.n, 3))
        self._thrust_sp = np.zeros(self.n)
        self._motors_on = np.zeros(self.n, dtype=bool)
        self._rate_mode = np.zeros(self.n, dtype=bool)
        self._rate_cmd = np.zeros((self.n, 3))
        self._integrator = np.zeros((self.n, 3))
        self._d_state = np.zeros((self.n, 3))
        self._prev_error = np.zeros((self.n, 3))
        self.last_sanitised = np.zeros(self.n, dtype=bool)
        """(N,) bool: vehicles whose last set_targets/set_rate_targets input had non-finite values."""
        self._phys = StepPhysics.of(params, self.dt)
        self._ctl = self.gains.for_step(self.dt)
        self._work = np.zeros((5, 4))  # advance's scratch
        if state is None:
            state = FleetState.at_rest(np.zeros((self.n, 3)), np.zeros(self.n), params=params)
        if len(state.pos) != self.n:
            raise ValueError(f"state holds {len(state.pos)} vehicles, the dynamics {self.n}")
        self.state = state  # the fleet's FleetState (arrays mutated in place by step)
        airborne = ~state.landed & ~state.crashed  # the targets hold it: hover if airborne, idle if landed
        self._targets_quat[:] = state.quat
        self._thrust_sp[:] = np.where(airborne, params.mass * params.g, 0.0)
        self._motors_on[:] = airborne

    def set_targets(
        self,
        quat_sp: np.ndarray,
        rate_ff: np.ndarray,
        thrust_sp: np.ndarray,
        motors_on: np.ndarray,
        tilt_max: float | np.ndarray = DEFAULT_TILT_MAX,
    ) -> None:
        """Hold new attitude targets for all vehicles until the next call.

        quat_sp (N,4) world <- body FLU/ENU target (normalised here); rate_ff (N,3) body FLU feed-forward
        rad/s; thrust_sp (N,) total collective N, clipped to [0, thrust_max], applied without tilt
        compensation; motors_on (N,) bool; tilt_max rad (scalar or (N,)), clipped to [0, pi], limits the
        target's tilt (ArduCopter ANGLE_MAX).
        Wrong shapes raise ValueError. Non-finite values are sanitised, never propagated: a bad quaternion
        (or one of near-zero norm) holds the current attitude, a bad rate_ff is 0, a bad thrust is hover
        thrust (m g), a bad tilt_max is 30 deg; such vehicles are flagged in `last_sanitised`.
        """
        n = self.n
        quat = _float_array(quat_sp, (n, 4), "quat_sp")
        rate_ff = _float_array(rate_ff, (n, 3), "rate_ff")
        thrust = _float_array(thrust_sp, (n,), "thrust_sp")
        motors_on = _bool_array(motors_on, n, "motors_on")
        tilt = np.asarray(tilt_max, dtype=float)
        if tilt.shape not in ((), (n,)):
            raise ValueError(f"tilt_max must be a scalar or have shape ({n},), not {tilt.shape}")
        tilt = np.full(n, tilt) if tilt.shape == () else np.ascontiguousarray(tilt)
        hover = self.params.mass * self.params.g
        store_targets(
            quat, rate_ff, thrust, motors_on, tilt, self.state.quat, hover, self.params.thrust_max,
            DEFAULT_TILT_MAX, self._targets_quat, self._rate_ff, self._thrust_sp, self._motors_on,
            self.last_sanitised,
        )  # fmt: skip

    def set_rate_targets(self, mask: np.ndarray, rates: np.ndarray) -> None:
        """Select rate-only control: vehicles with mask (N,) True track body rates (N,3) FLU rad/s directly.

        The angle loop is bypassed for them (SET_ATTITUDE_TARGET with the attitude ignored); vehicles with
        mask False return to attitude control. Collective and motors_on still come from set_targets. Rates are
        limited to the gains' rate_max; non-finite rates are replaced by 0 (flagged in last_sanitised).
        """
        mask = _bool_array(mask, self.n, "mask")
        rates = _float_array(rates, (self.n, 3), "rates")
        bad = ~np.all(np.isfinite(rates), axis=1)
        self.last_sanitised |= bad & mask
        rate_max = np.array(self._ctl.rate_max)
        rates = np.clip(np.where(bad[:, None], 0.0, rates), -rate_max, rate_max)
        self._rate_cmd[:] = np.where(mask[:, None], rates, 0.0)
        self._rate_mode[:] = mask

    def step(self, wind: np.ndarray, nsteps: int = 1) -> None:
        """Advance every vehicle nsteps * dt with air velocity wind (N,3) ENU m/s held constant (NaN -> 0)."""
        wind = _float_array(wind, (self.n, 3), "wind")
        if not np.all(np.isfinite(wind)):
            wind = np.where(np.isfinite(wind), wind, 0.0)
        if not (isinstance(nsteps, int | np.integer) and nsteps >= 0):
            raise ValueError(f"nsteps must be an integer >= 0, not {nsteps!r}")
        s = self.state
        advance(
            int(nsteps), self._phys, self._ctl,
            s.pos, s.vel, s.quat, s.omega, s.motor, s.landed, s.crashed, s.world_accel,
            self._targets_quat, self._rate_ff, self._thrust_sp, self._motors_on, self._rate_mode,
            self._rate_cmd, self._integrator, self._d_state, self._prev_error, wind, self._work,
        )  # fmt: skip


@kernel
def advance(
    nsteps, phys, ctl, pos, vel, quat, omega, motor, landed, crashed, accel_out,
    quat_t, rate_ff, thrust_sp, motors_on, rate_mode, rate_cmd, integ, d_state, prev_err, wind, work,
):  # fmt: skip  # noqa: ANN001, ANN201 - numba kernel over FleetDynamics' arrays
    """Advance all vehicles nsteps physics steps of phys.dt s; state and controller memory are updated in
    place. phys: StepPhysics; ctl: AttitudeGains.for_step; the arrays as FleetState and FleetDynamics hold
    them (targets quat_t (N,4), rate_ff (N,3) rad/s, thrust_sp (N,) N, motors_on, rate_mode (N,) bool,
    rate_cmd (N,3) rad/s; rate PID memory integ, d_state, prev_err (N,3); wind (N,3) ENU m/s); work (5,4)
    scratch.
    Vehicles are independent, so each one is advanced all nsteps in a row. (No array is allocated here: an
    allocation would compile numba's error-message machinery into the cold start.)"""
    mass, g, dt = phys.mass, phys.g, phys.dt
    ixx, iyy, izz = phys.ixx, phys.iyy, phys.izz
    arm_xy, yaw_coef, f_max = phys.arm_xy, phys.yaw_coef, phys.f_max
    alpha, drag_lin, drag_rot = phys.motor_alpha, phys.drag_lin, phys.drag_rot
    inv_4d = 1.0 / (4.0 * arm_xy)
    weight = mass * g
    rate_sp, torque, rp, yaw, f_cmd = work[0], work[1], work[2], work[3], work[4]

    for i in range(pos.shape[0]):
        for _ in range(nsteps):
            qw, qx, qy, qz = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
            active = motors_on[i] and not crashed[i]

            # --- attitude controller: angle loop (or a rate-only command), rate PID, mixer
            if rate_mode[i]:
                for k in range(3):
                    rate_sp[k] = rate_cmd[i, k]
            else:
                err = attitude_error(qw, qx, qy, qz, quat_t[i, 0], quat_t[i, 1], quat_t[i, 2], quat_t[i, 3])
                for k in range(3):
                    r = sqrt_controller(err[k], ctl.angle_p[k], ctl.accel_max[k], 0.0) + rate_ff[i, k]
                    rate_sp[k] = min(max(r, -ctl.rate_max[k]), ctl.rate_max[k])
            reset = landed[i] or not active
            for k in range(3):
                e = rate_sp[k] - omega[i, k]
                torque[k], integ[i, k], d_state[i, k] = rate_pid_axis(
                    e, prev_err[i, k], integ[i, k], d_state[i, k], ctl, k, reset, dt
                )
                prev_err[i, k] = e
                if landed[i]:
                    torque[k] = 0.0  # the attitude loop is relaxed on the ground
            if active:
                tx, ty, tz, collective = torque[0], torque[1], torque[2], thrust_sp[i]
                mix_x_quad(tx, ty, tz, collective, inv_4d, yaw_coef, f_max, rp, yaw, f_cmd)
            else:
                for j in range(4):
                    f_cmd[j] = 0.0

            # --- motor lag (exact first order) and the wrench of the motors
            thrust = 0.0
            tau_x, tau_y, tau_z = 0.0, 0.0, 0.0
            for j in range(4):
                f = 0.0 if crashed[i] else f_cmd[j] + (motor[i, j] - f_cmd[j]) * alpha
                motor[i, j] = f
                thrust += f
                tau_x += f * MOTOR_ROLL_SIGN[j]
                tau_y += f * MOTOR_PITCH_SIGN[j]
                tau_z += f * MOTOR_YAW_SIGN[j]
            tau_x *= arm_xy
            tau_y *= arm_xy
            tau_z *= yaw_coef

            # --- rigid body
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
            lx, ly, lz = ixx * wx, iyy * wy, izz * wz
            w_dot_x = (tau_x - (wy * lz - wz * ly) - drag_rot * wx) / ixx
            w_dot_y = (tau_y - (wz * lx - wx * lz) - drag_rot * wy) / iyy
            w_dot_z = (tau_z - (wx * ly - wy * lx) - drag_rot * wz) / izz
            vel[i, 0] += a_x * dt
            vel[i, 1] += a_y * dt
            vel[i, 2] += a_z * dt
            for k in range(3):
                pos[i, k] += vel[i, k] * dt
            omega[i, 0] += w_dot_x * dt
            omega[i, 1] += w_dot_y * dt
            omega[i, 2] += w_dot_z * dt
            accel_out[i, 0], accel_out[i, 1], accel_out[i, 2] = a_x, a_y, a_z

            # q * exp(omega dt / 2): the exact rotation for the body rates held over dt, renormalised
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


@kernel
def store_targets(
    quat_sp, rate_ff, thrust_sp, motors_on, tilt_max, current_quat, hover, thrust_max, default_tilt,
    out_quat, out_rate_ff, out_thrust, out_motors_on, out_sanitised,
):  # fmt: skip  # noqa: ANN001, ANN201 - numba kernel over FleetDynamics' arrays
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
        w, x, y, z = limit_tilt(w, x, y, z, min(max(tilt_lim, 0.0), math.pi))
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


def _float_array(value: np.ndarray, shape: tuple[int, ...], name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, not {array.shape}")
    return np.ascontiguousarray(array)


def _bool_array(value: np.ndarray, n: int, name: str) -> np.ndarray:
    array = np.asarray(value)
    if array.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), not {array.shape}")
    return np.ascontiguousarray(array, dtype=bool)
