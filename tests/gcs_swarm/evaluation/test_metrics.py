"""Spec 10 metric definitions on synthetic logs with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.evaluation import metrics
from gcs_swarm.guidance.formation import slot_positions


def test_reach_time_needs_the_hold():
    t = np.arange(0, 10, 0.05)
    d = np.full_like(t, 5.0)
    d[(t >= 2.0) & (t < 3.0)] = 0.2  # a 1 s visit does not count
    d[t >= 6.0] = 0.4  # from 6 s to the end (3.95 s) does
    assert metrics.reach_time(t, d, 0.5, 2.0) == pytest.approx(6.0)
    assert metrics.reach_time(t, d, 0.5, 0.5) == pytest.approx(2.0)
    assert metrics.reach_time(t, d, 0.1, 2.0) is None
    d[t >= 8.5] = 5.0  # leaves again after 2.5 s: still reached at 6 s
    assert metrics.reach_time(t, d, 0.5, 2.0) == pytest.approx(6.0)
    d[t >= 7.9] = 5.0  # only 1.9 s
    assert metrics.reach_time(t, d, 0.5, 2.0) is None


def test_oscillation_time_and_reversals_of_a_weaving_heading():
    """Heading weaves +-20 deg with period 4 s from t = 2 s to 14 s: extrema every 2 s from 3 s to 13 s."""
    t = np.arange(0, 20, 0.01)
    chi = np.where((t >= 2) & (t <= 14), np.radians(20) * np.sin(2 * np.pi * (t - 2) / 4), 0.0)
    vel = 5.0 * np.stack([np.cos(chi), np.sin(chi)], axis=1)
    t_osc, reversals = metrics.oscillation(t, vel)
    assert reversals == 6
    assert t_osc == pytest.approx(10.0, abs=0.02)
    np.testing.assert_allclose(metrics.heading_extrema(t, vel), [3, 5, 7, 9, 11, 13], atol=0.02)


def test_oscillation_ignores_small_wiggles_slow_samples_and_wraps():
    t = np.arange(0, 10, 0.01)
    chi = math.pi + np.radians(2) * np.sin(2 * np.pi * t)  # +-2 deg around 180 deg: below the 5 deg swing
    vel = np.stack([np.cos(chi), np.sin(chi)], axis=1) * 3.0
    assert metrics.oscillation(t, vel) == (0.0, 0)
    vel[:, :] = [[0.1, 0.3]]  # slower than 0.5 m/s: not counted at all
    vel[::2] = [[0.1, -0.3]]
    assert metrics.oscillation(t, vel) == (0.0, 0)


def test_path_length_and_min_separation():
    assert metrics.path_length(np.array([[0, 0], [3, 4], [3, 10]])) == pytest.approx(11.0)
    p = np.zeros((4, 3, 3))
    p[:, 1, 0] = [10, 8, 6, 9]
    p[:, 2, 1] = 20
    assert metrics.min_separation(p) == pytest.approx(6.0)
    assert metrics.min_separation(p[:, :1]) == math.inf


def test_obstacle_clearance_static_and_moving():
    p = np.zeros((3, 1, 2))
    p[:, 0, 0] = [0.0, 1.0, 2.0]
    c_min, hit = metrics.min_obstacle_clearance(p, np.array([[5.0, 0.0]]), np.array([1.0]))
    assert c_min == pytest.approx(2.0) and not hit
    moving = np.array([[[5.0, 0.0]], [[3.0, 0.0]], [[2.1, 0.0]]])
    c_min, hit = metrics.min_obstacle_clearance(p, moving, np.array([1.0]))
    assert c_min == pytest.approx(-0.9) and hit
    c_min, hit = metrics.min_obstacle_clearance(p, np.array([[3.3, 0.0]]), np.array([1.0]), l_arm=0.175)
    assert c_min == pytest.approx(0.3) and not hit
    assert metrics.min_obstacle_clearance(p, np.zeros((0, 2)), np.zeros(0)) == (math.inf, False)


def test_formation_error_settles_and_reports_after_settling():
    t = np.arange(0, 20, 0.1)
    offsets = np.array([[0, 0, 0], [-10.0, 5.0, 0]])
    psi = np.full_like(t, 0.5)
    leader = np.stack([t, 2 * t, np.full_like(t, 20.0)], axis=1)
    slots = slot_positions(leader, psi, offsets)
    error = 3.0 * np.exp(-t / 2.0)  # below 1 m from t = 2 ln 3 = 2.197 s
    p = slots.copy()
    p[:, 1, 2] += error
    fe = metrics.formation_error(t, p, 0, psi, offsets)
    np.testing.assert_allclose(fe.error[:, 1], error, atol=1e-12)
    assert fe.t_settle == pytest.approx(2.2, abs=1e-9)
    assert fe.max == pytest.approx(3.0 * math.exp(-1.1))
    assert fe.rms == pytest.approx(np.sqrt(np.mean(np.stack([np.zeros(178), error[22:]]) ** 2)))
    p[-1, 1, 2] += 5.0
    assert metrics.formation_error(t, p, 0, psi, offsets).t_settle is None


def test_formation_error_follows_a_new_leader_and_leaves_lost_vehicles_out():
    """The lead passes from vehicle 0 (lost at sample 5) to vehicle 1, which vehicle 2 then follows."""
    t = np.arange(10) * 0.1
    psi = np.zeros(10)
    before = np.array([[0.0, 0, 0], [-5, 5, 0], [-5, -5, 0]])
    after = np.array([[np.nan] * 3, [0.0, 0, 0], [0, -10, 0]])
    offsets = np.stack([before] * 5 + [after] * 5)
    leaders = np.array([0] * 5 + [1] * 5)
    p = np.zeros((10, 3, 3))
    p[:, 0] = [0, 0, 10]
    p[:, 1] = [-5, 5, 10]
    p[:, 2] = [-5, -5, 10]
    p[5:, 0] = [50, 50, 0]  # the lost vehicle is far away: it must not count
    p[5:, 2, 1] += 0.5  # 0.5 m off the new slot (-5, -5) relative to the new leader at (-5, 5)
    fe = metrics.formation_error(t, p, leaders, psi, offsets)
    assert np.isnan(fe.error[5:, 0]).all() and (fe.error[:5] == 0).all()
    np.testing.assert_allclose(fe.error[5:, 2], 0.5)
    assert fe.max == pytest.approx(0.5) and fe.t_settle == pytest.approx(0.0)


def test_settling_time_of_a_first_order_step():
    t = np.arange(0, 30, 0.01)
    y = 10.0 * (1 - np.exp(-t))  # 2 % of 10 m: |y - 10| <= 0.2 from t = ln 50 = 3.91 s
    assert metrics.settling_time(t, y, 0.05) == pytest.approx(math.log(50), abs=0.02)
    assert metrics.settling_time(t, y, 1.0) == pytest.approx(math.log(10), abs=0.02)


def test_chattering_amplitude_sees_fast_content_only():
    t = np.arange(0, 40, 0.01)
    slow = 3.0 * np.sin(0.05 * t) + 0.5 * t  # curvature small enough to leave < 1e-3 behind the 1 s average
    fast = 0.01 * (-1.0) ** np.arange(len(t))  # sample-to-sample chatter of +-0.01
    y = slow + np.where(t < 20, fast, 0.0)
    assert metrics.chattering_amplitude(t, y, (1.0, 19.0)) == pytest.approx(0.02, abs=0.001)
    assert metrics.chattering_amplitude(t, y, (21.0, 39.0)) < 1e-3
    with pytest.raises(ValueError, match="window"):
        metrics.chattering_amplitude(t, y, (50.0, 60.0))


def _brute_force_closest(p: np.ndarray) -> np.ndarray:
    """The definition, one pair at a time: per sample, the smallest |p_i - p_j| over pairs without NaN."""
    out = np.full(len(p), np.nan)
    for k, sample in enumerate(p):
        for i in range(sample.shape[0]):
            for j in range(i + 1, sample.shape[0]):
                d = math.dist(sample[i], sample[j])
                if not math.isnan(d) and not d >= out[k]:
                    out[k] = d
    return out


@pytest.mark.parametrize("n", [2, 3, 9, 16, 40])
def test_closest_pair_distance_is_the_definition(n):
    rng = np.random.default_rng(n)
    p = rng.normal(scale=50.0, size=(30, n, 3))
    p[3, 0] = np.nan  # a vehicle out of the log at one sample: its pairs are left out
    p[5, :] = np.nan  # nobody logged: no finite pair
    expected = _brute_force_closest(p)
    got = metrics.closest_pair_distance(p)
    np.testing.assert_allclose(got, expected, rtol=1e-12)
    assert np.isnan(got[5])
    assert metrics.min_separation(p) == pytest.approx(float(np.nanmin(expected)), rel=1e-12)


def test_nearest_neighbour_distance():
    p = np.zeros((2, 3, 3))
    p[:, 1, 0] = [3.0, 5.0]  # vehicle 1 on the x axis
    p[:, 2, 1] = [4.0, 1.0]  # vehicle 2 on the y axis
    d = metrics.nearest_neighbour_distance(p)
    np.testing.assert_allclose(d[0], [3.0, 3.0, 4.0])  # 0-1 3 m, 0-2 4 m, 1-2 5 m
    np.testing.assert_allclose(d[1], [1.0, 5.0, 1.0])  # 0-1 5 m, 0-2 1 m, 1-2 sqrt(26) m
    assert metrics.nearest_neighbour_distance(p[:, :1]).tolist() == [[math.inf], [math.inf]]
    p[1, 2] = np.nan
    assert np.isnan(metrics.nearest_neighbour_distance(p)[1]).all()  # as numpy's min: NaN spreads


def test_min_separation_without_finite_pairs_is_inf():
    p = np.full((4, 3, 3), np.nan)
    assert metrics.min_separation(p) == math.inf
