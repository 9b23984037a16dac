"""Derivations for the paper-style figures on synthetic data: relative angles (Fig 19), commanded attitude
rates (Fig 26), accelerations (Figs 14-16) and cruise figures (Fig 24)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.evaluation import signals
from gcs_swarm.guidance.formation import formation_offsets, slot_positions


def test_relative_angle_of_a_follower_behind_and_right_of_the_leader() -> None:
    # Leader at the origin heading North (90 deg); follower 10 m south-east: back-right in the leader frame.
    p = np.array([[[0.0, 0.0, 0.0], [10.0, -10.0, 0.0]]])
    angles = signals.relative_angles(p, 0, np.array([math.pi / 2]))
    assert np.isnan(angles[0, 0])
    assert angles[0, 1] == pytest.approx(math.radians(-135.0))


def test_relative_angles_of_slots_equal_the_desired_angles_at_any_heading() -> None:
    offsets = np.vstack([np.zeros(3), formation_offsets("v", 4, 20.0, 45.0)])
    psi = np.linspace(-3.0, 3.0, 7)
    p = slot_positions(np.zeros((len(psi), 3)), psi, offsets)
    angles = signals.relative_angles(p, 0, psi)
    desired = signals.desired_relative_angles(offsets, 0)
    assert np.isnan(desired[0])
    np.testing.assert_allclose(angles[:, 1:], np.broadcast_to(desired[1:], (len(psi), 4)), atol=1e-12)
    np.testing.assert_allclose(np.degrees(np.abs(desired[1:])), 135.0)


def test_attitude_rates_of_ramps_and_a_yaw_that_wraps() -> None:
    t = np.arange(0.0, 4.0, 0.02)
    yaw = (3.0 + 0.5 * t + math.pi) % (2 * math.pi) - math.pi  # crosses +-pi at t ~ 0.28 s
    att = np.stack([0.1 * t, -0.2 * t, yaw], axis=-1)[:, None, :]
    rates = signals.attitude_rates(t, att)
    assert rates.shape == (len(t), 1, 3)
    np.testing.assert_allclose(rates[:, 0, 0], 0.1, atol=1e-9)
    np.testing.assert_allclose(rates[:, 0, 1], -0.2, atol=1e-9)
    np.testing.assert_allclose(rates[:, 0, 2], 0.5, atol=1e-9)


def test_accelerations_of_a_linear_velocity_ramp() -> None:
    t = np.arange(0.0, 2.0, 0.02)
    vel = np.zeros((len(t), 2, 3))
    vel[:, 1, 0] = 3.0 * t
    acc = signals.accelerations(t, vel)
    np.testing.assert_allclose(acc[:, 1, 0], 3.0, atol=1e-9)
    np.testing.assert_allclose(acc[:, 0], 0.0)


def test_command_rate_figures_settle_after_a_ramp_and_measure_chattering() -> None:
    t = np.arange(0.0, 60.0, 0.02)
    pitch = np.minimum(t / 10.0, 1.0) * 0.5  # rate 0.05 rad/s for 10 s, then 0
    yaw = 0.01 * np.sign(np.sin(2 * np.pi * 5 * t))  # chattering square wave, +-0.01 rad
    att = np.stack([np.zeros_like(t), pitch, yaw], axis=-1)[:, None, :]
    figures = signals.command_rate_figures(t, att, ["uav1"])
    pitch_rate = figures["vehicles"][0]["pitch_rate"]
    assert pitch_rate["settling_s"] == pytest.approx(10.0, abs=0.1)
    assert pitch_rate["peak"] == pytest.approx(0.05, abs=1e-6)
    yaw_rate = figures["vehicles"][0]["yaw_rate"]
    assert yaw_rate["chatter_first_20s"] > 1.0  # 0.02 rad steps per 0.02 s
    # The raw rate chatters to the end; its 1 s trend is zero throughout.
    assert yaw_rate["settling_s"] > 59.0
    assert yaw_rate["trend_settling_s"] < 1.0
    assert figures["settling_s"] >= pitch_rate["settling_s"]


def test_neighbour_pairs_of_a_v_link_each_follower_to_the_slot_ahead() -> None:
    offsets = np.vstack([np.zeros(3), formation_offsets("v", 4, 20.0, 45.0)])
    pairs = signals.neighbour_pairs(offsets)
    assert pairs == [(1, 0), (2, 0), (3, 1), (4, 2)]
    for i, j in pairs:
        assert np.linalg.norm(offsets[i] - offsets[j]) == pytest.approx(20.0)


def test_cruise_figures_of_a_formation_flying_at_constant_speed() -> None:
    offsets = np.vstack([np.zeros(3), formation_offsets("v", 2, 20.0, 45.0)])
    t = np.arange(0.0, 100.0, 0.1)
    leader = np.stack([10.0 * t, np.zeros_like(t), np.full_like(t, 200.0)], axis=-1)
    p = slot_positions(leader, np.zeros_like(t), offsets)
    vel = np.broadcast_to([10.0, 0.0, 0.0], p.shape)
    error = np.zeros((len(t), 3))
    cruise = signals.cruise_figures(t, p, vel, 0, np.array([1000.0, 0.0, 200.0]), offsets, error, 50.0)
    assert cruise is not None
    assert cruise["speed_median_m_s"] == [10.0, 10.0, 10.0]
    assert cruise["spacing_median_m"] == [20.0, 20.0]
    assert cruise["spacing_max_abs_error_m"] == pytest.approx(0.0, abs=1e-9)
    assert cruise["window_s"][1] < 95.0  # ends when the leader is 50 m from the goal
    assert cruise["spacing_within_1m_fraction"] == 1.0
    never_settled = np.full((len(t), 3), signals.CRUISE_FORMATION_M + 1.0)
    assert signals.cruise_figures(t, p, vel, 0, np.zeros(3), offsets, never_settled, 50.0) is None


def test_a_vehicle_never_commanded_has_no_rate_figures_and_leaves_the_worst_to_the_others() -> None:
    """Issue 38: a follower taken over before the formation phase has NaN commands throughout; its figures
    are all None (every key present, no KeyError) and the fleet's worst is the other vehicle's. Vehicle 0's
    pitch ramps at 0.1 rad/s for 2 s then holds (as in the test above): its peak rate is 0.1 rad/s."""
    t = np.arange(0.0, 30.0, 0.02)
    att = np.zeros((len(t), 2, 3))
    att[:, 0, 1] = np.minimum(t / 2.0, 1.0) * 0.2
    att[:, 1] = np.nan
    figures = signals.command_rate_figures(t, att, ["lead", "left"])
    left = figures["vehicles"][1]
    for axis in ("pitch_rate", "yaw_rate"):
        assert set(left[axis]) == set(signals.RATE_FIGURES)
        assert all(value is None for value in left[axis].values())
    assert figures["peak_rad_s"] == pytest.approx(0.1, abs=1e-3)
    assert figures["trend_first_settled_s"] is not None


def test_a_yaw_that_wraps_is_unwrapped_while_another_vehicle_is_not_commanded() -> None:
    """Yaw of vehicle 0 grows 0.1 rad a tick of 0.1 s (1 rad/s) through +pi to -pi; vehicle 1 is not
    commanded (NaN) on half of the ticks. Vehicle 0's yaw rate stays 1 rad/s across the wrap (it was left
    wrapped, a -62 rad/s spike, whenever any vehicle had a NaN tick)."""
    t = np.arange(0.0, 6.0, 0.1)
    yaw = (3.0 + 0.1 * np.arange(len(t)) + math.pi) % (2.0 * math.pi) - math.pi
    att = np.zeros((len(t), 2, 3))
    att[:, 0, 2] = yaw
    att[::2, 1] = np.nan
    rates = signals.attitude_rates(t, att)
    np.testing.assert_allclose(rates[:, 0, 2], 1.0, atol=1e-9)
