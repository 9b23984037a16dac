"""Reference generator (spec 8 steps 3-6) and the paper-literal option."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.params import FieldParams, G, Limits, ReferenceParams, paper_plain_reference
from gcs_swarm.guidance.reference import (
    ReferenceGenerator,
    default_d_g,
    paper_literal_reference,
)


def test_default_d_g_is_v_max_over_k_v():
    assert default_d_g(FieldParams(), 20.0, 1.0) == 20.0
    assert default_d_g(FieldParams(), 15.0, 0.5) == 30.0
    assert default_d_g(FieldParams(d_g=7.0), 20.0, 1.0) == 7.0


def test_saturation_keeps_the_horizontal_direction_and_clips_vertical():
    """Step 3: v_cmd = v_ff + (K_v / k_att) F with its horizontal part scaled to the cap (direction kept) and
    its vertical part clipped to v_z; from rest with tau_v = 1 s the first-order step 4 gives a_r = v_cmd
    (within the acceleration limits)."""
    lim = Limits(a_xy=1e6, a_z=1e6, tilt_max_deg=70.0)
    gen = ReferenceGenerator(paper_plain_reference(tau_v=1.0), lim, k_att=100.0)
    gen.reset(np.zeros((2, 3)), np.zeros((2, 3)))
    force = np.array([[3000.0, 4000.0, -2500.0], [1.0, 1.0, 1.0]]) * 100.0  # v_cmd (30, 40, -25), (1, 1, 1)
    gen.step(force, np.zeros((2, 3)), np.array([10.0, 10.0]), 0.02, np.ones(2, dtype=bool))
    np.testing.assert_allclose(gen.a[0], [6.0, 8.0, -lim.v_z])
    np.testing.assert_allclose(gen.a[1], [1.0, 1.0, 1.0])


def test_velocity_and_acceleration_limits_and_leash():
    """The spec's plain generator (no shaping): the acceleration steps to its limit at once."""
    lim = Limits()
    gen = ReferenceGenerator(paper_plain_reference(), lim, k_att=100.0)
    pos = np.zeros((2, 3))
    gen.reset(pos, np.zeros((2, 3)))
    huge = np.array([[1e6, 0.0, 1e6], [0.0, 1e6, 0.0]])
    caps = np.array([10.0, 20.0])
    rows = np.ones(2, dtype=bool)
    a_xy_max = min(lim.a_xy, G * math.tan(lim.tilt_max))  # 6.86 m/s^2: the tilt limit binds
    p, v, a = gen.step(huge, np.zeros((2, 3)), caps, 0.02, rows)
    assert not p.any() and not v.any()  # the desired state of this instant: where the reference starts
    assert np.hypot(*a[0, :2]) == pytest.approx(a_xy_max)
    assert a[0, 2] == pytest.approx(lim.a_z)
    for _ in range(500):  # the vehicles stay put: the leash holds the references 5 m away
        gen.leash_and_lookahead(pos, rows)
        p, v, a = gen.step(huge, np.zeros((2, 3)), caps, 0.02, rows)
    assert np.hypot(*v[0, :2]) == pytest.approx(10.0)  # leader cap
    assert np.hypot(*v[1, :2]) == pytest.approx(20.0)
    assert v[0, 2] == pytest.approx(lim.v_z)
    np.testing.assert_allclose(np.linalg.norm(p - pos, axis=1), 5.0)


def test_near_the_target_the_reference_closes_at_k_v():
    """v_cmd = v_ff + K_v (T - p_r) for rho < d_g: the reference converges on a fixed target."""
    gen = ReferenceGenerator(paper_plain_reference(), Limits(), k_att=100.0)
    gen.reset(np.zeros((1, 3)), np.zeros((1, 3)))
    target = np.array([[3.0, -2.0, 1.0]])
    for _ in range(1000):
        gen.step(-100.0 * (gen.p - target), np.zeros((1, 3)), np.array([10.0]), 0.02, np.ones(1, dtype=bool))
    np.testing.assert_allclose(gen.p, target, atol=1e-6)


def test_a_moving_target_is_tracked_without_lag():
    """Slot feed-forward v_ff with the attraction toward the slot: the desired position handed to the SMC
    equals the slot of the same instant (no v dt offset)."""
    gen = ReferenceGenerator(ReferenceParams(), Limits(), k_att=100.0)
    velocity = np.array([[7.0, -3.0, 0.0]])
    slot = lambda t: np.array([[10.0, 5.0, 20.0]]) + velocity * t  # noqa: E731
    gen.reset(slot(0.0), velocity)
    for k in range(100):
        p, v, _ = gen.step(
            -100.0 * (gen.p - slot(k * 0.02)), velocity, np.array([20.0]), 0.02, np.ones(1, bool)
        )
        np.testing.assert_allclose(p, slot(k * 0.02), atol=1e-9)
        np.testing.assert_allclose(v, velocity, atol=1e-9)


def test_unselected_rows_do_not_move():
    gen = ReferenceGenerator(ReferenceParams(), Limits(), k_att=100.0)
    gen.reset(np.zeros((2, 3)), np.zeros((2, 3)))
    rows = np.array([True, False])
    gen.step(np.ones((2, 3)) * 500, np.zeros((2, 3)), np.array([10.0, 10.0]), 0.02, rows)
    gen.leash_and_lookahead(np.full((2, 3), 100.0), rows)
    assert gen.p[0].any() and not gen.p[1].any() and not gen.v[1].any()


def test_paper_literal_reference_shift_is_scaled_and_capped_at_l0():
    slots = np.array([[10.0, 0.0, 5.0], [0.0, 0.0, 5.0]])
    vel = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    f_rep = np.array([[300.0, 0.0, 400.0], [1e6, 0.0, 0.0]])  # 5 m shift; 1e4 m capped to l0 = 20
    x_d, xd_dot, xd_ddot = paper_literal_reference(slots, vel, f_rep, 100.0, 20.0)
    np.testing.assert_allclose(x_d, [[13.0, 0.0, 9.0], [20.0, 0.0, 5.0]])
    np.testing.assert_array_equal(xd_dot, vel)
    assert not xd_ddot.any()


def test_the_named_settings_are_the_kernels_last_parameters():
    """ReferenceConfig and SMCSettings are passed as *settings: their fields name the kernels' last
    parameters, in order."""
    import inspect

    from gcs_swarm.guidance.reference import ReferenceConfig, reference_step
    from gcs_swarm.guidance.smc import SMCSettings, smc_output

    for record, kernel in ((ReferenceConfig, reference_step), (SMCSettings, smc_output)):
        names = list(inspect.signature(kernel.py_func).parameters)
        assert names[-len(record._fields) :] == list(record._fields)
