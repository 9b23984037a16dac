"""LegTracker: the leg a leader flies, from its controller's waypoint progress (gcs_swarm.flight.legs)."""

from __future__ import annotations

from gcs_swarm.flight.legs import LegTracker
from gcs_swarm.mission.model import Leg

# three legs over a route of six waypoints: [0, 1], [2, 3, 4], [5]
LEGS = (
    Leg("a", 0, "v", 10.0, 10.0, None),
    Leg("b", 2, "line", 8.0, 6.0, None),
    Leg("c", 5, "column", 8.0, 8.0, 15.0),
)


def test_a_leg_is_due_once_when_the_leader_reaches_its_first_waypoint() -> None:
    tracker = LegTracker(LEGS)
    assert tracker.flown is None
    assert [tracker.due(k) for k in (0, 0, 1, 2, 2, 3, 4, 5, 5)] == [
        0,
        None,
        None,
        1,
        None,
        None,
        None,
        2,
        None,
    ]
    assert tracker.flown is LEGS[2]


def test_legs_passed_within_one_tick_are_skipped_to_the_latest() -> None:
    tracker = LegTracker(LEGS)
    assert tracker.due(0) == 0
    assert tracker.due(5) == 2  # leg b was never flown
    assert tracker.due(2) is None  # progress does not go back


def test_a_new_controller_counting_from_the_remaining_waypoints_keeps_the_legs_in_step() -> None:
    tracker = LegTracker(LEGS)
    assert tracker.due(1) == 0
    tracker.rebase(1)  # the lead passed on at mission waypoint 1: the new list starts there
    assert tracker.due(0) is None  # mission waypoint 1: still leg a
    assert tracker.due(1) == 1  # mission waypoint 2: leg b
    tracker.rebase(3)  # and again at mission waypoint 4 (the new list's index 3)
    assert tracker.due(1) == 2  # mission waypoint 5


def test_no_leg_starts_once_the_operator_moved_the_goal_nor_without_legs() -> None:
    tracker = LegTracker(LEGS)
    assert tracker.due(0) == 0
    tracker.ended = True
    assert tracker.due(5) is None and tracker.flown is None
    empty = LegTracker(())
    assert empty.due(0) is None and empty.flown is None
