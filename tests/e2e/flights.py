"""Flying missions end to end: bundled missions derived for a test, and the real `gcs-swarm run` process
flying one against the real simulator process, both on 127.0.0.1 free ports, bounded in time."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from swarm_common.ports import free_udp_base

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = ROOT / "missions"
# Tests that schedule link faults at fixed simulated times shorten the simulated EKF/GPS start-up (default
# 40 s, as a real ArduCopter SITL) to 5 s, so that formation flight has started by their fault times.
SHORT_BOOT = "--sim-arg=--ready-delay=5"


@dataclass
class RunOutcome:
    """A finished `gcs-swarm run`: exit status, output, and its run folder."""

    status: int
    output: str
    run_dir: Path

    @property
    def report(self) -> dict[str, Any]:
        return json.loads((self.run_dir / "report.json").read_text())


def fly(
    mission: Path,
    run_dir: Path,
    timeout_s: float = 400.0,
    extra: list[str] | None = None,
    env: dict[str, str] | None = None,
) -> RunOutcome:
    """Run `python -m gcs_swarm run` to completion (killed after timeout_s); `env` replaces the environment
    (None: this process's)."""
    n = len(yaml.safe_load(mission.read_text())["vehicles"])
    cmd = [
        sys.executable,
        "-m",
        "gcs_swarm",
        "run",
        str(mission),
        "--out",
        str(run_dir),
        "--base-port",
        str(free_udp_base(n)),
        *(extra or []),
    ]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout_s, env=env)
    return RunOutcome(proc.returncode, proc.stdout + proc.stderr, run_dir)


def numbers(node: Any) -> Any:
    """PyYAML reads `1e5` as a string (YAML 1.1); turn such strings back into numbers before re-dumping."""
    if isinstance(node, dict):
        return {k: numbers(v) for k, v in node.items()}
    if isinstance(node, list):
        return [numbers(v) for v in node]
    if isinstance(node, str):
        try:
            return float(node)
        except ValueError:
            return node
    return node


def derived_mission(tmp_path: Path, source: str, name: str, **changes: Any) -> Path:
    """A copy of a bundled mission with top-level sections replaced or updated (dicts merged one level)."""
    data = numbers(yaml.safe_load((MISSIONS / source).read_text()))
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(data.get(key), dict):
            data[key].update(value)
        else:
            data[key] = value
    data.setdefault("mission", {})["name"] = name
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def static6_short(tmp_path: Path, name: str, link: dict[str, Any] | None = None) -> Path:
    """Section 5.2.1 (paper_static_6) with the goal moved to (600, 600, 200), so the flight past obstacles
    (250, 160, 200) and (520, 350, 200) stays short; followers keep their Table 3 slots (the Table 3 targets
    lie 6 km away, so without them each follower's destination is its final slot). `link`: world.link."""
    mission = derived_mission(
        tmp_path, "paper_static_6.yaml", name, goal=[600.0, 600.0, 200.0], run={"time_limit_s": 240}
    )
    data = yaml.safe_load(mission.read_text())
    for v in data["vehicles"]:
        v.pop("target", None)
    if link is not None:
        data["world"]["link"] = link
    mission.write_text(yaml.safe_dump(data, sort_keys=False))
    return mission
