"""Whole-flight figures (docs/metrics.md) on synthetic trajectories whose answer is worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.evaluation import flight_quality as fq

DT = 0.02


def course(t: np.ndarray, heading: np.ndarray, speed: float) -> np.ndarray:
    """Horizontal velocity (T, 2) of a vehicle flying `speed` m/s along heading(t) rad."""
    return speed * np.column_stack([np.cos(heading), np.sin(heading)])


def test_a_straight_line_has_no_cusp():
    t = np.arange(0, 20, DT)
    assert fq.cusp_times(t, course(t, np.full_like(t, 0.7), 10.0)) == []


def test_a_quick_u_turn_is_one_cusp():
    """180 deg in 0.5 s at 5 m/s (a reversal): the course differs by more than 90 deg across every 1 s window
    that spans the turn; those windows start within 1 s of each other, so they are one cusp."""
    t = np.arange(0, 10, DT)
    heading = np.clip((t - 5.0) / 0.5, 0.0, 1.0) * math.pi
    assert len(fq.cusp_times(t, course(t, heading, 5.0))) == 1


def test_a_slow_reversal_through_a_stop_is_no_cusp():
    """The same reversal done by braking to rest and flying back: below 2 m/s at the turn, no cusp."""
    t = np.arange(0, 10, DT)
    v = np.column_stack([5.0 * np.cos(np.pi * t / 10.0), np.zeros_like(t)])  # 5 m/s east, 0, 5 m/s west
    assert fq.cusp_times(t, v) == []


def test_a_full_loop_in_two_seconds_is_two_cusps():
    """360 deg at pi rad/s (2 s): 180 deg per second, so the window at the loop's start counts and the next
    one can start 1 s later, where again 180 deg follow: 2 cusps (then the course is straight again)."""
    t = np.arange(0, 10, DT)
    heading = np.clip(t - 4.0, 0.0, 2.0) * math.pi
    assert len(fq.cusp_times(t, course(t, heading, 6.0))) == 2


def test_a_wide_turn_is_no_cusp():
    """90 deg over 3 s (30 deg/s): never more than 30 deg within 1 s."""
    t = np.arange(0, 10, DT)
    heading = np.clip((t - 2.0) / 3.0, 0.0, 1.0) * math.pi / 2
    assert fq.cusp_times(t, course(t, heading, 10.0)) == []


def test_a_command_step_has_the_rate_of_one_tick():
    """Pitch steps by 0.2 rad between two 20 ms ticks: 10 rad/s; roll ramps at 0.5 rad/s; yaw crosses +-pi
    at 0.3 rad/s (unwrapped, not a 2 pi jump)."""
    t = np.arange(0, 2, DT)
    att = np.zeros((len(t), 1, 3))
    att[50:, 0, 1] = 0.2
    att[:, 0, 0] = 0.5 * t
    att[:, 0, 2] = (math.pi - 0.3 + 0.3 * t + math.pi) % (2 * math.pi) - math.pi
    _, rates = fq.command_rates(t, att)
    assert np.abs(rates[:, 0, 1]).max() == pytest.approx(10.0)
    np.testing.assert_allclose(rates[:, 0, 0], 0.5)
    np.testing.assert_allclose(rates[:, 0, 2], 0.3, atol=1e-9)


def test_jerk_of_a_sinusoid():
    """x = A sin(w t): jerk -A w^3 cos(w t), so |jerk| peaks at A w^3 and its 99th percentile over whole
    periods is A w^3 cos(0.01 * pi / 2)... = within 0.1 % of A w^3. A = 2 m, w = 2 rad/s: 16 m/s^3."""
    t = np.arange(0, 20 * math.pi / 2, DT)  # 10 periods
    a, w = 2.0, 2.0
    vel = np.zeros((len(t), 1, 3))
    vel[:, 0, 0] = a * w * np.cos(w * t)
    jerk = fq.true_jerk(t, vel)
    assert np.percentile(jerk[10:-10], 99) == pytest.approx(a * w**3, rel=0.01)


def test_jerk_of_a_constant_acceleration_is_zero():
    t = np.arange(0, 5, DT)
    vel = np.zeros((len(t), 1, 3))
    vel[:, 0, 1] = 3.0 * t
    assert fq.true_jerk(t, vel).max() == pytest.approx(0.0, abs=1e-9)


def test_path_ratio_of_a_detour():
    """A 3-4-5 detour: from (0,0) to (3,4) to (6,0): 10 m over a straight 6 m route."""
    pos = np.array([[0.0, 0, 0], [3.0, 4, 0], [6.0, 0, 0]])
    assert fq.path_ratio(pos, np.array([[0.0, 0, 0], [6.0, 0, 0]])) == pytest.approx(10.0 / 6.0)


def test_time_below_a_distance():
    """Two vehicles 5 m apart close to 1 m over 4 s at 1 m/s: below 3 m from t = 2 s to the end (2 s)."""
    t = np.arange(0, 4 + DT / 2, DT)
    pos = np.zeros((len(t), 2, 3))
    pos[:, 1, 0] = 5.0 - t
    below, closest = fq.time_below(t, pos, 3.0)
    assert below == pytest.approx(2.0, abs=1.5 * DT)  # sample-counted: within a sample of the exact 2 s
    assert closest == pytest.approx(1.0)


def test_whole_flight_figures_of_a_known_flight():
    """A leader flies straight at 10 m/s; a follower flies 4 m off its slot for the first half and on it for
    the second: slot error rms sqrt(16/2) = 2.83 m, max 4 m; 0 cusps; altitude 9 m against a formation at
    10 m: a 1 m drop; a pitch command that ramps smoothly has no chatter."""
    t = np.arange(0, 10, DT)
    pos = np.zeros((len(t), 2, 3))
    vel = np.zeros_like(pos)
    pos[:, :, 0] = 10.0 * t[:, None]
    vel[:, :, 0] = 10.0
    pos[:, :, 2] = 9.0
    slot_error = np.zeros((len(t), 2))
    slot_error[:, 0] = np.nan
    slot_error[t < 5.0, 1] = 4.0
    att = np.zeros((len(t), 2, 3))
    att[:, :, 1] = 0.01 * t[:, None]
    out = fq.whole_flight_figures(
        t, pos, vel, slot_error, np.array([[0.0, 0, 9], [100.0, 0, 9]]), 0,
        (0.0, 10.0), np.array([10.0, 10.0]), (0.0, 10.0), (t, att), ["lead", "f"],
    )  # fmt: skip
    assert out["slot_error_rms_m"] == pytest.approx(math.sqrt(8.0), rel=0.01)
    assert out["slot_error_max_m"] == 4.0
    assert out["cusps"] == [0, 0]
    assert out["max_drop_below_formation_altitude_m"] == pytest.approx(1.0)
    assert out["min_altitude_in_formation_m"] == pytest.approx(9.0)
    assert out["pitch_command_chatter_max_rad"] == pytest.approx(0.0, abs=1e-9)
    assert out["max_tilt_command_rate_rad_s"] == pytest.approx(0.01)
    assert out["leader_path_ratio"] == pytest.approx(99.8 / 100.0, rel=1e-3)  # flies 99.8 m of 100 in 9.98 s


def test_the_cusps_are_timed_from_the_formations_start():
    """Formation flight from t = 2 s; the follower reverses in 0.5 s at 5 m/s from t = 6 s, the leader flies
    straight. The follower's course has turned 90 deg at 6.25 s, so the first 1 s window across more than 90
    deg starts at t_j = 5.25 s (to within a sample): one cusp, timed 3.25 s after the formation's start."""
    t = np.arange(0, 10, DT)
    vel = np.zeros((len(t), 2, 3))
    vel[:, 0, 0] = 5.0
    heading = np.clip((t - 6.0) / 0.5, 0.0, 1.0) * math.pi
    vel[:, 1, :2] = course(t, heading, 5.0)
    pos = np.cumsum(vel, axis=0) * DT
    out = fq.whole_flight_figures(
        t, pos, vel, None, np.array([[0.0, 0, 0], [50.0, 0, 0]]), 0,
        (2.0, 10.0), np.array([0.0, 0.0]), (0.0, 10.0), None, ["lead", "f"],
    )  # fmt: skip
    assert out["cusps"] == [0, 1]
    (only,) = out["cusp_times_s"][1]
    assert out["cusp_times_s"][0] == [] and only == pytest.approx(3.25, abs=DT)


