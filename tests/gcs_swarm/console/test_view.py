"""The console's displayed figures and their text rendering (fleet table, mission line, events, status)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from gcs_swarm.console.session import ConsoleEvent
from gcs_swarm.console.snapshot import (
    MissionLine,
    Snapshot,
    StreamLoss,
    VehicleRow,
    empty_snapshot,
    is_airborne,
    nearest_neighbour,
    obstacle_clearance,
    vehicle_warnings,
)
from gcs_swarm.console.view import event_line, fleet_table, mission_line, plain, status_lines
from gcs_swarm.flight.phase import Phase


def row(name: str, **changes: object) -> VehicleRow:
    base = VehicleRow(
        name=name,
        sysid=1,
        alive=True,
        age_s=0.1,
        loss=0.0,
        mode="GUIDED",
        armed=True,
        airborne=True,
        position=(1.0, 2.0, 10.0),
        speed=5.0,
        slot_error=0.8,
        obstacle=12.0,
        neighbour=9.5,
        warnings=(),
    )
    return replace(base, **changes)


def snapshot(rows: tuple[VehicleRow, ...], phase: Phase = Phase.FORMATION) -> Snapshot:
    line = MissionLine(phase, True, 23.4, 45.2, (160.0, 120.0, 10.0), 1.23, 7.54, "")
    return Snapshot("ready", rows, line, (Phase.CONNECT, phase), ())


def test_nearest_neighbour_ignores_unknown_positions() -> None:
    pos = np.array([[0.0, 0, 0], [3, 4, 0], [0, 0, 12], [np.nan, np.nan, np.nan]])
    assert nearest_neighbour(pos)[:3] == pytest.approx([5.0, 5.0, 12.0])
    assert math.isnan(nearest_neighbour(pos)[3])
    assert math.isnan(nearest_neighbour(np.zeros((1, 3)))[0])


def test_obstacle_clearance_is_to_the_nearest_surface() -> None:
    pos = np.array([[0.0, 0, 0], [10, 0, 0]])
    centres = np.array([[0.0, 5, 0], [20, 0, 0]])
    radii = np.array([1.0, 4.0])
    assert obstacle_clearance(pos, centres, radii) == pytest.approx([4.0, 6.0])
    assert np.isnan(obstacle_clearance(pos, np.zeros((0, 3)), np.zeros(0))).all()


def test_warnings_most_severe_first() -> None:
    assert vehicle_warnings(True, 0.1, 4, False, False) == ()
    assert vehicle_warnings(True, 2.0, 4, False, True) == ("STALE", "EMERGENCY")
    assert vehicle_warnings(False, 9.0, 5, False, False) == ("LOST", "FAILSAFE")
    assert vehicle_warnings(True, 0.1, 6, False, False) == ("CRASHED",)
    assert vehicle_warnings(True, 0.1, 4, True, False) == ("CRASHED",)


def test_airborne() -> None:
    assert is_airborne(True, 2, 0.0)
    assert not is_airborne(False, 2, 10.0)
    assert not is_airborne(True, 1, 10.0)
    assert is_airborne(True, 0, 3.0) and not is_airborne(True, 0, 0.1)


def test_stream_loss_from_stamps_and_counts() -> None:
    loss = StreamLoss(2, window_s=3.0)
    assert loss.fraction(0) is None
    loss.set_interval(0, 20.0)
    loss.set_interval(1, 20.0)
    for k in range(1, 101):  # 2 s at 50 Hz; vehicle 1 loses every other message
        loss.update(np.array([20 * k, 40 * (k // 2)]), np.array([k, k // 2]))
    assert loss.fraction(0) == pytest.approx(0.0)
    assert loss.fraction(1) == pytest.approx(0.5, abs=0.02)


def test_fleet_table_lines_up_and_styles_warnings() -> None:
    rows = (
        row("lead", slot_error=None),
        row("right", warnings=("EMERGENCY",), neighbour=2.1),
        row("far-away-7", alive=False, warnings=("LOST",), loss=None),
    )
    lines = fleet_table(snapshot(rows))
    text = [plain(line) for line in lines]
    assert (
        text[0].split()
        == (
            "name sysid age s loss rtt ms mode armed alt m m/s slot m obst m near m up B/s dn B/s budget "
            "warnings"
        ).split()
    )
    assert text[1].split()[:10] == ["lead", "1", "0.1", "0%", "-", "GUIDED", "ARMED", "10.0", "5.0", "lead"]
    assert text[2].endswith("EMERGENCY") and "2.1" in text[2]
    assert "LOST" in text[3] and text[3].split()[3] == "-"
    assert len({line.index("mode") if k == 0 else line.index("GUIDED") for k, line in enumerate(text)}) == 1
    assert ("class:emergency", "EMERGENCY") in lines[2]
    assert ("class:crashed", "LOST") in lines[3]
    assert lines[3][0][0] == "class:stale"


def test_mission_line_and_states() -> None:
    text = plain(mission_line(snapshot((row("lead"),))))
    for part in (
        "phase formation",
        "t 23.4 s",
        "leader to goal 45.2 m",
        "rms 1.23 m",
        "min separation 7.54 m",
    ):
        assert part in text
    assert "connecting" in plain(mission_line(empty_snapshot(["a"])))
    failed = replace(empty_snapshot(["a"]), state="failed", error="no HEARTBEAT from a")
    assert "no HEARTBEAT from a" in plain(mission_line(failed))
    idle = replace(
        snapshot((row("lead"),), "connect"),
        mission=replace(snapshot(()).mission, phase=Phase.CONNECT, started=False),
    )
    assert plain(mission_line(idle)).startswith("phase ready")
    assert "busy" not in text
    arming = replace(snapshot(()), mission=replace(snapshot(()).mission, busy="arm lead", busy_s=2.34))
    assert plain(mission_line(arming)).startswith("phase formation  [busy 2.3 s: arm lead]  t 23.4 s")


def test_event_and_status_lines() -> None:
    refused = ConsoleEvent(7, 12.345, "console", "uav2 refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED", "error")
    assert (
        plain(event_line(refused))
        == "[   12.35] console: error: uav2 refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED"
    )
    assert event_line(refused)[1][0] == "class:error"
    lines = status_lines(snapshot((row("lead"), row("right", warnings=("STALE",)))))
    assert len(lines) == 3
    assert "lead (sysid 1): GUIDED armed, airborne, at (1.0, 2.0, 10.0) m" in lines[1]
    assert lines[2].endswith("STALE")


def test_fleet_table_shows_link_use_beside_the_budget() -> None:
    """Up 3150 B/s (SET_ATTITUDE_TARGET: 63 bytes at 50 Hz) and down 4000 B/s (two 40-byte messages at 50 Hz)
    against a budget of 6275 B/s (a 64 kbit/s SiK radio, 10.2 bit times a byte): 7150 > 6275, over it."""
    rows = (
        row("lead", up_B_s=3150.0, down_B_s=4000.0, budget_B_s=6275.0),
        row("right", up_B_s=1000.0, down_B_s=2000.0, budget_B_s=6275.0),
        row("left"),  # not measured yet, no budget
    )
    lines = fleet_table(snapshot(rows))
    text = [plain(line) for line in lines]
    assert text[1].split()[12:16] == ["3150", "4000", "6275", "OVER"]
    assert ("class:failsafe", "OVER BUDGET") in lines[1]
    assert text[2].split()[12:15] == ["1000", "2000", "6275"] and "OVER" not in text[2]
    assert text[3].split()[12:15] == ["-", "-", "-"]
    status = status_lines(snapshot(rows))
    assert "link 3150 B/s up 4000 B/s down (budget 6275 B/s)" in status[1]
