"""`gcs-swarm compare MISSION.yaml --variants apf,iaapf [--controllers smc,pid] [--wind 0,5,10] [--out DIR]`:
fly the same mission once per combination (real lockstep flights, one after the other, each in its run folder
OUT/<variant>/ with its full report), then write compare.json, compare.md (the figures side by side) and
compare.png (overlaid leader paths, minimum inter-vehicle distance and formation error over time).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm.evaluation import figures, flights, variants
from gcs_swarm.evaluation.campaign_store import table_cell
from gcs_swarm.evaluation.run_data import load_commands, load_trajectories
from gcs_swarm.flight.fly import EXIT_FAILED, EXIT_OK, EXIT_USER_ERROR
from gcs_swarm.flight.run_folder import FLIGHT_FILE, RECORD_FILE
from gcs_swarm.mission import MissionError, load_mission

COMPARE_KEYS = ("status", "success", "collision", *flights.RESULT_KEYS, *flights.WHOLE_FLIGHT_RESULT_KEYS)


@dataclass(frozen=True)
class CompareOptions:
    """Command-line choices of `gcs-swarm compare`; None lists keep the mission's setting."""

    methods: list[str] | None = None
    controllers: list[str] | None = None
    winds: list[float] | None = None
    out_dir: Path | None = None


def render_table(mission_name: str, rows: list[dict[str, Any]]) -> str:
    """compare.md: one column per variant, one row per figure."""
    lines = [f"# Comparison: {mission_name}", "", "| figure | " + " | ".join(r["label"] for r in rows) + " |"]
    lines.append("|---|" + "---|" * len(rows))
    for key in COMPARE_KEYS:
        lines.append(f"| {key} | " + " | ".join(table_cell(r.get(key)) for r in rows) + " |")
    lines += ["", "Run folders: " + ", ".join(f"`{r['run_dir']}`" for r in rows)]
    return "\n".join(lines) + "\n"


def _compare_run(label: str, run_dir: Path, mission: Any) -> figures.CompareRun | None:
    flight_path = run_dir / FLIGHT_FILE
    if not flight_path.exists():
        return None
    flight = json.loads(flight_path.read_text())
    try:
        traj = load_trajectories(run_dir, mission)
    except (OSError, KeyError, ValueError):
        return None
    t0 = flight.get("t_formation_start")
    return figures.CompareRun(
        label=label,
        traj=traj,
        commands=load_commands(run_dir / RECORD_FILE, len(mission.vehicles)),
        offsets=np.array(flight["offsets"], dtype=float),
        leader=mission.leader_index,
        t0=float(t0 if t0 is not None else (traj.t[0] if len(traj.t) else 0.0)),
        flight=flight,
    )


def compare_command(mission_path: str, options: CompareOptions, say: Callable[[str], None]) -> int:
    """The whole `compare` command: 0 every variant flew (whatever its outcome), 1 a variant could not fly,
    2 user error. `say` shows the user a line (the command line prints it)."""
    path = Path(mission_path)
    try:
        base = load_mission(path)
        grid = variants.variant_grid(options.methods, options.controllers, options.winds)
    except (MissionError, variants.VariantError) as exc:
        say(f"error: {exc}")
        return EXIT_USER_ERROR
    out_dir = options.out_dir or Path("runs") / f"compare-{base.name}-{datetime.now():%Y%m%d-%H%M%S}"
    out_dir.mkdir(parents=True, exist_ok=True)
    derived = []
    for variant in grid:
        run_dir = out_dir / variant.label
        try:
            mission = variants.derive_variant(path, variant, run_dir / "mission.yaml")
        except MissionError as exc:
            say(f"error: variant {variant.label}: {exc}")
            return EXIT_USER_ERROR
        derived.append((variant, run_dir, mission))
    rows, runs = [], []
    status = EXIT_OK
    for k, (variant, run_dir, mission) in enumerate(derived, start=1):
        say(f"[{k}/{len(derived)}] flying {variant.label} -> {run_dir}")
        code = flights.fly(run_dir / "mission.yaml", run_dir, len(mission.vehicles))
        row = {
            "label": variant.label,
            "method": mission.field.method,
            "controller": mission.controller,
            "wind_speed_m_s": mission.wind.speed,
            "run_dir": str(run_dir),
        }
        row |= flights.flight_figures(run_dir, code, mission.safety.collision_radius)
        rows.append(row)
        status = EXIT_FAILED if code == EXIT_USER_ERROR else status
        say(
            f"    status {code}: reached={row['reached']} time_to_goal={row['time_to_goal_s']} s "
            f"min_separation={row['min_separation_m']} m formation_rms={row['formation_rms_m']} m"
        )
        compare_run = _compare_run(variant.label, run_dir, mission)
        if compare_run is not None:
            runs.append(compare_run)
    result = {"mission": base.name, "mission_path": str(path.resolve()), "variants": rows}
    (out_dir / "compare.json").write_text(json.dumps(result, indent=2) + "\n")
    (out_dir / "compare.md").write_text(render_table(base.name, rows))
    drawn = figures.plot_compare(runs, np.asarray(base.goal, dtype=float), out_dir / "compare.png")
    say((out_dir / "compare.md").read_text())
    say(
        f"written: {out_dir / 'compare.json'}, compare.md"
        + (", compare.png" if drawn else " (no matplotlib)")
    )
    return status
