"""ArduCopter-like attitude controller of one quadrotor, compiled (swarm_common.jit): the one implementation,
which the physics step (sitl_sim.vehicle_model.dynamics.advance) runs at the physics rate.

Spec 5 leaves the attitude loop open [add]; this follows ArduCopter's AC_AttitudeControl cascade:
quaternion attitude error (thrust-vector tilt first, heading second, no Euler singularity) -> sqrt/P angle
controller (swarm_common.shaping.sqrt_controller) -> desired body rates (+ feed-forward), limited ->
rate PID -> body torques -> X-quad mixer whose saturation handling keeps roll/pitch authority first, yaw
last, and moves the collective instead.

Quaternions are [w, x, y, z] (Hamilton product) and rotate body FLU vectors into world ENU (spec 1.1); the
kernels take and return their components as scalars. The numpy helpers at the top (Euler angles, level
attitudes) are vectorised over leading dimensions, N the vehicle count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from swarm_common.jit import kernel

# X-quad layout in ArduCopter's motor order (AP_MotorsMatrix QUAD X): 1 front-right CCW, 2 rear-left CCW,
# 3 front-left CW, 4 rear-right CW. Signs of each motor's contribution to the body FLU torques: roll = +y arm
# side (left motors raise the left side -> positive roll), pitch = rear motors (nose down = positive pitch,
# spec 1.1), yaw = reaction torque, a CCW propeller turns the body clockwise (negative FLU yaw).
MOTOR_ROLL_SIGN = np.array([-1.0, 1.0, 1.0, -1.0])
MOTOR_PITCH_SIGN = np.array([-1.0, 1.0, -1.0, 1.0])
MOTOR_YAW_SIGN = np.array([-1.0, -1.0, 1.0, 1.0])


# --- Euler angles and level attitudes (numpy, [w, x, y, z], body FLU -> world ENU) --------------------------


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


# --- controller -------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AttitudeGains:
    """Attitude/rate controller gains for the spec's 0.9 kg airframe (Table 2 inertias) [add].

    Angle loop (ArduCopter ATC_ANG_*_P with ATC_ACCEL_*_MAX through the sqrt controller): rad/s per rad and
    rad/s^2. Rate loop in physical units: P in N m per rad/s, I in N m per rad (integral of rate error),
    D in N m per rad/s^2, integrator limit in N m; per axis (roll, pitch, yaw), body FLU. Tuned at 1 kHz and
    250 Hz for quick, well-damped roll/pitch and yaw steps (tests/sitl_sim/vehicle_model/
    test_attitude_control.py states the bounds).
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

    def for_step(self, dt: float) -> StepGains:
        """The gains as the kernels take them for a physics step of dt s (per-axis triples as floats)."""
        return StepGains(
            angle_p=_triple((self.angle_p_rp, self.angle_p_rp, self.angle_p_yaw)),
            accel_max=_triple((self.accel_max_rp, self.accel_max_rp, self.accel_max_yaw)),
            rate_max=_triple((self.rate_max_rp, self.rate_max_rp, self.rate_max_yaw)),
            rate_p=_triple(self.rate_p),
            rate_i=_triple(self.rate_i),
            rate_d=_triple(self.rate_d),
            i_max=_triple(self.i_max),
            d_alpha=dt / (dt + 1.0 / (2.0 * math.pi * self.d_filter_hz)),
        )


class StepGains(NamedTuple):
    """AttitudeGains for one physics step, as the compiled kernels take them (AttitudeGains.for_step).

    Each triple is per body FLU axis (roll, pitch, yaw), indexed by the axis k in the kernels."""

    angle_p: tuple[float, float, float]  # angle loop P, rad/s per rad
    accel_max: tuple[float, float, float]  # angle loop acceleration limit, rad/s^2
    rate_max: tuple[float, float, float]  # body-rate demand limit, rad/s
    rate_p: tuple[float, float, float]  # rate PID P, N m per rad/s
    rate_i: tuple[float, float, float]  # rate PID I, N m per rad
    rate_d: tuple[float, float, float]  # rate PID D, N m per rad/s^2
    i_max: tuple[float, float, float]  # integrator limit, N m
    d_alpha: float  # smoothing factor of the first-order D-term filter for the step


def _triple(values: tuple[float, ...]) -> tuple[float, float, float]:
    return float(values[0]), float(values[1]), float(values[2])


@kernel
def attitude_error(
    qw: float, qx: float, qy: float, qz: float, tw: float, tx: float, ty: float, tz: float
) -> tuple[float, float, float]:
    """Rotation-vector error (rad, current body frame) from attitude q to target t, both unit quaternions.

    x, y: thrust-vector (tilt) correction about a horizontal body axis; z: the remaining heading error,
    wrapped to [-pi, pi]. The split of ArduCopter's thrust_heading_rotation_angles: e = conj(q) * t =
    swing * twist (twist about body z), singularity-free; at exactly 180 deg of tilt the twist is identity.
    """
    ew = qw * tw + qx * tx + qy * ty + qz * tz  # conj(q) * t
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
    return sx * factor, sy * factor, 2.0 * math.atan2(cz * sign, cw * sign)


