"""The phases of a mission run, in the order a run passes through them (gcs_swarm.flight.runner drives them).

A `StrEnum`: each phase is its lower-case name wherever it is written out (record.csv's phase column,
flight.json's `phase_reached`, progress lines, the console), so files and messages read as before.
"""

from __future__ import annotations

from enum import StrEnum


class Phase(StrEnum):
    """One phase of a run."""

    CONNECT = "connect"  # finding the vehicles, binding them, asking for telemetry
    PREFLIGHT = "preflight"  # checks, parameters, waiting for the EKFs
    LAUNCH = "launch"  # arming, take-off and the climb to formation altitude
    FORMATION = "formation"  # formation flight toward the goal
    HOLD = "hold"  # every vehicle brakes and holds (operator pause, waiting for a leader)
    LAND = "land"  # landing every vehicle
    DONE = "done"  # on the ground, the run is over

    @property
    def airborne(self) -> bool:
        """The ground station commands vehicles in the air: launch, formation or hold."""
        return self in AIRBORNE

    @property
    def in_formation(self) -> bool:
        """Formation flight or its pause (hold): the formation's slots and leader mean something."""
        return self in FORMATION_PHASES


AIRBORNE = frozenset({Phase.LAUNCH, Phase.FORMATION, Phase.HOLD})
FORMATION_PHASES = frozenset({Phase.FORMATION, Phase.HOLD})
