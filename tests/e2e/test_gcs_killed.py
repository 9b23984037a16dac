"""The ground station killed (SIGKILL) mid-flight at the worst moments: from the simulator's ground truth, no
vehicle touches anything, every one ends landed or holding (the GCS failsafe: BRAKE, docs/reliability.md),
the embedded simulator lands or holds them and then exits by itself (nothing is left running), and the logs
are intact up to the kill.

Kill moments are found on an undisturbed lockstep run of the same mission (the flight repeats exactly up to
the kill): (a) the moment a vehicle at speed is closest in time to an obstacle along its course, (b) the
leader's closest pass of an obstacle (mid avoidance), (c) one second into formation flight while the
followers are still assembling."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from pymavlink import mavutil

from gcs_swarm.guidance.failsafe_speed import distance_along_course
from tests.e2e.conftest import ROOT, derived_mission, fly, free_udp_base, static6_short

BRAKE, LAND = 17, 9  # ArduCopter custom_mode
D_EMG = 3.0  # m, the missions' safety.separation.d_emg
EXIT_WALL_S = 120.0  # wall s the orphaned simulator may take to land or hold its vehicles and exit


def _truth(run_dir: Path) -> np.ndarray:
    return np.genfromtxt(run_dir / "truth.csv", delimiter=",", names=True)


def _obstacle_centres(run_dir: Path, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Obstacle centres (T, K, 3) at the times t and radii (K,) from truth.obstacles.csv."""
    obs = np.genfromtxt(run_dir / "truth.obstacles.csv", delimiter=",", names=True)
    ids = np.unique(obs["obstacle"])
    centres = np.zeros((len(t), len(ids), 3))
    radii = np.zeros(len(ids))
    for k, ident in enumerate(ids):
        o = obs[obs["obstacle"] == ident]
        radii[k] = o["radius"][0]
        for axis, name in enumerate("xyz"):
            centres[:, k, axis] = np.interp(t, o["t"], o[name])
    return centres, radii


