"""flight.json and the report carry the ground station's own counts, e.g. how many vehicle-ticks' commands
the final guard changed (gcs_swarm.link.command_limits)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gcs_swarm.evaluation.report import render_markdown, report_from
from gcs_swarm.evaluation.run_data import Trajectories
from gcs_swarm.flight.fly import write_flight
from gcs_swarm.flight.runner import FlightResult
from gcs_swarm.mission import load_mission
from gcs_swarm.mission.geometry import mission_offsets

QUICKSTART = Path(__file__).resolve().parents[2] / "missions" / "quickstart.yaml"


def _hovering(mission, seconds: float = 2.0) -> Trajectories:
    """Every vehicle still at its start lifted to 10 m, sampled at 50 Hz."""
    t = np.arange(0.0, seconds, 0.02)
    start = np.array([v.start.position for v in mission.vehicles], dtype=float) + [0.0, 0.0, 10.0]
    pos = np.broadcast_to(start, (len(t), *start.shape)).copy()
    n = len(mission.vehicles)
    return Trajectories(
        t,
        pos,
        np.zeros_like(pos),
        np.zeros((len(t), n), dtype=bool),
        np.zeros((len(t), 0, 3)),
        np.zeros(0),
        "truth",
    )


def test_commands_limited_goes_from_flight_json_into_the_report(tmp_path: Path) -> None:
    mission = load_mission(QUICKSTART)
    result = FlightResult(t_formation_start=0.0, t_formation_end=1.9, ticks=95, degraded_s=0.5, holds=2)
    write_flight(tmp_path, mission, str(QUICKSTART), result, 1.5, [0.001, 0.002], commands_limited=7)
    flight = json.loads((tmp_path / "flight.json").read_text())
    assert flight["commands_limited"] == 7
    assert (flight["degraded_s"], flight["holds"], flight["max_telemetry_age_s"]) == (0.5, 2, 0.0)
    report = report_from(_hovering(mission), None, mission, flight)
    assert report["commands_limited"] == 7
    assert "| commands_limited | 7 |" in render_markdown(report)


def test_a_flight_json_without_the_count_reports_none() -> None:
    mission = load_mission(QUICKSTART)
    flight = {"offsets": mission_offsets(mission).tolist(), "t_formation_start": 0.0, "arrived": False}
    report = report_from(_hovering(mission), None, mission, flight)
    assert report["commands_limited"] is None
    assert "| commands_limited | - |" in render_markdown(report)
