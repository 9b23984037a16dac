"""SMC on a double integrator (spec 7, 11.2), its disturbance estimate and drag adaptation [add]."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from gcs_swarm.evaluation import metrics
from gcs_swarm.guidance.params import G, Limits, SMCAxisGains, SMCParams
from gcs_swarm.guidance.smc import SMCController
from gcs_swarm.mission import MissionError, parse_mission
from tests.gcs_swarm.guidance.spec_reference import spec_reference

PAPER_XY = SMCAxisGains(0.8, 1.5, 0.3, 0.05)  # the default xy gains without the disturbance estimate


# The spec 7.1 equations, written out here from the spec (not from the controller) to check it against.
def gain(params: SMCParams, name: str) -> np.ndarray:
    return np.array([getattr(params.xy, name), getattr(params.xy, name), getattr(params.z, name)])


def sliding_variable(x_d, xd_dot, x, v, params):
    """e1 = x_d - x, s = c1 e1 + xd_dot - v."""
    e1 = x_d - x
    return e1, gain(params, "c1") * e1 + xd_dot - v


def reaching_law(s, params):
    """s_dot = -k1 s - k2 |s|^xi1 sw(s) - k3 |s|^xi2 sw(s); sw = sgn, or sat(s / Phi) (spec 7.4)."""
    phi = params.boundary_layer
    switch = np.sign(s) if phi <= 0.0 else np.clip(s / phi, -1.0, 1.0)
    k1, k2, k3, xi1, xi2 = (gain(params, name) for name in ("k1", "k2", "k3", "xi1", "xi2"))
    return -k1 * s - k2 * np.abs(s) ** xi1 * switch - k3 * np.abs(s) ** xi2 * switch


def eq49(x_d, xd_dot, xd_ddot, x, v, params):
    """U = xd_ddot - c1^2 e1 + c1 s - reaching_law(s) + g z, and s."""
    c1 = gain(params, "c1")
    e1, s = sliding_variable(x_d, xd_dot, x, v, params)
    return xd_ddot - c1 * c1 * e1 + c1 * s - reaching_law(s, params) + np.array([0.0, 0.0, G]), s


def static(params: SMCParams | None = None) -> SMCParams:
    """params with the [add] estimates off: the controller is the paper's Eq 49."""
    base = dataclasses.replace(params or SMCParams(), drag_adaptation=0.0)
    return dataclasses.replace(base, xy=dataclasses.replace(base.xy, disturbance_gain=0.0))


def smc_control(x_d, xd_dot, xd_ddot, x, v, params):
    """The controller's U and s with the estimates off (a fresh controller: no state)."""
    ctl = SMCController(static(params), G)
    u = ctl(x_d, xd_dot, xd_ddot, x, v, 0.01)
    return u, ctl.s


def test_sliding_variable_obeys_the_reaching_law_on_a_double_integrator():
    """Integrate x_dd = U (z: U - g) with a fine step; the numerical s_dot equals the reaching law."""
    params = SMCParams()
    dt = 1e-4
    x = np.array([[3.0, -2.0, 1.0]])
    v = np.array([[0.0, 1.0, -1.0]])
    worst = 0.0
    ctl = SMCController(static(params), G)
    for k in range(20000):  # 2 s
        t = k * dt
        xd, vd, ad = spec_reference(t)
        u = ctl(xd, vd, ad, x, v, dt)
        s = ctl.s
        acc = u - np.array([0.0, 0.0, G])
        x_next, v_next = x + v * dt + 0.5 * acc * dt * dt, v + acc * dt
        _, s_next = sliding_variable(*spec_reference(t + dt)[:2], x_next, v_next, params)
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
    xd, vd, _ = spec_reference(0.0)
    x = xd - e0
    v = vd - de0
    times, errors = [], []
    ctl = SMCController(static(params), G)
    for k in range(int(t_end / dt)):
        t = k * dt
        xd, vd, ad = spec_reference(t)
        u = ctl(xd, vd, ad, x, v, dt)
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
    """Table 2 initial velocities (the UAVs hold their start positions): every axis of the paper's SMC (Eq 49,
    no disturbance estimate) settles."""
    table2_v = np.array([[5, 6, 5], [3, 4, 2], [2, 7, 5], [4, 4, 8], [2, 5, 3], [3, 1, 3]], dtype=float)
    ctl = SMCController(SMCParams(xy=SMCAxisGains(0.8, 1.5, 0.3, 0.05)))
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
        ctl = SMCController(static(params), G)
        for k in range(3000):
            t = k * dt
            xd, vd = np.full((1, 3), 5.0 + 2.0 * t), np.full((1, 3), 2.0)
            u = ctl(xd, vd, np.zeros((1, 3)), x, v, dt)
            v = v + (u - np.array([0.0, 0.0, G])) * dt
            x = x + v * dt
            us.append(u[0, 0])
            ts.append(t)
        return metrics.chattering_amplitude(np.array(ts), np.array(us), (20.0, 29.0))

    with_sgn = run(0.0)
    assert with_sgn == pytest.approx(9.2e-4, rel=0.1)
    assert run(0.05) < 0.01 * with_sgn


