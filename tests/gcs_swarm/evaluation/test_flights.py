"""One experiment flight's result line: collision rule, missing reports, ports."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from gcs_swarm.evaluation import flights


def _report(run_dir: Path, **figures) -> None:
    run_dir.mkdir(parents=True, exist_ok=True)
    base = {"reached": True, "collisions": 0, "min_separation_m": 8.0, "min_obstacle_clearance_m": 4.0}
    (run_dir / "report.json").write_text(json.dumps(base | figures))
    (run_dir / "flight.json").write_text(json.dumps({"events": ["e1"]}))


@pytest.mark.parametrize(
    ("figures", "collision"),
    [
        ({}, False),
        ({"collisions": 1}, True),
        ({"min_obstacle_clearance_m": 0.1}, True),  # inside the vehicle radius 0.175 m (spec 10)
        ({"min_separation_m": 0.3}, True),  # two vehicle radii overlap
        ({"min_obstacle_clearance_m": None, "min_separation_m": None}, False),
    ],
)
def test_collision_rule(tmp_path: Path, figures: dict, collision: bool) -> None:
    _report(tmp_path, **figures)
    result = flights.flight_figures(tmp_path, 0, 0.175)
    assert result["collision"] is collision
    assert result["success"] is True and result["events"] == ["e1"]
    assert set(flights.RESULT_KEYS) <= result.keys()


def test_a_run_without_report_has_no_figures(tmp_path: Path) -> None:
    result = flights.flight_figures(tmp_path, 1, 0.175)
    assert result["success"] is False and result["reached"] is False and result["collision"] is False
    assert result["min_separation_m"] is None and result["events"] == []
