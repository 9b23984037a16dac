"""The ground station's per-frame link cost at N vehicles, without a simulator: intake (N datagrams of
GLOBAL_POSITION_INT + ATTITUDE read, decoded and turned into state by `Fleet.pump`), commands (N
SET_ATTITUDE_TARGET packed, logged and sent by `Fleet.send_attitude_targets`), and an idle pump (`Fleet.pump`
with nothing to read: select and the link's housekeeping; in a 200-vehicle flight the ground station pumps
about 4 times a frame).

N loopback sockets play the vehicles: each says HEARTBEAT once (the link binds its sysid), then every frame
sends one datagram with the two 50 Hz messages as the simulator frames them (sitl_sim.network.streams.Framer),
stamped with the frame's time_boot_ms. The ground station writes its tlog as in a flight. Per frame it prints
the process CPU time (time.process_time, less sensitive to other load than wall time) of the intake and of the
commands, median over the frames of one invocation; each invocation is a fresh process.

    python benchmarks/bench_intake.py [--vehicles 200] [--frames 300] [--repeats 3]

With --baseline DIR: the same measurement with another tree's packages (DIR holds gcs_swarm, swarm_common
and sitl_sim, e.g. `git worktree add DIR <commit>`), interleaved invocation by invocation with this tree's,
so both see the same machine load.

    python benchmarks/bench_intake.py --baseline /tmp/base --repeats 5

CPU time per frame is not immune to other load: it rose up to 1.7 times while other jobs kept both vCPUs
busy (load average 2-3; BENCHMARKS.md 2026-11-27), so run it on a quiet machine and compare only interleaved
figures.
"""

from __future__ import annotations

import argparse
import socket
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import tree_ab  # noqa: E402

ORIGIN = (47.397742, 8.545594, 488.0)  # lat, lon deg, alt m AMSL: the mission origin
WARMUP_FRAMES = 20  # frames left out of the figures (first-call costs)
ARRIVAL_S = 0.003  # wall s between sending a frame and reading it: every datagram is in the socket buffer


def measure(vehicles: int, frames: int) -> dict[str, float | str]:
    """One invocation's medians: CPU ms per frame of the intake and of the commands; the tree gcs_swarm came
    from."""
    import numpy as np
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    import gcs_swarm
    from gcs_swarm.link.fleet import Fleet
    from gcs_swarm.link.vehicle import VehicleConfig
    from sitl_sim.network.streams import Framer

    vehicle_socks = []
    for _ in range(vehicles):
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
        vehicle_socks.append(sock)
    configs = [
        VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{s.getsockname()[1]}", sysid=i + 1)
        for i, s in enumerate(vehicle_socks)
    ]
    with tempfile.TemporaryDirectory() as tmp:
        fleet = Fleet(configs, ORIGIN, tlog_path=Path(tmp) / "telemetry.tlog", lockstep_answers=False)
        fleet.network.open(5.0, fleet.tlog_path)
        fleet.pump(0.0)  # the GCS heartbeats bind each udpout socket to a local port
        gcs_addresses = [link.channel.endpoint._conn.port.getsockname() for link in fleet.links]  # type: ignore[union-attr]
        framers = [Framer(i + 1, 1) for i in range(vehicles)]

        def send_frame(datagrams: list[bytes]) -> None:
            for sock, address, datagram in zip(vehicle_socks, gcs_addresses, datagrams, strict=True):
                sock.sendto(datagram, address)

        send_frame([f.pack(f.mav.heartbeat_encode(2, 3, 89, 4, 4, 3)) for f in framers])
        deadline = time.monotonic() + 5.0
        while not all(link.sysid for link in fleet.links):
            if time.monotonic() > deadline:
                raise RuntimeError("the links did not bind to the fake vehicles")
            fleet.pump(0.01)
        intake, commands = [], []
        zeros = np.zeros(vehicles)
        for k in range(1, frames + 1):
            t_ms = 1000 + 20 * k
            send_frame([
                f.frame(mavlink2.MAVLink_global_position_int_message, t_ms, 473977420 + 90 * i, 85455940,
                        498000, 10000, 120, -40, 3, 9000)
                + f.frame(mavlink2.MAVLink_attitude_message, t_ms, 0.01, -0.02, 1.2, 0.001, 0.002, 0.003)
                for i, f in enumerate(framers)
            ])  # fmt: skip
            time.sleep(ARRIVAL_S)
            start = time.process_time()
            while int(fleet.state.position_ms.min()) < t_ms:
                fleet.pump(0.05)
            read = time.process_time()
            fleet.send_attitude_targets(zeros + 0.05, zeros - 0.05, zeros + 0.3, zeros + 0.5)
            intake.append(read - start)
            commands.append(time.process_time() - read)
            for sock in vehicle_socks:  # drop the commands (the vehicles do not read them)
                try:
                    while sock.recv(2048):
                        pass
                except BlockingIOError:
                    pass
        idle = []
        for _ in range(frames):
            start = time.process_time()
            fleet.pump(0.0)
            idle.append(time.process_time() - start)
        fleet.network.close()
    for sock in vehicle_socks:
        sock.close()
    return {
        "intake_ms": statistics.median(intake[WARMUP_FRAMES:]) * 1e3,
        "commands_ms": statistics.median(commands[WARMUP_FRAMES:]) * 1e3,
        "idle_pump_us": statistics.median(idle[WARMUP_FRAMES:]) * 1e6,
        "tree": tree_ab.package_tree(gcs_swarm.__file__),
    }


def report(results: dict[str, list[tree_ab.Figures]], args: argparse.Namespace) -> None:
    """The table of the invocations' figures per tree."""
    print(
        "| tree | intake CPU ms/frame | per message us | commands CPU ms/frame | per command us "
        "| idle pump CPU us |"
    )
    print("|---|---|---|---|---|---|")
    for name, runs in results.items():
        intake = [r["intake_ms"] for r in runs]
        commands = [r["commands_ms"] for r in runs]
        per_message = [1e3 * v / (2 * args.vehicles) for v in intake]
        per_command = [1e3 * v / args.vehicles for v in commands]
        idle = [r["idle_pump_us"] for r in runs]
        cells = [tree_ab.spread(v) for v in (intake, per_message, commands, per_command, idle)]
        print(f"| {name} | " + " | ".join(cells) + " |")
    if args.baseline:
        print(tree_ab.ratios(results, ("intake_ms", "commands_ms", "idle_pump_us")))


if __name__ == "__main__":
    raise SystemExit(tree_ab.main(__file__, __doc__.splitlines()[0], WARMUP_FRAMES, measure, report))
