"""Stale telemetry in formation flight (gcs_swarm.flight.stale_telemetry) as the runner reports it: the lines
reach whichever progress callback the runner has *now* (the console replaces the one the runner was built
with), like the takeover lines."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.mission import load_mission
from tests.gcs_swarm.flight.scripted_fleet import ScriptedFleet

MISSIONS = Path(__file__).resolve().parents[3] / "missions"


def test_stale_telemetry_lines_reach_the_progress_callback_set_after_construction() -> None:
    """left's position 0.5 s old (quickstart: predict_s 0.3 < 0.5 <= hold_s 1.0): degraded flight, told to
    the console's callback, none to the one given at construction."""
    mission = load_mission(MISSIONS / "quickstart.yaml")
    pos = np.array([[0.0, 0.0, 10.0], [-1.4, -9.9, 10.0], [-9.9, 1.4, 10.0]])
    fleet = ScriptedFleet(["lead", "right", "left"], pos, yaw=math.radians(37.0))
    at_construction: list[str] = []
    runner = MissionRunner(mission, fleet, None, progress=at_construction.append)  # type: ignore[arg-type]
    runner.command_launch()
    runner.start_formation()
    console: list[str] = []
    runner.progress = console.append  # what FlightSession does
    fleet.state.position_ms[2] -= 500
    runner.step()

    assert "! stale telemetry: degraded flight (speed x0.5, spacing x1.5)" in console
    assert not [line for line in at_construction if "stale" in line]
    assert runner.result.events[-1].endswith("stale telemetry: degraded flight (speed x0.5, spacing x1.5)")
