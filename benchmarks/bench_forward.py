"""What one forward costs the control loop: tick latency with and without `--forward` at 9 and 100 vehicles.

The flights are bench_fleet_capacity's (a grid formation, airborne at 10 m, a 60 m leg, the simulator in REAL
TIME so it never waits for the ground station). With a forward, a thread of this process plays the watching
ground station: a UDP socket on the forward's port that reads (and counts) every frame it is sent. Each
configuration flies `--repeats` times; per configuration the table gives the median and the worst of the
flights' median, p99 and max tick latency (flight.json `tick_latency_ms`: a complete telemetry frame in to the
last SET_ATTITUDE_TARGET out) and the ticks missed.

Usage: python benchmarks/bench_forward.py [--sizes 9,100] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_fleet_capacity import RATE_HZ, grid_mission  # noqa: E402

from swarm_common.ports import free_udp_base  # noqa: E402


class Watcher:
    """A socket on a free loopback port reading everything sent to it, in a thread: the forwarded station."""

    def __init__(self) -> None:
        self.port = free_udp_base(1)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", self.port))
        self.sock.settimeout(0.2)
        self.datagrams = 0
        self.bytes = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(65535)
            except TimeoutError:
                continue
            self.datagrams += 1
            self.bytes += len(data)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


def fly(n: int, out: Path, forward: bool, repeat: int) -> dict[str, Any]:
    """One real-time flight of n vehicles, with or without one read-only forward."""
    mission = grid_mission(n, out, 60.0)
    run_dir = out / f"run{n}-{'fw' if forward else 'plain'}-{repeat}"
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir), "--quiet"]
    cmd += ["--time-mode", "realtime", "--base-port", str(free_udp_base(n))]
    watcher = Watcher() if forward else None
    if watcher is not None:
        cmd.append(f"--forward=udpout:127.0.0.1:{watcher.port}")
    try:
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900)
    finally:
        if watcher is not None:
            watcher.close()
    flight = json.loads((run_dir / "flight.json").read_text())
    t0, t1 = flight.get("t_formation_start"), flight.get("t_formation_end")
    expected = int(round((t1 - t0) * RATE_HZ)) + 1 if t0 is not None and t1 is not None else 0
    latency = flight.get("tick_latency_ms") or {}
    forwards = (flight.get("link_stats") or {}).get("forwards") or {}
    return {
        "status": proc.returncode,
        "missed": max(0, expected - int(flight.get("ticks", 0))),
        "median": latency.get("median", float("nan")),
        "p99": latency.get("p99", float("nan")),
        "max": latency.get("max", float("nan")),
        "frames": sum(f["sent"] for f in forwards.values()),
        "datagrams": watcher.datagrams if watcher is not None else 0,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="9,100", help="comma-separated fleet sizes (default 9,100)")
    parser.add_argument("--repeats", type=int, default=3, help="flights per configuration (default 3)")
    args = parser.parse_args()
    print(
        "| vehicles | forward | exit | tick latency median ms (median / worst) | p99 ms (median / worst) "
        "| max ms (median / worst) | missed ticks | frames forwarded (datagrams read) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(x) for x in args.sizes.split(",")):
            for forward in (False, True):
                runs = [fly(n, Path(tmp), forward, k) for k in range(args.repeats)]

                def cell(key: str, runs: list[dict[str, Any]] = runs) -> str:
                    values = [r[key] for r in runs]
                    return f"{statistics.median(values):.3f} / {max(values):.3f}"

                counts = ",".join(f"{r['frames']} ({r['datagrams']})" for r in runs) if forward else "-"
                print(
                    f"| {n} | {'one' if forward else 'none'} | {','.join(str(r['status']) for r in runs)} "
                    f"| {cell('median')} | {cell('p99')} | {cell('max')} "
                    f"| {','.join(str(r['missed']) for r in runs)} "
                    f"| {counts} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
