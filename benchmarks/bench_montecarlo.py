"""Monte Carlo throughput: runs per minute of `gcs-swarm montecarlo --jobs 2` on a small mission.

The mission is missions/quickstart.yaml shortened to a 30 m leg with three vehicles airborne at 5 m (about 20
s of simulated time per run, power-on to disarm); each run randomises one obstacle, the starts and the wind.
Prints the campaign's runs per minute (whole command: worker start-up, flights, reports) and the median and
spread of the wall time of one run inside it.

Usage: python benchmarks/bench_montecarlo.py [--quick] [--runs N] [--jobs J]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
RANGES = (
    "obstacles: {count: [1, 1], radius: [1, 1.5], cross_track: [-6, 6], keep_out: 2}\n"
    "starts: {position_jitter: 1, velocity: 0.5}\n"
    "wind: {speed: [0, 2], turbulence: [0, 0]}\n"
)


def small_mission(out: Path) -> Path:
    data = yaml.load((ROOT / "missions" / "quickstart.yaml").read_text(), Loader=yaml.SafeLoader)
    data["mission"]["name"] = "mc_bench"
    for vehicle in data["vehicles"]:
        vehicle["start"]["position"][2] = 5.0
    data["formation"]["altitude"] = 5.0
    data["goal"] = [24.0, 18.0, 5.0]
    data["world"]["obstacles"] = []
    data["guidance"]["k_rep"] = 1e5
    data["guidance"]["k_uav"] = 5e4
    data["run"] |= {"airborne_start": True, "time_limit_s": 25.0}
    path = out / "mc_bench.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4 runs instead of 8")
    parser.add_argument("--runs", type=int)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    runs = args.runs or (4 if args.quick else 8)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        mission = small_mission(out)
        (out / "ranges.yaml").write_text(RANGES)
        cmd = [sys.executable, "-m", "gcs_swarm", "montecarlo", str(mission), "--runs", str(runs)]
        cmd += ["--jobs", str(args.jobs), "--ranges", str(out / "ranges.yaml"), "--out", str(out / "c")]
        start = time.monotonic()
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=3600)
        wall = time.monotonic() - start
        if proc.returncode not in (0, 1):
            print(proc.stdout[-2000:] + proc.stderr[-2000:], file=sys.stderr)
            return 1
        rows = [json.loads(line) for line in (out / "c" / "results.jsonl").read_text().splitlines()]
    per_run = [r["wall_s"] for r in rows]
    sim = [r["sim_duration_s"] for r in rows if r.get("sim_duration_s")]
    ok = sum(1 for r in rows if r.get("success"))
    print(
        "| runs | jobs | campaign wall s | runs per minute | run wall s median (min-max) | sim s per run "
        "| ok |"
    )
    print("|---|---|---|---|---|---|---|")
    print(
        f"| {len(rows)} | {args.jobs} | {wall:.1f} | {60.0 * len(rows) / wall:.2f} | "
        f"{statistics.median(per_run):.1f} ({min(per_run):.1f}-{max(per_run):.1f}) | "
        f"{statistics.median(sim):.1f} | {ok}/{len(rows)} |"
    )
    print(
        "\nOne campaign; a run is a real lockstep flight (simulator + ground station processes) of 3 "
        "vehicles, 30 m leg; runs per minute over the whole command, run wall time measured in the worker."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
