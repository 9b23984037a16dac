"""The link layer against the real simulator process in lockstep: connect, preflight, take off, fly
attitude targets, land; telemetry in the mission frame matches the simulator's ground truth."""

from __future__ import annotations

import importlib.util
import queue
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gcs_swarm.link.fleet import Fleet, VehicleConfig, thrust_from_acc

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("sitl_sim.__main__") is None, reason="the sitl_sim simulator is not installed"
)

ORIGIN = (47.397742, 8.545594, 488.0)
N = 2
BOOT_TIMEOUT_S = 60.0


def free_port_block(n: int) -> int:
    """A base port with base..base+n-1 free for UDP on 127.0.0.1 (a moment ago)."""
    for _ in range(100):
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        probe.bind(("127.0.0.1", 0))
        base = probe.getsockname()[1]
        held = [probe]
        try:
            for k in range(1, n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                held.append(s)
                s.bind(("127.0.0.1", base + k))
            return int(base)
        except OSError:
            continue
        finally:
            for s in held:
                s.close()
    raise RuntimeError("no block of free UDP ports")


@pytest.fixture
def simulator(tmp_path: Path) -> Iterator[tuple[int, Path]]:
    """A lockstep sitl_sim with N vehicles: (base port, truth log path); terminated afterwards."""
    base = free_port_block(N)
    truth = tmp_path / "truth.csv"
    home = ",".join(f"{v:.7f}" for v in ORIGIN)
    args = [sys.executable, "-m", "sitl_sim", "--vehicles", str(N), "--base-port", str(base), "--lockstep"]
    args += ["--home", home, "--ready-delay", "1", "--truth-log", str(truth), "--lockstep-timeout", "3"]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: queue.Queue[str] = queue.Queue()
    reader = threading.Thread(target=lambda: [lines.put(line.strip()) for line in proc.stdout], daemon=True)  # type: ignore[union-attr]
    reader.start()
    try:
        seen = []
        while "READY" not in seen:
            try:
                seen.append(lines.get(timeout=BOOT_TIMEOUT_S))
            except queue.Empty:
                pytest.fail(f"sitl_sim printed no READY within {BOOT_TIMEOUT_S:g} s: {seen}")
            if proc.poll() is not None and lines.empty():
                pytest.fail(f"sitl_sim exited with status {proc.returncode}: {seen}")
        yield base, truth
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
        reader.join(timeout=5)


def test_fly_and_land_two_vehicles_in_lockstep(simulator: tuple[int, Path], tmp_path: Path) -> None:
    base, truth_path = simulator
    configs = [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{base + i}", i + 1) for i in range(N)]
    samples = []
    with Fleet(configs, ORIGIN, tlog_path=tmp_path / "flight.tlog") as fleet:
        fleet.connect(timeout_s=10.0)
        fleet.request_streams_all(50.0)
        fleet.wait_ready(timeout_s=20.0)
        fleet.param_set_all("GUID_OPTIONS", 8)
        hover = fleet.param_get_all("MOT_THST_HOVER")
        assert np.all((hover > 0.1) & (hover < 0.7))
        fleet.set_mode_all("GUIDED")
        fleet.arm_all()
        fleet.takeoff_all(3.0)
        fleet.wait_until(lambda: bool(np.all(fleet.pos[:, 2] > 2.7)), 20.0, "both at 3 m")
        for _ in range(100):  # 2 s of level attitude at hover thrust, yaw held
            assert fleet.wait_tick(timeout_s=5.0)
            samples.append((fleet.time_ms.copy(), fleet.pos, fleet.att))
            yaw = samples[0][2][:, 2]
            fleet.send_attitude_targets(np.zeros(N), np.zeros(N), yaw, thrust_from_acc(9.8, hover))
            fleet.answer_frame()
        assert np.all(np.abs(fleet.vel) < 1.0) and np.all(fleet.pos[:, 2] > 1.5)
        fleet.land_all()
        fleet.wait_until(lambda: not fleet.armed.any(), 60.0, "both landed and disarmed")
        assert np.all(fleet.alive) and all(c["bad"] == 0 and c["lost"] == 0 for c in fleet.stats().values())
        # TIMESYNC round trips (one a wall second) were measured on every link
        assert np.all(np.isfinite(fleet.rtt_ms)) and np.all((fleet.rtt_ms > 0) & (fleet.rtt_ms < 5000))
    truth = np.genfromtxt(truth_path, names=True, delimiter=",")
    rows = {(round(t * 1000), int(v)): r for t, v, r in zip(truth["t"], truth["vehicle"], truth, strict=True)}
    for time_ms, pos, att in samples[::10]:
        for i in range(N):
            row = rows[(int(time_ms[i]), i)]
            np.testing.assert_allclose(pos[i], [row["x"], row["y"], row["z"]], atol=0.02)
            np.testing.assert_allclose(att[i], [row["roll"], row["pitch"], row["yaw"]], atol=1e-4)
