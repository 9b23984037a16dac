"""A run's report: metrics of spec 10 from ground truth (the simulator's truth log) when there is one,
else from the ground station's own telemetry record; written as report.json + report.md, plus report.png when
matplotlib is installed.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm import metrics
from gcs_swarm.guidance.formation import slot_positions

TRUTH_FILE = "truth.csv"
RECORD_FILE = "record.csv"
FLIGHT_FILE = "flight.json"


@dataclass(frozen=True)
class Trajectories:
    """Positions of N vehicles on a common time base. t (T,) s; pos, vel (T, N, 3) ENU; crashed (T, N) bool;
    obstacle centres (T, K, 3) and radii (K,)."""

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    crashed: np.ndarray
    obstacle_centres: np.ndarray
    obstacle_radii: np.ndarray
    source: str


def _read_csv(path: Path) -> np.ndarray:
    data = np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")
    return np.atleast_1d(data)


def _by_vehicle(rows: np.ndarray, key: str, columns: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Pivot long rows (one per vehicle per sample) into t (T,) and values (T, N, len(columns))."""
    ids = np.unique(rows[key])
    n = len(ids)
    usable = len(rows) // n * n  # a log cut mid-sample (killed process) drops its partial last sample
    rows = rows[:usable]
    t = rows["t"].reshape(-1, n)[:, 0].astype(float)
    values = np.stack([rows[c].astype(float) for c in columns], axis=-1).reshape(len(t), n, len(columns))
    return t, values


def load_truth(path: Path) -> Trajectories:
    """Read the simulator's truth log (and its .obstacles.csv sidecar)."""
    rows = _read_csv(path)
    t, v = _by_vehicle(rows, "vehicle", ["x", "y", "z", "vx", "vy", "vz", "crashed"])
    obstacle_path = path.with_suffix(".obstacles.csv")
    centres = np.zeros((len(t), 0, 3))
    radii = np.zeros(0)
    if obstacle_path.exists() and obstacle_path.stat().st_size > 0:
        orows = _read_csv(obstacle_path)
        if orows.size and orows.dtype.names and "obstacle" in orows.dtype.names:
            ot, ov = _by_vehicle(orows, "obstacle", ["x", "y", "z", "radius"])
            idx = np.clip(np.searchsorted(ot, t), 0, len(ot) - 1)
            centres, radii = ov[idx, :, :3], ov[0, :, 3]
    return Trajectories(t, v[..., :3], v[..., 3:6], v[..., 6] > 0.5, centres, radii, "truth")


def load_record(path: Path, obstacles: list[Any]) -> Trajectories:
    """The ground station's telemetry record as trajectories (used when no truth log exists)."""
    rows = _read_csv(path)
    t, v = _by_vehicle(rows, "vehicle", ["x", "y", "z", "vx", "vy", "vz"])
    centres = np.array([[o.center_at(tt) for o in obstacles] for tt in t]).reshape(len(t), len(obstacles), 3)
    radii = np.array([o.radius for o in obstacles], dtype=float)
    crashed = np.zeros(v.shape[:2], dtype=bool)
    return Trajectories(t, v[..., :3], v[..., 3:6], crashed, centres, radii, "telemetry")


def _leader_heading(record_path: Path, t: np.ndarray) -> np.ndarray | None:
    """psi_L (T,) from the run record, held between ticks; None without a record."""
    if not record_path.exists():
        return None
    rows = _read_csv(record_path)
    if rows.size == 0:
        return None
    rt, psi = _by_vehicle(rows, "vehicle", ["psi_l"])
    idx = np.clip(np.searchsorted(rt, t, side="right") - 1, 0, len(rt) - 1)
    return psi[idx, 0, 0]


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else round(float(x), 4)