DRAG = 0.25 / 0.9  # 1/s, the simulator's linear drag per unit mass (sitl_sim.vehicle_model drag_lin / mass)


def with_estimate(gain: float, d_max: float = 4.0, base: SMCParams | None = None) -> SMCParams:
    """SMCParams with the disturbance estimate [add] set on both channels (and no drag adaptation)."""
    base = base or SMCParams(drag_adaptation=0.0)
    xy = dataclasses.replace(base.xy, disturbance_gain=gain, disturbance_max=d_max)
    z = dataclasses.replace(base.z, disturbance_gain=gain, disturbance_max=d_max)
    return dataclasses.replace(base, xy=xy, z=z)


def test_zero_disturbance_gain_is_eq_49_bit_for_bit():
    """k_d = 0 (the default) leaves the paper's static law: identical bits to smc_control on every call,
    whatever disturbance_max, and that is Eq 49 written out."""
    rng = np.random.default_rng(7)
    params = with_estimate(0.0, d_max=0.5)
    ctl = SMCController(params, G, Limits())
    ctl.reset(5)
    for _ in range(50):
        x_d, xd_dot, xd_ddot, x, v = (rng.normal(0.0, 5.0, (5, 3)) for _ in range(5))
        u = ctl(x_d, xd_dot, xd_ddot, x, v, 0.02)
        expected, s = smc_control(x_d, xd_dot, xd_ddot, x, v, params)
        np.testing.assert_array_equal(u, expected)
        np.testing.assert_array_equal(ctl.s, s)
        assert not ctl.d_hat.any()
        written_out, s_hand = eq49(x_d, xd_dot, xd_ddot, x, v, params)
        np.testing.assert_allclose(u, written_out, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ctl.s, s_hand, rtol=1e-12, atol=1e-12)


def fly_ramp(params: SMCParams, limits: Limits | None, t_end: float = 60.0, dt: float = 0.02):
    """Point mass v_dot = U - g e_z - DRAG v tracking x_d = (10 t, 0, 10) from rest at (0, 0, 10), sampled at
    dt like the ground station; returns times (T,), e1 (T, 3) and the controller."""
    ctl = SMCController(params, G, limits)
    ctl.reset(1)
    x, v = np.array([[0.0, 0.0, 10.0]]), np.zeros((1, 3))
    times, errors = [], []
    for k in range(int(t_end / dt)):
        t = k * dt
        x_d, xd_dot = np.array([[10.0 * t, 0.0, 10.0]]), np.array([[10.0, 0.0, 0.0]])
        u = ctl(x_d, xd_dot, np.zeros((1, 3)), x, v, dt)
        times.append(t)
        errors.append((x_d - x)[0])
        v = v + (u - np.array([0.0, 0.0, G]) - DRAG * v) * dt
        x = x + v * dt
    return np.array(times), np.array(errors), ctl


