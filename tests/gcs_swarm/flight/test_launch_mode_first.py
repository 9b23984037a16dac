"""Preflight puts a PX4 left in OFFBOARD by its last flight (PX4 returns to the last armable mode after
"Disarmed by landing"; its arming checks never pass in OFFBOARD without setpoints) into its launch mode before
awaiting its pre-arm checks; ArduCopters, and PX4s already in their launch mode or armed, are left alone."""

from __future__ import annotations

import numpy as np

from gcs_swarm.flight.preflight import into_launch_mode
from gcs_swarm.link.autopilots import ARDUPILOT, PX4, ModeChoice, mode_name_in

OFFBOARD, LOITER = 6 << 16, (4 << 16) | (3 << 24)  # px4_custom_mode.h: main 6; main 4 sub 3
GUIDED = 4  # ArduCopter


class ModesOnly:
    """The parts of a Fleet `into_launch_mode` reads and commands."""

    def __init__(self) -> None:
        self.names = ["apm", "px4_offboard", "px4_loiter", "px4_armed", "px4_silent"]
        self.dialects = [ARDUPILOT, PX4, PX4, PX4, PX4]
        self.alive = np.array([True, True, True, True, False])
        self.armed = np.array([False, False, False, True, False])
        self.mode = np.array([GUIDED, OFFBOARD, LOITER, OFFBOARD, OFFBOARD])
        self.commanded: list[tuple[str | int, list[int]]] = []

    def mode_number(self, i: int, mode: ModeChoice) -> int:
        dialect = self.dialects[i]
        return dialect.mode_number(mode_name_in(dialect, mode))

    def set_mode_all(self, mode: ModeChoice, vehicles: list[int]) -> None:
        names = {mode_name_in(self.dialects[i], mode) for i in vehicles}
        self.commanded.append((names.pop(), list(vehicles)))


def test_only_a_disarmed_px4_out_of_its_launch_mode_is_moved() -> None:
    fleet, events = ModesOnly(), list[str]()
    into_launch_mode(fleet, events)  # type: ignore[arg-type]
    assert fleet.commanded == [("LOITER", [1])]
    assert events == ["preflight: px4_offboard put in their launch mode first"]
