"""Real ArduCopter SITL at the SiK budget (issue 38 "What it must show"): one stock `arducopter` process (a
built ArduPilot; docs/ardupilot-sitl.md) behind a rate-limited relay that carries its link through the
simulator's `sik64` radio model (tests/e2e/radio_relay.py: 64 kbit/s of half-duplex air time, 10.2 bit times a
byte, 1850-byte buffers, timed by the wall clock), flown by `gcs-swarm run --connect-only`. The mission names
the radio, so the ground station budgets for it before take-off: position targets at 10 Hz with the
telemetry slowed, which ArduCopter GUIDED flies with its own pos-vel-accel controller. Runs only when
ARDUPILOT_SITL names the binary (`-m ardupilot`); about two minutes of wall time and a full core."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from gcs_swarm.mission import load_mission
from swarm_common.ports import free_udp_base
from swarm_common.radio_presets import RADIO_PRESETS
from tests.e2e.ardupilot_sitl import SitlBuild, start_vehicles, stop_vehicles
from tests.e2e.flights import MISSIONS, ROOT, numbers
from tests.e2e.radio_relay import RadioRelay

BUILD = SitlBuild.from_environment()
pytestmark = [
    pytest.mark.ardupilot,
    pytest.mark.skipif(BUILD is None, reason="ARDUPILOT_SITL does not name an ArduCopter SITL binary"),
]
SIK64_B_S = 64000 / 10.2  # MAVLink bytes/s a SiK pair at 64 kbit/s carries, up and down (docs/radio.md)


def _missions(tmp_path: Path) -> tuple[Path, Path, int, int]:
    """missions/ardupilot_sitl_3.yaml's leader alone over `sik64`: the ground station's mission (udpin on a
    free port P) and the vehicle's (sending to the relay's port R), and P, R."""
    data = numbers(yaml.safe_load((MISSIONS / "ardupilot_sitl_3.yaml").read_text()))
    data["vehicles"] = data["vehicles"][:1]
    data["world"]["link"] = {"radio": "sik64"}
    gcs_port = free_udp_base(2)
    relay_port = gcs_port + 1
    paths = []
    for name, port in (("gcs", gcs_port), ("vehicle", relay_port)):
        data["vehicles"][0]["connection"] = f"udpin:127.0.0.1:{port}"
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        paths.append(path)
    return paths[0], paths[1], gcs_port, relay_port


def test_a_stock_arducopter_behind_a_sik64_radio_flies_position_targets_to_the_goal(tmp_path: Path) -> None:
    assert BUILD is not None
    gcs_mission, vehicle_mission, gcs_port, relay_port = _missions(tmp_path)
    relay = RadioRelay(RADIO_PRESETS["sik64"], [relay_port], [gcs_port])
    relay.start()
    procs: list[subprocess.Popen[bytes]] = []
    try:
        procs = start_vehicles(load_mission(vehicle_mission), BUILD, tmp_path / "vehicles")
        run_dir = tmp_path / "run"
        cmd = [
            sys.executable,
            "-m",
            "gcs_swarm",
            "run",
            str(gcs_mission),
            "--connect-only",
            "--out",
            str(run_dir),
        ]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=480)
    finally:
        stop_vehicles(procs)
        relay.stop()
    output = proc.stdout + proc.stderr
    radio = relay.summary()[0]
    assert proc.returncode == 0, output[-3000:] + "\n" + radio
    report = json.loads((run_dir / "report.json").read_text())
    assert report["reached"] and report["collisions"] == 0 and report["safety_events"] == [], radio
    flight = json.loads((run_dir / "flight.json").read_text())
    mode = flight["command_mode"]
    assert (mode["mode"], mode["setpoint_hz"], mode["state_hz"]) == ("position", 10.0, 10.0)
    use = flight["link_use"]["lead"]
    # the radio cannot carry more than its capacity on average (its counts are in the radio line)
    assert use["up_mean_B_s"] + use["down_mean_B_s"] <= SIK64_B_S, (use, radio)
    print(radio)
