"""The simulator's CPU cost per ground-station command: N vehicles, each sent one SET_ATTITUDE_TARGET datagram
per 20 ms frame, as gcs_swarm sends them in formation flight (swarm_common.mavlink_codec.Packer, rates
ignored, time_boot_ms echoing the frame), read and obeyed by `Simulator._serve` (select over the vehicles'
sockets -> VehicleEndpoint.receive -> handle_datagram -> the setpoint handler -> Autopilot.set_attitude_target
-> the lockstep answer).

An in-process Simulator (no physics ticks) on free loopback ports, every vehicle airborne in GUIDED; one
socket plays the ground station. Per frame: send the N datagrams, wait ARRIVAL_S so that all are in the socket
buffers, then time `_serve` in process CPU time (time.process_time: less sensitive to other load than wall
time). Figure: CPU us per datagram, the median over the frames of one invocation, once with the lockstep clock
(as bundled flights run: answers registered, the clock started) and once in real time. Each invocation is a
fresh process.

    python benchmarks/bench_sim_intake.py [--vehicles 200] [--frames 300] [--repeats 3]

With --baseline DIR: the same measurement with another tree's packages (DIR holds sitl_sim and swarm_common,
e.g. `git worktree add DIR HEAD`), interleaved invocation by invocation with this tree's, so both see the same
machine load; printed as median (min-max) over the invocations.

    python benchmarks/bench_sim_intake.py --baseline /tmp/base --repeats 5

CPU time per datagram is not immune to other load (it rises while other jobs keep both vCPUs busy,
BENCHMARKS.md 2026-11-27): compare only interleaved figures.
"""

from __future__ import annotations

import argparse
import math
import socket
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tree_ab  # noqa: E402

WARMUP_FRAMES = 20  # frames left out of the figures (the first datagram of a peer greets it, first calls)
ARRIVAL_S = 0.003  # wall s between sending a frame and reading it: every datagram is in its socket buffer
FRAME_MS = 20  # the ground station's frame (50 Hz)
GCS_SYSID, GCS_COMPID = 255, 190
ATTITUDE_IGNORE_RATES = 0b111  # SET_ATTITUDE_TARGET.type_mask of gcs_swarm.link.setpoints


def measure_mode(vehicles: int, frames: int, lockstep: bool) -> float:
    """CPU us per datagram (median over frames) of one Simulator in lockstep or real-time mode."""
    import numpy as np
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    from sitl_sim.clock import plan_timing
    from sitl_sim.simulator import SimConfig, Simulator
    from sitl_sim.world import Obstacles
    from swarm_common.mavlink_codec import Packer
    from swarm_common.ports import free_udp_base

    start = np.column_stack((3.0 * np.arange(vehicles), np.zeros(vehicles), np.full(vehicles, 10.0)))
    config = SimConfig(
        base_port=free_udp_base(vehicles),
        bind="127.0.0.1",
        sysid_base=1,
        timing=plan_timing(1000.0, 100.0, 1000.0 / FRAME_MS if lockstep else None, 50.0),
        speedup=1.0,
        lockstep=lockstep,
        lockstep_timeout=5.0,
        lockstep_delay=1,
        home=(47.397742, 8.545594, 488.0),
        start_pos=start,
        start_vel=np.zeros((vehicles, 3)),
        start_yaw=np.zeros(vehicles),
        obstacles=Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))),
        wind=(0.0, 0.0, 0.0),
        truth_log=None,
        seed=0,
        ready_delay=0.0,
    )
    sim = Simulator(config)
    sim.lockstep_started = True  # past the boot wait for the clients, as in flight
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    gcs.setblocking(False)
    packer = Packer(mavlink2.MAVLink_set_attitude_target_message)
    links = [mavlink2.MAVLink(None, GCS_SYSID, GCS_COMPID) for _ in range(vehicles)]
    addresses = [("127.0.0.1", config.base_port + i) for i in range(vehicles)]
    per_datagram = []
    try:
        for k in range(1, frames + 1):
            frame_ms = FRAME_MS * k
            for i, (mav, address) in enumerate(zip(links, addresses, strict=True)):
                half_yaw = 0.05 * (i % 7)  # level, headings 0..0.6 rad: unit quaternions NED -> FRD
                q = (math.cos(half_yaw), 0.0, 0.0, math.sin(half_yaw))
                packet = packer.pack(mav, frame_ms, *q, 0.0, 0.0, 0.0, 0.52, i + 1, 1, ATTITUDE_IGNORE_RATES)
                mav.seq = (mav.seq + 1) % 256
                gcs.sendto(packet, address)
            time.sleep(ARRIVAL_S)
            cpu = 0.0
            deadline = time.monotonic() + 5.0
            while sum(ep.counters.received for ep in sim.endpoints) < k * vehicles:
                if time.monotonic() > deadline:
                    raise RuntimeError(f"frame {k}: not every datagram arrived within 5 s")
                began = time.process_time()
                sim._serve(0.0, frame_ms if lockstep else None)
                cpu += time.process_time() - began
            per_datagram.append(cpu / vehicles)
            try:  # the vehicles' greetings of a new peer: nobody reads them
                while gcs.recv(65535):
                    pass
            except BlockingIOError:
                pass
        for ep in sim.endpoints:
            c = ep.counters
            if c.invalid or c.refused or c.foreign or c.bad_frames or c.handler_errors:
                raise RuntimeError(f"vehicle {ep.index} did not take every attitude target: {c.summary()}")
    finally:
        gcs.close()
        sim.close()
    return statistics.median(per_datagram[WARMUP_FRAMES:]) * 1e6


def measure(vehicles: int, frames: int) -> dict[str, float | str]:
    """One invocation: CPU us per datagram in lockstep and in real time, and the tree sitl_sim came from."""
    import sitl_sim

    return {
        "lockstep_us": measure_mode(vehicles, frames, lockstep=True),
        "real_time_us": measure_mode(vehicles, frames, lockstep=False),
        "tree": tree_ab.package_tree(sitl_sim.__file__),
    }


def report(results: dict[str, list[tree_ab.Figures]], args: argparse.Namespace) -> None:
    """The table of the invocations' figures per tree."""
    print("| tree | lockstep: CPU us per datagram | real time: CPU us per datagram |")
    print("|---|---|---|")
    keys = ("lockstep_us", "real_time_us")
    for name, runs in results.items():
        cells = [tree_ab.spread([r[key] for r in runs]) for key in keys]
        print(f"| {name} | " + " | ".join(cells) + " |")
    if args.baseline:
        print(tree_ab.ratios(results, keys))


if __name__ == "__main__":
    raise SystemExit(tree_ab.main(__file__, __doc__.splitlines()[0], WARMUP_FRAMES, measure, report))
