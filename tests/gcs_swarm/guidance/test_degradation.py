"""Stale-telemetry policy: prediction, degraded mode with its recovery time, holds (docs/reliability.md)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_swarm.guidance import degradation
from gcs_swarm.guidance.degradation import StaleTelemetryMonitor
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.params import TelemetryParams

P = TelemetryParams(
    predict_s=0.3, hold_s=1.0, lost_s=3.0, degraded_speed=0.5, degraded_spacing=1.5, recover_s=2.0
)
POS = np.array([[0.0, 0.0, 10.0], [10.0, 0.0, 10.0], [20.0, 0.0, 10.0]])
VEL = np.array([[10.0, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, -1.0]])
ALIVE = np.ones(3, dtype=bool)


def test_fresh_telemetry_is_predicted_forward_and_flown_normally() -> None:
    verdict = StaleTelemetryMonitor(P).assess(0.0, POS, VEL, np.array([0.0, 0.1, 0.2]), ALIVE, leader=0)
    np.testing.assert_allclose(verdict.pos, POS + VEL * np.array([[0.0], [0.1], [0.2]]))
    assert not verdict.degraded and not verdict.held.any()
    assert (verdict.speed_scale, verdict.spacing_scale) == (1.0, 1.0)


def test_an_old_follower_degrades_the_fleet_until_recover_s_of_fresh_telemetry() -> None:
    monitor = StaleTelemetryMonitor(P)
    late = monitor.assess(10.0, POS, VEL, np.array([0.0, 0.5, 0.0]), ALIVE, leader=0)
    assert late.degraded and (late.speed_scale, late.spacing_scale) == (0.5, 1.5)
    assert not late.held.any()
    np.testing.assert_allclose(late.pos[1], POS[1] + VEL[1] * 0.5)
    fresh = np.zeros(3)
    assert monitor.assess(11.9, POS, VEL, fresh, ALIVE, leader=0).degraded
    recovered = monitor.assess(12.01, POS, VEL, fresh, ALIVE, leader=0)
    assert not recovered.degraded and recovered.speed_scale == 1.0


def test_a_follower_older_than_hold_s_is_held_until_within_predict_s() -> None:
    monitor = StaleTelemetryMonitor(P)
    held = monitor.assess(0.0, POS, VEL, np.array([0.0, 1.2, 0.0]), ALIVE, leader=0)
    assert held.held.tolist() == [False, True, False]
    np.testing.assert_array_equal(held.pos[1], POS[1])  # a held vehicle is not extrapolated
    still = monitor.assess(0.02, POS, VEL, np.array([0.0, 0.5, 0.0]), ALIVE, leader=0)
    assert still.held.tolist() == [False, True, False]  # hysteresis: 0.5 s is not fresh
    back = monitor.assess(0.04, POS, VEL, np.array([0.0, 0.2, 0.0]), ALIVE, leader=0)
    assert not back.held.any()


def test_a_held_leader_holds_every_live_vehicle_and_lost_ones_are_not_held() -> None:
    alive = np.array([True, True, False])
    verdict = StaleTelemetryMonitor(P).assess(0.0, POS, VEL, np.array([2.0, 0.0, np.inf]), alive, leader=0)
    assert verdict.held.tolist() == [True, True, False]


def test_missing_or_non_finite_ages_count_as_old() -> None:
    verdict = StaleTelemetryMonitor(P).assess(0.0, POS, VEL, np.array([0.0, np.nan, np.inf]), ALIVE, leader=0)
    assert verdict.held.tolist() == [False, True, True] and verdict.degraded
    assert np.isfinite(verdict.pos).all()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"predict_s": 1.0, "hold_s": 1.0},
        {"hold_s": 4.0},
        {"degraded_speed": 0.0},
        {"degraded_speed": 1.5},
        {"degraded_spacing": 0.9},
        {"recover_s": -1.0},
    ],
)
def test_inconsistent_telemetry_params_are_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(ValueError):
        TelemetryParams(**kwargs)


V_POS = np.array([[0.0, 0, 10], [-10, 10, 10], [-10, -10, 10]])  # a V at its slots, leader first


def _controller() -> FleetController:
    ctl = FleetController(3, 0, V_POS - V_POS[0], np.array([[1000.0, 0.0, 10.0]]))
    ctl.reset(V_POS, np.zeros((3, 3)), np.zeros(3))
    return ctl


def test_degraded_controller_widens_slots_and_caps_the_reference_speed() -> None:
    pos = V_POS
    normal, slow = _controller(), _controller()
    slow.set_degraded(0.5, 1.5)
    obstacles = (np.zeros((0, 3)), np.zeros(0))
    for k in range(500):  # 10 s of reference integration with the state held at the start
        a = normal.tick(k * 0.02, pos, np.zeros((3, 3)), np.zeros((3, 3)), *obstacles, ALIVE)
        b = slow.tick(k * 0.02, pos, np.zeros((3, 3)), np.zeros((3, 3)), *obstacles, ALIVE)
    np.testing.assert_allclose(b.slots[1:] - pos[0], 1.5 * (a.slots[1:] - pos[0]), atol=1e-9)
    lead_speed = np.linalg.norm(b.ref_vel[0, :2])
    assert lead_speed <= 0.5 * normal.limits.v_xy_leader + 1e-9
    assert np.linalg.norm(a.ref_vel[0, :2]) > 0.9 * normal.limits.v_xy_leader
    with pytest.raises(ValueError):
        slow.set_degraded(0.0, 1.0)


ages = st.one_of(
    st.floats(-1.0, 5.0),
    st.sampled_from([0.0, -0.0, 0.3, 1.0, float("inf"), float("-inf"), float("nan")]),
)


@given(
    st.lists(st.tuples(ages, st.booleans(), st.booleans()), min_size=1, max_size=9),
    st.integers(0, 8),
    st.integers(0, 2**32 - 1),
)
def test_the_rule_holds_row_by_row(rows, leader, seed) -> None:
    """The rule of docs/reliability.md, checked row by row: a live vehicle is held for its own telemetry when
    its age is not within hold_s, or it was held and its age is not yet within predict_s (NaN and inf ages
    count as old, so a comparison that fails holds); a held leader holds every live vehicle; the fleet is
    late when a live age is not within predict_s; an unheld vehicle is predicted pos + vel * age with the
    age clipped to [0, hold_s] (NaN and inf: no prediction). Ages at and around the limits, negative,
    signed zeros, infinite and NaN, any mix of live and previously held vehicles, any leader."""
    age = np.array([r[0] for r in rows])
    alive, was = (np.array([r[k] for r in rows], dtype=bool) for k in (1, 2))
    rng = np.random.default_rng(seed)
    pos, vel = rng.normal(0.0, 100.0, (len(rows), 3)), rng.normal(0.0, 10.0, (len(rows), 3))
    lead = leader % len(rows)
    held, own, late, predicted = degradation.stale_verdict(age, alive, was, pos, vel, lead, 1.0, 0.3)
    for i, (a, live, before) in enumerate(rows):
        fresh, recent = a <= 1.0, a <= 0.3  # False for NaN
        assert own[i] == (live and (not fresh or (before and not recent)))
        assert held[i] == (live if own[lead] else own[i])
        horizon = 0.0 if held[i] or not np.isfinite(a) else min(max(a, 0.0), 1.0)
        np.testing.assert_array_equal(predicted[i], pos[i] + vel[i] * horizon)
    assert late == any(live and not a <= 0.3 for a, live, _ in rows)
    assert held.dtype == bool and own.dtype == bool
