"""The takeover rule (gcs_swarm.flight.takeover): a vehicle is taken over when its HEARTBEAT shows a mode
other than the one the ground station itself last commanded for it; the ground station's own changes
(GUIDED at launch, BRAKE for drifting vehicles, LAND at the end, the console's mode commands) never are."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from gcs_swarm.flight.result import FlightResult
from gcs_swarm.flight.takeover import UNKNOWN_MODE, TakeoverWatch, newly_taken
from gcs_swarm.link.autopilots import DEFAULT_DIALECT, ModeChoice, mode_name_in

# ArduCopter custom_mode numbers (ArduCopter/mode.h), written out rather than taken from the code under test
GUIDED, LOITER, RTL, LAND, BRAKE = 4, 5, 6, 9, 17
NAMES = ["lead", "right", "left"]


class FakeFleet:
    """The parts of a Fleet the watch reads: names, HEARTBEAT modes, liveness, positions, each vehicle's
    dialect (ArduCopter) and mode name."""

    def __init__(self) -> None:
        self.names = NAMES
        self.mode = np.full(3, UNKNOWN_MODE, dtype=np.int64)
        self.alive = np.ones(3, dtype=bool)
        self.pos = np.array([[0.0, 0.0, 10.0], [-7.0, -7.0, 10.0], [-7.0, 7.0, 10.0]])
        self.vel = np.array([[5.0, 0.0, 0.0], [0.5, 0.0, 0.0], [np.nan, 0.0, 0.0]])

    def mode_number(self, i: int, mode: ModeChoice) -> int:
        return DEFAULT_DIALECT.mode_number(mode_name_in(DEFAULT_DIALECT, mode))

    def vehicle(self, i: int) -> SimpleNamespace:
        return SimpleNamespace(
            channel=SimpleNamespace(autopilot=DEFAULT_DIALECT),
            mode_name=lambda: DEFAULT_DIALECT.mode_name(int(self.mode[i])),
        )


def watch() -> tuple[TakeoverWatch, FakeFleet, FlightResult, list[str]]:
    fleet, result, lines = FakeFleet(), FlightResult(), list[str]()
    return TakeoverWatch(fleet, result, lines.append), fleet, result, lines  # type: ignore[arg-type]


def test_rule_table() -> None:
    """Row by row: in the commanded mode; switched by someone else; no HEARTBEAT yet; never commanded;
    not heard any more; already taken."""
    mode = np.array([GUIDED, LOITER, UNKNOWN_MODE, RTL, LOITER, BRAKE])
    commanded = np.array([GUIDED, GUIDED, GUIDED, UNKNOWN_MODE, GUIDED, GUIDED])
    alive = np.array([True, True, True, True, False, True])
    taken = np.array([False, False, False, False, False, True])
    np.testing.assert_array_equal(
        newly_taken(mode, commanded, alive, taken), [False, True, False, False, False, False]
    )


def test_own_mode_changes_are_not_takeovers() -> None:
    w, fleet, result, lines = watch()
    fleet.mode[:] = BRAKE  # before launch: the ground station stopped drifting vehicles itself
    w.commanded("BRAKE", [0, 1, 2])
    assert w.detect(1.0) == []
    w.commanded("GUIDED")  # launch
    fleet.mode[:] = GUIDED
    assert w.detect(2.0) == []
    w.commanded_landing(np.ones(3, dtype=bool))  # the end of the run
    fleet.mode[:] = LAND
    assert w.detect(3.0) == [] and not w.taken.any()
    assert result.taken_over == [] and lines == []


def test_someone_elses_mode_is_a_takeover_told_once_with_time_vehicle_and_mode() -> None:
    w, fleet, result, lines = watch()
    w.commanded("GUIDED")
    fleet.mode[:] = GUIDED
    assert w.detect(10.0) == []
    fleet.mode[2] = LOITER  # QGC / MAVProxy / an RC switch
    assert w.detect(12.5) == [2]
    np.testing.assert_array_equal(w.flown, [True, True, False])
    assert result.taken_over == [{"t_s": 12.5, "vehicle": "left", "mode": "LOITER", "by": "someone else"}]
    assert result.left_to_operator == ["left"]
    assert any(e.startswith("t=12.50 s left taken over: now in LOITER") for e in result.events)
    assert len(lines) == 1 and lines[0].startswith("! left taken over")
    assert w.detect(13.0) == []  # told once
    fleet.mode[2] = RTL  # the operator switches on: still theirs, said so
    assert w.detect(14.0) == []
    assert result.events[-1] == "t=14.00 s left (taken over) now in RTL"
    assert len(result.taken_over) == 1


def test_failsafe_after_a_loss_is_a_takeover_once_heard_again() -> None:
    """A vehicle whose GCS failsafe switched it to LAND while it was lost is taken over when heard again,
    not flown as if it still obeyed attitude targets."""
    w, fleet, result, _ = watch()
    w.commanded("GUIDED")
    fleet.mode[:] = GUIDED
    fleet.alive[1] = False
    fleet.mode[1] = LAND
    assert w.detect(5.0) == []
    fleet.alive[1] = True
    assert w.detect(6.0) == [1]
    assert result.taken_over[0]["mode"] == "LAND"


def test_console_release_and_rejoin() -> None:
    w, fleet, result, lines = watch()
    w.commanded("GUIDED")
    fleet.mode[:] = GUIDED
    w.release(1, "loiter", 20.0)  # the operator's own `mode LOITER right` in our console
    assert w.taken[1] and result.taken_over[-1]["by"] == "console"
    fleet.mode[1] = LOITER  # its HEARTBEAT then shows the mode asked for: no second line
    n_events = len(result.events)
    assert w.detect(21.0) == [] and len(result.events) == n_events
    w.commanded("GUIDED", [1])  # rejoin: GUIDED commanded, confirmed, then flown again
    fleet.mode[1] = GUIDED
    w.rejoined(1, 22.0)
    assert not w.taken.any() and result.left_to_operator == []
    assert result.events[-1] == "t=22.00 s right rejoined: back in GUIDED, flying to its slot"
    assert w.detect(23.0) == []
    w.release(0, "GUIDED", 24.0)  # GUIDED from the console hands nothing over
    assert not w.taken.any()


def test_taken_vehicles_are_moving_obstacles_at_their_measured_state() -> None:
    w, fleet, _, _ = watch()
    w.commanded("GUIDED")
    fleet.mode[:] = [GUIDED, LOITER, LOITER]
    w.detect(1.0)
    placed: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    controller = SimpleNamespace(place_uncommanded=lambda row, p, v: placed.__setitem__(row, (p, v)))
    centres, radii = w.place(controller, 3.0)  # type: ignore[arg-type]
    np.testing.assert_array_equal(centres, fleet.pos[1:])
    np.testing.assert_array_equal(radii, [3.0, 3.0])
    np.testing.assert_array_equal(placed[1][1], [0.5, 0.0, 0.0])
    np.testing.assert_array_equal(placed[2][1], [0.0, 0.0, 0.0])  # an unknown velocity component: 0
    fleet.alive[2] = False  # lost: the lost-vehicle prediction takes over (flight.lost_vehicles)
    centres, _ = w.place(controller, 3.0)  # type: ignore[arg-type]
    assert len(centres) == 1
