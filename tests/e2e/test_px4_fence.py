"""The site fence and rally points on a fleet of ArduCopter and PX4 vehicles (issue 37 item 5):
missions/mixed_fleet.yaml with an inclusion polygon around the course, an exclusion circle beside it, four
rally points, `safety.geofence.upload: true` and the fence action "rtl", flown in lockstep against the
embedded simulator. Every vehicle, PX4 ones too, takes the fence items and its own rally point (verified by
download before the flight), its autopilot's own parameters are set (PX4's GF_ACTION 3 = Return mode,
geofence_params.c, and RTL_TYPE 1, rally points before home; ArduCopter's FENCE_TYPE 4 and FENCE_ENABLE 1, its
FENCE_ACTION 1 = RTL already being its default, and RALLY_INCL_HOME 0, RALLY_LIMIT_KM 0), nothing is
breached, and after landing everything is put back (params_changed in flight.json)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.e2e.flights import derived_mission, fly

POLYGON = [[-40.0, -50.0], [200.0, -50.0], [200.0, 160.0], [-40.0, 160.0]]  # ENU m, around starts and goal
POND = {"name": "pond", "center": [150.0, 0.0], "radius": 5.0}  # 150 m east: far off the diagonal route
ITEMS = len(POLYGON) + 1  # one vertex item per corner, one circle
# ENU m, inside the polygon, off the route: four, one for each vehicle (geofence.rally_by_vehicle)
RALLY = [[100.0, 20.0, 15.0], [20.0, 100.0, 15.0], [60.0, -30.0, 15.0], [-30.0, 60.0, 15.0]]


def test_px4_and_arducopter_take_the_site_fence_and_rally_points_and_get_them_back(tmp_path: Path) -> None:
    mission = derived_mission(
        tmp_path,
        "mixed_fleet.yaml",
        "mixed_fleet_fenced",
        safety={
            "geofence": {"polygon": POLYGON, "exclusions": [POND], "upload": True},
            "rally": RALLY,
            "dead_gcs": {"fence": {"action": "rtl"}},
        },
    )
    run = fly(mission, tmp_path / "run", timeout_s=600, extra=["--time-mode", "lockstep"])
    assert run.status == 0, run.output[-3000:]
    flight = json.loads((run.run_dir / "flight.json").read_text())
    report = json.loads((run.run_dir / "report.json").read_text())
    assert report["reached"] and report["collisions"] == 0
    assert not [e for e in flight.get("events", []) if "breach" in e or "violation" in e]
    rows = {(c["vehicle"], c["name"]): c for c in flight["params_changed"]}
    for px4 in ("px4_right", "px4_tail"):
        # a fresh simulated vehicle has no fence: 0 items before, ITEMS flown; GF_ACTION from PX4's default
        # 2 (Hold) to 3 (Return)
        assert rows[(px4, "fence items")] == {
            "vehicle": px4, "name": "fence items", "original": 0.0, "flown": float(ITEMS), "restored": True,
        }  # fmt: skip
        assert rows[(px4, "GF_ACTION")] == {
            "vehicle": px4, "name": "GF_ACTION", "original": 2.0, "flown": 3.0, "restored": True,
        }  # fmt: skip
        assert rows[(px4, "rally items")] == {
            "vehicle": px4, "name": "rally items", "original": 0.0, "flown": 1.0, "restored": True,
        }  # fmt: skip
        # RTL_TYPE from PX4's default 0 (closest of home and rally points) to 1 (rally points first)
        assert rows[(px4, "RTL_TYPE")] == {
            "vehicle": px4, "name": "RTL_TYPE", "original": 0.0, "flown": 1.0, "restored": True,
        }  # fmt: skip
        assert (px4, "FENCE_TYPE") not in rows  # no ArduPilot parameter is asked of a PX4 vehicle
    for apm in ("lead", "apm_left"):
        assert rows[(apm, "fence items")]["restored"] and rows[(apm, "fence items")]["flown"] == ITEMS
        # FENCE_TYPE from its default 7 to 4, FENCE_ENABLE from 0 to 1 (sitl_sim params.py defaults)
        assert (rows[(apm, "FENCE_TYPE")]["original"], rows[(apm, "FENCE_TYPE")]["flown"]) == (7.0, 4.0)
        assert (rows[(apm, "FENCE_ENABLE")]["original"], rows[(apm, "FENCE_ENABLE")]["flown"]) == (0.0, 1.0)
        assert rows[(apm, "FENCE_TYPE")]["restored"] and rows[(apm, "FENCE_ENABLE")]["restored"]
        assert (apm, "GF_ACTION") not in rows
        assert rows[(apm, "rally items")]["restored"] and rows[(apm, "rally items")]["flown"] == 1.0
        # Copter's defaults RALLY_INCL_HOME 1 and RALLY_LIMIT_KM 0.3 (sitl_sim params.py) to 0 and 0
        assert (rows[(apm, "RALLY_INCL_HOME")]["original"], rows[(apm, "RALLY_INCL_HOME")]["flown"]) == (
            1.0,
            0.0,
        )
        assert rows[(apm, "RALLY_LIMIT_KM")]["original"] == pytest.approx(0.3)
        assert rows[(apm, "RALLY_INCL_HOME")]["restored"] and rows[(apm, "RALLY_LIMIT_KM")]["restored"]