def compute_report(run_dir: Path, mission: Any, flight: dict[str, Any]) -> dict[str, Any]:
    """All figures of report.json from the files in run_dir and the flight summary (flight.json)."""
    truth_path = run_dir / TRUTH_FILE
    record_path = run_dir / RECORD_FILE
    if truth_path.exists() and truth_path.stat().st_size > 0:
        traj = load_truth(truth_path)
    else:
        traj = load_record(record_path, list(mission.obstacles))
    leader = mission.leader_index
    names = [v.name for v in mission.vehicles]
    offsets = np.array(flight["offsets"], dtype=float)
    t0 = flight.get("t_formation_start")
    t_end = flight.get("t_formation_end") or float(traj.t[-1])
    window = (traj.t >= (t0 if t0 is not None else traj.t[0])) & (traj.t <= t_end)
    if not window.any():
        window = np.ones_like(traj.t, dtype=bool)
    tw, pw, vw = traj.t[window], traj.pos[window], traj.vel[window]

    psi = _leader_heading(record_path, tw)
    psi_final = float(psi[-1]) if psi is not None else 0.0
    goals = slot_positions(np.asarray(mission.goal, dtype=float)[None, :], np.array([psi_final]), offsets)[0]
    if flight.get("final_targets") is not None:
        goals = np.array(flight["final_targets"], dtype=float)
    tol, hold = mission.run.goal_tolerance_m, mission.run.hold_s
    reach = [
        metrics.reach_time(tw, np.linalg.norm(pw[:, i] - goals[i], axis=1), tol, hold)
        for i in range(len(names))
    ]
    crashed_any = traj.crashed.any(axis=0)
    reached = all(r is not None for r in reach) and not crashed_any.any() and bool(flight.get("arrived"))
    min_sep = metrics.min_separation(traj.pos)
    clearance, _ = metrics.min_obstacle_clearance(traj.pos, traj.obstacle_centres, traj.obstacle_radii)
    if psi is not None and len(tw) > 1:
        fe = metrics.formation_error(tw, pw, leader, psi, offsets)
        formation_rms, formation_max = fe.rms, fe.max
        settling = None if fe.t_settle is None else fe.t_settle - tw[0]
    else:
        formation_rms = formation_max = settling = None
    t_osc, reversals = metrics.oscillation(tw, vw[:, leader, :2])
    per_vehicle = []
    for i, name in enumerate(names):
        sep_i = np.delete(np.linalg.norm(traj.pos - traj.pos[:, i : i + 1], axis=-1), i, axis=1)
        clear_i, _ = metrics.min_obstacle_clearance(
            traj.pos[:, i : i + 1], traj.obstacle_centres, traj.obstacle_radii
        )
        per_vehicle.append(
            {
                "name": name,
                "reached": reach[i] is not None,
                "time_to_goal_s": _finite(None if reach[i] is None or t0 is None else reach[i] - t0),
                "final_error_m": _finite(float(np.linalg.norm(pw[-1, i] - goals[i]))),
                "min_separation_m": _finite(float(sep_i.min()) if sep_i.size else None),
                "min_obstacle_clearance_m": _finite(clear_i),
                "max_speed_m_s": _finite(float(np.linalg.norm(traj.vel[:, i], axis=1).max())),
                "crashed": bool(crashed_any[i]),
            }
        )
    times = [r for r in reach if r is not None]
    return {
        "mission": mission.name,
        "reached": bool(reached),
        "time_to_goal_s": _finite(max(times) - t0) if reached and t0 is not None else None,
        "collisions": int(crashed_any.sum()),
        "min_separation_m": _finite(min_sep),
        "min_obstacle_clearance_m": _finite(clearance),
        "formation_rms_m": _finite(formation_rms),
        "formation_max_m": _finite(formation_max),
        "oscillation_time_s": _finite(t_osc),
        "heading_reversals": int(reversals),
        "settling_time_s": _finite(settling),
        "sim_duration_s": _finite(float(traj.t[-1])),
        "wall_duration_s": _finite(flight.get("wall_duration_s")),
        "vehicles": per_vehicle,
        "lost": list(flight.get("lost", [])),
        "events": list(flight.get("events", [])),
        "source": traj.source,
    }


