"""Attitude controller: quaternion errors, tilt limit, mixer saturation, closed-loop step responses.

The controller's kernels take one vehicle's scalars; the helpers below apply them row by row and hold the
independent references (rotation matrices from quaternions, the X-quad wrench of four motor thrusts)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.vehicle_model.airframe import QuadParams
from sitl_sim.vehicle_model.attitude_control import (
    MOTOR_PITCH_SIGN,
    MOTOR_ROLL_SIGN,
    MOTOR_YAW_SIGN,
    AttitudeGains,
    mix_x_quad,
    rate_pid_axis,
)
from sitl_sim.vehicle_model.attitude_control import attitude_error as attitude_error_kernel
from sitl_sim.vehicle_model.attitude_control import limit_tilt as limit_tilt_kernel
from sitl_sim.vehicle_model.dynamics import FleetDynamics, FleetState
from swarm_common.rotations import euler_to_quaternion, quaternion_multiply

P = QuadParams()
HOVER = P.mass * P.g


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4) [w, x, y, z] through the rotation matrix."""
    q = np.asarray(q, dtype=float)[..., None, :]
    q, v = np.broadcast_arrays(q, np.asarray(v, dtype=float)[..., None])
    w, x, y, z = q[..., 0, 0], q[..., 0, 1], q[..., 0, 2], q[..., 0, 3]
    vx, vy, vz = v[..., 0, 0], v[..., 1, 0], v[..., 2, 0]
    return np.stack(
        (
            (1 - 2 * (y * y + z * z)) * vx + 2 * (x * y - w * z) * vy + 2 * (x * z + w * y) * vz,
            2 * (x * y + w * z) * vx + (1 - 2 * (x * x + z * z)) * vy + 2 * (y * z - w * x) * vz,
            2 * (x * z - w * y) * vx + 2 * (y * z + w * x) * vy + (1 - 2 * (x * x + y * y)) * vz,
        ),
        axis=-1,
    )