def drag_offset(params: SMCParams, speed: float) -> float:
    """e1 where the xy reaching law balances the drag at `speed`: k1 s + k2 s^xi1 + k3 s^xi2 = DRAG speed,
    s = c1 e1 (bisection)."""
    g = params.xy
    lo, hi = 0.0, 10.0
    for _ in range(60):
        s = 0.5 * (lo + hi)
        lo, hi = (s, hi) if g.k1 * s + g.k2 * s**g.xi1 + g.k3 * s**g.xi2 < DRAG * speed else (lo, s)
    return lo / g.c1


def test_disturbance_estimate_removes_the_steady_drag_offset():
    """A 10 m/s ramp against linear drag (2.8 m/s^2): Eq 49 alone settles 1.93 m behind, where the reaching
    law balances the drag; with d_hat_dot = k_d s the error goes to zero and d_hat to the drag."""
    plain = SMCParams(xy=PAPER_XY, drag_adaptation=0.0)  # Eq 49 alone
    offset = drag_offset(plain, 10.0)
    assert offset == pytest.approx(1.93, abs=0.01)
    times, e, ctl = fly_ramp(plain, Limits())
    late = times >= 40.0
    np.testing.assert_allclose(e[late, 0], offset, atol=2e-3)
    for gain in (0.2, 0.5, 1.0):
        times, e, ctl = fly_ramp(with_estimate(gain), Limits())
        assert np.abs(e[late]).max() < 0.03 and np.abs(e[-1]).max() < 0.01  # 0.2 1/s: slowest
        assert ctl.d_hat[0, 0] == pytest.approx(DRAG * 10.0, abs=0.05)
        assert np.abs(ctl.d_hat[0, 1:]).max() < 1e-6


def test_disturbance_estimate_clamp_holds():
    """A drag the clamp cannot cover (4 m/s^2 cap, 5.6 m/s^2 needed at 20 m/s): |d_hat| sits at the cap and
    the remaining offset is that of 1.6 m/s^2 unmodelled; the horizontal norm is clamped, not each axis."""
    params = with_estimate(1.0, d_max=4.0)
    ctl = SMCController(params, G)
    ctl.reset(2)
    zero = np.zeros((2, 3))
    far = np.array([[1e3, 1e3, 1e3], [-1e3, 0.0, -1e3]])
    for _ in range(500):
        ctl(far, zero, zero, zero, zero, 0.02)
        assert np.hypot(ctl.d_hat[:, 0], ctl.d_hat[:, 1]).max() <= 4.0 + 1e-12
        assert np.abs(ctl.d_hat[:, 2]).max() <= 4.0
    np.testing.assert_allclose(ctl.d_hat[0], [4.0 / math.sqrt(2), 4.0 / math.sqrt(2), 4.0])
    np.testing.assert_allclose(ctl.d_hat[1], [-4.0, 0.0, -4.0])


def test_disturbance_estimate_holds_while_the_inversion_saturates():
    """With the spec 5 limits known, a reference far ahead (U beyond the tilt cone and the thrust cap) does
    not wind the estimate up in its direction; a step against a saturated U (unwinding) is still taken."""
    ctl = SMCController(with_estimate(1.0), G, Limits())
    ctl.reset(1)
    zero = np.zeros((1, 3))
    for _ in range(500):
        ctl(np.array([[1e3, 0.0, 1e3]]), zero, zero, zero, zero, 0.02)
    assert not ctl.d_hat.any()
    # U_z floored (reference far below) and U_x = 3 m/s^2 of estimate beyond the 10 deg cone, s_x < 0.
    ctl = SMCController(with_estimate(1.0), G, Limits(tilt_max_deg=10.0))
    ctl.reset(1)
    ctl.d_hat[:] = [[3.0, 0.0, -1.0]]
    for _ in range(10):
        ctl(np.array([[-0.1, 0.0, -1e3]]), zero, zero, zero, zero, 0.02)
    assert 2.9 < ctl.d_hat[0, 0] < 3.0  # against the saturated U_x: unwinds
    assert ctl.d_hat[0, 2] == -1.0  # s_z < 0 would push U_z further below the floor: held


