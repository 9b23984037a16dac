"""SMC on a double integrator (spec 7, 11.2), the PID baseline, and the thrust/attitude inversion (spec 5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm import metrics
from gcs_swarm.guidance.inversion import invert, limit_thrust_vector, thrust_vector
from gcs_swarm.guidance.params import G, Limits, PIDParams, SMCAxisGains, SMCParams
from gcs_swarm.guidance.pid import PIDController
from gcs_swarm.guidance.smc import SMCController, reaching_law, sliding_variable, smc_control


def reference(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """5 sin(0.5 t) + 2 t on every axis (spec 11.2), (1, 3) position, velocity, acceleration."""
    one = np.ones((1, 3))
    return (
        one * (5 * math.sin(0.5 * t) + 2 * t),
        one * (2.5 * math.cos(0.5 * t) + 2),
        one * (-1.25 * math.sin(0.5 * t)),
    )


def test_sliding_variable_obeys_the_reaching_law_on_a_double_integrator():
    """Integrate x_dd = U (z: U - g) with a fine step; the numerical s_dot equals the reaching law."""
    params = SMCParams()
    dt = 1e-4
    x = np.array([[3.0, -2.0, 1.0]])
    v = np.array([[0.0, 1.0, -1.0]])
    worst = 0.0
    for k in range(20000):  # 2 s
        t = k * dt
        xd, vd, ad = reference(t)
        u, s = smc_control(xd, vd, ad, x, v, params)
        acc = u - np.array([0.0, 0.0, G])
        x_next, v_next = x + v * dt + 0.5 * acc * dt * dt, v + acc * dt
        _, s_next = sliding_variable(*reference(t + dt)[:2], x_next, v_next, params)
        s_dot = (s_next - s) / dt
        law = 0.5 * (reaching_law(s, params) + reaching_law(s_next, params))
        if k > 10:
            worst = max(worst, float(np.max(np.abs(s_dot - law))))
        x, v = x_next, v_next
    assert worst < 5e-3


def simulate_axis(gains: SMCAxisGains, e0: float, de0: float, t_end: float, a_max: float | None = None):
    """One axis, double integrator, regulation to the moving reference; returns times and e1 (T,)."""
    params = SMCParams(xy=gains, z=gains)
    dt = 1e-3
    xd, vd, _ = reference(0.0)
    x = xd - e0
    v = vd - de0
    times, errors = [], []
    for k in range(int(t_end / dt)):
        t = k * dt
        xd, vd, ad = reference(t)
        u, _ = smc_control(xd, vd, ad, x, v, params)
        u[:, 2] -= G
        if a_max is not None:
            u = np.clip(u, -a_max, a_max)
        v = v + u * dt
        x = x + v * dt
        times.append(t)
        errors.append(float((xd - x)[0, 0]))
    return np.array(times), np.array(errors)


@pytest.mark.parametrize("a_max", [None, 6.9, 20.0])
def test_converges_from_the_spec_initial_error(a_max):
    """8 m and 1.5 m/s initial error, c1 = 0.6, k1 = 1: |e1| < 0.1 m after 8.5 s, < 0.01 m after 12.3 s,
    with and without acceleration saturation (spec 11.2)."""
    times, e = simulate_axis(SMCAxisGains(0.6, 1.0, 0.3, 0.05), 8.0, 1.5, 20.0, a_max)
    assert np.abs(e[times >= 8.6]).max() < 0.1
    assert np.abs(e[times >= 12.4]).max() < 0.01
    assert abs(e[-1]) < 1e-3  # the sampled sgn terms leave a small limit cycle (spec: 3e-7 continuous)


def test_converges_from_the_paper_initial_velocities():
    """Table 2 initial velocities (the UAVs hold their start positions): every axis settles."""
    table2_v = np.array([[5, 6, 5], [3, 4, 2], [2, 7, 5], [4, 4, 8], [2, 5, 3], [3, 1, 3]], dtype=float)
    ctl = SMCController(SMCParams())
    x = np.zeros((6, 3))
    v = table2_v.copy()
    zero = np.zeros((6, 3))
    dt = 0.01
    for _ in range(2000):
        u = ctl(zero, zero, zero, x, v, dt)
        u[:, 2] -= G
        v += u * dt
        x += v * dt
    assert np.abs(x).max() < 1e-3 and np.abs(v).max() < 1e-3


def test_gain_validation_rejects_k1_c1_at_or_below_a_quarter():
    with pytest.raises(ValueError, match="k1\\*c1 > 1/4"):
        SMCAxisGains(c1=0.5, k1=0.5, k2=0.1, k3=0.1)
    with pytest.raises(ValueError):
        SMCAxisGains(c1=0.3, k1=0.5, k2=0.1, k3=0.1)
    SMCAxisGains(c1=0.51, k1=0.5, k2=0.1, k3=0.1)


def test_boundary_layer_reduces_chattering():
    """Sampled at 100 Hz, tracking a 2 m/s ramp, the sgn law chatters around s = 0 (peak-to-peak of U about
    9.2e-4 m/s^2, spec 11.2); sat(s/Phi) with Phi = 0.05 removes it (spec 7.4)."""

    def run(phi: float) -> float:
        params = SMCParams(boundary_layer=phi)
        dt = 0.01
        x, v = np.zeros((1, 3)), np.zeros((1, 3))
        us, ts = [], []
        for k in range(3000):
            t = k * dt
            xd, vd = np.full((1, 3), 5.0 + 2.0 * t), np.full((1, 3), 2.0)
            u, _ = smc_control(xd, vd, np.zeros((1, 3)), x, v, params)
            v = v + (u - np.array([0.0, 0.0, G])) * dt
            x = x + v * dt
            us.append(u[0, 0])
            ts.append(t)
        return metrics.chattering_amplitude(np.array(ts), np.array(us), (20.0, 29.0))

    with_sgn = run(0.0)
    assert with_sgn == pytest.approx(9.2e-4, rel=0.1)
    assert run(0.05) < 0.01 * with_sgn


def test_pid_tracks_and_limits_its_integral():
    ctl = PIDController(PIDParams())
    ctl.reset(1)
    dt = 0.01
    x, v = np.zeros((1, 3)), np.zeros((1, 3))
    for k in range(3000):
        xd, vd, ad = reference(k * dt)
        u = ctl(xd, vd, ad, x, v, dt)
        v = v + (u - np.array([0.0, 0.0, G])) * dt
        x = x + v * dt
    assert np.abs(reference(3000 * dt)[0] - x).max() < 0.05
    ctl.reset(1)
    far = np.full((1, 3), 1e4)
    zero = np.zeros((1, 3))
    for _ in range(1000):
        ctl(far, zero, zero, zero, zero, 0.1)
    assert np.all(np.abs(ctl.integral) <= PIDParams().i_limit)
    ctl.reset_rows(np.array([True]))
    assert not ctl.integral.any()


@pytest.mark.parametrize("yaw_deg", [-179.0, -135.0, -90.0, -30.0, 0.0, 45.0, 90.0, 150.0, 180.0])
def test_inversion_round_trip_in_every_quadrant(yaw_deg):
    rng = np.random.default_rng(int(yaw_deg) + 200)
    n = 200
    lim = Limits(tilt_max_deg=60.0)
    roll = rng.uniform(-0.6, 0.6, n)
    pitch = rng.uniform(-0.6, 0.6, n)
    yaw = np.full(n, math.radians(yaw_deg))
    thrust = rng.uniform(0.5 * G, 1.9 * G, n)
    u = thrust_vector(roll, pitch, yaw, thrust)
    cmd = invert(u, yaw, lim)
    np.testing.assert_allclose(cmd.roll, roll, atol=1e-12)
    np.testing.assert_allclose(cmd.pitch, pitch, atol=1e-12)
    np.testing.assert_allclose(cmd.thrust_acc, thrust, rtol=1e-12)
    np.testing.assert_allclose(thrust_vector(cmd.roll, cmd.pitch, yaw, cmd.thrust_acc), u, atol=1e-12)
    measured = invert(u, yaw, lim, G, roll, pitch)  # Eq 36 with the measured = desired angles: same thrust
    np.testing.assert_allclose(measured.thrust_acc, thrust, rtol=1e-12)


def test_thrust_vector_rows_are_unit_vectors():
    """The corrected y row (cos psi, not sin psi) keeps R e3 a unit vector (spec 5 [fix])."""
    rng = np.random.default_rng(2)
    a = rng.uniform(-math.pi, math.pi, (3, 500))
    np.testing.assert_allclose(np.linalg.norm(thrust_vector(*a, np.ones(500)), axis=1), 1.0, atol=1e-12)


def test_limits_apply_in_order():
    lim = Limits()
    tan = math.tan(lim.tilt_max)
    # 1. U_z floor first, then 2. the tilt limit shortens U_xy (direction kept) against the floored U_z.
    u = limit_thrust_vector(np.array([[30.0, 40.0, -5.0]]), lim)
    assert u[0, 2] == pytest.approx(0.3 * G)
    assert np.hypot(u[0, 0], u[0, 1]) == pytest.approx(0.3 * G * tan)
    assert u[0, 1] / u[0, 0] == pytest.approx(40.0 / 30.0)
    # inside the cone nothing changes
    inside = np.array([[1.0, -1.0, G]])
    np.testing.assert_array_equal(limit_thrust_vector(inside, lim), inside)
    # 3. thrust cap last: direction (angles) kept, magnitude 2 g
    cmd = invert(np.array([[0.0, 5.0, 40.0]]), np.zeros(1), lim)
    assert cmd.thrust_acc[0] == pytest.approx(2 * G)
    assert cmd.roll[0] == pytest.approx(-math.atan2(5.0, 40.0))


def test_measured_angle_thrust_floors_the_tilt_compensation():
    """Eq 36 divides by cos(phi)cos(theta) of the measured attitude, never by less than cos(tilt_max)."""
    lim = Limits(thrust_max_g=10.0)
    u = np.array([[0.0, 0.0, G]])
    tilted = invert(u, np.zeros(1), lim, G, np.array([0.2]), np.array([0.1]))
    assert tilted.thrust_acc[0] == pytest.approx(G / (math.cos(0.2) * math.cos(0.1)))
    flipped = invert(u, np.zeros(1), lim, G, np.array([3.0]), np.array([0.0]))
    assert flipped.thrust_acc[0] == pytest.approx(G / math.cos(lim.tilt_max))
