"""The live page's cost and delay (issue 39): telemetry-to-page latency, and the control loop's tick latency
with and without a page open.

(1) Latency at 9 and 200 vehicles through the live page's own path: a thread plays the flight thread, putting
a snapshot (gcs_swarm.web.live.LiveSnapshot, stamped with the wall clock when made) into the Handoff at the
page's rate (live.RATE_HZ); the LiveServer (its thread, its loop) turns each into a frame and sends it over a
loopback WebSocket to a client in this process, which notes its receipt time. Latency = receipt - stamp.

(2) Tick latency: `gcs-swarm run missions/quickstart.yaml --time-mode lockstep --quiet` (with `--fleet N`: a
grid of N vehicles flying 200 m east, bench_fleet_capacity.grid_mission), interleaved: without `--web`, then
with `--web 127.0.0.1:0` and a WebSocket client (another process) reading every frame, `--repeats` times
each. Per flight: flight.json tick_latency_ms (median, p99: a complete telemetry frame in to
the last command out); for the flights with the page, the page's latency of the real flight's frames too.

Usage: python benchmarks/bench_web_latency.py [--sizes 9,200] [--seconds 20] [--repeats 3] [--fleet N]
"""

from __future__ import annotations

import argparse
import asyncio
import dataclasses
import json
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import aiohttp
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_fleet_capacity import grid_mission  # noqa: E402

from gcs_swarm.link.autopilots import dialect_named  # noqa: E402
from gcs_swarm.mission import Mission, load_mission  # noqa: E402
from gcs_swarm.web.live import RATE_HZ, Handoff, LiveServer, LiveSnapshot  # noqa: E402
from swarm_common.ports import free_udp_base  # noqa: E402

QUICKSTART = ROOT / "missions" / "quickstart.yaml"
FLEET_LEG_M = 200.0  # m the --fleet grid's leader flies east


def fleet_mission(n: int) -> Mission:
    """quickstart with n vehicles (its vehicles repeated, renamed v0..): only the scene reads it."""
    base = load_mission(QUICKSTART, to_fly=False)
    vehicles = tuple(
        dataclasses.replace(base.vehicles[i % len(base.vehicles)], name=f"v{i}") for i in range(n)
    )
    return dataclasses.replace(base, vehicles=vehicles)


