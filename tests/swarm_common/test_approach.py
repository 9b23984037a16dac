"""The closest two linearly moving points come (swarm_common.approach)."""

from __future__ import annotations

import pytest

from swarm_common.approach import segment_min_norm


@pytest.mark.parametrize(
    "start, end, expected",
    [
        ((-1.0, 0.5, 0.0), (1.0, 0.5, 0.0), 0.5),  # passes 0.5 m off at the segment's middle
        ((2.0, 0.0, 0.0), (3.0, 0.0, 0.0), 2.0),  # moving away: closest at the start
        ((3.0, 0.0, 0.0), (2.0, 0.0, 0.0), 2.0),  # moving closer without passing: closest at the end
        ((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), 3**0.5),  # not moving
        ((0.0, 0.0, -4.0), (0.0, 0.0, 4.0), 0.0),  # through each other
        ((-3.0, 4.0, 12.0), (3.0, 4.0, 12.0), 12.649110640673518),  # sqrt(4^2 + 12^2) at the middle
    ],
)
def test_the_closest_approach_of_a_relative_segment(start, end, expected):
    assert segment_min_norm(*start, *end) == pytest.approx(expected, abs=1e-12)
