"""Cost of the sitl_sim physics + attitude loop alone (no MAVLink): the compiled physics step.

Prints, for N = 1, 9, 100 vehicles at 1 kHz, the wall time per vehicle-step (us) and the simulated seconds per
wall second, median of several repeats with the spread (min..max). Each call advances `chunk` physics steps
after a set_targets (chunk 20 = one 50 Hz lockstep frame; chunk 1 = the per-call overhead worst case).

    python benchmarks/bench_physics.py [--repeats 7] [--sim-seconds 1.0]

It uses only FleetDynamics' public calls, so it also runs against another tree (PYTHONPATH=<tree>) for an
interleaved A/B comparison.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from sitl_sim.vehicle_model.airframe import QuadParams
from sitl_sim.vehicle_model.dynamics import FleetDynamics, FleetState
from swarm_common.rotations import euler_to_quaternion

RATE_HZ = 1000.0


def make_fleet(n: int) -> tuple[FleetDynamics, tuple]:
    rng = np.random.default_rng(0)
    pos = np.column_stack((rng.uniform(-50, 50, (n, 2)), np.full(n, 20.0)))
    dyn = FleetDynamics(n, rate_hz=RATE_HZ, state=FleetState.at_rest(pos, np.zeros(n)))
    hover = QuadParams().mass * QuadParams().g
    angles = (rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-3, 3, n))
    quat = euler_to_quaternion(np.column_stack(angles))
    targets = (quat, np.zeros((n, 3)), np.full(n, hover), np.ones(n, dtype=bool), np.radians(30.0))
    return dyn, targets


def time_run(n: int, chunk: int, sim_seconds: float) -> float:
    """Wall seconds to simulate sim_seconds with one set_targets + step(chunk) per call."""
    dyn, targets = make_fleet(n)
    wind = np.zeros((n, 3))
    calls = max(1, round(sim_seconds * RATE_HZ / chunk))
    dyn.set_targets(*targets)
    dyn.step(wind, chunk)  # warm-up: loads (or compiles) the kernel
    start = time.perf_counter()
    for _ in range(calls):
        dyn.set_targets(*targets)
        dyn.step(wind, chunk)
    return (time.perf_counter() - start) * sim_seconds / (calls * chunk / RATE_HZ)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="repeats per case (median and spread)")
    parser.add_argument("--sim-seconds", type=float, default=1.0, help="simulated seconds per repeat")
    args = parser.parse_args()
    start = time.perf_counter()
    make_fleet(1)[0].step(np.zeros((1, 3)), 1)
    print(f"kernel load/compile: {time.perf_counter() - start:.2f} s (cached after the first run)")
    print(f"physics + attitude control at {RATE_HZ:.0f} Hz, median of {args.repeats} (min..max)")
    print(f"{'N':>4} {'chunk':>5} {'us/vehicle-step':>26} {'sim s / wall s':>28}")
    for n in (1, 9, 100):
        for chunk in (1, 20):
            walls = [time_run(n, chunk, args.sim_seconds) for _ in range(args.repeats)]
            per_step = sorted(w / (args.sim_seconds * RATE_HZ * n) * 1e6 for w in walls)
            speed = sorted(args.sim_seconds / w for w in walls)
            print(
                f"{n:4d} {chunk:5d} "
                f"{statistics.median(per_step):9.3f} ({per_step[0]:7.3f}..{per_step[-1]:7.3f}) "
                f"{statistics.median(speed):10.1f} ({speed[0]:8.1f}..{speed[-1]:8.1f})"
            )


if __name__ == "__main__":
    main()