def render_markdown(report: dict[str, Any]) -> str:
    """Human-readable report.md."""

    def fmt(v: Any) -> str:
        return "-" if v is None else (f"{v:.2f}" if isinstance(v, float) else str(v))

    lines = [
        f"# Run report: {report['mission']}",
        "",
        f"Figures from **{report['source']}**.",
        "",
        "| figure | value |",
        "|---|---|",
    ]
    for key in (
        "reached",
        "time_to_goal_s",
        "collisions",
        "min_separation_m",
        "min_obstacle_clearance_m",
        "formation_rms_m",
        "formation_max_m",
        "oscillation_time_s",
        "heading_reversals",
        "settling_time_s",
        "sim_duration_s",
        "wall_duration_s",
    ):
        lines.append(f"| {key} | {fmt(report.get(key))} |")
    lines += [
        "",
        "| vehicle | reached | time to goal s | final error m | min sep m | min clearance m | crashed |",
    ]
    lines.append("|---|---|---|---|---|---|---|")
    for v in report["vehicles"]:
        lines.append(
            f"| {v['name']} | {v['reached']} | {fmt(v['time_to_goal_s'])} | {fmt(v['final_error_m'])} | "
            f"{fmt(v['min_separation_m'])} | {fmt(v['min_obstacle_clearance_m'])} | {v['crashed']} |"
        )
    if report["lost"] or report["events"]:
        lines += ["", "## Events", ""] + [f"- {e}" for e in report["events"]]
    return "\n".join(lines) + "\n"


def plot_report(run_dir: Path, mission: Any, path: Path) -> bool:
    """Trajectories (top view) and inter-vehicle distances as PNG; False when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    truth_path = run_dir / TRUTH_FILE
    if truth_path.exists() and truth_path.stat().st_size > 0:
        traj = load_truth(truth_path)
    else:
        traj = load_record(run_dir / RECORD_FILE, list(mission.obstacles))
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5))
    for i, v in enumerate(mission.vehicles):
        ax1.plot(traj.pos[:, i, 0], traj.pos[:, i, 1], lw=1.2, label=v.name)
    for k, r in enumerate(traj.obstacle_radii):
        c = traj.obstacle_centres[0, k]
        ax1.add_patch(plt.Circle((c[0], c[1]), r, color="0.4", alpha=0.6))
        if traj.obstacle_centres.shape[0] > 1:
            path_k = traj.obstacle_centres[:, k]
            ax1.plot(path_k[:, 0], path_k[:, 1], ":", color="0.4", lw=0.8)
    goal = np.asarray(mission.goal)
    ax1.plot(goal[0], goal[1], "k*", ms=12, label="goal")
    ax1.set_aspect("equal")
    ax1.set_xlabel("East (m)")
    ax1.set_ylabel("North (m)")
    ax1.set_title("Trajectories (top view)")
    ax1.legend(fontsize=8, loc="best")
    n = traj.pos.shape[1]
    for i in range(n):
        for j in range(i + 1, n):
            d = np.linalg.norm(traj.pos[:, i] - traj.pos[:, j], axis=1)
            ax2.plot(traj.t, d, lw=0.8, label=f"{mission.vehicles[i].name}-{mission.vehicles[j].name}")
    d_emg = mission.safety.separation.d_emg
    ax2.axhline(d_emg, color="r", ls="--", lw=1, label=f"D_Emg {d_emg:g} m")
    ax2.set_xlabel("time (s)")
    ax2.set_ylabel("distance (m)")
    ax2.set_title("Inter-vehicle distances")
    if n * (n - 1) // 2 <= 15:
        ax2.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def write_report(run_dir: Path, mission: Any) -> dict[str, Any]:
    """(Re)build report.json, report.md and report.png of a run folder; returns the report."""
    flight = json.loads((run_dir / FLIGHT_FILE).read_text())
    report = compute_report(run_dir, mission, flight)
    (run_dir / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    (run_dir / "report.md").write_text(render_markdown(report))
    plot_report(run_dir, mission, run_dir / "report.png")
    return report
