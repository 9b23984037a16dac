"""End to end: ground station + simulator over real MAVLink/UDP in lockstep.

Prints, per scenario, the real-time factor (simulated s / wall s of the whole run, power-on to disarm) and the
ground station's per-tick latency (wall time from a complete telemetry tick to its last SET_ATTITUDE_TARGET
out: median and p99). Scenarios: the bundled paper missions with their goals shortened (the full legs take
10-20 simulated minutes; the per-tick work is the same), and a generated 100-vehicle grid.

Usage: python benchmarks/bench_end_to_end.py [--quick]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

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


def fly(mission: Path, n: int, run_dir: Path) -> dict[str, Any]:
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir), "--quiet"]
    cmd += ["--base-port", str(free_udp_base(n))]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=3600)
    flight = json.loads((run_dir / "flight.json").read_text())
    report = json.loads((run_dir / "report.json").read_text()) if (run_dir / "report.json").exists() else {}
    return {"status": proc.returncode, "flight": flight, "report": report}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="one repeat, no 100-vehicle case")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        cases = [
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
            cases.append(("grid of 100, 150 m leg", grid_mission(100, out), 100))
        print(
            "| scenario | vehicles | exit | sim s | wall s | real-time factor | tick latency median ms "
            "| p99 ms |"
        )
        print("|---|---|---|---|---|---|---|---|")
        for label, mission, n in cases:
            reps = 1 if n >= 100 else repeats  # the 100-vehicle flight alone takes several wall minutes
            runs = [fly(mission, n, out / f"{mission.stem}-{k}") for k in range(reps)]
            rtf = [
                r["report"]["sim_duration_s"] / r["flight"]["wall_duration_s"] for r in runs if r["report"]
            ]
            lat = [r["flight"]["tick_latency_ms"] for r in runs if r["flight"].get("tick_latency_ms")]
            sim_s = runs[0]["report"].get("sim_duration_s", float("nan"))
            wall = statistics.median(r["flight"]["wall_duration_s"] for r in runs)
            med = statistics.median(x["median"] for x in lat) if lat else float("nan")
            p99 = statistics.median(x["p99"] for x in lat) if lat else float("nan")
            spread = f" ({min(rtf):.1f}-{max(rtf):.1f})" if len(rtf) > 1 else ""
            status = ",".join(str(r["status"]) for r in runs)
            rtf_med = statistics.median(rtf) if rtf else float("nan")
            print(
                f"| {label} | {n} | {status} | {sim_s:.1f} | {wall:.1f} | {rtf_med:.1f}x{spread} | "
                f"{med:.2f} | {p99:.2f} |"
            )
    print(
        f"\nMedian of {repeats} run(s) each (one for 100 vehicles). Real-time factor = simulated seconds "
        "of the whole run (power-on to disarm) per wall second. Tick latency = wall time from a complete "
        "telemetry tick (every vehicle's GLOBAL_POSITION_INT of the frame in) to the last "
        "SET_ATTITUDE_TARGET out."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
