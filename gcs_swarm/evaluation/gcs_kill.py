"""Killing the ground station on purpose: fly a mission with `gcs-swarm run`, SIGKILL it at a chosen moment
of simulated time, and read from the simulator's ground truth what the vehicles did on their own
(docs/reliability.md, "When the ground station dies"). Used by tests/e2e/test_gcs_killed.py and
benchmarks/bench_gcs_kill.py.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from gcs_swarm.evaluation import metrics
from gcs_swarm.evaluation.run_data import load_truth
from gcs_swarm.guidance.failsafe_speed import distance_along_course
from swarm_common.obstacle_shapes import NO_SHAPES

HOLDING_SPEED = 0.3  # m/s: a vehicle slower than this in the air, at the end, holds (BRAKE, PX4's Hold, ...)
EXIT_WALL_S = 120.0  # wall s the orphaned simulator may take to land or hold its vehicles and exit


@dataclass(frozen=True)
class KillOutcome:
    """What happened after a kill at `killed_at` (simulated s), from truth.csv: vehicles crashed, the
    smallest obstacle clearance (m) and pair separation (m) from the kill on, how each vehicle ended
    ("landed", "holding" (in the air at rest: ArduCopter BRAKE, PX4 Hold), "crashed", or its mode number and
    speed), the simulator's exit
    (wall s after the kill; None if it had to be killed), whether record.csv runs up to the kill."""

    killed_at: float
    crashed: int
    clearance_after_m: float
    separation_after_m: float
    ends: tuple[str, ...]
    simulator_exit_s: float | None
    record_to_kill: bool

    @property
    def safe(self) -> bool:
        return self.crashed == 0 and all(e in ("landed", "holding") for e in self.ends)


def kill_moments(run_dir: Path, t_formation: float, t_end: float) -> dict[str, float]:
    """Simulated times of three worst moments on an undisturbed run: `heading_at_obstacle` (a vehicle at
    speed closest in time to an obstacle along its course), `mid_avoidance` (the leader's closest pass of an
    obstacle), `assembling` (1 s into formation flight)."""
    traj = load_truth(run_dir / "truth.csv")
    t, pos, vel = traj.t, traj.pos, traj.vel
    flying = (t > t_formation) & (t < t_end)
    urgency = np.zeros(len(t))
    closest = np.full(len(t), np.inf)
    radii = traj.obstacle_radii
    for k in np.flatnonzero(flying):
        if len(radii) == 0:
            break
        d = distance_along_course(pos[k], vel[k], traj.obstacle_centres[k], radii, 0.0, *NO_SHAPES, np.inf)
        speed = np.hypot(vel[k, :, 0], vel[k, :, 1])
        urgency[k] = np.max(np.where((speed > 5.0) & np.isfinite(d), speed / np.maximum(d, 0.1), 0.0))
        closest[k] = (np.linalg.norm(pos[k, 0] - traj.obstacle_centres[k], axis=1) - radii).min()
    moments = {"assembling": t_formation + 1.0}
    if urgency.max() > 0.0:
        moments["heading_at_obstacle"] = float(t[np.argmax(urgency)])
    if np.isfinite(closest).any():
        moments["mid_avoidance"] = float(t[np.argmin(closest)])
    return moments


def fly_and_kill(
    mission: Path, run_dir: Path, t_kill: float, base_port: int, cwd: Path | None = None
) -> KillOutcome:
    """Fly `mission` (embedded simulator on base_port..) with `--crash-at t_kill`: the ground station SIGKILLs
    itself at that vehicle time, exactly (in lockstep the frame of the kill repeats run to run). Then wait
    (at most EXIT_WALL_S) for the orphaned simulator to exit by itself, and read the outcome. Everything the
    run started is killed before returning."""
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir)]
    cmd += ["--base-port", str(base_port), "--quiet", "--crash-at", f"{t_kill:.3f}"]
    proc = subprocess.Popen(
        cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    exit_s = None
    try:
        status = proc.wait(300)
        if status != -signal.SIGKILL:
            raise RuntimeError(f"the ground station ended with status {status} before t = {t_kill} s")
        waited = time.monotonic()
        while time.monotonic() - waited < EXIT_WALL_S:
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                exit_s = time.monotonic() - waited
                break
            time.sleep(0.1)
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return outcome_after(run_dir, t_kill, exit_s)


def outcome_after(run_dir: Path, killed_at: float, exit_s: float | None) -> KillOutcome:
    """KillOutcome of a run folder whose ground station died at killed_at (simulated s)."""
    truth = np.genfromtxt(run_dir / "truth.csv", delimiter=",", names=True)
    traj = load_truth(run_dir / "truth.csv")
    after = traj.t >= killed_at
    pos = traj.pos[after]
    n = pos.shape[1]
    clearance, _ = metrics.min_obstacle_clearance(pos, traj.obstacle_centres[after], traj.obstacle_radii)
    ends = []
    for i in range(n):
        last = truth[truth["vehicle"] == i][-1]
        speed = float(np.hypot(last["vx"], last["vy"]))
        if last["crashed"]:
            ends.append("crashed")
        elif last["landed"] and not last["armed"]:
            ends.append("landed")
        elif float(np.hypot(speed, last["vz"])) < HOLDING_SPEED:
            ends.append("holding")
        else:
            ends.append(f"mode {int(last['mode'])} at {speed:.1f} m/s")
    record = run_dir / "record.csv"
    record_ok = False
    if record.exists():
        rows = [ln for ln in record.read_text().splitlines()[1:] if ln.count(",") > 5]
        record_ok = bool(rows) and float(rows[-1].split(",")[0]) >= killed_at - 1.5
    return KillOutcome(
        killed_at=killed_at,
        crashed=int(traj.crashed.any(axis=0).sum()),
        clearance_after_m=clearance,
        separation_after_m=metrics.min_separation(pos),
        ends=tuple(ends),
        simulator_exit_s=exit_s,
        record_to_kill=record_ok,
    )
