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

Two interchangeable backends advance all vehicles: a fused numba kernel (sitl_sim.vehicle_model.kernels, the
default when numba imports) and the numpy reference below. SWARM_SIM_BACKEND=numpy forces the reference.
"""

from __future__ import annotations

import math
import os

import numpy as np

from sitl_sim.vehicle_model.airframe import QuadParams, motor_wrench
from sitl_sim.vehicle_model.attitude_control import (
    AttitudeGains,
    angle_rate_demand,
    cross,
    euler_from_quat,
    level_quat,
    limit_tilt,
    mix_x_quad,
    quat_rotate,
    rate_pid,
    yaw_from_quat,
)
from swarm_common.rotations import quaternion_multiply

DEFAULT_TILT_MAX = math.radians(30.0)  # ArduCopter ANGLE_MAX default, 3000 cdeg
BACKEND_ENV = "SWARM_SIM_BACKEND"


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
        self.world_accel = np.zeros((n, 3))  # last computed acceleration, see accel()

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

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return len(self.pos)

    def euler(self) -> np.ndarray:
        """(N,3) roll, pitch, yaw (ZYX, rad, spec 1.1)."""
        return euler_from_quat(self.quat)

    def accel(self) -> np.ndarray:
        """(N,3) world acceleration of the last step, m/s^2 (zero while landed; IMU-style outputs)."""
        return self.world_accel


class FleetDynamics:
    """N quadrotors with their attitude controllers, advanced together at rate_hz.

    Targets (set_targets / set_rate_targets) are held until the next call, as an autopilot outer loop at
    100-400 Hz would hold them. `state` may be replaced by another FleetState of the same N; the targets are
    then reset to hold that state (hover if airborne, idle if landed).
    """

    def __init__(
        self,
        n: int,
        params: QuadParams = QuadParams(),  # noqa: B008 - frozen dataclass, safe as a default
        rate_hz: float = 1000.0,
        attitude_gains: AttitudeGains | None = None,
        backend: str | None = None,
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
        self.backend = _choose_backend(backend)
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
        if self.backend == "numba":
            from sitl_sim.vehicle_model import kernels

            self._kernel = kernels.advance
            self._store_targets = kernels.store_targets
            self._phys = kernels.pack_physics(params, self.dt)
            self._ctl = kernels.pack_gains(self.gains, self.dt)
        if state is None:
            state = FleetState.at_rest(np.zeros((self.n, 3)), np.zeros(self.n), params=params)
        self.state = state

    @property
    def state(self) -> FleetState:
        """The fleet's FleetState (arrays mutated in place by step)."""
        return self._state

    @state.setter
    def state(self, state: FleetState) -> None:
        if state.n != self.n:
            raise ValueError(f"state holds {state.n} vehicles, the dynamics {self.n}")
        self._state = state
        for i in range(self.n):
            self._hold_current(i)

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
        if self.backend == "numba":
            self._store_targets(
                quat, rate_ff, thrust, motors_on, tilt, self._state.quat, hover, self.params.thrust_max,
                DEFAULT_TILT_MAX, self._targets_quat, self._rate_ff, self._thrust_sp, self._motors_on,
                self.last_sanitised,
            )  # fmt: skip
            return
        norm = np.linalg.norm(quat, axis=1)
        bad_quat = ~np.isfinite(norm) | (norm < 1e-6)
        bad_rate = ~np.all(np.isfinite(rate_ff), axis=1)
        bad_thrust = ~np.isfinite(thrust)
        bad_tilt = ~np.isfinite(tilt)
        self.last_sanitised[:] = bad_quat | bad_rate | bad_thrust | bad_tilt
        quat = np.where(bad_quat[:, None], self._state.quat, quat / np.where(bad_quat, 1.0, norm)[:, None])
        tilt = np.clip(np.where(bad_tilt, DEFAULT_TILT_MAX, tilt), 0.0, math.pi)
        self._targets_quat[:] = limit_tilt(quat, tilt)
        self._rate_ff[:] = np.where(bad_rate[:, None], 0.0, rate_ff)
        self._thrust_sp[:] = np.clip(np.where(bad_thrust, hover, thrust), 0.0, self.params.thrust_max)
        self._motors_on[:] = motors_on

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
        rate_max = self.gains.rate_max
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
        if self.backend == "numba":
            s = self._state
            self._kernel(
                int(nsteps), self._phys, self._ctl,
                s.pos, s.vel, s.quat, s.omega, s.motor, s.landed, s.crashed, s.world_accel,
                self._targets_quat, self._rate_ff, self._thrust_sp, self._motors_on, self._rate_mode,
                self._rate_cmd, self._integrator, self._d_state, self._prev_error, wind,
            )  # fmt: skip
        else:
            for _ in range(nsteps):
                self._step_numpy(wind)

    def reset_vehicle(self, i: int, pos: np.ndarray, yaw: float, vel: np.ndarray | None = None) -> None:
        """Put vehicle i back at rest like FleetState.at_rest (crash cleared, controller reset)."""
        if not (isinstance(i, int | np.integer) and 0 <= i < self.n):
            raise ValueError(f"vehicle index must be in 0..{self.n - 1}, not {i!r}")
        vel = None if vel is None else np.reshape(vel, (1, 3))
        fresh = FleetState.at_rest(np.reshape(pos, (1, 3)), np.array([yaw]), vel, self.params)
        s = self._state
        for name in ("pos", "vel", "quat", "omega", "motor", "landed", "crashed", "world_accel"):
            getattr(s, name)[i] = getattr(fresh, name)[0]
        self._hold_current(i)

    def _hold_current(self, i: int) -> None:
        """Targets and controller memory of vehicle i that hold its current state (hover or idle)."""
        s = self._state
        airborne = not s.landed[i] and not s.crashed[i]
        self._targets_quat[i] = s.quat[i]
        self._rate_ff[i] = 0.0
        self._thrust_sp[i] = self.params.mass * self.params.g if airborne else 0.0
        self._motors_on[i] = airborne
        self._rate_mode[i] = False
        self._rate_cmd[i] = 0.0
        self._integrator[i] = 0.0
        self._d_state[i] = 0.0
        self._prev_error[i] = 0.0

    def _step_numpy(self, wind: np.ndarray) -> None:
        """One dt of the numpy reference: control, mixing, motors, rigid body, ground (= the kernel)."""
        s, p, dt = self._state, self.params, self.dt
        active = self._motors_on & ~s.crashed
        rate_sp = np.where(
            self._rate_mode[:, None],
            self._rate_cmd,
            angle_rate_demand(s.quat, self._targets_quat, self._rate_ff, self.gains),
        )
        reset = s.landed | ~active
        memory = (self._integrator, self._d_state, self._prev_error)
        torque_cmd = rate_pid(rate_sp, s.omega, *memory, reset, self.gains, dt)
        torque_cmd = np.where(s.landed[:, None], 0.0, torque_cmd)  # attitude loop relaxed on the ground
        f_cmd = mix_x_quad(np.where(active, self._thrust_sp, 0.0), torque_cmd, p.arm, p.yaw_coef, p.f_max)
        f_cmd = np.where(active[:, None], f_cmd, 0.0)
        alpha = math.exp(-dt / p.motor_tau)
        s.motor[:] = np.where(s.crashed[:, None], 0.0, f_cmd + (s.motor - f_cmd) * alpha)

        thrust, torque = motor_wrench(s.motor, p)
        weight = p.mass * p.g
        s.landed &= ~(thrust > weight)
        free = ~s.landed[:, None]
        thrust_axis = quat_rotate(s.quat, np.array([0.0, 0.0, 1.0]))
        accel = thrust_axis * (thrust / p.mass)[:, None] - (p.drag_lin / p.mass) * (s.vel - wind)
        accel[:, 2] -= p.g
        inertia = p.inertia
        omega_dot = (torque - cross(s.omega, inertia * s.omega) - p.drag_rot * s.omega) / inertia
        vel = s.vel + accel * dt
        omega = s.omega + omega_dot * dt
        s.pos[:] = np.where(free, s.pos + vel * dt, s.pos)
        s.vel[:] = np.where(free, vel, 0.0)
        s.omega[:] = np.where(free, omega, 0.0)
        s.world_accel[:] = np.where(free, accel, 0.0)
        s.quat[:] = np.where(free, integrate_attitude(s.quat, omega, dt), s.quat)

        below = ~s.landed & (s.pos[:, 2] < 0.0)
        touchdown = below & (thrust * thrust_axis[:, 2] <= weight)
        s.pos[:, 2] = np.where(below, 0.0, s.pos[:, 2])
        s.vel[:, 2] = np.where(below, np.maximum(s.vel[:, 2], 0.0), s.vel[:, 2])
        s.vel[:] = np.where(touchdown[:, None], 0.0, s.vel)
        s.omega[:] = np.where(touchdown[:, None], 0.0, s.omega)
        s.world_accel[:] = np.where(touchdown[:, None], 0.0, s.world_accel)
        s.quat[:] = np.where(touchdown[:, None], level_quat(yaw_from_quat(s.quat)), s.quat)
        s.landed |= touchdown


