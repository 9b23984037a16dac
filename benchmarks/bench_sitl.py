"""Benchmark of the simulator process `sitl-sim` (prints a table; no assertions).

(a) lockstep: a scripted pymavlink commander (non-blocking sockets, parse_buffer) answers every 20 ms frame of
    every vehicle with SYSTEM_TIME echoing its time_boot_ms, with ATTITUDE and GLOBAL_POSITION_INT at 50 Hz;
(b) free running with --speedup 1000 while a client receives ATTITUDE and GLOBAL_POSITION_INT at 50 Hz from
    every vehicle;
both for 1, 9 and 100 vehicles: simulated seconds per wall second (median of repeats, min..max), and the
simulator process's own CPU time per vehicle and physics step (from /proc). (c) in-process cost of one
autopilot tick (autopilot + physics + world + telemetry encoding) per vehicle and physics step, without any
network client.

    python benchmarks/bench_sitl.py [--repeats 3] [--seconds 4] [--vehicles 1 9 100]
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import socket
import statistics
import subprocess
import sys
import time

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

M = mavlink
RATE_HZ = 1000  # physics steps per simulated second (the default)
STREAMS = (M.MAVLINK_MSG_ID_ATTITUDE, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT)


def free_base_port(count: int) -> int:
    """A base port with count free UDP ports after it."""
    for base in range(24000, 60000, 500):
        try:
            sockets = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(count)]
            for offset, sock in enumerate(sockets):
                sock.bind(("127.0.0.1", base + offset))
            return base
        except OSError:
            continue
        finally:
            for sock in sockets:
                sock.close()
    raise RuntimeError("no free port range")


def start(vehicles: int, mode_args: list[str]) -> tuple[subprocess.Popen[str], int]:
    """Start the simulator and wait for READY."""
    base = free_base_port(vehicles)
    proc = subprocess.Popen(
        [sys.executable, "-m", "sitl_sim", "--vehicles", str(vehicles), "--base-port", str(base),
         "--ready-delay", "1", *mode_args],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )  # fmt: skip
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.strip() == "READY":
            return proc, base
    raise RuntimeError("simulator did not start")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process, s."""
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class Commander:
    """Minimal ground station: one socket and MAVLink object per vehicle, 50 Hz streams requested."""

    def __init__(self, base: int, vehicles: int, lockstep: bool) -> None:
        self.lockstep = lockstep
        self.socks = []
        self.mavs = []
        for i in range(vehicles):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.connect(("127.0.0.1", base + i))
            sock.setblocking(False)
            self.socks.append(sock)
            self.mavs.append(M.MAVLink(None, srcSystem=255, srcComponent=190))
        self.times = np.zeros(vehicles, dtype=np.int64)
        self.answered = np.zeros(vehicles, dtype=np.int64)
        self.fd_index = {sock.fileno(): i for i, sock in enumerate(self.socks)}
        for i, (sock, mav) in enumerate(zip(self.socks, self.mavs, strict=True)):
            out = mav.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(mav)
            for msg_id in STREAMS:
                out += mav.command_long_encode(
                    i + 1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, msg_id, 20000, 0, 0, 0, 0, 0
                ).pack(mav)
            sock.send(out)

    def serve(self, seconds: float) -> float:
        """Run for `seconds` wall seconds; returns the simulated time reached (min over vehicles), s."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            readable, _, _ = select.select(self.socks, [], [], 0.1)
            for sock in readable:
                i = self.fd_index[sock.fileno()]
                while True:
                    try:
                        data = sock.recv(65535)
                    except (BlockingIOError, ConnectionRefusedError):
                        break
                    for msg in self.mavs[i].parse_buffer(data) or []:
                        stamp = getattr(msg, "time_boot_ms", None)
                        if stamp is not None and stamp > self.times[i]:
                            self.times[i] = stamp
                if self.lockstep and self.times[i] > self.answered[i]:
                    mav = self.mavs[i]
                    sock.send(mav.system_time_encode(0, int(self.times[i])).pack(mav))
                    self.answered[i] = self.times[i]
        return float(self.times.min()) / 1000.0

    def close(self) -> None:
        for sock in self.socks:
            sock.close()


def run_case(vehicles: int, lockstep: bool, seconds: float) -> tuple[float, float]:
    """(simulated s per wall s, simulator CPU us per vehicle-step) of one run."""
    mode = ["--lockstep", "--lockstep-timeout", "30"] if lockstep else ["--speedup", "1000"]
    proc, base = start(vehicles, mode)
    commander = Commander(base, vehicles, lockstep)
    try:
        commander.serve(1.0)  # warm up: boot, streams set, lockstep clients registered
        sim0, wall0, cpu0 = commander.serve(0.0), time.monotonic(), cpu_seconds(proc.pid)
        sim1 = commander.serve(seconds)
        wall1, cpu1 = time.monotonic(), cpu_seconds(proc.pid)
    finally:
        commander.close()
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
    simulated = sim1 - sim0
    steps = simulated * RATE_HZ * vehicles
    return simulated / (wall1 - wall0), (cpu1 - cpu0) / steps * 1e6 if steps else float("nan")


def tick_cost(vehicles: int, ticks: int = 400) -> tuple[float, float]:
    """In-process: (us per autopilot tick, us per vehicle-step) with telemetry encoded for one peer each."""
    from sitl_sim.clock import plan_timing
    from sitl_sim.simulator import SimConfig, Simulator
    from sitl_sim.world import Obstacles

    config = SimConfig(
        base_port=free_base_port(vehicles), bind="127.0.0.1", sysid_base=1,
        timing=plan_timing(RATE_HZ, 100.0, None, 50.0), speedup=1.0, lockstep=False, lockstep_timeout=5.0,
        lockstep_delay=1,
        home=(-35.36, 149.16, 584.0),
        start_pos=np.column_stack((5.0 * np.arange(vehicles), np.zeros((vehicles, 2)))),
        start_vel=np.zeros((vehicles, 3)), start_yaw=np.zeros(vehicles),
        obstacles=Obstacles(np.array([[0.0, 50.0, 10.0]]), np.array([3.0]), np.zeros((1, 3))),
        wind=(3.0, 90.0, 1.0), truth_log=None, seed=0, ready_delay=0.0,
    )  # fmt: skip
    sim = Simulator(config)
    try:
        sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sink.bind(("127.0.0.1", 0))
        for i, endpoint in enumerate(sim.endpoints):
            endpoint.peers[sink.getsockname()] = time.monotonic() + 1e9
            for msg_id in STREAMS:
                sim.streams.set_interval(i, msg_id, 20000, 0)
        for i in range(vehicles):
            sim.autopilot.arm(i, force=True)
            sim.autopilot.set_mode(i, 4)
            sim.autopilot.takeoff(i, 10.0)
        for _ in range(50):
            sim._tick()
        start_time = time.perf_counter()
        for _ in range(ticks):
            sim._tick()
        per_tick = (time.perf_counter() - start_time) / ticks * 1e6
        sink.close()
    finally:
        sim.close()
    return per_tick, per_tick / (vehicles * sim.timing.steps_per_tick)


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):9.1f}  ({min(values):.1f}..{max(values):.1f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=4.0, help="wall seconds measured per run")
    parser.add_argument("--vehicles", type=int, nargs="+", default=[1, 9, 100])
    args = parser.parse_args()
    print(f"sitl-sim benchmark: {os.cpu_count()} CPUs, physics {RATE_HZ} Hz, autopilot 100 Hz, 50 Hz streams")
    print(f"{'case':<22}{'N':>4}  {'sim s / wall s (median, range)':>34}  {'CPU us / vehicle-step':>26}")
    for lockstep in (True, False):
        name = "(a) lockstep" if lockstep else "(b) speedup 1000"
        for n in args.vehicles:
            results = [run_case(n, lockstep, args.seconds) for _ in range(args.repeats)]
            rates = [r[0] for r in results]
            cpus = [r[1] for r in results]
            print(f"{name:<22}{n:>4}  {spread(rates):>34}  {spread(cpus):>26}", flush=True)
    for n in args.vehicles:
        costs = [tick_cost(n) for _ in range(args.repeats)]
        per_tick = [c[0] for c in costs]
        per_step = [c[1] for c in costs]
        print(f"{'(c) in-process tick':<22}{n:>4}  {spread(per_tick) + ' us':>34}  {spread(per_step):>26}")


if __name__ == "__main__":
    main()
