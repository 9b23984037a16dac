"""ArduCopter-like attitude controller for N quadrotors: numpy reference implementation.

Spec 5 leaves the attitude loop open [add]; this follows ArduCopter's AC_AttitudeControl cascade:
quaternion attitude error (thrust-vector tilt first, heading second, no Euler singularity) -> sqrt/P angle
controller -> desired body rates (+ feed-forward), limited -> rate PID -> body torques -> X-quad mixer whose
saturation handling keeps roll/pitch authority first, yaw last, and moves the collective instead.

`sitl_sim.vehicle_model.kernels` holds a fused numba transcription of exactly this arithmetic (the fast
backend); the backend-agreement test keeps the two equal, so change both together.

Quaternions are [w, x, y, z] (Hamilton product) and rotate body FLU vectors into world ENU (spec 1.1).
Every function is vectorised over leading dimensions; shapes below use N for the vehicle count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarm_common.rotations import quaternion_multiply

# X-quad layout in ArduCopter's motor order (AP_MotorsMatrix QUAD X): 1 front-right CCW, 2 rear-left CCW,
# 3 front-left CW, 4 rear-right CW. Signs of each motor's contribution to the body FLU torques: roll = +y arm
# side (left motors raise the left side -> positive roll), pitch = rear motors (nose down = positive pitch,
# spec 1.1), yaw = reaction torque, a CCW propeller turns the body clockwise (negative FLU yaw).
MOTOR_ROLL_SIGN = np.array([-1.0, 1.0, 1.0, -1.0])
MOTOR_PITCH_SIGN = np.array([-1.0, 1.0, -1.0, 1.0])
MOTOR_YAW_SIGN = np.array([-1.0, -1.0, 1.0, 1.0])


# --- quaternion algebra ([w, x, y, z], body FLU -> world ENU) ---------------------------------------------


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse rotation of unit (..., 4) quaternions."""
    return np.asarray(q, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate (..., 3) body vectors v into the world frame by unit quaternions q (..., 4)."""
    q = np.asarray(q, dtype=float)
    v = np.asarray(v, dtype=float)
    u = q[..., 1:]
    t = 2.0 * cross(u, v)
    return v + q[..., :1] * t + cross(u, t)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of (..., 3) vectors (np.cross is slow for small arrays)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx), axis=-1)


def euler_from_quat(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternion -> (..., 3) ZYX Euler angles roll, pitch, yaw (rad, spec 1.1).

    Not swarm_common.rotations.quaternion_to_euler: that one normalises q first, which changes the last bits
    of the truth log's roll/pitch/yaw columns (the state's quaternions are renormalised every step anyway).
    """
    w, x, y, z = _components(q)
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack((roll, pitch, yaw), axis=-1)


def yaw_from_quat(q: np.ndarray) -> np.ndarray:
    """ZYX yaw (rad) of (..., 4) quaternions."""
    w, x, y, z = _components(q)
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _components(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    q = np.asarray(q, dtype=float)
    return q[..., 0], q[..., 1], q[..., 2], q[..., 3]


def level_quat(yaw: np.ndarray) -> np.ndarray:
    """Level attitude with the given yaw (rad), (...) -> (..., 4)."""
    half = 0.5 * np.asarray(yaw, dtype=float)
    zero = np.zeros_like(half)
    return np.stack((np.cos(half), zero, zero, np.sin(half)), axis=-1)


def _swing_twist(q: np.ndarray) -> tuple[np.ndarray, ...]:
    """Split q = swing * twist (twist about body z, swing about a horizontal body axis).

    Returns (cw, cz) the unit twist (w, z) pair, (sx, sy) the swing's x/y components (its z is 0 and its w is
    n = |(w, z)|), n, and h = |(x, y)|; tilt angle = 2 atan2(h, n). At exactly 180 deg of tilt the twist is
    undefined and taken as identity.
    """
    w, x, y, z = _components(q)
    n = np.hypot(w, z)
    degenerate = n < 1e-12
    safe_n = np.where(degenerate, 1.0, n)
    cw = np.where(degenerate, 1.0, w / safe_n)
    cz = np.where(degenerate, 0.0, z / safe_n)
    sx = x * cw - y * cz
    sy = y * cw + x * cz
    return cw, cz, sx, sy, n, np.hypot(x, y)


def limit_tilt(quat_sp: np.ndarray, tilt_max: np.ndarray) -> np.ndarray:
    """Shorten the tilt of target attitudes (N, 4) to at most tilt_max (rad, scalar or (N,)), keeping heading.

    Tilt = angle between the target thrust axis and world up (ArduCopter ANGLE_MAX). The target is split into
    a heading twist about z and a tilt swing about a horizontal axis; only the swing angle is reduced.
    """
    cw, cz, sx, sy, n, h = _swing_twist(quat_sp)
    tilt = 2.0 * np.arctan2(h, n)
    half = 0.5 * np.minimum(tilt, tilt_max)
    safe_h = np.where(h > 0.0, h, 1.0)
    scale = np.sin(half) / safe_h
    swing = np.stack((np.cos(half), sx * scale, sy * scale, np.zeros_like(h)), axis=-1)
    twist = np.stack((cw, np.zeros_like(cw), np.zeros_like(cw), cz), axis=-1)
    limited = quaternion_multiply(swing, twist)
    return np.where((tilt > tilt_max)[..., None], limited, quat_sp)


def attitude_error(quat: np.ndarray, quat_target: np.ndarray) -> np.ndarray:
    """Rotation-vector attitude error (N, 3) in the current body frame, rad.

    x, y: thrust-vector (tilt) correction about a horizontal body axis; z: remaining heading error, wrapped
    to [-pi, pi]. Same split as ArduCopter's thrust_heading_rotation_angles; singularity-free.
    """
    e = quaternion_multiply(quat_conjugate(quat), quat_target)
    cw, cz, sx, sy, n, h = _swing_twist(e)
    tilt = 2.0 * np.arctan2(h, n)
    factor = np.where(h > 1e-12, tilt / np.where(h > 1e-12, h, 1.0), 2.0)
    sign = np.where(cw < 0.0, -1.0, 1.0)
    yaw = 2.0 * np.arctan2(cz * sign, cw * sign)
    return np.stack((sx * factor, sy * factor, yaw), axis=-1)


# --- controller -------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AttitudeGains:
    """Attitude/rate controller gains for the spec's 0.9 kg airframe (Table 2 inertias) [add].

    Angle loop (ArduCopter ATC_ANG_*_P with ATC_ACCEL_*_MAX through the sqrt controller): rad/s per rad and
    rad/s^2. Rate loop in physical units: P in N m per rad/s, I in N m per rad (integral of rate error),
    D in N m per rad/s^2, integrator limit in N m; per axis (roll, pitch, yaw), body FLU. Tuned (at 1 kHz and
    250 Hz) so a 30 deg roll/pitch step reaches 90 % in 0.21 s and a 30 deg yaw step in 0.45 s, both with
    < 1 % overshoot (tests/sitl_sim/vehicle_model/test_attitude_control.py).
    """

    angle_p_rp: float = 9.0
    angle_p_yaw: float = 4.5
    accel_max_rp: float = 60.0  # rad/s^2, below the ~130 rad/s^2 the motors can give around hover
    accel_max_yaw: float = 5.0  # rad/s^2, yaw authority is only ~11 rad/s^2 (k_D/k_T = 0.02 m)
    rate_max_rp: float = 6.0  # rad/s (~340 deg/s)
    rate_max_yaw: float = 2.0  # rad/s (~115 deg/s)
    rate_p: tuple[float, float, float] = (0.25, 0.25, 0.2)
    rate_i: tuple[float, float, float] = (0.05, 0.05, 0.02)
    rate_d: tuple[float, float, float] = (0.002, 0.002, 0.0)
    i_max: tuple[float, float, float] = (0.3, 0.3, 0.1)
    d_filter_hz: float = 20.0  # low-pass on the D term (ATC_RAT_*_FLTD)

    def __post_init__(self) -> None:
        positive = ("angle_p_rp", "angle_p_yaw", "accel_max_rp", "accel_max_yaw", "rate_max_rp")
        for name in (*positive, "rate_max_yaw", "d_filter_hz"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise ValueError(f"attitude gain {name} must be a finite number > 0")
        for name in ("rate_p", "rate_i", "rate_d", "i_max"):
            values = getattr(self, name)
            if len(values) != 3 or not all(math.isfinite(v) and v >= 0 for v in values):
                raise ValueError(f"attitude gain {name} must be three finite numbers >= 0 (roll, pitch, yaw)")

    @property
    def angle_p(self) -> np.ndarray:
        """(3,) angle P per body axis, rad/s per rad."""
        return np.array([self.angle_p_rp, self.angle_p_rp, self.angle_p_yaw])

    @property
    def accel_max(self) -> np.ndarray:
        """(3,) angular-acceleration limit of the angle loop per body axis, rad/s^2."""
        return np.array([self.accel_max_rp, self.accel_max_rp, self.accel_max_yaw])

    @property
    def rate_max(self) -> np.ndarray:
        """(3,) body-rate demand limit per axis, rad/s."""
        return np.array([self.rate_max_rp, self.rate_max_rp, self.rate_max_yaw])

    def d_alpha(self, dt: float) -> float:
        """Smoothing factor of the first-order D-term filter for a step dt (s)."""
        return dt / (dt + 1.0 / (2.0 * math.pi * self.d_filter_hz))


def sqrt_controller(error: np.ndarray, p: np.ndarray, accel_max: np.ndarray) -> np.ndarray:
    """ArduCopter's sqrt_controller: P near zero, constant-deceleration sqrt law beyond accel_max / p^2."""
    linear_dist = accel_max / (p * p)
    magnitude = np.abs(error)
    sqrt_law = np.sqrt(2.0 * accel_max * np.maximum(magnitude - 0.5 * linear_dist, 0.0))
    return np.where(magnitude > linear_dist, np.copysign(sqrt_law, error), p * error)


def angle_rate_demand(
    quat: np.ndarray, quat_target: np.ndarray, rate_ff: np.ndarray, gains: AttitudeGains
) -> np.ndarray:
    """Desired body rates (N, 3) rad/s from the angle loop plus feed-forward, limited to gains.rate_max."""
    error = attitude_error(quat, quat_target)
    rates = sqrt_controller(error, gains.angle_p, gains.accel_max) + rate_ff
    return np.clip(rates, -gains.rate_max, gains.rate_max)


def rate_pid(
    rate_sp: np.ndarray,
    omega: np.ndarray,
    integrator: np.ndarray,
    d_state: np.ndarray,
    prev_error: np.ndarray,
    reset: np.ndarray,
    gains: AttitudeGains,
    dt: float,
) -> np.ndarray:
    """Body torques (N, 3) N m from the rate PID; updates integrator, d_state, prev_error (N, 3) in place.

    reset (N,) bool (landed or motors off): integrator and D term are cleared (ArduCopter resets the rate
    I terms on the ground) so no wind-up carries into the next take-off.
    """
    error = rate_sp - omega
    d_raw = (error - prev_error) / dt
    d_new = d_state + gains.d_alpha(dt) * (d_raw - d_state)
    i_max = np.asarray(gains.i_max)
    i_new = np.clip(integrator + np.asarray(gains.rate_i) * error * dt, -i_max, i_max)
    keep = ~reset[:, None]
    integrator[:] = np.where(keep, i_new, 0.0)
    d_state[:] = np.where(keep, d_new, 0.0)
    prev_error[:] = error
    return np.asarray(gains.rate_p) * error + integrator + np.asarray(gains.rate_d) * d_state


def mix_x_quad(
    collective: np.ndarray, torque: np.ndarray, arm: float, yaw_coef: float, f_max: float
) -> np.ndarray:
    """Per-motor thrust commands (N, 4) N in [0, f_max] for total thrust (N,) N and body torques (N, 3) N m.

    arm: motor distance from the centre (m); yaw_coef = k_D/k_T (m): reaction torque per newton.
    Saturation (like AP_MotorsMatrix::output_armed_stabilizing): roll/pitch are scaled down only if they alone
    exceed the motor range; yaw then gets what range is left (scaled by the largest factor that fits); last,
    the collective is shifted into the remaining band so the torques are produced exactly.
    """
    inv_4d = 1.0 / (4.0 * arm * math.sqrt(0.5))
    rp = (MOTOR_ROLL_SIGN * torque[:, :1] + MOTOR_PITCH_SIGN * torque[:, 1:2]) * inv_4d
    rp_span = rp.max(axis=1) - rp.min(axis=1)
    rp_saturated = rp_span > f_max
    rp = rp * np.where(rp_saturated, f_max / np.where(rp_saturated, rp_span, 1.0), 1.0)[:, None]
    yaw = MOTOR_YAW_SIGN * torque[:, 2:3] * (0.25 / yaw_coef)
    dy = yaw[:, :, None] - yaw[:, None, :]
    drp = rp[:, :, None] - rp[:, None, :]
    rising = dy > 0.0
    limits = np.where(rising, (f_max - drp) / np.where(rising, dy, 1.0), np.inf)
    yaw_scale = np.maximum(np.minimum(limits.min(axis=(1, 2)), 1.0), 0.0)
    yaw_scale = np.where(rp_saturated, 0.0, yaw_scale)
    diff = rp + yaw * yaw_scale[:, None]
    low = -diff.min(axis=1)
    high = f_max - diff.max(axis=1)
    per_motor = np.minimum(np.maximum(0.25 * collective, low), high)
    return np.clip(per_motor[:, None] + diff, 0.0, f_max)
