"""Largest fleet the ground station holds at 50 Hz in REAL TIME: no telemetry frame missed in formation.

For each fleet size N (default 25, 50, 100, 150, 200, 300, 500; stopping after the first N that fails unless
--all) the simulator runs in real time (`gcs-swarm run --time-mode realtime`: it never waits for the ground
station) and the ground station flies a grid of N vehicles, airborne at 10 m, `--leg` m east (600 m: about a
minute of formation flight at the leader's 10 m/s), `--repeats` flights per size (default 3).

A frame is missed when a vehicle's GLOBAL_POSITION_INT arrived and was replaced by a newer one before the
ground station ticked on it (flight.json `frames_missed`, counted by the link against what the vehicles sent,
formation phase only). N holds when every flight exited 0 and missed no frame. Per size the table gives, as
the median / the worst of the flights: frames missed, the tick work (wall ms from waiting for the frame to
its last answer, without the wait: flight.json `tick_phases_ms`) at its median, p99 and max, the tick latency
p99 (a complete frame in to the last SET_ATTITUDE_TARGET out, `tick_latency_ms`), how fast the vehicles'
clock ran against the wall clock (1.00 = real time: below, the simulator itself fell behind and the size
proves nothing), how far the simulator itself fell behind the wall clock (its exit report in simulator.log:
the worst lag, and how many of its ticks started more than one 20 ms frame late: a simulator that falls behind
sends the frames it owes in a burst, so missed frames beside a large lag are the simulator's, not the ground
station's), and what the worst tick of all flights was spent on (`worst_tick`).

With --baseline DIR (another tree, e.g. `git worktree add DIR <commit>`), every flight of this tree is
followed by the same flight with DIR's code (tree_ab.flight_environment), and each size gets a row per tree;
only this tree's rows decide the largest fleet held.

Usage: python benchmarks/bench_fleet_capacity.py [--sizes 25,50,...] [--repeats 3] [--leg 600] [--all]
       [--json FILE] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import json
import math
import re
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

from gcs_swarm.guidance.formation import formation_offsets  # noqa: E402
from swarm_common.ports import free_udp_base  # noqa: E402

RATE_HZ = 50.0
SPACING_M = 10.0
LEADER_SPEED_MS = 10.0  # limits.v_xy_leader default
SIZES = (25, 50, 100, 150, 200, 300, 500)
REAL_TIME_MIN = 0.98  # vehicle s per wall s below which the simulator, not the ground station, fell behind
PACING = re.compile(
    r"real-time pacing: worst lag ([\d.]+) ms, (\d+) of (\d+) ticks"
)  # sitl_sim.clock.PacingLag


def simulator_lag(run_dir: Path) -> tuple[float, int | None]:
    """(worst lag ms, ticks more than a frame late) from the simulator's exit report; (nan, None) without."""
    log = run_dir / "simulator.log"
    found = PACING.search(log.read_text(errors="replace")) if log.exists() else None
    return (float(found.group(1)), int(found.group(2))) if found else (math.nan, None)


