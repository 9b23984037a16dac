"""Cost of one FleetController.tick (formation targets, obstacle + inter-UAV field, reference generator, SMC,
inversion) for the whole fleet, N = 9, 100, 1000 vehicles with K = 10 and 100 obstacles.

The fleet flies a grid formation with 9 m spacing (inside D_max = 10 m, so the inter-UAV term is active);
obstacles are spread over the fleet's area, so many vehicle-obstacle pairs are inside l0 = 20 m. Prints a
Markdown table: median per tick over repeats, with the spread (min..max of the repeat medians).

    python benchmarks/bench_guidance.py [--repeats 7] [--ticks 50] [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.params import FieldParams

SPACING = 9.0  # m
DT = 0.02  # s, 50 Hz


def scenario(n: int, k: int, seed: int = 0):
    """A controller, the fleet state and obstacles; deterministic."""
    rng = np.random.default_rng(seed)
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("grid", n - 1, SPACING)
    ctl = FleetController(n, 0, offsets, np.array([[5000.0, 0.0, 50.0]]), control_dt=DT)
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="repeats per case (median and spread)")
    parser.add_argument("--ticks", type=int, default=50, help="ticks timed per repeat")
    parser.add_argument("--quick", action="store_true", help="3 repeats of 20 ticks")
    args = parser.parse_args()
    repeats, ticks = (3, 20) if args.quick else (args.repeats, args.ticks)
    fp = FieldParams()
    print(
        f"FleetController.tick, SMC + IAAPF, grid spacing {SPACING:g} m, median of {repeats} x {ticks} ticks"
    )
    print()
    columns = ("N", "K", "obstacle pairs < l0", "UAV pairs < D_max", "ms / tick (min..max)", "us / vehicle")
    print("| " + " | ".join(columns) + " | 50 Hz load |")
    print("|---|---|---|---|---|---|---|")
    for n in (9, 100, 1000):
        for k in (10, 100):
            ctl, pos, _, _, centres, radii = scenario(n, k)
            n_obs, n_uav = close_pairs(pos, centres, radii, fp.l0, ctl.d_max)
            per_tick = [x * 1e3 for x in time_ticks(n, k, repeats, ticks)]
            med = statistics.median(per_tick)
            cost = f"{med:.3f} ({min(per_tick):.3f}..{max(per_tick):.3f})"
            load = med / (DT * 1e3) * 100
            print(f"| {n} | {k} | {n_obs} | {n_uav} | {cost} | {med / n * 1e3:.1f} | {load:.1f} % |")


if __name__ == "__main__":
    main()
