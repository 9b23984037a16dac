"""End to end: ground station + simulator over real MAVLink/UDP in lockstep, `--repeats` flights per scenario.

Prints, per scenario, the median and the range (min-max) over the flights of the real-time factor (simulated s
/ wall s of the whole run, power-on to disarm: report.json `sim_duration_s` / flight.json `wall_duration_s`;
and apart, of the formation ticks, where the ground station sets the pace, and of the rest of the flight,
mostly take-off and landing, where the simulator does) and of the ground station's tick latency (wall
time from a complete telemetry tick to its last SET_ATTITUDE_TARGET out: median and p99 of each flight), and
the worst flight (the lowest real-time factor) with its worst tick (flight.json `worst_tick`: the tick with
the most work, and what it was spent on).
Scenarios: the bundled paper missions with their goals shortened (the full legs take 10-20 simulated minutes;
the per-tick work is the same), and a generated 100-vehicle grid (not with --quick); or one given mission
(`--mission FILE`, flown as it is, e.g. the full missions/paper_static_6.yaml). The flights are interleaved
(every scenario once, then again) so that a change in the machine's load spreads over the scenarios.

With --baseline DIR (another tree, e.g. `git worktree add DIR <commit>`), every flight of this tree is
followed by the same flight with DIR's code (tree_ab.flight_environment), and each scenario gets a row per
tree.

Usage: python benchmarks/bench_end_to_end.py [--quick] [--repeats 3] [--mission FILE] [--json FILE]
       [--baseline DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import tree_ab  # noqa: E402

from swarm_common.ports import free_udp_base  # noqa: E402
from tests.e2e.flights import numbers  # noqa: E402


def derived(source: str, name: str, out: Path, goal: list[float], time_limit_s: float) -> Path:
    data = numbers(yaml.safe_load((ROOT / "missions" / source).read_text()))
    data["mission"]["name"] = name
    data["goal"] = goal
    data.setdefault("run", {})["time_limit_s"] = time_limit_s
    for v in data["vehicles"]:
        v.pop("target", None)
    path = out / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def grid_mission(n: int, out: Path) -> Path:
    """n vehicles in a grid formation (10 m spacing), ground start, 150 m leg past 4 obstacles."""
    side = int(n**0.5 + 0.999)
    vehicles = []
    for i in range(n):
        row, col = divmod(i, side)
        vehicles.append(
            {
                "name": f"v{i}",
                "role": "leader" if i == 0 else "follower",
                "start": {"position": [-10.0 * row, 10.0 * col, 0.0]},
            }
        )
    data: dict[str, Any] = {
        "mission": {"name": f"grid{n}"},
        "vehicles": vehicles,
        "formation": {"shape": "grid", "spacing": 10.0, "altitude": 10.0},
        "goal": [150.0, 0.0, 10.0],
        "world": {"obstacles": [{"center": [60.0, 20.0 * k - 30.0, 10.0], "radius": 3.0} for k in range(4)]},
        "safety": {"geofence": {"radius": 2000.0, "max_alt": 300.0}},
        "run": {"time_limit_s": 120.0},
    }
    path = out / f"grid{n}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def fly(mission: Path, n: int, run_dir: Path, tree: Path = ROOT) -> dict[str, Any]:
    """One `gcs-swarm run` of `mission` (n vehicles) with `tree`'s code: exit status, real-time factor, tick
    figures."""
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir), "--quiet"]
    cmd += ["--base-port", str(free_udp_base(n))]
    cwd, env = tree_ab.flight_environment(tree)
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=3600)
    flight_path, report_path = run_dir / "flight.json", run_dir / "report.json"
    flight = json.loads(flight_path.read_text()) if flight_path.exists() else {}
    report = json.loads(report_path.read_text()) if report_path.exists() else {}
    sim_s, wall_s = number(report.get("sim_duration_s")), number(flight.get("wall_duration_s"))
    latency = flight.get("tick_latency_ms") or {}
    phases = flight.get("tick_phases_ms") or {}
    formation_sim_s, formation_wall_s = number(phases.get("vehicle_s")), number(phases.get("wall_s"))
    return {
        "tree": str(tree),
        "status": proc.returncode,
        "sim_s": sim_s,
        "wall_s": wall_s,
        "real_time_factor": ratio(sim_s, wall_s),
        # formation flight (the ground station's tick sets the pace) and the rest (mostly the simulator's)
        "formation_factor": ratio(formation_sim_s, formation_wall_s),
        "outside_formation_factor": ratio(sim_s - formation_sim_s, wall_s - formation_wall_s),
        "latency_median_ms": latency.get("median", math.nan),
        "latency_p99_ms": latency.get("p99", math.nan),
        "worst_tick": flight.get("worst_tick"),
    }


def number(value: float | None) -> float:
    """A figure of flight.json or report.json, NaN when it is missing (a failed flight)."""
    return math.nan if value is None else float(value)


def ratio(sim_s: float, wall_s: float) -> float:
    """Simulated s per wall s, NaN when either is NaN or the wall time is not positive."""
    return sim_s / wall_s if wall_s > 0 else math.nan


def spread(values: list[float], fmt: str, unit: str = "") -> str:
    """`median (min-max)` of the finite values ("-" without any)."""
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return "-"
    med = f"{statistics.median(finite):{fmt}}{unit}"
    return med if len(finite) == 1 else f"{med} ({min(finite):{fmt}}-{max(finite):{fmt}})"


def worst_run(runs: list[dict[str, Any]]) -> str:
    """The flight with the lowest real-time factor (a failed flight first), and its worst tick."""
    worst = min(runs, key=lambda r: (r["status"] == 0, nan_low(r["real_time_factor"])))
    text = f"exit {worst['status']}, {worst['real_time_factor']:.1f}x, p99 {worst['latency_p99_ms']:.2f} ms"
    tick = worst["worst_tick"]
    if tick:
        top = max(tick["phases_ms"].items(), key=lambda kv: kv[1])
        text += f"; worst tick {tick['work_ms']:.1f} ms at t={tick['t_s']:.1f} s ({top[0]} {top[1]:.1f})"
    return text


def nan_low(x: float) -> float:
    return -math.inf if x is None or math.isnan(x) else x


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="no 100-vehicle case")
    parser.add_argument("--repeats", type=int, default=3, help="flights per scenario (default 3)")
    parser.add_argument("--mission", help="time this one mission file instead of the scenarios")
    parser.add_argument("--json", help="also write every flight's figures to this file")
    parser.add_argument("--baseline", type=Path, help="another tree to fly after each flight (A/B)")
    args = parser.parse_args()
    trees = [ROOT] + ([args.baseline.resolve()] if args.baseline else [])
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        if args.mission:
            path = Path(args.mission).resolve()
            n = len(yaml.safe_load(path.read_text())["vehicles"])
            scenarios = [(f"{args.mission} (as it is)", path, n)]
        else:
            scenarios = [
                ("quickstart (3)", ROOT / "missions" / "quickstart.yaml", 3),
                (
                    "paper_static_6, goal (600,600,200)",
                    derived("paper_static_6.yaml", "s6", out, [600, 600, 200], 300),
                    6,
                ),
                (
                    "paper_nine_9, goal (-300,600,200)",
                    derived("paper_nine_9.yaml", "n9", out, [-300, 600, 200], 400),
                    9,
                ),
            ]
            if not args.quick:
                scenarios.append(("grid of 100, 150 m leg", grid_mission(100, out), 100))
        cases = [  # each scenario once per tree, one after the other
            (f"{label}{'' if tree == ROOT else f' (baseline {args.baseline})'}", mission, n, tree)
            for label, mission, n in scenarios
            for tree in trees
        ]
        runs: dict[str, list[dict[str, Any]]] = {label: [] for label, _, _, _ in cases}
        for k in range(args.repeats):
            for i, (label, mission, n, tree) in enumerate(cases):
                print(f"flight {k + 1}/{args.repeats}: {label}", file=sys.stderr, flush=True)
                runs[label].append(fly(mission, n, out / f"{mission.stem}-{k}-{i}", tree))
    print(
        "| scenario | vehicles | exit | sim s | real-time factor | in formation | outside formation "
        "| tick latency median ms | p99 ms | worst flight |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, _, n, _ in cases:
        rs = runs[label]
        print(
            f"| {label} | {n} | {','.join(str(r['status']) for r in rs)} "
            f"| {spread([r['sim_s'] for r in rs], '.1f')} "
            f"| {spread([r['real_time_factor'] for r in rs], '.1f', 'x')} "
            f"| {spread([r['formation_factor'] for r in rs], '.1f', 'x')} "
            f"| {spread([r['outside_formation_factor'] for r in rs], '.1f', 'x')} "
            f"| {spread([r['latency_median_ms'] for r in rs], '.2f')} "
            f"| {spread([r['latency_p99_ms'] for r in rs], '.2f')} | {worst_run(rs)} |"
        )
    print(
        f"\nMedian (min-max) of {args.repeats} flight(s) each, interleaved. Real-time factor = simulated "
        "seconds of the whole run (power-on to disarm) per wall second; in formation: of the formation "
        "ticks alone (flight.json tick_phases_ms vehicle_s / wall_s), where the ground station's tick sets "
        "the pace; outside formation: of the rest (take-off, landing), where the simulator does. Tick "
        "latency = wall time from a complete telemetry tick (every vehicle's GLOBAL_POSITION_INT of the "
        "frame in) to the last SET_ATTITUDE_TARGET out, each flight's median and p99. Worst flight: the "
        "lowest real-time factor, with its worst tick (the most work) and the phase that took most of it."
    )
    if args.json:
        summary = {
            "benchmark": "end_to_end",
            "started_unix_s": started,
            "repeats": args.repeats,
            "mission": args.mission,
            "baseline": str(args.baseline) if args.baseline else None,
            "scenarios": [
                {"label": label, "vehicles": n, "flights": runs[label]} for label, _, n, _ in cases
            ],
        }
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
