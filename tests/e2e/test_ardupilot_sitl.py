"""Stock ArduCopter, out of the box: three real `arducopter` SITL processes (a built ArduPilot; see
docs/ardupilot-sitl.md) flown by `gcs-swarm run --connect-only` and driven by `gcs-swarm console
--connect-only`. Runs only when ARDUPILOT_SITL names the binary (ARDUPILOT_DEFAULTS its copter.parm, else the
source tree's); never in the default CI run, which has no ArduPilot build. Each test takes about two minutes
of wall time: a real vehicle needs about 45 s from boot before its EKF uses GPS."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from gcs_swarm.mission import load_mission
from swarm_common.ports import free_udp_base
from tests.e2e.ardupilot_sitl import SitlBuild, start_vehicles, stop_vehicles
from tests.e2e.flights import MISSIONS, ROOT, numbers

BUILD = SitlBuild.from_environment()
pytestmark = [
    pytest.mark.ardupilot,
    pytest.mark.skipif(BUILD is None, reason="ARDUPILOT_SITL does not name an ArduCopter SITL binary"),
]


def _mission_on_free_ports(tmp_path: Path) -> Path:
    """missions/ardupilot_sitl_3.yaml with its three udpin ports moved to free ones."""
    data = numbers(yaml.safe_load((MISSIONS / "ardupilot_sitl_3.yaml").read_text()))
    base = free_udp_base(3)
    for k, vehicle in enumerate(data["vehicles"]):
        vehicle["connection"] = f"udpin:127.0.0.1:{base + k}"
    path = tmp_path / "ardupilot_sitl_3.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_three_stock_arducopters_fly_the_formation(tmp_path: Path) -> None:
    assert BUILD is not None
    mission_path = _mission_on_free_ports(tmp_path)
    procs = start_vehicles(load_mission(mission_path), BUILD, tmp_path / "vehicles")
    try:
        run_dir = tmp_path / "run"
        cmd = [
            sys.executable,
            "-m",
            "gcs_swarm",
            "run",
            str(mission_path),
            "--connect-only",
            "--out",
            str(run_dir),
        ]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=420)
    finally:
        stop_vehicles(procs)
    output = proc.stdout + proc.stderr
    assert proc.returncode == 0, output[-3000:]
    report = json.loads((run_dir / "report.json").read_text())
    assert report["reached"] and report["collisions"] == 0 and report["safety_events"] == []
    assert report["source"] == "telemetry"  # no simulator of ours: the vehicles' own reports
    whole = report["whole_flight"]
    assert whole["cusps_total"] == 0 and whole["min_separation_whole_flight_m"] > 3.0
    flight = json.loads((run_dir / "flight.json").read_text())
    changed = flight["params_changed"]
    assert {c["name"] for c in changed} >= {"GUID_OPTIONS", "FS_GCS_ENABLE", "GUID_TIMEOUT"}
    assert all(c["restored"] for c in changed), changed  # landed and disarmed: put back


CONSOLE_SCRIPT = """\
wait 50
param get MAV_SYSID lead
param get SYSID_THISMAV right
param set WPNAV_SPEED 800 left
param get WPNAV_SPEED left
mode GUIDED all
wait 2
arm all
wait 2
takeoff 5 all
wait 15
status
land all
wait 25
status
quit
"""


def test_the_console_drives_three_stock_arducopters(tmp_path: Path) -> None:
    """Its verbs on real vehicles: parameters under the 4.7 name and the 4.6 one (read under the name the
    vehicle has), GUIDED, arm, take off, land. The script first waits out the vehicles' EKF start-up."""
    assert BUILD is not None
    mission_path = _mission_on_free_ports(tmp_path)
    script = tmp_path / "ops.txt"
    script.write_text(CONSOLE_SCRIPT)
    procs = start_vehicles(load_mission(mission_path), BUILD, tmp_path / "vehicles")
    try:
        cmd = [sys.executable, "-m", "gcs_swarm", "console", str(mission_path), "--connect-only", "--yes"]
        cmd += ["--script", str(script), "--out", str(tmp_path / "run")]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    finally:
        stop_vehicles(procs)
    output = proc.stdout + proc.stderr
    assert "Traceback" not in output, output[-3000:]
    assert re.search(r"lead: MAV_SYSID = 1\b", output), output[-3000:]
    assert re.search(r"right: (SYSID_THISMAV|MAV_SYSID) = 2\b", output), output[-3000:]
    assert re.search(r"left: WPNAV_SPEED = 800\b", output), output[-3000:]
    assert output.count("Arming motors") >= 3, output[-3000:]
    assert "Disarming motors" in output, output[-3000:]
