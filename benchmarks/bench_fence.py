"""The autopilots' geofence (safety.dead_gcs.fence, docs/reliability.md "The ground station dies"), measured:

1. normal flight with the fence on: the quickstart and the six-UAV mission (paper_static_6 with the goal at
   (600, 600, 200)) must never breach; prints the smallest horizontal gap between a vehicle and each fenced
   obstacle's cross-section + body (the fence edge lies `margin` beyond it);
2. the ground station killed at the worst moments of those flights (gcs_swarm.evaluation.gcs_kill):
   collisions, clearance, how the vehicles end;
3. a kill that would hit an obstacle without the fence: one obstacle on the quickstart's route, a 3 m/s wind
   along it, FS_GCS_TIMEOUT 15 s, speed scheduling off; killed while heading at it, with the fence on "report
   only" (FENCE_ACTION 0) and on "brake".

    python benchmarks/bench_fence.py                 # margin 10 m, about 4 minutes on 2 cores
    python benchmarks/bench_fence.py --margin 8 --no-kills
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gcs_swarm.evaluation.gcs_kill import fly_and_kill, kill_moments  # noqa: E402
from gcs_swarm.evaluation.run_data import load_truth  # noqa: E402
from gcs_swarm.evaluation.variants import read_yaml  # noqa: E402
from gcs_swarm.flight.geofence import exclusion_circles  # noqa: E402
from gcs_swarm.mission import load_mission  # noqa: E402
from swarm_common.ports import free_udp_base  # noqa: E402


def variant(folder: Path, source: str, name: str, fence: dict, **changes: object) -> Path:
    data = read_yaml(ROOT / "missions" / source)  # YAML 1.2 numbers (1e5) as the mission loader reads them
    assert isinstance(data, dict)
    data.setdefault("mission", {})["name"] = name
    if source == "paper_static_6.yaml":  # the six-UAV mission of the end-to-end tests (static6_short)
        data["goal"] = [600.0, 600.0, 200.0]
        data.setdefault("run", {})["time_limit_s"] = 240
        for v in data["vehicles"]:
            v.pop("target", None)
    dead = data.setdefault("safety", {}).setdefault("dead_gcs", {})
    dead["fence"] = fence
    dead.update(changes.pop("dead_gcs", {}))  # type: ignore[call-overload]
    data.update(changes)
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def fly(mission: Path, run_dir: Path) -> dict:
    n = len(yaml.safe_load(mission.read_text())["vehicles"])
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(mission), "--out", str(run_dir), "--quiet"]
    subprocess.run([*cmd, "--base-port", str(free_udp_base(n))], cwd=ROOT, capture_output=True, timeout=600)
    flight = json.loads((run_dir / "flight.json").read_text())
    report = json.loads((run_dir / "report.json").read_text())
    return {"flight": flight, "report": report, "n": n}


def gaps(mission: Path, run_dir: Path) -> list[str]:
    """Smallest horizontal distance (m) of an airborne vehicle beyond each fenced obstacle's section + body
    (the fence edge lies `margin` further out)."""
    traj = load_truth(run_dir / "truth.csv")
    airborne = traj.pos[:, :, 2] > 1.0
    circles, _ = exclusion_circles(load_mission(mission), 0.0)
    out = []
    for c in circles:
        d = np.hypot(traj.pos[:, :, 0] - c.centre[0], traj.pos[:, :, 1] - c.centre[1]) - c.radius
        out.append(f"obstacle {c.obstacle} {float(np.where(airborne, d, np.inf).min()):.2f} m")
    return out


def kills(mission: Path, run_dir: Path, result: dict, folder: Path, which: list[str] | None = None) -> None:
    f = result["flight"]
    moments = kill_moments(run_dir, f["t_formation_start"], f["t_formation_end"])
    for label, t in moments.items():
        if which is not None and label not in which:
            continue
        o = fly_and_kill(mission, folder / f"{mission.stem}_{label}", t, free_udp_base(result["n"]), cwd=ROOT)
        print(
            f"  killed at {label} (t = {t:.2f} s): crashed {o.crashed}, "
            f"clearance after {o.clearance_after_m:.2f} m, ends {', '.join(o.ends)}",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--margin", type=float, default=10.0, help="safety.dead_gcs.fence.margin_m (m)")
    parser.add_argument("--no-kills", action="store_true", help="normal flights only")
    parser.add_argument("--out", type=Path, default=None, help="keep the run folders here")
    args = parser.parse_args()
    folder = args.out or Path(tempfile.mkdtemp(prefix="bench_fence_"))
    folder.mkdir(parents=True, exist_ok=True)
    fence = {"enabled": True, "margin_m": args.margin, "action": "brake"}
    for source, name in (("quickstart.yaml", "quickstart"), ("paper_static_6.yaml", "six_uav")):
        mission = variant(folder, source, f"{name}_fenced", fence)
        run_dir = folder / f"{name}_reference"
        result = fly(mission, run_dir)
        breaches = [e for e in result["flight"]["events"] if "breached" in e]
        rep = result["report"]
        print(
            f"{name}, fence margin {args.margin:g} m: reached {rep['reached']}, "
            f"collisions {rep['collisions']}, breaches {len(breaches)}, "
            f"min obstacle clearance {rep['min_obstacle_clearance_m']} m; "
            f"horizontal gap beyond obstacle + body: {'; '.join(gaps(mission, run_dir))}",
            flush=True,
        )
        if not args.no_kills:
            kills(mission, run_dir, result, folder)
    if args.no_kills:
        return
    route = {
        "world": {
            "obstacles": [{"center": [80.0, 60.0, 10.0], "radius": 6.0}],
            "wind": {"speed": 3.0, "direction_deg": 233.13, "turbulence": 0.0},
        },
        "dead_gcs": {"failsafe_timeout_s": 15.0, "speed_scheduling": False},
    }
    brake = variant(folder, "quickstart.yaml", "on_route_brake", fence, **route)  # type: ignore[arg-type]
    result = fly(brake, folder / "on_route_reference")
    f = result["flight"]
    t = kill_moments(folder / "on_route_reference", f["t_formation_start"], f["t_formation_end"])
    print(
        f"obstacle on the route, 3 m/s wind at it, FS_GCS_TIMEOUT 15 s, no speed scheduling: normal flight "
        f"breaches {len([e for e in f['events'] if 'breached' in e])}, collisions "
        f"{result['report']['collisions']}; killed heading at it (t = {t['heading_at_obstacle']:.2f} s):",
        flush=True,
    )
    for action in ("report", "brake"):
        mission = variant(
            folder, "quickstart.yaml", f"on_route_{action}", {**fence, "action": action}, **route
        )  # type: ignore[arg-type]
        o = fly_and_kill(
            mission,
            folder / f"on_route_{action}_killed",
            t["heading_at_obstacle"],
            free_udp_base(3),
            cwd=ROOT,
        )
        print(
            f"  fence action {action}: crashed {o.crashed}, clearance after {o.clearance_after_m:.2f} m, "
            f"ends {', '.join(o.ends)}",
            flush=True,
        )


if __name__ == "__main__":
    main()