def test_jerk_of_a_vehicle_with_a_gap_is_fitted_on_each_stretch():
    """v_x = t^3 m/s: the jerk d^2v/dt^2 = 6 t, which the cubic Savitzky-Golay fit gives exactly. Vehicle 1
    has no velocity (a truth gap: NaN) for 1 s in the middle and for a stretch of 3 samples (too short: NaN),
    vehicle 0 none missing; both get 6 t wherever they have a long enough stretch."""
    t = np.arange(0.0, 4.0, 0.02)
    vel = np.zeros((len(t), 2, 3))
    vel[:, :, 0] = (t**3)[:, None]
    gap = (t >= 1.5) & (t < 2.5)
    vel[gap, 1] = np.nan
    short = slice(len(t) - 10, len(t) - 7)
    vel[len(t) - 11, 1] = np.nan
    vel[len(t) - 7, 1] = np.nan
    jerk = fq.true_jerk(t, vel)
    np.testing.assert_allclose(jerk[:, 0], 6.0 * t, rtol=1e-6, atol=1e-6)
    fitted = np.isfinite(jerk[:, 1])
    np.testing.assert_allclose(jerk[fitted, 1], 6.0 * t[fitted], rtol=1e-6, atol=1e-6)
    assert not fitted[gap].any() and not fitted[short].any()
    assert fitted[: np.flatnonzero(gap)[0]].all()


def test_jerk_of_too_short_a_log_is_unknown_not_zero():
    assert np.isnan(fq.true_jerk(np.arange(5) * 0.02, np.ones((5, 2, 3)))).all()
