"""What a run's report costs, and the pair-distance crossover behind it.

`gcs-swarm report RUN_DIR` rebuilds report.json, report.md and the figures of a flown run; for large fleets
its cost is the pair distances (every pair of vehicles at every truth sample). Two modes:

    python benchmarks/bench_report.py --run RUN_DIR [--repeats 3]
        wall s of `gcs-swarm report RUN_DIR` (a fresh process each, so imports count, as a user sees it):
        median (min-max) over the repeats.

    python benchmarks/bench_report.py --fleet N [--leg 300] [--repeats 3]
        the same for a run folder flown first (in lockstep, into a temporary folder) with
        benchmarks/bench_fleet_capacity.py's grid mission of N vehicles and a `--leg` m leg.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench_fleet_capacity import grid_mission  # noqa: E402

from swarm_common.ports import free_udp_base  # noqa: E402


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.3f} ({min(values):.3f}-{max(values):.3f})"


def report_run(run_dir: Path, repeats: int) -> None:
    spent = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "gcs_swarm", "report", str(run_dir)],
            cwd=ROOT,
            check=False,
            capture_output=True,
            timeout=3600,
        )
        spent.append(time.perf_counter() - start)
    print(f"gcs-swarm report {run_dir}: {spread(spent)} s over {repeats} invocations")


def fly_grid(n: int, leg_m: float, out: Path) -> Path:
    """Fly the capacity grid mission of n vehicles in lockstep into out/run; the run folder."""
    run_dir = out / "run"
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(grid_mission(n, out, leg_m)), "--out", str(run_dir)]
    cmd += ["--time-mode", "lockstep", "--quiet", "--base-port", str(free_udp_base(n))]
    subprocess.run(cmd, cwd=ROOT, check=False, capture_output=True, timeout=3600)
    if not (run_dir / "flight.json").exists():
        raise SystemExit(f"the {n}-vehicle grid flight wrote no flight.json in {run_dir}")
    return run_dir


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--run", type=Path, help="a flown run folder to rebuild the report of")
    mode.add_argument("--fleet", type=int, help="fly the capacity grid of this many vehicles, then time it")
    parser.add_argument("--leg", type=float, default=300.0, help="m the grid's leader flies (--fleet)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if args.fleet:
        with tempfile.TemporaryDirectory() as tmp:
            report_run(fly_grid(args.fleet, args.leg, Path(tmp)), args.repeats)
    else:
        report_run(args.run, args.repeats)


if __name__ == "__main__":
    main()