def test_reset_rows_clears_the_estimate_and_inactive_rows_hold():
    """reset_rows zeroes the chosen vehicles only; rows with a non-finite state (inactive) keep theirs."""
    ctl = SMCController(with_estimate(0.5), G, Limits())
    ctl.reset(3)
    zero = np.zeros((3, 3))
    x_d = np.array([[1.0, -1.0, 0.5], [0.5, 0.5, -0.5], [2.0, 0.3, 0.2]])
    for _ in range(20):
        ctl(x_d, zero, zero, zero, zero, 0.02)
    before = ctl.d_hat.copy()
    assert np.all(before != 0.0)
    ctl.reset_rows(np.array([False, True, False]))
    np.testing.assert_array_equal(ctl.d_hat[[0, 2]], before[[0, 2]])
    assert not ctl.d_hat[1].any()
    held = ctl.d_hat[2].copy()
    x = np.zeros((3, 3))
    x[2] = np.nan
    u = ctl(x_d, zero, zero, x, zero, 0.02)
    assert np.isnan(u[2]).all() and np.isfinite(u[:2]).all()
    np.testing.assert_array_equal(ctl.d_hat[2], held)
    ctl.reset(3)
    assert not ctl.d_hat.any()
    with pytest.raises(ValueError, match="reset for 3 vehicles, got 2"):
        ctl(x_d[:2], zero[:2], zero[:2], zero[:2], zero[:2], 0.02)
    fresh = SMCController(with_estimate(0.5))  # never reset: the estimate starts at zero
    np.testing.assert_array_equal(
        fresh(x_d, zero, zero, zero, zero, 0.02), smc_control(x_d, zero, zero, zero, zero, SMCParams())[0]
    )


def test_disturbance_settings_are_mission_keys_with_one_sentence_errors():
    base = "vehicles:\n  - {name: lead, role: leader, start: {position: [0, 0, 0]}}\ngoal: [100, 50, 10]\n"
    text = base + "control: {smc: {xy: {disturbance_gain: 0.5, disturbance_max: 3}}}\n"
    mission = parse_mission(text, "m.yaml")
    assert mission.smc.xy == dataclasses.replace(SMCParams().xy, disturbance_gain=0.5, disturbance_max=3.0)
    assert mission.smc.z == SMCParams().z
    for bad, fragment in (
        ("{xy: {disturbance_gain: -0.5}}", "disturbance_gain must be >= 0 (0 turns"),
        ("{z: {disturbance_max: 0}}", "disturbance_max must be > 0"),
        ("{xy: {disturbance_gain: fast}}", "expected a number, got the text 'fast'"),
    ):
        with pytest.raises(MissionError) as info:
            parse_mission(base + f"control: {{smc: {bad}}}\n", "m.yaml")
        message = str(info.value)
        assert message.startswith("m.yaml:4: control.smc.") and fragment in message, message
        assert "\n" not in message and message.count(". ") == 0, message


def test_drag_adaptation_removes_the_trail_and_learns_the_drag():
    """The same ramp with the drag adaptation [add] (gamma 0.01 1/m^2, the default): the adaptive law
    c_hat_dot = gamma s . v_xy makes V = s^2/2 + (c_hat - c)^2/(2 gamma) non-increasing, so s -> 0, the
    1.93 m trail goes (to under 5 cm after 40 s) and, with v persistently 10 m/s, c_hat -> the true drag
    0.278 1/s. At rest the term adds nothing whatever c_hat is. (The xy disturbance estimate, on by default,
    is left out here: it would take a share of the drag and c_hat would not learn it all.)"""
    params = SMCParams(xy=PAPER_XY)
    assert params.drag_adaptation == 0.01
    times, e, ctl = fly_ramp(params, Limits())
    late = times >= 40.0
    assert np.abs(e[late, 0]).max() < 0.05
    assert ctl.c_hat[0] == pytest.approx(DRAG, abs=0.01)
    zero = np.zeros((1, 3))
    u_rest = ctl(zero, zero, zero, zero, zero, 0.02)
    expected, _ = eq49(zero, zero, zero, zero, zero, params)
    np.testing.assert_array_equal(u_rest, expected)
