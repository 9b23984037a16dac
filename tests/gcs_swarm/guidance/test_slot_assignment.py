"""Slot assignment by the shortest longest move (gcs_swarm.guidance.slot_assignment), checked against brute
force over every permutation."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import pdist

from gcs_swarm.guidance.slot_assignment import (
    AssignmentRule,
    assign_moves,
    bottleneck_distance,
    closest_approach,
    gap_floor,
)


def _flat(rng: np.random.Generator, m: int, half: float) -> np.ndarray:
    return np.column_stack([rng.uniform(-half, half, (m, 2)), np.zeros(m)])


def _longest(starts: np.ndarray, goals: np.ndarray) -> float:
    return float(np.linalg.norm(starts - goals, axis=1).max())


def _crossing(a0, a1, b0, b1) -> bool:
    def orient(p, q, r):
        return np.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    return orient(a0, a1, b0) * orient(a0, a1, b1) < 0 and orient(b0, b1, a0) * orient(b0, b1, a1) < 0


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 100_000), st.integers(2, 6))
def test_bottleneck_is_the_least_longest_move_of_all_permutations(seed, m):
    rng = np.random.default_rng(seed)
    starts, goals = _flat(rng, m, 30.0), _flat(rng, m, 15.0)
    distance = np.linalg.norm(starts[:, None] - goals[None], axis=-1)
    brute = min(max(distance[i, p[i]] for i in range(m)) for p in itertools.permutations(range(m)))
    assert bottleneck_distance(distance) == pytest.approx(brute)
    order, rule = assign_moves(starts, goals, 4.0)
    assert sorted(order) == list(range(m))
    if rule is AssignmentRule.BOTTLENECK:
        assert _longest(starts, goals[order]) == pytest.approx(brute)


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 100_000))
def test_moves_never_cross_unless_only_least_squares_keeps_them_apart(seed):
    """Six followers from random spots to random slots: the moves do not cross in the plane (rules 1 and 2);
    the least-squares fallback keeps at least 1/sqrt(2) of the closer of start and slot spacing (CAPT)."""
    rng = np.random.default_rng(seed)
    starts, goals = _flat(rng, 6, 40.0), _flat(rng, 6, 20.0)
    order, rule = assign_moves(starts, goals, 4.0)
    ends = goals[order]
    if rule is AssignmentRule.LEAST_SQUARES:
        spacing = min(closest_approach(starts, starts), closest_approach(goals, goals))
        assert closest_approach(starts, ends) >= spacing / math.sqrt(2.0) - 1e-9
        return
    for i, j in itertools.combinations(range(6), 2):
        assert not _crossing(starts[i], ends[i], starts[j], ends[j])
    assert closest_approach(starts, ends) >= gap_floor(starts, goals, 4.0) - 1e-9


def test_the_longest_move_is_never_longer_than_least_total_travel_and_often_shorter():
    """Over 300 random launches of seven followers the longest move is never longer than that of the least
    total travel assignment (the rule before issue 36), and shorter in some."""
    from scipy.optimize import linear_sum_assignment

    rng = np.random.default_rng(7)
    shorter = 0
    for _ in range(300):
        starts, goals = _flat(rng, 7, 30.0), _flat(rng, 7, 20.0)
        distance = np.linalg.norm(starts[:, None] - goals[None], axis=-1)
        _, least_travel = linear_sum_assignment(distance)
        order, rule = assign_moves(starts, goals, 4.0)
        old, new = _longest(starts, goals[least_travel]), _longest(starts, goals[order])
        if rule is not AssignmentRule.LEAST_SQUARES:
            assert new <= old + 1e-9
        shorter += new < old - 1e-6
    assert shorter > 10


def test_a_launch_row_fills_a_v_without_sending_anyone_across():
    """Four followers on a launch row 6 m apart behind the leader, V slots 10 m apart: each takes the slot on
    its own side (the two left spots the left arm), so no move crosses the row."""
    starts = np.array([[-6.0, 9.0, 0.0], [-6.0, 3.0, 0.0], [-6.0, -3.0, 0.0], [-6.0, -9.0, 0.0]])
    a = math.radians(45.0)
    goals = np.array(
        [[-r * 10 * math.cos(a), s * r * 10 * math.sin(a), 0.0] for r in (1, 2) for s in (-1, 1)]
    )
    order, rule = assign_moves(starts, goals, 4.0)
    assert rule is AssignmentRule.BOTTLENECK
    assert all(np.sign(goals[order][k, 1]) == np.sign(starts[k, 1]) for k in range(4))


def test_one_or_no_follower_keeps_its_slot():
    one = np.array([[1.0, 2.0, 3.0]])
    assert assign_moves(one, one + 5.0, 4.0)[0].tolist() == [0]
    assert assign_moves(np.zeros((0, 3)), np.zeros((0, 3)), 4.0)[0].tolist() == []


@pytest.mark.parametrize("seed", range(5))
def test_the_closest_approach_is_the_least_distance_sampled_along_the_moves(seed):
    """closest_approach (compiled, exact) against the moves sampled at 20001 moments with scipy's pdist: never
    above the sampled least, and within what the pairs' relative speed covers between two samples; inf for a
    single vehicle."""
    rng = np.random.default_rng(seed)
    starts, goals = rng.uniform(-30.0, 30.0, (8, 3)), rng.uniform(-30.0, 30.0, (8, 3))
    lam = np.linspace(0.0, 1.0, 20001)
    sampled = min(float(pdist(starts + k * (goals - starts)).min()) for k in lam)
    step = float(pdist(goals - starts).max()) / (len(lam) - 1)  # m a pair's separation changes per sample
    exact = closest_approach(starts, goals)
    assert exact <= sampled + 1e-9
    assert exact >= sampled - step
    assert closest_approach(starts[:1], goals[:1]) == math.inf
