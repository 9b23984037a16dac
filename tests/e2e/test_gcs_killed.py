"""The ground station killed mid-flight: every vehicle reaches a safe state by itself (its GCS failsafe), and
the run's logs up to that moment are intact and readable."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from gcs_swarm.report import load_truth
from tests.e2e.conftest import ROOT, derived_mission, free_udp_base

LAND = 9  # ArduCopter custom_mode


def _formation_time(record: Path) -> float:
    """Vehicle time of the last flushed formation row of the run record (0 if none yet)."""
    if not record.exists():
        return 0.0
    rows = [ln.split(",") for ln in record.read_text().splitlines()[1:] if ",formation," in ln]
    return float(rows[-1][0]) - float(rows[0][0]) if len(rows) > 1 else 0.0


def test_vehicles_land_by_themselves_and_logs_survive(tmp_path: Path) -> None:
    # Speedup instead of lockstep: once the ground station is gone nobody answers frames, and the failsafe
    # landing should not take minutes of wall time. FS_GCS_ENABLE = LAND (safety.gcs_failsafe: land).
    # No obstacles: an autopilot that lost its ground station coasts on (GUID_TIMEOUT, then FS_GCS_TIMEOUT)
    # and knows nothing of the mission's obstacles, so a kill just before one is a crash by design.
    mission = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "killed",
        world={"obstacles": []},
        safety={"gcs_failsafe": "land"},
        run={"simulator": {"embedded": True, "time_mode": "speedup", "speedup": 4}},
    )
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir)]
    cmd += ["--base-port", str(free_udp_base(3))]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    try:
        deadline = time.monotonic() + 120
        while _formation_time(run_dir / "record.csv") < 4.0:  # a few seconds into formation flight
            assert proc.poll() is None, "the ground station ended before it could be killed"
            assert time.monotonic() < deadline, "formation flight never started"
            time.sleep(0.2)
        os.kill(proc.pid, signal.SIGKILL)  # the ground station only: its simulator child flies on
        proc.wait(10)
        killed_at = time.monotonic()
        truth_path = run_dir / "truth.csv"
        while True:  # FS_GCS_TIMEOUT (5 s) -> LAND -> touchdown -> auto-disarm, at 4x real time
            time.sleep(1.0)
            lines = truth_path.read_text().splitlines()
            n = 3
            last = [ln.split(",") for ln in lines[-n:]]
            header = lines[0].split(",")
            armed = [int(r[header.index("armed")]) for r in last]
            if len(lines) > 1 + n and not any(armed):
                break
            assert time.monotonic() - killed_at < 90, "the vehicles did not land and disarm by themselves"
    finally:
        os.killpg(proc.pid, signal.SIGTERM)  # the orphaned simulator (same session): closes its truth log
        time.sleep(1.0)
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    truth = np.genfromtxt(run_dir / "truth.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    for i in range(3):
        mine = truth[truth["vehicle"] == i]
        assert LAND in set(mine["mode"].tolist()), f"vehicle {i} never switched to LAND"
        assert mine["armed"][-1] == 0 and abs(mine["z"][-1]) < 0.2 and not mine["crashed"].any()
    assert load_truth(run_dir / "truth.csv").pos.shape[1] == 3

    # The ground station's own logs up to the kill: the run record parses, the tlog reads back.
    record = np.genfromtxt(run_dir / "record.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert len(record) > 100 and np.isfinite(record["x"]).all()
    log = mavutil.mavlink_connection(str(run_dir / "telemetry.tlog"))
    count = 0
    while log.recv_match() is not None:
        count += 1
    assert count > 1000
