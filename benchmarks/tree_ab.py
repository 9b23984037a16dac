"""Interleaved A/B runs of one in-process measurement: this tree against a baseline tree (another checkout,
e.g. `git worktree add DIR <commit>`), one fresh process per invocation, alternating, so both see the same
machine load. A benchmark script using it measures in `--one` mode and prints its figures as one JSON object
with the key "tree": the folder its packages were imported from (checked here, so a baseline run cannot
silently measure this tree).

Used by bench_intake.py (the ground station's link) and bench_sim_intake.py (the simulator's command intake).
Flight benchmarks (bench_end_to_end.py, bench_fleet_capacity.py) run `python -m gcs_swarm` per flight and take
their cwd and environment from `flight_environment`: `python -m` puts the working directory first on sys.path,
before PYTHONPATH, so a flight started from this tree flies this tree's code whatever PYTHONPATH says (flight
A/Bs made that way before 2026-11-27 12:00 UTC compared this tree with itself; BENCHMARKS.md).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
Figures = dict[str, float]


def main(
    script: str,
    description: str,
    warmup_frames: int,
    measure: Callable[[int, int], dict[str, float | str]],
    report: Callable[[dict[str, list[Figures]], argparse.Namespace], None],
) -> int:
    """The command line of an A/B benchmark `script` (its __file__): --vehicles, --frames, --repeats,
    --baseline; `measure(vehicles, frames)` makes one invocation's figures (with "tree"), `report(results,
    args)` prints the table of run_interleaved's results."""
    parser = argparse.ArgumentParser(description=description)
    _add_arguments(parser, warmup_frames)
    args = parser.parse_args()
    if args.frames <= warmup_frames or args.vehicles < 1 or args.repeats < 1:
        parser.error(f"--frames must exceed {warmup_frames}, --vehicles and --repeats be at least 1")
    if args.one:
        print(json.dumps(measure(args.vehicles, args.frames)))
        return 0
    report(run_interleaved(Path(script).resolve(), args), args)
    return 0


def _add_arguments(parser: argparse.ArgumentParser, warmup_frames: int) -> None:
    parser.add_argument("--vehicles", type=int, default=200)
    parser.add_argument("--frames", type=int, default=300, help=f"frames per invocation (>{warmup_frames})")
    parser.add_argument("--repeats", type=int, default=3, help="invocations per tree (default 3)")
    parser.add_argument("--baseline", type=Path, help="another tree to compare with, interleaved")
    parser.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # one measurement, JSON out


def package_tree(package_file: str) -> str:
    """The tree (folder) a package was imported from, given its module's __file__."""
    return str(Path(package_file).resolve().parents[1])


def flight_environment(tree: Path) -> tuple[Path, dict[str, str]]:
    """Working directory and environment for a `python -m gcs_swarm ...` flight with `tree`'s packages (the
    simulator it starts inherits both); RuntimeError when a process started that way imports any of
    gcs_swarm, sitl_sim and swarm_common from elsewhere."""
    tree = tree.resolve()
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), os.environ.get("PYTHONPATH", "")])}
    packages = ("gcs_swarm", "sitl_sim", "swarm_common")
    probe = f"import {', '.join(packages)}; print({', '.join(f'{p}.__file__' for p in packages)})"
    cmd = [sys.executable, "-c", probe]
    out = subprocess.run(cmd, cwd=tree, env=env, check=True, capture_output=True, text=True, timeout=60)
    trees = {package_tree(f) for f in out.stdout.split()}
    if trees != {str(tree)}:
        raise RuntimeError(f"a flight started in {tree} imports packages from {sorted(trees)}")
    return tree, env


def invoke(script: Path, tree: Path, vehicles: int, frames: int) -> Figures:
    """`script --one` in a fresh process importing the packages of `tree` first; its figures."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), os.environ.get("PYTHONPATH", "")])}
    cmd = [sys.executable, str(script), "--one", "--vehicles", str(vehicles), "--frames", str(frames)]
    out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True, timeout=600)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if Path(result.pop("tree")) != tree.resolve():
        raise RuntimeError(f"the invocation for {tree} did not import its packages")
    figures: Figures = result
    return figures


def run_interleaved(script: Path, args: argparse.Namespace) -> dict[str, list[Figures]]:
    """Each tree's figures over args.repeats alternating invocations ("this tree", then "baseline" if given),
    after a line saying the load average and the sizes."""
    trees = {"this tree": ROOT} | ({"baseline": args.baseline.resolve()} if args.baseline else {})
    print(
        f"load average {os.getloadavg()[0]:.2f}; {args.vehicles} vehicles, {args.frames} frames per "
        f"invocation, {args.repeats} invocations per tree"
    )
    results: dict[str, list[Figures]] = {name: [] for name in trees}
    for _ in range(args.repeats):
        for name, tree in trees.items():
            results[name].append(invoke(script, tree, args.vehicles, args.frames))
    return results


def spread(values: list[float]) -> str:
    """'median (min-max)' of a figure over the invocations."""
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def ratios(results: dict[str, list[Figures]], keys: tuple[str, ...]) -> str:
    """'key baseline/this x' per key, from the medians (empty without a baseline)."""
    if "baseline" not in results:
        return ""
    parts = []
    for key in keys:
        base = statistics.median(r[key] for r in results["baseline"])
        this = statistics.median(r[key] for r in results["this tree"])
        parts.append(f"{key} {base / this:.2f}x")
    return "baseline / this tree (medians): " + ", ".join(parts)
