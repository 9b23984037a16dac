"""Which follower takes which slot [add]: the assignment that minimises the longest move (bottleneck) and
whose straight, synchronised moves neither cross nor bring two vehicles within a given gap.

Followers move from their starts to their slots together, each on a straight line at a speed proportional to
its length (everyone arrives at once; this is how the formation assembles and how a reshape interpolates the
slots). The rule, `assign_moves`:

1. the least longest move t* over all assignments (bottleneck assignment: bisection over the sorted
   distances, a perfect matching among the moves no longer than the candidate by
   scipy.sparse.csgraph.maximum_bipartite_matching);
2. among the assignments using only moves <= t*, the least total travel
   (scipy.optimize.linear_sum_assignment);
3. if in that assignment two moves cross in the horizontal plane or two vehicles come closer than `min_gap`
   while moving (or than they stand at the start or at their slots, where that is closer: `gap_floor`), the
   least total travel over all assignments (its moves never cross: two crossing moves
   could swap ends and both get shorter, by the triangle inequality), and if even that brings two vehicles
   within the gap, the least sum of squared moves (CAPT, Turpin, Michael and Kumar 2014: synchronised
   straight moves of that assignment keep vehicles apart whenever the starts and the slots are at least
   sqrt(2) times as far apart as they must stay).

Positions are (M, 3) ENU or leader-frame metres, one row per follower to place.
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse import csr_array
from scipy.sparse.csgraph import maximum_bipartite_matching

from swarm_common.approach import segment_min_norm
from swarm_common.jit import kernel


class AssignmentRule(StrEnum):
    """Which step of `assign_moves` gave the assignment (module docstring)."""

    BOTTLENECK = "shortest longest move"
    LEAST_TRAVEL = "least total travel"
    LEAST_SQUARES = "least squared travel"


def _perfect_within(distance: np.ndarray, limit: float) -> bool:
    """Whether every row can take its own column using only entries <= limit (M, M)."""
    matching = maximum_bipartite_matching(csr_array(distance <= limit), perm_type="column")
    return bool((matching >= 0).all())


def bottleneck_distance(distance: np.ndarray) -> float:
    """The least possible longest move (m) of an assignment of rows to columns of the (M, M) distances."""
    values = np.unique(distance)
    lo, hi = 0, len(values) - 1  # values[hi] always admits a perfect matching
    while lo < hi:
        mid = (lo + hi) // 2
        if _perfect_within(distance, float(values[mid])):
            hi = mid
        else:
            lo = mid + 1
    return float(values[lo])


def crossing_pairs(starts: np.ndarray, goals: np.ndarray) -> bool:
    """Whether the horizontal projections of any two segments starts[i]-goals[i] (M, 3) properly intersect
    (each strictly separates the other's ends)."""
    if len(starts) < 2:
        return False
    a0, a1 = starts[:, None, :2], goals[:, None, :2]  # segment i along rows
    b0, b1 = starts[None, :, :2], goals[None, :, :2]  # segment j along columns

    def side(p: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
        return (q[..., 0] - p[..., 0]) * (r[..., 1] - p[..., 1]) - (q[..., 1] - p[..., 1]) * (
            r[..., 0] - p[..., 0]
        )

    cross = (side(b0, b1, a0) * side(b0, b1, a1) < 0.0) & (side(a0, a1, b0) * side(a0, a1, b1) < 0.0)
    return bool(cross.any())


@kernel
def closest_approach(starts: np.ndarray, goals: np.ndarray) -> float:
    """Smallest distance (m) between any two of the (M, 3) vehicles moving together on straight lines from
    `starts` to `goals` (positions s + lam (g - s), lam in [0, 1]): each pair's relative position moves
    linearly (swarm_common.approach.segment_min_norm); inf for fewer than two. Compiled: every change of
    shape checks it for each way its slots may move, a hundred slots at a time (reshape.plan_move)."""
    best = math.inf
    for i in range(starts.shape[0]):
        for j in range(i + 1, starts.shape[0]):
            best = min(
                best,
                segment_min_norm(
                    starts[i, 0] - starts[j, 0], starts[i, 1] - starts[j, 1], starts[i, 2] - starts[j, 2],
                    goals[i, 0] - goals[j, 0], goals[i, 1] - goals[j, 1], goals[i, 2] - goals[j, 2],
                ),
            )  # fmt: skip
    return best


def gap_floor(starts: np.ndarray, goals: np.ndarray, min_gap: float) -> float:
    """The distance m the moves starts -> goals (M, 3) must keep between vehicles: min_gap, or less where the
    vehicles already stand closer at the start or will at their slots (no assignment can do better there)."""
    return min(min_gap, closest_approach(starts, starts), closest_approach(goals, goals))


def moves_conflict(starts: np.ndarray, goals: np.ndarray, min_gap: float) -> bool:
    """Whether any two of the straight moves starts -> goals (M, 3) cross in the horizontal plane or bring
    two vehicles closer than `gap_floor` while they move together."""
    if crossing_pairs(starts, goals):
        return True
    return closest_approach(starts, goals) < gap_floor(starts, goals, min_gap)


def assign_moves(starts: np.ndarray, goals: np.ndarray, min_gap: float) -> tuple[np.ndarray, AssignmentRule]:
    """The slot for each vehicle: `order` (M,) with vehicle k taking goals[order[k]], by the rule of the
    module docstring, and which step decided it. starts, goals (M, 3) m; min_gap m."""
    starts, goals = np.asarray(starts, dtype=float), np.asarray(goals, dtype=float)
    m = len(starts)
    if m < 2:
        return np.arange(m), AssignmentRule.BOTTLENECK
    distance = np.linalg.norm(starts[:, None, :] - goals[None, :, :], axis=-1)
    longest = bottleneck_distance(distance)
    excluded = distance.max() * m + 1.0  # dearer than any assignment within the bottleneck
    cost = np.where(distance <= longest, distance, excluded)
    _, order = linear_sum_assignment(cost)
    if not moves_conflict(starts, goals[order], min_gap):
        return order, AssignmentRule.BOTTLENECK
    _, order = linear_sum_assignment(distance)
    if closest_approach(starts, goals[order]) >= gap_floor(starts, goals, min_gap):
        return order, AssignmentRule.LEAST_TRAVEL
    _, order = linear_sum_assignment(distance * distance)
    return order, AssignmentRule.LEAST_SQUARES
