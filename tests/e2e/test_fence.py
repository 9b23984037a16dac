"""The autopilots' geofence as the last line when the ground station dies (docs/reliability.md "The ground
station dies"): an obstacle right on the route, a 3 m/s wind blowing the formation at it, FS_GCS_TIMEOUT 15 s
and the speed scheduling off, so that a ground station killed while heading at the obstacle lets a vehicle
drift into it before its GCS failsafe brakes. With the obstacle fenced (an exclusion circle 10 m beyond
obstacle + body, FENCE_ACTION Brake) the same kill ends with no collision, the vehicle holding in BRAKE; with
the same fence on "report only" (FENCE_ACTION 0, the same flight up to the kill) it hits the obstacle. Normal
flight with the fence never breaches it, and the run puts the vehicles' parameters and fences back."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from gcs_swarm.evaluation.gcs_kill import fly_and_kill, kill_moments
from swarm_common.ports import free_udp_base
from tests.e2e.flights import ROOT, derived_mission, fly

COURSE_FROM_DEG = 233.13  # the wind blows from here: along the quickstart's route (0, 0) -> (160, 120)


def _mission(folder: Path, action: str) -> Path:
    mission = derived_mission(
        folder,
        "quickstart.yaml",
        f"fenced_{action}",
        world={
            "obstacles": [{"center": [80.0, 60.0, 10.0], "radius": 6.0}],
            "wind": {"speed": 3.0, "direction_deg": COURSE_FROM_DEG, "turbulence": 0.0},
        },
    )
    data = yaml.safe_load(mission.read_text())
    data["safety"]["dead_gcs"].update(
        failsafe_timeout_s=15.0,
        speed_scheduling=False,
        fence={"enabled": True, "margin_m": 10.0, "action": action},
    )
    mission.write_text(yaml.safe_dump(data, sort_keys=False))
    return mission


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, float]:
    """The fenced mission flown undisturbed: the folder and the moment a vehicle heads at the obstacle."""
    folder = tmp_path_factory.mktemp("fence")
    run = fly(_mission(folder, "brake"), folder / "reference", timeout_s=300)
    assert run.status == 0, run.output[-2000:]
    flight = json.loads((folder / "reference" / "flight.json").read_text())
    # before the formation starts to change shape for the obstacle: until then every vehicle flies along the
    # route, which the wind blows along, straight at the obstacle
    t_end = min([flight["t_formation_end"], *(change["t_s"] for change in flight["reshapes"])])
    moments = kill_moments(folder / "reference", flight["t_formation_start"], t_end)
    return folder, moments["heading_at_obstacle"]


def test_normal_flight_never_breaches_and_everything_is_put_back(reference):
    folder, _ = reference
    run = folder / "reference"
    flight = json.loads((run / "flight.json").read_text())
    report = json.loads((run / "report.json").read_text())
    assert report["collisions"] == 0 and report["reached"]
    assert not [e for e in flight["events"] if "breached" in e]
    assert "fence breached" not in (run / "simulator.log").read_text()
    changed = {(c["name"], c["restored"]) for c in flight["params_changed"]}
    assert {("fence items", True), ("FENCE_ENABLE", True), ("FENCE_TYPE", True)} <= changed


def test_killed_heading_at_the_obstacle_the_fence_stops_the_drift(reference, tmp_path):
    folder, t_kill = reference
    reported = fly_and_kill(
        _mission(folder, "report"), tmp_path / "report", t_kill, free_udp_base(3), cwd=ROOT
    )
    assert reported.crashed >= 1, reported  # without a fence action the wind carries it into the obstacle
    braked = fly_and_kill(_mission(folder, "brake"), tmp_path / "brake", t_kill, free_udp_base(3), cwd=ROOT)
    assert braked.crashed == 0 and braked.clearance_after_m > 0.0, braked
    assert all(end in ("holding", "landed") for end in braked.ends), braked.ends
    log = (tmp_path / "brake" / "simulator-orphan.log").read_text()
    assert "Polygon fence breached" in log and "FENCE_ACTION 4, mode BRAKE" in log
    assert "FENCE_ACTION 0, mode GUIDED" in (tmp_path / "report" / "simulator-orphan.log").read_text()