def grid_mission(n: int, out: Path, leg_m: float) -> Path:
    """N vehicles airborne at 10 m, already in their grid slots (10 m apart), leader flying leg_m east at
    50 Hz; the formation time limit leaves room for the leg at the leader's 10 m/s plus a minute."""
    offsets = formation_offsets("grid", n - 1, SPACING_M)
    starts = [[0.0, 0.0, 10.0]] + [[float(o[0]), float(o[1]), 10.0] for o in offsets]
    vehicles = [
        {"name": f"v{i}", "role": "leader" if i == 0 else "follower", "start": {"position": p}}
        for i, p in enumerate(starts)
    ]
    data: dict[str, Any] = {
        "mission": {"name": f"capacity{n}"},
        "vehicles": vehicles,
        "formation": {"shape": "grid", "spacing": SPACING_M, "altitude": 10.0},
        "goal": [leg_m, 0.0, 10.0],
        "safety": {"geofence": {"radius": max(2000.0, 2 * leg_m), "max_alt": 300.0}},
        "run": {
            "airborne_start": True,
            "time_limit_s": leg_m / LEADER_SPEED_MS + 60.0,
            "control_rate_hz": RATE_HZ,
        },
    }
    path = out / f"capacity{n}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def fly_realtime(n: int, leg_m: float, out: Path, repeat: int, tree: Path = ROOT) -> dict[str, Any]:
    """One real-time flight of n vehicles with `tree`'s code: its exit status and flight.json's timing and
    missed frames."""
    mission = grid_mission(n, out, leg_m)
    run_dir = out / f"run{n}-{repeat}-{tree.name}"
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir), "--quiet"]
    cmd += ["--time-mode", "realtime", "--base-port", str(free_udp_base(n))]
    cwd, env = tree_ab.flight_environment(tree)
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=3600)
    flight_path = run_dir / "flight.json"
    flight = json.loads(flight_path.read_text()) if flight_path.exists() else {}
    t0, t1 = flight.get("t_formation_start"), flight.get("t_formation_end")
    phases = flight.get("tick_phases_ms") or {}
    missed = ((flight.get("frames_missed") or {}).get("by_phase") or {}).get("formation")
    wall_s = phases.get("wall_s") or math.nan
    sim_lag_ms, sim_late_ticks = simulator_lag(run_dir)
    return {
        "vehicles": n,
        "tree": str(tree),
        "status": proc.returncode,
        "formation_s": (t1 - t0) if t0 is not None and t1 is not None else math.nan,
        "ticks": flight.get("ticks", 0),
        "frames_missed": None if missed is None else missed["total"],
        "missed_by_vehicle": None if missed is None else missed["by_vehicle"],
        "real_time": phases.get("vehicle_s", math.nan) / wall_s,
        "work_median_ms": (phases.get("median") or {}).get("work", math.nan),
        "work_p99_ms": (phases.get("p99") or {}).get("work", math.nan),
        "work_max_ms": (phases.get("max") or {}).get("work", math.nan),
        "latency_p99_ms": (flight.get("tick_latency_ms") or {}).get("p99", math.nan),
        "worst_tick": flight.get("worst_tick"),
        "simulator_worst_lag_ms": sim_lag_ms,
        "simulator_late_ticks": sim_late_ticks,
        "stderr": proc.stderr[-400:] if proc.returncode not in (0, 1) else "",
    }


def holds(runs: list[dict[str, Any]]) -> bool:
    """Every flight exited 0, missed no frame in formation flight, with the vehicles' clock in real time."""
    return all(r["status"] == 0 and r["frames_missed"] == 0 and r["real_time"] >= REAL_TIME_MIN for r in runs)


def median_worst(values: list[float], fmt: str, worst: Any = max) -> str:
    """`median / worst` of the flights' figures ("-" without any)."""
    values = [v for v in values if v is not None and not math.isnan(v)]
    if not values:
        return "-"
    return f"{statistics.median(values):{fmt}} / {worst(values):{fmt}}"


def spent_on(runs: list[dict[str, Any]]) -> str:
    """What the worst tick of all the flights was spent on, largest phase first."""
    ticks = [r["worst_tick"] for r in runs if r["worst_tick"]]
    if not ticks:
        return "-"
    worst = max(ticks, key=lambda w: w["work_ms"])
    parts = sorted(worst["phases_ms"].items(), key=lambda kv: -kv[1])
    shown = ", ".join(f"{name} {ms:.1f}" for name, ms in parts if ms >= 0.05)
    return f"{worst['work_ms']:.1f} ms at t={worst['t_s']:.2f} s: {shown} (waited {worst['wait_ms']:.1f})"


