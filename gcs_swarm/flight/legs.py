"""Which leg of the mission's route the leader flies (mission key `legs`, model.Leg) [add] (issue 37).

The controller counts the leader's progress as an index into its own waypoint list; that list is the
mission's route until the lead passes to another vehicle (its remaining waypoints) or the operator moves the
goal (the legs end there). `LegTracker` maps the progress back onto the mission's legs, so that the runner
changes formation and speed when, and only when, the leader starts a new leg.
"""

from __future__ import annotations

from gcs_swarm.mission.model import Leg, leg_at


class LegTracker:
    """The leg flown; `due` says when a new one starts. Without legs it never does."""

    def __init__(self, legs: tuple[Leg, ...]) -> None:
        self.legs = legs
        self.current: int | None = None  # index into legs of the leg flown (None: before the first)
        self.offset = 0  # mission waypoints passed before the controller's own list begins
        self.ended = False  # the operator moved the goal: no leg starts any more

    def due(self, waypoint_index: int) -> int | None:
        """The index of the leg that starts now, the controller being at its waypoint `waypoint_index`, or
        None (the leg flown goes on). Legs the leader passed in one tick are skipped to the latest."""
        if not self.legs or self.ended:
            return None
        k = leg_at(self.legs, self.offset + waypoint_index)
        if self.current is not None and k <= self.current:
            return None
        self.current = k
        return k

    def rebase(self, waypoint_index: int) -> None:
        """The controller is replaced by one whose list starts at its predecessor's waypoint `waypoint_index`
        (a new leader flies on to the remaining waypoints)."""
        self.offset += waypoint_index

    @property
    def flown(self) -> Leg | None:
        """The leg flown now (None: no legs, before the first, or ended)."""
        return None if self.current is None or self.ended else self.legs[self.current]