@kernel
def limit_tilt(w: float, x: float, y: float, z: float, tilt_max: float) -> tuple[float, float, float, float]:
    """Unit target attitude (w, x, y, z) with its tilt shortened to at most tilt_max rad, heading kept.

    Tilt = angle between the target thrust axis and world up (ArduCopter ANGLE_MAX). The target is split into
    a heading twist about z and a tilt swing about a horizontal axis; only the swing angle is reduced.
    """
    n = math.hypot(w, z)
    if n < 1e-12:
        cw, cz = 1.0, 0.0
    else:
        cw, cz = w / n, z / n
    h = math.hypot(x, y)
    tilt = 2.0 * math.atan2(h, n)
    if tilt <= tilt_max:
        return w, x, y, z
    half = 0.5 * tilt_max
    scale = math.sin(half) / (h if h > 0.0 else 1.0)
    sx, sy, sw = (x * cw - y * cz) * scale, (y * cw + x * cz) * scale, math.cos(half)
    return sw * cw, sx * cw + sy * cz, sy * cw - sx * cz, sw * cz


@kernel
def rate_pid_axis(
    error: float,
    prev_error: float,
    integrator: float,
    d_state: float,
    gains: StepGains,
    k: int,
    reset: bool,
    dt: float,
) -> tuple[float, float, float]:
    """One body axis k (0 roll, 1 pitch, 2 yaw) of the rate PID: (torque N m, new integrator, new D state).

    error, prev_error: rate error now and one step dt (s) earlier, rad/s; gains: AttitudeGains.for_step. reset
    (landed or motors off): integrator and D term cleared (ArduCopter resets the rate I terms on the ground),
    so no wind-up carries into the next take-off.
    """
    if reset:
        integrator = 0.0
        d_state = 0.0
    else:
        d_state = d_state + gains.d_alpha * ((error - prev_error) / dt - d_state)
        i_max = gains.i_max[k]
        integrator = min(max(integrator + gains.rate_i[k] * error * dt, -i_max), i_max)
    return gains.rate_p[k] * error + integrator + gains.rate_d[k] * d_state, integrator, d_state


@kernel
def mix_x_quad(
    torque_x: float,
    torque_y: float,
    torque_z: float,
    collective: float,
    inv_4d: float,
    yaw_coef: float,
    f_max: float,
    rp: np.ndarray,
    yaw: np.ndarray,
    f_cmd: np.ndarray,
) -> None:
    """Per-motor thrust commands f_cmd (4,) N in [0, f_max] for the total thrust `collective` N and body FLU
    torques (N m); inv_4d = 1 / (4 arm / sqrt(2)), yaw_coef = k_D/k_T (m); rp, yaw: (4,) scratch.

    Saturation (like AP_MotorsMatrix::output_armed_stabilizing): roll/pitch are scaled down only if they alone
    exceed the motor range; yaw then gets what range is left (scaled by the largest factor that fits); last,
    the collective is shifted into the remaining band so the torques are produced exactly.
    """
    rp_hi, rp_lo = -np.inf, np.inf
    for j in range(4):
        rp[j] = (MOTOR_ROLL_SIGN[j] * torque_x + MOTOR_PITCH_SIGN[j] * torque_y) * inv_4d
        rp_hi, rp_lo = max(rp_hi, rp[j]), min(rp_lo, rp[j])
    rp_span = rp_hi - rp_lo
    yaw_scale = 1.0
    if rp_span > f_max:
        for j in range(4):
            rp[j] = rp[j] * (f_max / rp_span)
        yaw_scale = 0.0
    for j in range(4):
        yaw[j] = MOTOR_YAW_SIGN[j] * torque_z * (0.25 / yaw_coef)
    if yaw_scale > 0.0:
        for a in range(4):
            for b in range(4):
                dy = yaw[a] - yaw[b]
                if dy > 0.0:
                    yaw_scale = min(yaw_scale, (f_max - (rp[a] - rp[b])) / dy)
        yaw_scale = max(yaw_scale, 0.0)
    d_hi, d_lo = -np.inf, np.inf
    for j in range(4):
        f_cmd[j] = rp[j] + yaw[j] * yaw_scale  # the differential part first
        d_hi, d_lo = max(d_hi, f_cmd[j]), min(d_lo, f_cmd[j])
    per_motor = min(max(0.25 * collective, -d_lo), f_max - d_hi)
    for j in range(4):
        f_cmd[j] = min(max(per_motor + f_cmd[j], 0.0), f_max)
