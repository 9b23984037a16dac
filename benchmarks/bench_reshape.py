"""Cost of the deliberate reshaping (gcs_swarm.guidance.reshape) and of the leader's pace from the followers'
measured drag (gcs_swarm.guidance.capability) in FleetController.tick: a grid of N vehicles 9 m apart flies
east at 8 m/s past 10 obstacles spread beside its course toward a gap 24 m wide between two spheres, narrower
than the grid, so the formation changes shape in the first decisions; 150 ticks, with `guidance.reshape`
off, on, and on with `guidance.pace` (fed every tick, sampled every 0.2 s), interleaved run by run. Prints
per N and setting the median tick (ms), the median decision tick (ms; the ticks in which the reshape
decided, every `decide_every_s`, each predicting the leader's path over its look-ahead), the slowest tick
that changed the shape (ms; with the number of changes in brackets) and the slowest tick (ms) of each run.

Usage: python benchmarks/bench_reshape.py [--sizes 9,100] [--repeats 5]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from gcs_swarm.guidance.fleet_controller import FleetController  # noqa: E402
from gcs_swarm.guidance.formation import formation_offsets  # noqa: E402
from gcs_swarm.guidance.params import CapabilityParams, ReshapeParams  # noqa: E402

TICKS = 150
DT = 0.02  # s


# the two spheres (centre ENU m, radius m) of the gap ahead: 24 m between their surfaces, across the leader's
# line at x = 60 m, narrower than a grid of 9 (18 m wide) with its clearance_m (10 m) either side; a column
# passes it
GAP_CENTRES = np.array([[60.0, -22.0, 10.0], [60.0, 22.0, 10.0]])
GAP_RADII = np.array([10.0, 10.0])


def run(
    n: int, reshape: ReshapeParams | None, pace: CapabilityParams | None = None
) -> tuple[float, float, float, int, float]:
    """(median, median of the decision ticks (NaN without reshaping), slowest tick that changed the shape
    (NaN when none did), the number of changes of shape, max) ms of TICKS ticks of an N-vehicle grid."""
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("grid", n - 1, 9.0)
    rng = np.random.default_rng(0)
    across = rng.uniform(16, 40, 10) * rng.choice([-1.0, 1.0], 10)  # m, off the leader's line
    scattered = np.column_stack([rng.uniform(20, 200, 10), across, np.full(10, 10.0)])
    centres = np.vstack([scattered, GAP_CENTRES])
    radii = np.concatenate([np.full(10, 3.0), GAP_RADII])
    ctl = FleetController(
        n, 0, offsets, np.array([[400.0, 0.0, 10.0]]), reshape=reshape, pace=pace, z_min=1.0
    )
    pos = offsets + [0.0, 0.0, 10.0]
    vel = np.zeros((n, 3))
    vel[:, 0] = 8.0
    att = np.zeros((n, 3))
    ctl.reset(pos, vel, np.zeros(n))
    active = np.ones(n, dtype=bool)
    ticks, decisions, changing = [], [], []
    for k in range(TICKS):
        due = None if ctl.shaper is None else ctl.shaper.next_decision
        start = time.perf_counter()
        ctl.tick(k * DT, pos + vel * k * DT, vel, att, centres, radii, active)
        ticks.append(time.perf_counter() - start)
        changes = ctl.drain_shape_changes()
        if ctl.shaper is not None and ctl.shaper.next_decision != due:
            decisions.append(ticks[-1])
        if changes:
            changing.append(ticks[-1])
    decided = statistics.median(decisions) * 1e3 if decisions else math.nan
    changed = max(changing) * 1e3 if changing else math.nan
    return statistics.median(ticks) * 1e3, decided, changed, len(changing), max(ticks) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="9,100")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    run(3, ReshapeParams())  # compile or load every kernel first
    columns = (
        "N", "reshape", "median tick ms, per run", "median decision tick ms",
        "slowest tick changing the shape ms (changes)", "slowest tick ms",
    )  # fmt: skip
    print("| " + " | ".join(columns) + " |")
    print("|---|---|---|---|---|---|")
    for n in (int(s) for s in args.sizes.split(",")):
        settings = {
            "off": (None, None),
            "on": (ReshapeParams(), None),
            "on, pace": (ReshapeParams(), CapabilityParams()),
        }
        results: dict[str, list[tuple[float, float, float, int, float]]] = {label: [] for label in settings}
        for _ in range(args.repeats):
            for label, (reshape, pace) in settings.items():
                results[label].append(run(n, reshape, pace))
        for label, rows in results.items():
            medians = ", ".join(f"{m:.3f}" for m, _, _, _, _ in rows)
            decided = ", ".join("-" if math.isnan(d) else f"{d:.2f}" for _, d, _, _, _ in rows)
            changed = ", ".join("-" if math.isnan(c) else f"{c:.1f} ({k})" for _, _, c, k, _ in rows)
            slowest = ", ".join(f"{s:.1f}" for _, _, _, _, s in rows)
            print(f"| {n} | {label} | {medians} | {decided} | {changed} | {slowest} |")


if __name__ == "__main__":
    main()