def attitude_error(quat: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The kernel over rows: (N, 4), (N, 4) -> (N, 3)."""
    quat, target = np.broadcast_arrays(np.atleast_2d(quat), np.atleast_2d(target))
    return np.array([attitude_error_kernel(*q, *t) for q, t in zip(quat, target, strict=True)])


def limit_tilt(target: np.ndarray, tilt_max: float | np.ndarray) -> np.ndarray:
    """The kernel over rows: (N, 4), tilt_max scalar or (N,) -> (N, 4)."""
    tilt = np.broadcast_to(tilt_max, (len(target),))
    return np.array(
        [limit_tilt_kernel(w, x, y, z, float(t)) for (w, x, y, z), t in zip(target, tilt, strict=True)]
    )


def motor_wrench(motor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total thrust (N,) N and body FLU torques (N,3) N m of motor thrusts (N,4): X quad, ArduCopter order,
    roll/pitch arm = arm / sqrt(2), yaw reaction torque = (k_D/k_T) f per motor."""
    arm_xy = P.arm * math.sqrt(0.5)
    torque = np.stack(
        (
            (motor * MOTOR_ROLL_SIGN).sum(axis=1) * arm_xy,
            (motor * MOTOR_PITCH_SIGN).sum(axis=1) * arm_xy,
            (motor * MOTOR_YAW_SIGN).sum(axis=1) * P.yaw_coef,
        ),
        axis=1,
    )
    return motor.sum(axis=1), torque


def tilt_of(q: np.ndarray) -> np.ndarray:
    return np.arccos(np.clip(quat_rotate(q, np.array([0.0, 0.0, 1.0]))[..., 2], -1.0, 1.0))


# --- quaternion error and tilt limit ------------------------------------------------------------------------


def test_attitude_error_axes_and_wrapping():
    level = euler_to_quaternion([0.0, 0.0, 0.0])[None]
    assert np.allclose(attitude_error(level, level), 0.0)
    assert np.allclose(attitude_error(level, euler_to_quaternion([0.3, 0.0, 0.0])[None]), [[0.3, 0.0, 0.0]])
    assert np.allclose(attitude_error(level, euler_to_quaternion([0.0, -0.4, 0.0])[None]), [[0.0, -0.4, 0.0]])
    # heading error takes the short way round: from -170 deg to +170 deg is -20 deg
    current = euler_to_quaternion([0.0, 0.0, math.radians(-170)])[None]
    target = euler_to_quaternion([0.0, 0.0, math.radians(170)])[None]
    assert np.allclose(attitude_error(current, target), [[0.0, 0.0, math.radians(-20)]])
    # q and -q are the same attitude
    assert np.allclose(attitude_error(-current, target), attitude_error(current, -target))


def test_attitude_error_is_in_the_body_frame_and_singularity_free():
    rng = np.random.default_rng(2)
    q = rng.normal(size=(500, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    target = rng.normal(size=(500, 4))
    target /= np.linalg.norm(target, axis=1)[:, None]
    target[0] = quaternion_multiply(q[0], [0.0, 1.0, 0.0, 0.0])  # exactly upside down relative to q[0]
    target[1] = q[1]
    err = attitude_error(q, target)
    assert np.all(np.isfinite(err))
    assert np.allclose(err[1], 0.0)
    assert np.linalg.norm(err[0, :2]) == pytest.approx(math.pi)
    # rotating the body about its tilt error axis by the tilt angle aligns the thrust axes
    axis_angle = err[2:, :2]
    angle = np.linalg.norm(axis_angle, axis=1)
    half = 0.5 * angle
    xy = axis_angle * (np.sin(half) / angle)[:, None]
    rotation = np.column_stack((np.cos(half), xy, np.zeros(len(half))))
    corrected = quaternion_multiply(q[2:], rotation)
    up = np.array([0.0, 0.0, 1.0])
    assert np.allclose(quat_rotate(corrected, up), quat_rotate(target[2:], up), atol=1e-9)


def test_limit_tilt_caps_tilt_and_keeps_heading():
    rng = np.random.default_rng(3)
    roll, pitch, yaw = rng.uniform(-1.2, 1.2, 300), rng.uniform(-1.2, 1.2, 300), rng.uniform(-3, 3, 300)
    target = euler_to_quaternion(np.stack((roll, pitch, yaw), axis=-1))
    tilt_max = 0.5
    limited = limit_tilt(target, tilt_max)
    assert np.all(tilt_of(limited) <= tilt_max + 1e-12)
    inside = tilt_of(target) <= tilt_max
    assert inside.any() and not inside.all()
    assert np.allclose(limited[inside], target[inside])
    # same thrust azimuth and same heading (the remaining error after re-tilting is zero yaw)
    up = np.array([0.0, 0.0, 1.0])
    azimuth_in = np.arctan2(*quat_rotate(target, up)[:, 1::-1].T)
    azimuth_out = np.arctan2(*quat_rotate(limited, up)[:, 1::-1].T)
    assert np.allclose(np.remainder(azimuth_in - azimuth_out + math.pi, 2 * math.pi), math.pi)
    assert np.allclose(attitude_error(limited, target)[:, 2], 0.0, atol=1e-9)
    assert np.allclose(limit_tilt(target, np.full(300, math.pi)), target)


def test_gains_validation():
    with pytest.raises(ValueError, match="angle_p_rp"):
        AttitudeGains(angle_p_rp=0.0)
    with pytest.raises(ValueError, match="rate_p"):
        AttitudeGains(rate_p=(0.1, 0.1))
    with pytest.raises(ValueError, match="i_max"):
        AttitudeGains(i_max=(0.1, -0.1, 0.1))


def test_rate_pid_integrates_clamps_and_resets():
    gains = AttitudeGains()
    step_gains = gains.for_step(1e-3)
    for k in range(3):
        integ = d_state = 0.0
        for _ in range(100):  # a constant error of 1 rad/s for 0.1 s
            torque, integ, d_state = rate_pid_axis(1.0, 1.0, integ, d_state, step_gains, k, False, 1e-3)
        assert integ == pytest.approx(min(gains.rate_i[k] * 0.1, gains.i_max[k]))
        assert d_state == 0.0  # a constant error has no derivative
        assert torque == pytest.approx(gains.rate_p[k] * 1.0 + integ)
        big = rate_pid_axis(1e6, 1e6, integ, 0.0, step_gains, k, False, 1e-3)[1]
        assert big == gains.i_max[k] or gains.rate_i[k] == 0.0  # the integrator is clamped
        assert rate_pid_axis(1.0, 0.0, integ, 5.0, step_gains, k, True, 1e-3) == (gains.rate_p[k], 0.0, 0.0)


# --- mixer -----------------------------------------------------------------------------------------------


def mix(collective: float, torque: np.ndarray) -> np.ndarray:
    """Motor thrusts (1, 4) of the mixer kernel for one collective N and torques (1, 3) N m."""
    f_cmd = np.empty(4)
    inv_4d = 1.0 / (4.0 * P.arm * math.sqrt(0.5))
    tx, ty, tz = np.ravel(torque)
    mix_x_quad(tx, ty, tz, collective, inv_4d, P.yaw_coef, P.f_max, np.empty(4), np.empty(4), f_cmd)
    return f_cmd[None]


def test_mixer_reproduces_unsaturated_wrench():
    torque = np.array([[0.2, -0.1, 0.03]])
    f = mix(HOVER, torque)
    thrust, produced = motor_wrench(f)
    assert thrust[0] == pytest.approx(HOVER)
    assert np.allclose(produced, torque)


def test_mixer_keeps_roll_pitch_at_full_collective_and_yaw_last():
    torque = np.array([[0.5, 0.3, 0.3]])  # yaw beyond the range left at this roll/pitch demand
    f = mix(P.thrust_max, torque)
    assert np.all((f >= 0) & (f <= P.f_max))
    thrust, produced = motor_wrench(f)
    assert np.allclose(produced[0, :2], torque[0, :2])  # roll and pitch exactly
    assert 0.0 < produced[0, 2] < torque[0, 2]  # yaw reduced, same sign
    assert thrust[0] < P.thrust_max  # collective gave way


def test_mixer_scales_excessive_roll_pitch_keeping_direction():
    torque = np.array([[5.0, 2.5, 0.1]])
    thrust, produced = motor_wrench(mix(HOVER, torque))
    assert produced[0, 0] / produced[0, 1] == pytest.approx(2.0)
    # the motor pair spread is exactly f_max: roll = arm_xy * (7.5 + 7.5 + 2.5 + 2.5) / 15 * f_max
    assert produced[0, 0] == pytest.approx(4 / 3 * P.f_max * P.arm * math.sqrt(0.5))
    assert thrust[0] == pytest.approx(2 * P.f_max)  # the only collective left once the spread uses 0..f_max
    assert produced[0, 2] == pytest.approx(0.0)


def test_mixer_raises_low_collective_for_attitude_authority():
    torque = np.array([[0.2, 0.0, 0.0]])
    f = mix(0.0, torque)
    assert np.all(f >= 0)
    assert np.allclose(motor_wrench(f)[1], torque)


# --- closed loop -----------------------------------------------------------------------------------------


def hovering(n: int, rate_hz: float = 1000.0) -> FleetDynamics:
    pos = np.column_stack((np.arange(n) * 5.0, np.zeros(n), np.full(n, 50.0)))
    return FleetDynamics(n, rate_hz=rate_hz, state=FleetState.at_rest(pos, np.zeros(n)))


def step_response(angles, rate_hz=1000.0, thrust=HOVER, seconds=2.0, tilt_max=0.8):
    """Euler angles (deg) of one hovering vehicle after a step to `angles` (roll, pitch, yaw in deg)."""
    dyn = hovering(1, rate_hz)
    target = euler_to_quaternion(np.radians(angles))[None]
    dyn.set_targets(target, np.zeros((1, 3)), np.array([thrust]), np.array([True]), tilt_max)
    samples = int(seconds * rate_hz)
    out = np.empty((samples, 3))
    for k in range(samples):
        dyn.step(np.zeros((1, 3)))
        out[k] = np.degrees(dyn.state.euler()[0])
    return np.arange(1, samples + 1) / rate_hz, out


def rise_overshoot_settle(t, y, final):
    rise = t[np.argmax(y >= 0.9 * final)] if np.any(y >= 0.9 * final) else math.inf
    overshoot = (y.max() - final) / final
    tail = y[t > t[-1] - 0.5]
    return rise, overshoot, np.max(np.abs(tail - final))


@pytest.mark.parametrize("rate_hz", [1000.0, 250.0])
@pytest.mark.parametrize("axis", [0, 1])
def test_thirty_degree_roll_pitch_step(axis, rate_hz):
    angles = [0.0, 0.0, 0.0]
    angles[axis] = 30.0
    t, y = step_response(angles, rate_hz)
    rise, overshoot, settle_error = rise_overshoot_settle(t, y[:, axis], 30.0)
    assert rise <= 0.35
    assert overshoot < 0.15
    assert settle_error < 0.3  # degrees, settled: no sustained oscillation
    assert np.max(np.abs(y[:, 2])) < 1.0  # no yaw coupling


@pytest.mark.parametrize("yaw_deg", [30.0, 90.0])
def test_yaw_step(yaw_deg):
    t, y = step_response([0.0, 0.0, yaw_deg], seconds=3.0)
    rise, overshoot, settle_error = rise_overshoot_settle(t, y[:, 2], yaw_deg)
    assert rise <= 1.0
    assert overshoot < 0.15
    assert settle_error < 0.3
    assert np.max(np.abs(y[:, :2])) < 1.0


def test_saturated_collective_still_rolls():
    t, y = step_response([30.0, 0.0, 40.0], thrust=P.thrust_max, seconds=1.5)
    rise, overshoot, settle_error = rise_overshoot_settle(t, y[:, 0], 30.0)
    assert rise <= 0.35 and overshoot < 0.15 and settle_error < 0.5


def test_tilt_limit_argument_caps_the_target():
    t, y = step_response([60.0, 0.0, 0.0], tilt_max=math.radians(30), seconds=1.0)
    assert y[-1, 0] == pytest.approx(30.0, abs=0.3)
    assert y[:, 0].max() < 33.0


def test_rate_only_mode_tracks_body_rates_then_returns_to_attitude():
    dyn = hovering(2)
    rates = np.array([[0.0, 0.0, 1.5], [0.8, 0.0, 0.0]])
    dyn.set_rate_targets(np.array([True, False]), rates)
    dyn.step(np.zeros((2, 3)), 500)
    assert dyn.state.omega[0] == pytest.approx(rates[0], abs=0.02)
    assert np.linalg.norm(dyn.state.omega[1]) < 1e-6  # unmasked vehicle keeps holding its attitude
    dyn.set_rate_targets(np.array([False, True]), rates)
    dyn.step(np.zeros((2, 3)), 300)
    assert dyn.state.omega[1] == pytest.approx(rates[1], abs=0.02)
    dyn.step(np.zeros((2, 3)), 1500)
    assert np.linalg.norm(dyn.state.omega[0]) < 0.01  # back on the angle loop, holding the last target


def test_integrator_reset_while_motors_off():
    dyn = hovering(1)
    roll_03 = euler_to_quaternion([0.3, 0.0, 0.0])[None]
    dyn.set_targets(roll_03, np.zeros((1, 3)), np.array([HOVER]), [True], 1.0)
    dyn.step(np.zeros((1, 3)), 50)
    assert np.any(dyn._integrator != 0.0)
    dyn.set_targets(roll_03, np.zeros((1, 3)), np.array([HOVER]), [False], 1.0)
    dyn.step(np.zeros((1, 3)), 1)
    assert np.all(dyn._integrator == 0.0)


def test_shared_rotations_keep_the_simulator_conventions():
    """swarm_common.rotations replaced the simulator's own Euler->quaternion and Hamilton product: check them
    against the spec 1.1 conventions written out independently, R = Rz(yaw) Ry(pitch) Rx(roll) rotating body
    FLU into world ENU, and `p * q` = rotate by q first, then by p."""
    rng = np.random.default_rng(11)
    angles = rng.uniform([-3.0, -1.5, -3.0], [3.0, 1.5, 3.0], (50, 3))

    def rx(a: float) -> np.ndarray:
        return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])

    def ry(a: float) -> np.ndarray:
        return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])

    def rz(a: float) -> np.ndarray:
        return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])

    quats = euler_to_quaternion(angles)
    vectors = rng.normal(size=(50, 3))
    for (roll, pitch, yaw), q, v in zip(angles, quats, vectors, strict=True):
        assert np.allclose(quat_rotate(q, v), rz(yaw) @ ry(pitch) @ rx(roll) @ v, atol=1e-12)
    p, q = quats[:25], quats[25:]
    composed = quat_rotate(quaternion_multiply(p, q), vectors[:25])
    assert np.allclose(composed, quat_rotate(p, quat_rotate(q, vectors[:25])), atol=1e-12)