def synthetic(mission: Mission, k: int, events: tuple[str, ...]) -> LiveSnapshot:
    """Snapshot k of a grid of len(mission.vehicles) vehicles moving east, stamped now."""
    n = len(mission.vehicles)
    grid = np.c_[np.arange(n) % 15 * 3.0, np.arange(n) // 15 * 3.0, np.full(n, 10.0)]
    pos = grid + [0.1 * k, 0.0, 0.0]
    return LiveSnapshot(
        mission=mission,
        stamp=time.time(),
        t=k / RATE_HZ,
        phase="formation",
        pos=pos,
        yaw=np.zeros(n),
        slots=pos[:, :2] + 0.5,
        modes=np.full(n, 4),
        dialects=(dialect_named("ardupilot"),) * n,
        alive=np.ones(n, dtype=bool),
        taken=np.zeros(n, dtype=bool),
        link=np.tile([1669.0, 4757.0], (n, 1)),
        budget=None,
        leader=0,
        goal=np.array([200.0, 0.0, 10.0]),
        formation_rms=0.5,
        formation_s=k / RATE_HZ,
        events=events,
    )


async def _read_frames(url: str, seconds: float) -> list[float]:
    """Latency s of every frame received for `seconds`."""
    latencies: list[float] = []
    async with aiohttp.ClientSession() as http, http.ws_connect(url + "ws", max_msg_size=0) as ws:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = await ws.receive(timeout=30)
            now = time.time()
            if msg.type != aiohttp.WSMsgType.TEXT:
                break
            frame = json.loads(msg.data)
            if frame["type"] == "frame":
                latencies.append(now - frame["stamp"])
    return latencies


def synthetic_latency(n: int, seconds: float) -> dict[str, Any]:
    mission = fleet_mission(n)
    handoff = Handoff()
    server = LiveServer(handoff, "127.0.0.1", 0)
    url = server.start()
    stop = threading.Event()

    def feed() -> None:
        k = 0
        events = ("command mode: attitude targets at 50 Hz",)
        while not stop.is_set():
            handoff.put(synthetic(mission, k, events))
            k += 1
            time.sleep(1.0 / RATE_HZ)

    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    try:
        latencies = asyncio.run(_read_frames(url, seconds))
    finally:
        stop.set()
        feeder.join()
        server.stop()
    return summary(latencies, seconds)


def summary(latencies: list[float], seconds: float | None) -> dict[str, Any]:
    ms = np.asarray(latencies) * 1000.0
    out = {
        "frames": len(ms),
        "p50_ms": round(float(np.percentile(ms, 50)), 2),
        "p95_ms": round(float(np.percentile(ms, 95)), 2),
        "max_ms": round(float(ms.max()), 2),
    }
    if seconds:
        out["frames_per_s"] = round(len(ms) / seconds, 1)
    return out


CLIENT = """
import asyncio, json, sys, time, aiohttp
async def main(url, out):
    lat = []
    async with aiohttp.ClientSession() as http, http.ws_connect(url + "ws", max_msg_size=0) as ws:
        async for msg in ws:
            if msg.type != aiohttp.WSMsgType.TEXT:
                break
            now = time.time()
            frame = json.loads(msg.data)
            if frame["type"] == "frame":
                lat.append(now - frame["stamp"])
    open(out, "w").write(json.dumps(lat))
asyncio.run(main(sys.argv[1], sys.argv[2]))
"""


def flight(web: bool, out: Path, mission: Path = QUICKSTART, n: int = 3) -> dict[str, Any]:
    """One lockstep flight of `mission` (n vehicles); with `web`, a page client in another process reads
    every frame."""
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(out)]
    cmd += ["--time-mode", "lockstep", "--quiet", "--base-port", str(free_udp_base(max(n, 10)))]
    if web:
        cmd += ["--web", "127.0.0.1:0"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    client = None
    assert proc.stdout is not None
    if web:
        line = proc.stdout.readline()
        url = line.split(" at ", 1)[1].split()[0]
        client = subprocess.Popen([sys.executable, "-c", CLIENT, url, str(out / "page.json")])
    rest = proc.stdout.read()
    proc.wait()
    if client is not None:
        client.wait(timeout=60)
    flown = json.loads((out / "flight.json").read_text())
    result: dict[str, Any] = {
        "web": web,
        "status": proc.returncode,
        "tick_latency_ms": flown["tick_latency_ms"],
    }
    if web:
        result["page"] = summary(json.loads((out / "page.json").read_text()), None)
    if proc.returncode != 0:
        result["output"] = rest[-500:]
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="9,200")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--fleet", type=int, default=0, help="tick A/B with a grid of N vehicles (0: quickstart)"
    )
    args = parser.parse_args()
    for n in (int(s) for s in args.sizes.split(",")):
        print(json.dumps({"vehicles": n, "synthetic": synthetic_latency(n, args.seconds)}), flush=True)
    flights: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        mission, n = QUICKSTART, 3
        if args.fleet:
            mission, n = grid_mission(args.fleet, Path(tmp), FLEET_LEG_M), args.fleet
        for k in range(args.repeats):
            for web in (False, True):
                flights.append(flight(web, Path(tmp) / f"{k}-{int(web)}", mission, n))
                print(json.dumps(flights[-1]), flush=True)
    for web in (False, True):
        ours = [f["tick_latency_ms"] for f in flights if f["web"] is web]
        if not ours:
            continue
        medians = [f["median"] for f in ours]
        p99s = [f["p99"] for f in ours]
        which = "with" if web else "without"
        print(
            f"{which} the page: tick latency median {statistics.median(medians):.3f} ms "
            f"(flights {min(medians):.3f}..{max(medians):.3f}), p99 {statistics.median(p99s):.3f} ms "
            f"({min(p99s):.3f}..{max(p99s):.3f})"
        )


if __name__ == "__main__":
    main()