def integrate_attitude(quat: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """q * exp(omega dt / 2): exact rotation for body rates (N,3) held over dt, renormalised."""
    rate = np.linalg.norm(omega, axis=1)
    half = 0.5 * rate * dt
    small = half < 1e-6
    scale = np.where(small, 0.5 * dt * (1.0 - half * half / 6.0), np.sin(half) / np.where(small, 1.0, rate))
    delta = np.concatenate((np.cos(half)[:, None], omega * scale[:, None]), axis=1)
    q = quaternion_multiply(quat, delta)
    return q / np.linalg.norm(q, axis=1)[:, None]


def _choose_backend(backend: str | None) -> str:
    """Resolve "numba" | "numpy" | None (= SWARM_SIM_BACKEND, else numba when importable)."""
    requested = backend if backend is not None else os.environ.get(BACKEND_ENV, "").strip().lower() or None
    if requested not in (None, "numba", "numpy"):
        source = "backend" if backend is not None else BACKEND_ENV
        raise ValueError(f"{source} must be 'numba' or 'numpy', not {requested!r}")
    if requested == "numpy":
        return "numpy"
    try:
        import numba  # noqa: F401
    except ImportError:
        if requested == "numba":
            raise ValueError("backend 'numba' requested but numba is not installed") from None
        return "numpy"
    return "numba"


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
