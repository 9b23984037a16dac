"""Cost of one FleetController.tick (formation targets, obstacle + inter-UAV field, reference generator, SMC,
inversion) for the whole fleet, and of the command guard after it (ArduPilot thrust + guard_attitude_commands,
as gcs_swarm.flight.formation_tick runs them): small fleets N = 3, 6, 9 with K = 0 and 10 obstacles, and
N = 9, 100, 1000 with K = 10 and 100.

The fleet flies a grid formation with 9 m spacing (inside D_max = 10 m, so the inter-UAV term is active);
obstacles are spread over the fleet's area, so many vehicle-obstacle pairs are inside l0 = 20 m. The
controller is configured as the bundled missions fly it: an altitude floor and the dead-GCS speed scheduling
on. Prints a Markdown table: median per tick over repeats, with the spread (min..max of the repeat medians).

    python benchmarks/bench_guidance.py [--repeats 7] [--ticks 50] [--quick] [--max-n 1000]

With --compiled-ab: the tick with the reference generator's shaping compiled (numba, the default when
installed) against the numpy reference (gcs_swarm.guidance.reference.compiled_shaping = None), interleaved
repeat by repeat, N = 3, 6, 9, 25, 100 with K = 10.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from gcs_swarm.guidance import reference
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.params import DeadGcsParams, FieldParams, G
from gcs_swarm.link.autopilots import ardupilot
from gcs_swarm.link.command_limits import CommandLimits, guard_attitude_commands

SPACING = 9.0  # m
DT = 0.02  # s, 50 Hz


def scenario(n: int, k: int, seed: int = 0):
    """A controller, the fleet state and obstacles; deterministic."""
    rng = np.random.default_rng(seed)
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("grid", n - 1, SPACING)
    ctl = FleetController(
        n, 0, offsets, np.array([[5000.0, 0.0, 50.0]]), control_dt=DT, z_min=5.0,
        dead_gcs=DeadGcsParams(failsafe_timeout_s=3.0, brake_accel=2.5, brake_jerk=5.0),
    )  # fmt: skip
    pos = offsets + np.array([0.0, 0.0, 50.0]) + rng.normal(0.0, 0.5, (n, 3))
    vel = np.tile([8.0, 0.0, 0.0], (n, 1)) + rng.normal(0.0, 0.3, (n, 3))
    att = np.zeros((n, 3))
    lo, hi = pos.min(axis=0) - 20.0, pos.max(axis=0) + 20.0
    centres = lo + rng.uniform(0.0, 1.0, (k, 3)) * (hi - lo)
    radii = rng.uniform(1.0, 4.0, k)
    centres[:, 0] += 15.0  # keep the vehicles themselves outside the spheres
    ctl.reset(pos, vel, att[:, 2])
    return ctl, pos, vel, att, centres, radii


def close_pairs(pos: np.ndarray, centres: np.ndarray, radii: np.ndarray, l0: float, d_max: float):
    """Vehicle-obstacle pairs within l0 of the surface and vehicle pairs within D_max (for context)."""
    obs = int((np.linalg.norm(pos[:, None] - centres[None], axis=2) - radii <= l0).sum())
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
    return obs, int(((d < d_max).sum() - len(pos)) // 2)


def time_ticks(n: int, k: int, repeats: int, ticks: int) -> list[float]:
    """Per-tick seconds, one median per repeat."""
    ctl, pos, vel, att, centres, radii = scenario(n, k)
    active = np.ones(n, dtype=bool)
    t = 0.0
    for _ in range(5):  # warm-up
        ctl.tick(t, pos, vel, att, centres, radii, active)
        t += DT
    out = []
    for _ in range(repeats):
        samples = []
        for _ in range(ticks):
            start = time.perf_counter()
            ctl.tick(t, pos, vel, att, centres, radii, active)
            samples.append(time.perf_counter() - start)
            t += DT
        out.append(statistics.median(samples))
    return out


def time_compiled_ab(n: int, k: int, repeats: int, ticks: int) -> tuple[list[float], list[float]]:
    """Per-tick seconds with the compiled shaping and with the numpy one, one median per repeat each; the
    two run alternately (compiled, numpy, compiled...) on two controllers of the same scenario."""
    compiled = reference.compiled_shaping
    runs = {path: scenario(n, k) for path in ("compiled", "numpy")}
    active = np.ones(n, dtype=bool)
    times: dict[str, list[float]] = {"compiled": [], "numpy": []}
    t = 0.0
    try:
        for repeat in range(repeats + 1):  # the first round is a warm-up
            for path, (ctl, pos, vel, att, centres, radii) in runs.items():
                reference.compiled_shaping = compiled if path == "compiled" else None
                samples = []
                for tick in range(ticks):
                    start = time.perf_counter()
                    ctl.tick(t + tick * DT, pos, vel, att, centres, radii, active)
                    samples.append(time.perf_counter() - start)
                if repeat:
                    times[path].append(statistics.median(samples))
            t += ticks * DT
    finally:
        reference.compiled_shaping = compiled
    return times["compiled"], times["numpy"]


def compiled_ab(repeats: int, ticks: int) -> None:
    """Print the A/B table of the compiled shaping (time_compiled_ab)."""
    if reference.compiled_shaping is None:
        raise SystemExit("numba is not installed: no compiled path to compare")
    print(
        f"FleetController.tick, compiled vs numpy step-4 shaping, K = 10, median of {repeats} x {ticks} ticks"
    )
    print()
    print("| N | compiled ms / tick (min..max) | numpy ms / tick (min..max) | saved ms / tick | saved % |")
    print("|---|---|---|---|---|")
    for n in (3, 6, 9, 25, 100):
        fast, slow = time_compiled_ab(n, 10, repeats, ticks)
        (fast_med, fast_txt), (slow_med, slow_txt) = spread(fast), spread(slow)
        saved = slow_med - fast_med
        print(f"| {n} | {fast_txt} | {slow_txt} | {saved:.3f} | {saved / slow_med * 100:.1f} % |")


GUARD = CommandLimits(math.radians(35.0), 2.0, 5.0, 7000.0, 400.0)


def time_guard(n: int, k: int, repeats: int, ticks: int) -> list[float]:
    """Per-tick seconds of the command guard for one tick's command (formation_tick: unboosted thrust,
    normalised thrust, guard_attitude_commands), one median per repeat."""
    ctl, pos, vel, att, centres, radii = scenario(n, k)
    cmd = ctl.tick(0.0, pos, vel, att, centres, radii, np.ones(n, dtype=bool))
    hover, boost = np.full(n, 0.45), np.arange(n) % 2 == 0
    out = []
    for _ in range(repeats):
        samples = []
        for _ in range(ticks):
            start = time.perf_counter()
            acc = ardupilot.unboosted_thrust(cmd.thrust_acc, att[:, 0], att[:, 1], boost)
            thrust = ardupilot.thrust_from_acc(np.nan_to_num(acc), hover, G)
            guard_attitude_commands(
                cmd.roll_d, cmd.pitch_d, cmd.yaw_d, thrust, pos, att[:, 2], hover, GUARD, vel=vel
            )
            samples.append(time.perf_counter() - start)
        out.append(statistics.median(samples))
    return out


def spread(seconds: list[float]) -> tuple[float, str]:
    """Median in ms and "median (min..max)" of per-repeat medians in seconds."""
    ms = [x * 1e3 for x in seconds]
    med = statistics.median(ms)
    return med, f"{med:.3f} ({min(ms):.3f}..{max(ms):.3f})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="repeats per case (median and spread)")
    parser.add_argument("--ticks", type=int, default=50, help="ticks timed per repeat")
    parser.add_argument("--quick", action="store_true", help="3 repeats of 20 ticks")
    parser.add_argument("--max-n", type=int, default=1000, help="skip fleets larger than this")
    parser.add_argument("--compiled-ab", action="store_true", help="compiled vs numpy shaping, N = 3..100")
    args = parser.parse_args()
    repeats, ticks = (3, 20) if args.quick else (args.repeats, args.ticks)
    if args.compiled_ab:
        compiled_ab(repeats, ticks)
        return
    fp = FieldParams()
    print(
        f"FleetController.tick, SMC + IAAPF, grid spacing {SPACING:g} m, median of {repeats} x {ticks} ticks"
    )
    print()
    columns = ("N", "K", "obstacle pairs < l0", "UAV pairs < D_max", "ms / tick (min..max)", "us / vehicle")
    print("| " + " | ".join(columns) + " | 50 Hz load | guard ms / tick (min..max) |")
    print("|---|---|---|---|---|---|---|---|")
    small = [(n, k) for n in (3, 6, 9) for k in (0, 10)]
    large = [(n, k) for n in (9, 100, 1000) for k in (10, 100) if (n, k) not in small]
    for n, k in [case for case in small + large if case[0] <= args.max_n]:
        ctl, pos, _, _, centres, radii = scenario(n, k)
        n_obs, n_uav = close_pairs(pos, centres, radii, fp.l0, ctl.d_max)
        med, cost = spread(time_ticks(n, k, repeats, ticks))
        _, guard = spread(time_guard(n, k, repeats, ticks))
        load = med / (DT * 1e3) * 100
        print(f"| {n} | {k} | {n_obs} | {n_uav} | {cost} | {med / n * 1e3:.1f} | {load:.1f} % | {guard} |")


if __name__ == "__main__":
    main()
