"""Rigid body, motors, drag, wind and ground contact of sitl_sim.vehicle_model.dynamics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.vehicle_model.airframe import QuadParams
from sitl_sim.vehicle_model.attitude_control import euler_from_quat
from sitl_sim.vehicle_model.dynamics import FleetDynamics, FleetState
from sitl_sim.vehicle_model.wind import Wind
from swarm_common.rotations import euler_to_quaternion
from tests.sitl_sim.vehicle_model.test_attitude_control import quat_rotate

P = QuadParams()
HOVER = P.mass * P.g


def make(n: int, z: float = 10.0, yaw: float | np.ndarray = 0.0, **kw) -> FleetDynamics:
    pos = np.zeros((n, 3))
    pos[:, 2] = z
    state = FleetState.at_rest(pos, np.broadcast_to(yaw, (n,)))
    return FleetDynamics(n, state=state, **kw)


def attitude_targets(dyn: FleetDynamics, roll=0.0, pitch=0.0, yaw=0.0, thrust=HOVER, on=True, tilt=1.5):
    n = dyn.n
    quat = euler_to_quaternion(np.stack([np.broadcast_to(a, (n,)) for a in (roll, pitch, yaw)], axis=-1))
    dyn.set_targets(quat, np.zeros((n, 3)), np.broadcast_to(thrust, (n,)), np.full(n, on), tilt)


def still(n: int) -> np.ndarray:
    return np.zeros((n, 3))


# --- parameters, conventions, construction -----------------------------------------------------------------


def test_params_derived_values():
    assert P.f_max == pytest.approx(2.5 * 0.9 * 9.8 / 4)
    assert P.thrust_max == pytest.approx(4 * P.f_max)
    assert P.hover_fraction == pytest.approx(0.4)
    assert P.yaw_coef == pytest.approx(0.02)
    with pytest.raises(ValueError, match="mass"):
        QuadParams(mass=0.0)
    with pytest.raises(ValueError, match="thrust_to_weight"):
        QuadParams(thrust_to_weight=0.9)


def test_euler_round_trip_and_spec_convention():
    rng = np.random.default_rng(1)
    angles = rng.uniform([-3, -1.5, -3], [3, 1.5, 3], size=(200, 3))
    q = euler_to_quaternion(angles)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.allclose(euler_from_quat(q), angles, atol=1e-9)
    # spec 1.1: R = Rz(psi) Ry(theta) Rx(phi)
    phi, theta, psi = angles[0]
    rx = np.array([[1, 0, 0], [0, math.cos(phi), -math.sin(phi)], [0, math.sin(phi), math.cos(phi)]])
    ry = np.array([[math.cos(theta), 0, math.sin(theta)], [0, 1, 0], [-math.sin(theta), 0, math.cos(theta)]])
    rz = np.array([[math.cos(psi), -math.sin(psi), 0], [math.sin(psi), math.cos(psi), 0], [0, 0, 1]])
    assert np.allclose(quat_rotate(q[0], np.eye(3)), (rz @ ry @ rx).T)
    # theta > 0 tilts thrust toward +x_B, phi > 0 toward -y_B
    assert quat_rotate(euler_to_quaternion([0.0, 0.3, 0.0]), [0, 0, 1])[0] > 0.2
    assert quat_rotate(euler_to_quaternion([0.3, 0.0, 0.0]), [0, 0, 1])[1] < -0.2


def test_at_rest_landed_and_airborne():
    pos = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 5.0], [2.0, 0.0, -1.0], [3.0, 0.0, 0.0]])
    vel = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [1.0, 0, 0]])
    s = FleetState.at_rest(pos, np.array([0.0, 1.0, 2.0, 3.0]), vel)
    assert s.landed.tolist() == [True, False, True, False]
    assert s.pos[2, 2] == 0.0  # clamped to the ground
    assert np.allclose(s.motor[1], HOVER / 4) and np.all(s.motor[0] == 0.0)
    assert np.allclose(s.euler()[:, 2], [0.0, 1.0, 2.0, 3.0])
    assert s.world_accel.shape == (4, 3)


def test_bad_construction_and_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="vehicle count"):
        FleetDynamics(0)
    with pytest.raises(ValueError, match="rate_hz"):
        FleetDynamics(1, rate_hz=0.0)
    dyn = make(2)
    with pytest.raises(ValueError, match="quat_sp"):
        dyn.set_targets(np.zeros((3, 4)), still(2), np.zeros(2), np.ones(2, bool), 0.5)
    with pytest.raises(ValueError, match="wind"):
        dyn.step(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="nsteps"):
        dyn.step(still(2), -1)


# --- free flight -------------------------------------------------------------------------------------------


def test_hover_at_hover_thrust_stays_put():
    dyn = make(3, yaw=np.array([0.0, 1.0, -2.5]))
    start = dyn.state.pos.copy()
    attitude_targets(dyn, yaw=np.array([0.0, 1.0, -2.5]))
    dyn.step(still(3), 5000)
    assert np.max(np.linalg.norm(dyn.state.pos - start, axis=1)) < 0.01
    assert not dyn.state.landed.any()


def test_free_fall_with_motors_off_accelerates_at_g():
    dyn = make(1, z=100.0, params=QuadParams(drag_lin=0.0))
    attitude_targets(dyn, thrust=0.0, on=False)
    t = 1.0
    dyn.step(still(1), 1000)
    # the hover thrust of the start decays with motor_tau: its impulse is m g tau (1 - exp(-t/tau))
    tau = P.motor_tau
    assert dyn.state.vel[0, 2] == pytest.approx(-P.g * t + P.g * tau * (1 - math.exp(-t / tau)), abs=0.01)
    assert dyn.state.world_accel[0] == pytest.approx([0.0, 0.0, -P.g], abs=1e-6)
    assert np.all(dyn.state.motor == pytest.approx(0.0, abs=1e-12))


def test_free_fall_with_linear_drag_follows_the_analytic_solution():
    dyn = make(1, z=100.0)
    attitude_targets(dyn, thrust=0.0, on=False)
    dyn.step(still(1), 200)  # 0.2 s = 10 motor time constants: the motors are off
    k = P.drag_lin / P.mass  # v' = -g - k v
    v0, z0, t = dyn.state.vel[0, 2], dyn.state.pos[0, 2], 2.0
    assert dyn.state.world_accel[0, 2] == pytest.approx(-P.g - k * v0, abs=0.01)
    dyn.step(still(1), 2000)
    v_expected = -P.g / k + (v0 + P.g / k) * math.exp(-k * t)
    z_expected = z0 - P.g / k * t + (v0 + P.g / k) * (1 - math.exp(-k * t)) / k
    assert dyn.state.vel[0, 2] == pytest.approx(v_expected, abs=0.01)
    assert dyn.state.pos[0, 2] == pytest.approx(z_expected, abs=0.02)


def test_level_target_with_thrust_above_weight_climbs():
    dyn = make(1)
    attitude_targets(dyn, thrust=1.2 * HOVER)
    dyn.step(still(1), 1000)
    assert dyn.state.pos[0, 2] > 10.0 + 0.5 * 0.2 * P.g * 0.8
    assert np.linalg.norm(dyn.state.pos[0, :2]) < 0.01


@pytest.mark.parametrize("yaw, direction", [(0.0, [1.0, 0.0]), (math.pi / 2, [0.0, 1.0])])
def test_positive_pitch_accelerates_along_body_x(yaw, direction):
    dyn = make(1, yaw=yaw)
    pitch = math.radians(15)
    attitude_targets(dyn, pitch=pitch, yaw=yaw, thrust=HOVER / math.cos(pitch))
    dyn.step(still(1), 1500)
    v_xy = dyn.state.vel[0, :2]
    assert np.dot(v_xy, direction) > 2.0
    assert abs(v_xy[0] * direction[1] - v_xy[1] * direction[0]) < 0.05 * np.linalg.norm(v_xy)
    assert abs(dyn.state.pos[0, 2] - 10.0) < 0.3


def test_terminal_speed_matches_drag_balance():
    tilt = math.radians(20)
    dyn = make(1, z=50.0)
    attitude_targets(dyn, pitch=tilt, thrust=HOVER / math.cos(tilt))
    dyn.step(still(1), 40_000)  # 40 s = 11 drag time constants m / drag_lin
    expected = HOVER * math.tan(tilt) / P.drag_lin  # T sin(tilt) = drag_lin v with T cos(tilt) = m g
    assert dyn.state.vel[0, 0] == pytest.approx(expected, rel=0.01)
    assert abs(dyn.state.vel[0, 2]) < 0.01
    # the [add] default reaches the spec's 20 m/s cruise at the default 30 deg tilt limit
    assert HOVER * math.tan(math.radians(30)) / P.drag_lin > 20.0


def test_wind_pushes_a_hovering_vehicle_downwind():
    wind = Wind(1, seed=0, speed=5.0, direction_deg=0.0)  # from the North
    dyn = make(1)
    attitude_targets(dyn)
    for _ in range(100):
        dyn.step(wind.sample(0.1), 100)
    t_drag = P.mass / P.drag_lin
    assert dyn.state.vel[0, 1] == pytest.approx(-5.0 * (1 - math.exp(-10.0 / t_drag)), abs=0.05)
    assert dyn.state.pos[0, 1] < -20.0
    assert abs(dyn.state.pos[0, 0]) < 0.01


def test_body_rates_integrate_the_quaternion():
    dyn = make(1, z=1000.0)
    dyn.set_rate_targets(np.array([True]), np.array([[0.0, 0.0, 1.0]]))
    dyn.step(still(1), 2000)
    # after the yaw rate has settled, attitude advances by omega * t around body z
    yaw0 = dyn.state.euler()[0, 2]
    omega = dyn.state.omega[0, 2]
    dyn.step(still(1), 500)
    assert omega == pytest.approx(1.0, abs=0.01)
    turned = math.remainder(dyn.state.euler()[0, 2] - yaw0 - 0.5 * omega, 2 * math.pi)
    assert turned == pytest.approx(0.0, abs=0.01)
    assert np.linalg.norm(dyn.state.quat[0]) == pytest.approx(1.0, abs=1e-12)


def test_torque_free_spin_conserves_world_angular_momentum():
    """Gyroscopic term: with motors off and no rotational drag, R I w is constant while w nutates."""
    dyn = make(1, z=1000.0, params=QuadParams(drag_rot=0.0))
    dyn.state.crashed[0] = True  # motors off
    dyn.state.omega[0] = [2.0, 0.0, 6.0]
    inertia = np.array([P.ixx, P.iyy, P.izz])

    def momentum():
        return quat_rotate(dyn.state.quat[0], inertia * dyn.state.omega[0])

    start = momentum()
    dyn.step(still(1), 1000)
    assert abs(dyn.state.omega[0, 1]) > 0.5  # the body rates did nutate
    assert np.allclose(momentum(), start, atol=2e-3 * np.linalg.norm(start))


# --- ground contact and crashes ---------------------------------------------------------------------------


def test_ground_contact_cannot_sink_then_lands_level_keeping_yaw():
    dyn = make(1, z=3.0, yaw=0.7)
    attitude_targets(dyn, roll=0.2, yaw=0.7, thrust=0.5 * HOVER)
    lowest = math.inf
    for _ in range(300):
        dyn.step(still(1), 10)
        lowest = min(lowest, dyn.state.pos[0, 2])
        if dyn.state.landed[0]:
            break
    s = dyn.state
    assert lowest >= 0.0
    assert s.landed[0] and s.pos[0, 2] == 0.0
    assert np.all(s.vel[0] == 0.0) and np.all(s.omega[0] == 0.0)
    roll, pitch, yaw = s.euler()[0]
    assert roll == pytest.approx(0.0, abs=1e-12) and pitch == pytest.approx(0.0, abs=1e-12)
    assert yaw == pytest.approx(0.7, abs=0.05)
    x_landed = s.pos[0].copy()
    dyn.step(np.array([[8.0, 0.0, 0.0]]), 1000)  # still below weight, in wind: stays put
    assert s.landed[0] and np.all(s.pos[0] == x_landed)


def test_lift_off_when_thrust_exceeds_weight():
    dyn = make(1, z=0.0)
    assert dyn.state.landed[0]
    attitude_targets(dyn, thrust=0.95 * HOVER)
    dyn.step(still(1), 500)
    assert dyn.state.landed[0] and dyn.state.pos[0, 2] == 0.0
    attitude_targets(dyn, thrust=1.3 * HOVER)
    dyn.step(still(1), 500)
    assert not dyn.state.landed[0]
    assert dyn.state.pos[0, 2] > 0.1
    assert np.linalg.norm(dyn.state.pos[0, :2]) < 0.01


def test_crashed_vehicle_motors_off_falls_and_lies_on_ground():
    dyn = make(2, z=20.0)
    attitude_targets(dyn, thrust=P.thrust_max)
    dyn.state.crashed[0] = True
    dyn.state.omega[0] = [3.0, -2.0, 1.0]  # tumbling
    dyn.step(still(2), 1)
    assert np.all(dyn.state.motor[0] == 0.0) and np.all(dyn.state.motor[1] > 0.0)
    dyn.step(still(2), 4000)
    assert dyn.state.crashed[0] and dyn.state.landed[0] and dyn.state.pos[0, 2] == 0.0
    assert dyn.state.pos[1, 2] > 20.0


# --- vectorisation, robustness, compiled and interpreted ----------------------------------------------------


def test_hundred_vehicles_match_single_vehicle_runs():
    n = 100
    rng = np.random.default_rng(7)
    roll, pitch, yaw = rng.uniform(-0.4, 0.4, n), rng.uniform(-0.4, 0.4, n), rng.uniform(-3, 3, n)
    thrust = rng.uniform(0.6, 1.5, n) * HOVER
    wind = rng.normal(0, 3, (n, 3))
    fleet = make(n)
    attitude_targets(fleet, roll, pitch, yaw, thrust)
    fleet.step(wind, 300)
    for i in (0, 37, 99):
        single = make(1)
        attitude_targets(single, roll[i], pitch[i], yaw[i], thrust[i])
        single.step(wind[i : i + 1], 300)
        assert np.allclose(single.state.pos[0], fleet.state.pos[i], atol=1e-12)
        assert np.allclose(single.state.quat[0], fleet.state.quat[i], atol=1e-12)


def test_extreme_and_nan_inputs_never_produce_nan():
    n = 6
    dyn = make(n)
    quat = euler_to_quaternion(np.stack((np.zeros(n), np.zeros(n), np.zeros(n)), axis=-1))
    quat[0] = np.nan
    quat[1] = 0.0
    quat[2] = [0.0, 1.0, 0.0, 0.0]  # upside down
    rate_ff = np.zeros((n, 3))
    rate_ff[3] = [np.inf, 1e9, -1e9]
    thrust = np.array([np.nan, 1e9, -5.0, HOVER, np.inf, HOVER])
    tilt = np.array([0.5, 0.5, np.nan, 0.5, 0.5, 10.0])
    dyn.set_targets(quat, rate_ff, thrust, np.ones(n, bool), tilt)
    assert dyn.last_sanitised.tolist() == [True, True, True, True, True, False]
    wind = np.array([[np.nan, 0, 0], [1e3, 0, 0], [0, 0, -50], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    dyn.state.omega[5] = [50.0, -50.0, 50.0]
    for _ in range(20):
        dyn.step(wind, 100)
    s = dyn.state
    for array in (s.pos, s.vel, s.quat, s.omega, s.motor, s.world_accel):
        assert np.all(np.isfinite(array))
    assert np.all(s.pos[:, 2] >= 0.0)
    assert np.all((s.motor >= 0.0) & (s.motor <= P.f_max))
    assert np.allclose(np.linalg.norm(s.quat, axis=1), 1.0)
    assert np.linalg.norm(s.pos[0] - [0, 0, 10]) < 0.05  # NaN targets sanitised to hold attitude at hover
    dyn.set_rate_targets(np.ones(n, bool), np.full((n, 3), np.nan))
    dyn.step(wind, 100)
    assert dyn.last_sanitised.all() and np.all(np.isfinite(s.quat))


def _scripted_run(rate_hz: float = 1000.0) -> FleetState:
    """500 steps exercising every branch: tilt, yaw, saturation, rate mode, NaN targets, ground, crash."""
    n = 7
    pos = np.zeros((n, 3))
    pos[:, 2] = [10.0, 0.3, 10.0, 0.0, 0.3, 10.0, 10.0]
    state = FleetState.at_rest(pos, np.linspace(-3, 3, n))
    dyn = FleetDynamics(n, rate_hz=rate_hz, state=state)
    roll = np.array([0.5, -0.3, 0.0, 0.0, 0.2, 1.2, 0.0])
    pitch = np.array([0.2, 0.5, 0.0, 0.0, 0.0, -0.4, 0.0])
    yaw = np.array([1.0, -2.0, 3.0, 0.0, 0.5, 0.0, 0.0])
    thrust = np.array([1.1, 1.0, 2.5, 1.4, 0.3, 2.5, 0.0]) * HOVER
    quat = euler_to_quaternion(np.stack((roll, pitch, yaw), axis=-1))
    wind = np.random.default_rng(3).normal(0, 4, (n, 3))
    dyn.set_targets(quat, np.full((n, 3), 0.1), thrust, np.ones(n, bool), np.full(n, 0.6))
    dyn.set_rate_targets(np.arange(n) == 2, np.tile([2.0, -1.0, 1.5], (n, 1)))
    dyn.step(wind, 100)
    dyn.state.crashed[1] = True
    thrust = np.array([0.9, 1.0, 1.2, 0.5, 0.2, np.nan, 2.5]) * HOVER
    quat = euler_to_quaternion(np.stack((-roll, pitch, -yaw), axis=-1))
    quat[6] = np.nan
    tilt = np.array([0.8, 0.8, 0.8, 0.8, 0.8, 0.8, np.nan])
    dyn.set_targets(quat, np.zeros((n, 3)), thrust, np.ones(n, bool), tilt)
    assert dyn.last_sanitised.tolist() == [False] * 5 + [True, True]
    dyn.step(wind, 200)
    dyn.set_rate_targets(np.zeros(n, bool), np.zeros((n, 3)))
    dyn.step(wind, 200)
    return dyn.state


FIELDS = ("pos", "vel", "quat", "omega", "motor", "world_accel")

if __name__ == "__main__":  # the interpreted run of test_compiled_and_interpreted_physics_agree
    import sys

    final = _scripted_run(float(sys.argv[2]))
    np.savez(sys.argv[1], landed=final.landed, **{name: getattr(final, name) for name in FIELDS})


@pytest.mark.parametrize("rate_hz", [1000.0, 250.0])
def test_compiled_and_interpreted_physics_agree(rate_hz, tmp_path):
    """The one physics kernel flies the same compiled (the default) and as plain Python (NUMBA_DISABLE_JIT=1),
    within rounding of the math library: every branch of the scripted run."""
    import os
    import subprocess
    import sys

    out = tmp_path / "interpreted.npz"
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    subprocess.run(
        [sys.executable, "-m", "tests.sitl_sim.vehicle_model.test_dynamics", str(out), str(rate_hz)],
        check=True, env=env, timeout=300,
    )  # fmt: skip
    compiled = _scripted_run(rate_hz)
    interpreted = np.load(out)
    assert compiled.landed.tolist() == interpreted["landed"].tolist()
    assert compiled.landed[1] and compiled.landed[3]  # the run did exercise the crash, lift-off, touchdown
    for name in FIELDS:
        assert np.allclose(getattr(compiled, name), interpreted[name], rtol=0, atol=1e-9), name
