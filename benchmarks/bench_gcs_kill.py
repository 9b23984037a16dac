"""Monte Carlo of ground-station crashes: kill `gcs-swarm run` (SIGKILL, via --crash-at) at random moments of
formation flight and count, from the simulator's ground truth, what the vehicles did on their own.

    python benchmarks/bench_gcs_kill.py --runs 20 --seed 1                      # quickstart, every policy
    python benchmarks/bench_gcs_kill.py --mission missions/paper_static_6.yaml --goal 600,600,200 --runs 20

Policies (mission `safety` settings, docs/reliability.md):
  default   as the mission file says: gcs_failsafe land (the default), GUID_TIMEOUT 0.5 s,
            FS_GCS_TIMEOUT = lost_s, failsafe speed scheduling on LAND's stop
  brake     BRAKE (Brake or Land: holds in the air) instead of LAND, otherwise default
  stock     what ArduCopter does with the old settings: RTL after 5 s, GUID_TIMEOUT 3 s, no speed scheduling
Prints one line per run and a summary per policy (collisions, smallest clearance and separation after the
kill, how the vehicles ended, the simulator's exit time).
"""

from __future__ import annotations

import argparse
import json
import random
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gcs_swarm.evaluation.gcs_kill import fly_and_kill  # noqa: E402
from swarm_common.ports import free_udp_base  # noqa: E402

POLICIES = {
    "default": {},
    "stock": {
        "gcs_failsafe": "rtl",
        "dead_gcs": {"guided_timeout_s": 3.0, "failsafe_timeout_s": 5.0, "speed_scheduling": False},
    },
    "brake": {"gcs_failsafe": "brake"},
}


def derived(mission: Path, policy: str, goal: list[float] | None, folder: Path) -> Path:
    data = yaml.safe_load(mission.read_text())
    safety = data.setdefault("safety", {}) or {}
    for key, value in POLICIES[policy].items():
        if isinstance(value, dict):
            safety[key] = {**(safety.get(key) or {}), **value}
        else:
            safety[key] = value
    data["safety"] = safety
    if goal is not None:
        data["goal"] = goal
        for v in data["vehicles"]:
            v.pop("target", None)
    path = folder / f"{policy}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--mission", type=Path, default=ROOT / "missions" / "quickstart.yaml")
    parser.add_argument("--goal", help="x,y,z: move the leader's goal (shorter paper legs)")
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--policies", default=",".join(POLICIES))
    args = parser.parse_args()
    goal = [float(x) for x in args.goal.split(",")] if args.goal else None
    rng = random.Random(args.seed)
    n = len(yaml.safe_load(args.mission.read_text())["vehicles"])
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for policy in args.policies.split(","):
            mission = derived(args.mission, policy, goal, folder)
            ref = folder / f"{policy}-reference"
            cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(ref), "--quiet"]
            subprocess.run(cmd + ["--base-port", str(free_udp_base(n))], cwd=ROOT, check=False)
            flight = json.loads((ref / "flight.json").read_text())
            t0, t1 = flight["t_formation_start"], flight["t_formation_end"]
            outcomes = []
            for k in range(args.runs):
                t_kill = round(rng.uniform(t0, t1), 2)
                o = fly_and_kill(mission, folder / f"{policy}-{k}", t_kill, free_udp_base(n), cwd=ROOT)
                outcomes.append(o)
                print(
                    f"{policy:8s} kill at {t_kill:7.2f} s: crashed {o.crashed}, clearance after "
                    f"{o.clearance_after_m:6.2f} m, separation after {o.separation_after_m:6.2f} m, "
                    f"ends {'/'.join(o.ends)}, simulator exit {o.simulator_exit_s} s",
                    flush=True,
                )
            crashed = sum(o.crashed for o in outcomes)
            runs_with = sum(1 for o in outcomes if o.crashed)
            clear = [o.clearance_after_m for o in outcomes]
            sep = [o.separation_after_m for o in outcomes]
            exits = [o.simulator_exit_s for o in outcomes if o.simulator_exit_s is not None]
            print(
                f"SUMMARY {policy}: {len(outcomes)} kills in {t0:.1f}-{t1:.1f} s (seed {args.seed}); "
                f"vehicles crashed {crashed} (in {runs_with} runs); clearance after min {min(clear):.2f} m, "
                f"median {np.median(clear):.2f} m; separation after min {min(sep):.2f} m; "
                "all ended landed or holding in "
                f"{sum(1 for o in outcomes if o.safe)}/{len(outcomes)}; simulator exited by itself in "
                f"{len(exits)}/{len(outcomes)} (max {max(exits) if exits else float('nan'):.1f} s wall)",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