def _tracks(truth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample times (T,), positions and velocities (T, N, 3) of a truth log."""
    n = int(truth["vehicle"].max()) + 1
    rows = [truth[truth["vehicle"] == i] for i in range(n)]
    m = min(len(r) for r in rows)
    pos = np.stack([np.column_stack([r["x"][:m], r["y"][:m], r["z"][:m]]) for r in rows], axis=1)
    vel = np.stack([np.column_stack([r["vx"][:m], r["vy"][:m], r["vz"][:m]]) for r in rows], axis=1)
    return rows[0]["t"][:m], pos, vel


def kill_moments(run_dir: Path, t_formation: float, t_end: float) -> dict[str, float]:
    """The three kill moments (module docstring) from an undisturbed run, in simulated s."""
    t, pos, vel = _tracks(_truth(run_dir))
    centres, radii = _obstacle_centres(run_dir, t)
    flying = (t > t_formation) & (t < t_end)
    urgency = np.zeros(len(t))  # 1 / (s to reach an obstacle along the course), worst vehicle
    closest = np.full(len(t), np.inf)  # the leader's smallest surface distance
    for k in np.flatnonzero(flying):
        d = distance_along_course(pos[k], vel[k], centres[k], radii, 0.0)
        speed = np.hypot(vel[k, :, 0], vel[k, :, 1])
        urgency[k] = np.max(np.where((speed > 5.0) & np.isfinite(d), speed / np.maximum(d, 0.1), 0.0))
        closest[k] = (np.linalg.norm(pos[k, 0] - centres[k], axis=1) - radii).min()
    assert urgency.max() > 0.0, "no vehicle's course ever met an obstacle: nothing to kill at"
    return {
        "heading_at_obstacle": float(t[np.argmax(urgency)]),
        "mid_avoidance": float(t[np.argmin(closest)]),
        "assembling": t_formation + 1.0,
    }


def fly_and_kill(mission: Path, run_dir: Path, t_kill: float) -> float:
    """Fly `mission` and SIGKILL the ground station once the simulator's clock reaches t_kill; then wait for
    the orphaned simulator to exit by itself. Returns the simulated time of the kill."""
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir)]
    cmd += ["--base-port", str(free_udp_base(len(yaml.safe_load(mission.read_text())["vehicles"])))]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    truth = run_dir / "truth.csv"
    killed_at = None
    try:
        deadline = time.monotonic() + 180
        while killed_at is None:
            assert proc.poll() is None, "the ground station ended before it could be killed"
            assert time.monotonic() < deadline, f"the flight never reached t = {t_kill} s"
            time.sleep(0.01)
            if not truth.exists() or truth.stat().st_size < 200:
                continue
            with truth.open("rb") as f:
                f.seek(-200, os.SEEK_END)
                last = f.read().decode(errors="replace").strip().splitlines()[-1]
            try:
                now = float(last.split(",")[0])
            except ValueError:
                continue
            if now >= t_kill:
                os.kill(proc.pid, signal.SIGKILL)  # the ground station only: the simulator flies on
                killed_at = now
        proc.wait(10)
        waited = time.monotonic()
        while True:  # no process of the run may survive: the simulator exits once its vehicles are down
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                break
            assert time.monotonic() - waited < EXIT_WALL_S, "the orphaned simulator is still running"
            time.sleep(0.2)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return killed_at


def assert_safe_after(run_dir: Path, t_kill: float) -> None:
    """Ground truth after the kill: nobody crashed, separation stayed above D_Emg, every vehicle ends landed
    and disarmed or holding in BRAKE; the ground station's logs run up to the kill."""
    truth = _truth(run_dir)
    t, pos, vel = _tracks(truth)
    after = t >= t_kill
    assert not truth["crashed"].any(), "a vehicle hit something"
    gaps = [
        np.linalg.norm(pos[after, i] - pos[after, j], axis=1).min()
        for i in range(pos.shape[1])
        for j in range(i + 1, pos.shape[1])
    ]
    assert min(gaps) >= D_EMG, f"separation fell to {min(gaps):.2f} m after the kill"
    for i in range(pos.shape[1]):
        last = truth[truth["vehicle"] == i][-1]
        landed = bool(last["landed"]) and not bool(last["armed"])
        holding = int(last["mode"]) == BRAKE and float(np.hypot(last["vx"], last["vy"])) < 0.3
        assert landed or holding, f"vehicle {i} ends neither landed nor holding (mode {int(last['mode'])})"
    record = np.genfromtxt(run_dir / "record.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    assert np.isfinite(record["x"]).all() and record["t"][-1] >= t_kill - 1.5  # flushed up to the kill
    log = mavutil.mavlink_connection(str(run_dir / "telemetry.tlog"))
    count = 0
    while log.recv_match() is not None:
        count += 1
    assert count > 500


def _reference(mission: Path, folder: Path) -> dict[str, float]:
    run = fly(mission, folder / "reference", timeout_s=300)
    assert run.status == 0, run.output[-2000:]
    data = json.loads((folder / "reference" / "flight.json").read_text())
    return kill_moments(folder / "reference", data["t_formation_start"], data["t_formation_end"])


@pytest.fixture(scope="module")
def quickstart_moments(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, float]]:
    folder = tmp_path_factory.mktemp("quickstart_killed")
    mission = derived_mission(folder, "quickstart.yaml", "killed")  # a copy: same flight, own run folders
    return mission, _reference(mission, folder)


@pytest.fixture(scope="module")
def static6_moments(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, float]]:
    folder = tmp_path_factory.mktemp("static6_killed")
    mission = static6_short(folder, "static6_killed")
    return mission, _reference(mission, folder)


@pytest.mark.parametrize("moment", ["heading_at_obstacle", "mid_avoidance", "assembling"])
def test_quickstart_killed_at_the_worst_moments(
    moment: str, quickstart_moments: tuple[Path, dict[str, float]], tmp_path: Path
) -> None:
    mission, moments = quickstart_moments
    killed_at = fly_and_kill(mission, tmp_path / "run", moments[moment])
    assert_safe_after(tmp_path / "run", killed_at)


@pytest.mark.parametrize("moment", ["mid_avoidance", "assembling"])
def test_six_uav_paper_mission_killed_at_the_worst_moments(
    moment: str, static6_moments: tuple[Path, dict[str, float]], tmp_path: Path
) -> None:
    mission, moments = static6_moments
    killed_at = fly_and_kill(mission, tmp_path / "run", moments[moment])
    assert_safe_after(tmp_path / "run", killed_at)