def row(label: str, runs: list[dict[str, Any]]) -> str:
    status = ",".join(str(r["status"]) for r in runs)
    missed = ", ".join("-" if r["frames_missed"] is None else str(r["frames_missed"]) for r in runs)
    late = ", ".join("-" if (k := r["simulator_late_ticks"]) is None else str(k) for r in runs)
    return (
        f"| {label} | {status} | {missed} | {median_worst([r['work_median_ms'] for r in runs], '.2f')} "
        f"| {median_worst([r['work_p99_ms'] for r in runs], '.2f')} "
        f"| {median_worst([r['work_max_ms'] for r in runs], '.2f')} "
        f"| {median_worst([r['latency_p99_ms'] for r in runs], '.2f')} "
        f"| {median_worst([r['real_time'] for r in runs], '.3f', min)} "
        f"| {median_worst([r['formation_s'] for r in runs], '.1f', min)} "
        f"| {median_worst([r['simulator_worst_lag_ms'] for r in runs], '.1f')} "
        f"({late}) "
        f"| {spent_on(runs)} | {'yes' if holds(runs) else 'no'} |"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", help=f"comma-separated fleet sizes (default {','.join(map(str, SIZES))})")
    parser.add_argument("--repeats", type=int, default=3, help="flights per size (default 3)")
    parser.add_argument("--leg", type=float, default=600.0, help="m the leader flies east (default 600)")
    parser.add_argument("--all", action="store_true", help="fly every size, not stopping at the first fail")
    parser.add_argument("--json", help="also write every flight's figures to this file")
    parser.add_argument("--baseline", type=Path, help="another tree to fly after each flight (A/B)")
    args = parser.parse_args()
    trees = [ROOT] + ([args.baseline.resolve()] if args.baseline else [])
    sizes = [int(x) for x in args.sizes.split(",")] if args.sizes else list(SIZES)
    print(
        "| vehicles | exit | frames missed per flight | tick work median ms | p99 ms | max ms "
        "| latency p99 ms | vehicle s per wall s | formation s | simulator worst lag ms (ticks > 20 ms late) "
        "| worst tick spent on (ms) | holds |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    largest, flights, baseline_flights = None, [], []
    started = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            by_tree: dict[Path, list[dict[str, Any]]] = {tree: [] for tree in trees}
            for k in range(args.repeats):
                for tree in trees:  # interleaved: both trees see the same machine load
                    by_tree[tree].append(fly_realtime(n, args.leg, Path(tmp), k, tree))
            runs = by_tree[ROOT]
            flights += runs
            baseline_flights += [r for tree in trees[1:] for r in by_tree[tree]]
            print(row(str(n), runs), flush=True)
            if args.baseline:
                print(row(f"{n} (baseline {args.baseline})", by_tree[trees[1]]), flush=True)
            for r in [r for tree in trees for r in by_tree[tree]]:
                if r["stderr"]:
                    print(f"  exit {r['status']}: {r['stderr'].strip().splitlines()[-1]}", file=sys.stderr)
            if holds(runs):
                largest = max(largest or 0, n)
            elif not args.all:
                break
    print(
        f"\nLargest fleet held at {RATE_HZ:g} Hz in real time: {largest if largest else 'none'} (sizes "
        f"{', '.join(map(str, sizes))}{'' if args.all else ', stopping at the first that fails'}; "
        f"{args.repeats} flight(s) each of a {args.leg:g} m leg; figures are the median / the worst of the "
        "flights; a size holds when every flight exited 0 and missed no frame in formation flight, with the "
        f"vehicles' clock at >= {REAL_TIME_MIN:g} of real time). Simulator and ground station share the "
        "machine's cores."
    )
    if args.json:
        summary = {
            "benchmark": "fleet_capacity",
            "started_unix_s": started,
            "sizes": sizes,
            "repeats": args.repeats,
            "leg_m": args.leg,
            "baseline": str(args.baseline) if args.baseline else None,
            "largest_held": largest,
            "flights": flights,
            "baseline_flights": baseline_flights,
        }
        Path(args.json).write_text(json.dumps(summary, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
