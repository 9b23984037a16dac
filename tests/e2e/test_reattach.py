"""A ground station started again while its vehicles are still in the air (a previous one crashed and their
GCS failsafe, set to brake here, left them holding in BRAKE): `gcs-swarm run --connect-only` reads their
state and refuses to launch on top of them, `--airborne land` lands them where they are, `--airborne finish`
flies the mission on from where they are. Against a free-running `sitl-sim` (the vehicles must keep flying
between the two ground stations), on free loopback ports, every process killed at the end."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import yaml

from swarm_common.ports import free_udp_base
from tests.e2e.flights import ROOT, derived_mission

SPEEDUP = 4.0  # the simulator's pace: fast enough for a short test, slow enough for a loaded machine
KILL_AT_S = 24.0  # vehicle s: a few seconds into formation flight (boot 5 s, preflight and take-off ~12 s)
FAILSAFE_S = 10.0  # s, FS_GCS_TIMEOUT of the test mission
BRAKE = 17  # ArduCopter custom_mode


def _gcs(
    mission: Path, run_dir: Path, *extra: str, timeout_s: float = 180.0
) -> subprocess.CompletedProcess[str]:
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--connect-only", "--out", str(run_dir)]
    return subprocess.run([*cmd, *extra], cwd=ROOT, capture_output=True, text=True, timeout=timeout_s)


@pytest.fixture
def held_fleet(tmp_path: Path) -> Iterator[tuple[Path, Path]]:
    """The quickstart on a free-running simulator, flown until its ground station SIGKILLs itself mid-flight
    and the vehicles' GCS failsafe (BRAKE) has acted. Yields (mission, truth log)."""
    base = free_udp_base(3)
    data = yaml.safe_load((ROOT / "missions" / "quickstart.yaml").read_text())
    for vehicle in data["vehicles"]:
        vehicle.pop("connection", None)  # udpout:127.0.0.1:<base_port + i>
    data["run"]["simulator"]["base_port"] = base
    # brake: they hold in the air for the next ground station (the default, land, would bring them down);
    # FS_GCS_TIMEOUT 10 s: at SPEEDUP x real time, a ground station starved of CPU for 3 s / SPEEDUP of wall
    # time (a loaded test machine) would otherwise set off the failsafe of vehicles it is still flying
    data["safety"]["gcs_failsafe"] = "brake"
    data["safety"]["dead_gcs"]["failsafe_timeout_s"] = FAILSAFE_S
    mission = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "reattach",
        vehicles=data["vehicles"],
        run=data["run"],
        safety=data["safety"],
    )
    truth = tmp_path / "truth.csv"
    sim_cmd = [sys.executable, "-m", "sitl_sim", "--mission", str(mission), "--base-port", str(base)]
    sim_cmd += ["--speedup", str(SPEEDUP), "--ready-delay", "5", "--truth-log", str(truth)]
    sim = subprocess.Popen(sim_cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        crashed = _gcs(mission, tmp_path / "crashed", "--crash-at", str(KILL_AT_S))
        assert crashed.returncode == -9, crashed.stdout[-2000:]  # SIGKILL, as a crash
        assert "phase formation" in crashed.stdout
        time.sleep((FAILSAFE_S + 6.0) / SPEEDUP)  # FS_GCS_TIMEOUT and the brake play out
        yield mission, truth
    finally:
        sim.kill()
        sim.wait(10)


def _last_rows(truth: Path) -> np.ndarray:
    rows = np.genfromtxt(truth, delimiter=",", names=True)
    return np.array([rows[rows["vehicle"] == i][-1] for i in range(3)])


def test_refuses_then_lands_where_they_are(held_fleet: tuple[Path, Path], tmp_path: Path) -> None:
    mission, truth = held_fleet
    refused = _gcs(mission, tmp_path / "refused")
    assert refused.returncode == 2, refused.stdout[-2000:]
    assert "vehicles already flying: lead BRAKE at" in refused.stdout
    assert "--airborne finish" in refused.stdout and "--airborne land" in refused.stdout
    held = _last_rows(truth)
    assert (held["armed"] == 1).all() and (held["mode"] == BRAKE).all()  # nothing was launched on top

    landed = _gcs(mission, tmp_path / "landed", "--airborne", "land")
    assert landed.returncode == 0, landed.stdout[-2000:]
    assert "every vehicle landed and disarmed" in landed.stdout
    time.sleep(1.0)  # the truth log's last rows
    end = _last_rows(truth)
    assert (end["landed"] == 1).all() and (end["armed"] == 0).all() and (end["crashed"] == 0).all()
    # landed where they were holding (LAND descends in place), not at home
    drift = np.hypot(end["x"] - held["x"], end["y"] - held["y"])
    assert (drift < 2.0).all(), drift
    flight = json.loads((tmp_path / "landed" / "flight.json").read_text())
    assert flight["reattached"] == "land"


def test_finishes_the_mission_from_where_they_are(held_fleet: tuple[Path, Path], tmp_path: Path) -> None:
    mission, truth = held_fleet
    finished = _gcs(mission, tmp_path / "finished", "--airborne", "finish")
    assert finished.returncode == 0, finished.stdout[-2000:]
    assert "finishing the mission from here" in finished.stdout
    report = json.loads((tmp_path / "finished" / "report.json").read_text())
    assert report["reached"] and report["collisions"] == 0
    end = _last_rows(truth)
    assert (end["crashed"] == 0).all() and (end["armed"] == 0).all()
    goal = np.array([160.0, 120.0])  # missions/quickstart.yaml goal; the leader lands on it
    assert np.hypot(end["x"][0] - goal[0], end["y"][0] - goal[1]) < 2.0
