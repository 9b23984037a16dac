"""Soak: the nine-UAV paper mission flown in lockstep through faulty links from power-on, with one vehicle's
link silent for 2 s (it is held, docs/reliability.md) and another's killed for good.

Prints collisions (must be 0), minimum separation, commands changed by the final limit guard, refused
commands, messages the simulated radio dropped, the oldest telemetry flown on, the time flown degraded, and
the time the ground station took to declare the dead vehicle lost. The leg is the paper's V at 10 m/s towards
a goal `--leg` metres north of the leader.

Usage: python benchmarks/bench_soak.py [--quick] [--leg M] [--loss P] [--jitter-ms MS] [--from-s S]
                                      [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from swarm_common.ports import free_udp_base  # noqa: E402
from tests.e2e.flights import numbers  # noqa: E402

KILLED = 4  # 0-based index of the vehicle whose link dies
QUIET = 6  # 0-based index of the vehicle whose link is silent for QUIET_S (longer than hold_s, < lost_s)
QUIET_S = 2.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 600 m leg instead of 2000 m")
    parser.add_argument("--leg", type=float, help="leg length north of the leader, m")
    parser.add_argument("--loss", type=float, default=0.1, help="packet loss on every link (0..1)")
    parser.add_argument("--jitter-ms", type=float, default=100.0, help="delay jitter on every link, ms")
    parser.add_argument("--from-s", type=float, default=0.0, help="faults act from this simulated s on")
    parser.add_argument("--keep", help="keep the mission and run folder in this directory")
    args = parser.parse_args()
    leg = args.leg or (600.0 if args.quick else 2000.0)
    with tempfile.TemporaryDirectory() as scratch:
        tmp = args.keep or scratch
        Path(tmp).mkdir(parents=True, exist_ok=True)
        data = numbers(yaml.safe_load((ROOT / "missions" / "paper_nine_9.yaml").read_text()))
        start = data["vehicles"][0]["start"]["position"]
        data["mission"]["name"] = "soak9"
        data["goal"] = [start[0], start[1] + leg, start[2]]
        data["run"]["time_limit_s"] = leg / 10.0 + 300.0
        for v in data["vehicles"]:
            v.pop("target", None)
        mission = Path(tmp) / "soak9.yaml"
        mission.write_text(yaml.safe_dump(data, sort_keys=False))
        quiet_at, kill_at = 40.0, 52.0
        sim_args = [
            f"--link-loss={args.loss}",
            f"--link-jitter-ms={args.jitter_ms}",
            f"--link-from={args.from_s}",
            f"--link-outage={QUIET}@{quiet_at}:{QUIET_S}",
            f"--link-outage={KILLED}@{kill_at}:inf",
        ]
        run_dir = Path(tmp) / "run"
        cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir), "--quiet"]
        cmd += ["--base-port", str(free_udp_base(9)), *(f"--sim-arg={a}" for a in sim_args)]
        proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=7200)
        flight = json.loads((run_dir / "flight.json").read_text())
        report_path = run_dir / "report.json"
        report = json.loads(report_path.read_text()) if report_path.exists() else {}
        counters: dict[str, int] = {}
        for line in (run_dir / "simulator.log").read_text().splitlines():
            if "vehicle" in line and "received=" in line:
                for key, value in re.findall(r"(\w+)=(\d+)", line):
                    counters[key] = counters.get(key, 0) + int(value)
        refused = sum("refused" in e for e in flight["events"])
        killed_name, quiet_name = data["vehicles"][KILLED]["name"], data["vehicles"][QUIET]["name"]
        detected = flight.get("lost_at_s", {}).get(killed_name)
    rows = [
        ("exit status (1 = a vehicle was lost, as staged)", proc.returncode),
        ("simulated time, s", report.get("sim_duration_s")),
        ("wall time, s", round(flight["wall_duration_s"], 1)),
        ("collisions", report.get("collisions")),
        ("minimum separation, m", report.get("min_separation_m")),
        ("minimum obstacle clearance, m", report.get("min_obstacle_clearance_m")),
        ("vehicles lost", ", ".join(flight["lost"]) or "none"),
        (
            f"time to declare {killed_name} lost, s (link killed at {kill_at:g} s)",
            None if detected is None else round(detected - kill_at, 2),
        ),
        ("commands refused by vehicles", refused),
        ("commands changed by the final limit guard (vehicle-ticks)", flight.get("commands_limited")),
        ("oldest position telemetry flown on, s", flight.get("max_telemetry_age_s")),
        (f"holds ({quiet_name} silent {QUIET_S:g} s from {quiet_at:g} s)", flight.get("holds")),
        ("time flown degraded (slower, wider), s", flight.get("degraded_s")),
        (
            "radio: messages dropped (loss and the killed link) / corrupted / duplicated",
            "{} / {} / {}".format(
                counters.get("link_lost"), counters.get("link_corrupted"), counters.get("link_duplicated")
            ),
        ),
        (
            "simulator intake: bad frames / invalid",
            f"{counters.get('bad_frames')} / {counters.get('invalid')}",
        ),
    ]
    print(
        f"Nine UAVs, {leg:g} m leg, {args.loss:.0%} loss and {args.jitter_ms:g} ms jitter on every link from "
        f"{args.from_s:g} s, one link silent for {QUIET_S:g} s, one killed; one lockstep flight.\n"
    )
    print("| figure | value |\n|---|---|")
    for name, value in rows:
        print(f"| {name} | {value} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
