"""Figures in the paper's style, drawn with matplotlib (the optional extra `plot`); every function returns
what it wrote, nothing (an empty list or False) when matplotlib is not installed.

Run figures (one run folder, `write_run_figures`): report.png (overview: top view with the formation's shape
at eight moments, inter-vehicle distances, each follower's distance from its slot over the whole formation
flight with the reshapes marked, commanded roll and pitch),
fig_trajectories.png (3-D paths with obstacle spheres and the 2-D top view, paper Figs 13, 18, 20, 22, 25),
fig_velocity_acceleration.png (per-axis velocity and acceleration, Figs 14-16), fig_distances.png
(inter-vehicle distances with the safe-distance line, Fig 17), fig_relative_angle.png (angle of each follower
from the leader's heading, Fig 19), fig_attitude_rates.png (commanded pitch and yaw rates, Fig 26).
Comparison and Monte Carlo figures: `plot_compare`, `plot_histograms`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

import numpy as np

from gcs_swarm.evaluation import flight_quality, signals
from gcs_swarm.evaluation.site_drawing import draw_site, has_site

if TYPE_CHECKING:
    from gcs_swarm.evaluation.run_data import CommandLog, Trajectories

ENABLED = True  # False: write_run_figures draws nothing (Monte Carlo workers)
MAX_POINTS = 4000  # samples per plotted series; longer logs are decimated for drawing only
MAX_LEGEND = 10  # vehicles (or pairs) beyond which legends are left out
FORMATION_SNAPSHOTS = 8  # moments of formation flight whose shape the top view shows


def pyplot() -> ModuleType | None:
    """matplotlib.pyplot on the Agg backend, or None when matplotlib is not installed."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    return plt


def _every(n: int) -> slice:
    return slice(None, None, max(1, n // MAX_POINTS))


def _draw_top_view(ax: Any, plt: ModuleType, traj: Trajectories, names: list[str], goal: np.ndarray) -> None:
    s = _every(len(traj.t))
    for i, name in enumerate(names):
        ax.plot(traj.pos[s, i, 0], traj.pos[s, i, 1], lw=1.1, label=name)
    for k, r in enumerate(traj.obstacle_radii if len(traj.obstacle_centres) else ()):
        c = traj.obstacle_centres[0, k]
        ax.add_patch(plt.Circle((c[0], c[1]), r, color="0.4", alpha=0.6))
        if len(traj.obstacle_centres) > 1 and np.any(traj.obstacle_centres[-1, k] != c):
            ax.plot(traj.obstacle_centres[s, k, 0], traj.obstacle_centres[s, k, 1], ":", color="0.4", lw=0.8)
    ax.plot(goal[0], goal[1], "k*", ms=12, label="goal")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set(xlabel="East x (m)", ylabel="North y (m)", title="Trajectories, top view")
    if len(names) <= MAX_LEGEND:
        ax.legend(fontsize=7, loc="best")


def _pair_distances(traj: Trajectories) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Distances (T, P) of every pair i < j, or of each vehicle to its nearest neighbour when the fleet is
    larger than MAX_LEGEND (pairs (i, -1))."""
    n = traj.pos.shape[1]
    if n <= MAX_LEGEND:
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
        d = [np.linalg.norm(traj.pos[:, i] - traj.pos[:, j], axis=1) for i, j in pairs]
        return np.array(d).T.reshape(len(traj.t), len(pairs)), pairs
    return traj.nearest_neighbour, [(i, -1) for i in range(n)]


def _draw_distances(ax: Any, traj: Trajectories, names: list[str], mission: Any, t0: float) -> None:
    d, pairs = _pair_distances(traj)
    s = _every(len(traj.t))
    for k, (i, j) in enumerate(pairs):
        label = f"{names[i]}-{names[j]}" if j >= 0 else f"{names[i]} nearest"
        ax.plot(traj.t[s] - t0, d[s, k], lw=0.8, label=label)
    sep = mission.safety.separation
    ax.axhline(sep.d_emg, color="r", ls="--", lw=1, label=f"safe distance D_Emg {sep.d_emg:g} m")
    ax.axhline(sep.d_max, color="orange", ls=":", lw=1, label=f"D_max {sep.d_max:g} m")
    ax.set(xlabel="time since formation start (s)", ylabel="distance (m)", title="Inter-vehicle distances")
    if len(pairs) <= 15:
        ax.legend(fontsize=6, loc="best")


def _draw_slot_errors(
    ax: Any,
    traj: Trajectories,
    commands: CommandLog | None,
    flight: dict[str, Any],
    mission: Any,
    names: list[str],
    t0: float,
) -> None:
    """Each follower's distance from its slot over the whole formation flight (docs/metrics.md)."""
    ax.set_title("Follower-to-slot error, whole formation flight")
    ax.set(xlabel="time since formation start (s)", ylabel="distance from slot (m)")
    if commands is None or len(commands.t) < 2 or len(names) < 2:
        ax.text(0.5, 0.5, "no record of the formation", ha="center", transform=ax.transAxes)
        return
    sel = (traj.t >= t0) & (traj.t <= commands.t[-1])
    t = traj.t[sel]
    if len(t) < 2:
        ax.text(0.5, 0.5, "no positions in formation flight", ha="center", transform=ax.transAxes)
        return
    psi = signals.held_at(commands.t, commands.psi_l, t)
    leader = int(flight.get("leader", mission.leader_index))
    offsets = np.array(flight["offsets"], dtype=float)
    _, err = flight_quality.scheduled_formation_error(t, traj.pos[sel], psi, flight, leader, offsets)
    s = _every(len(t))
    for i, name in enumerate(names):
        if np.isfinite(err[:, i]).any():
            ax.plot(t[s] - t0, err[s, i], lw=0.9, label=name, color=f"C{i % 10}")  # as in the top view
    # the formation's changes of shape (guidance.reshape), and the legs of the route (mission key `legs`)
    marks = [(when, what, "0.5", "--") for when, what in reshape_events(flight)]
    marks += [(when, what, "tab:blue", "-") for when, what in leg_events(flight)]
    for when, what, color, style in marks:
        ax.axvline(when - t0, color=color, lw=0.8, ls=style)
        ax.text(
            when - t0,
            1.0,
            what,
            rotation=90,
            va="top",
            ha="right",
            fontsize=6,
            color=color,
            transform=ax.get_xaxis_transform(),
        )
    if len(names) <= MAX_LEGEND:
        ax.legend(fontsize=7, loc="best")


def reshape_events(flight: dict[str, Any]) -> list[tuple[float, str]]:
    """(vehicle time s, what) of each change of the formation's shape, from flight.json's reshapes
    (guidance.reshape.ShapeChange.as_json): "narrows: column", "widens: formation x0.71", "restored"."""
    return [
        (float(r["t_s"]), "restored" if r["change"] == "restored" else f"{r['change']}: {r['shape']}")
        for r in flight.get("reshapes", [])
    ]


def leg_events(flight: dict[str, Any]) -> list[tuple[float, str]]:
    """(vehicle time s, what) of the start of each leg of the route, from flight.json's legs ("leg 2 (north):
    line")."""
    return [
        (float(row["t_s"]), f"leg {int(row['index']) + 1} ({row['name']}): {row['shape']}")
        for row in flight.get("legs", [])
    ]


def _draw_legs(ax: Any, traj: Trajectories, mission: Any, flight: dict[str, Any]) -> None:
    """The leader's route (start, waypoints) as a dotted line on the top view, where the leader truly was
    when each leg of the route began (flight.json's legs), labelled with the leg and its formation, and the
    via points of legs flown round a gap (flight.json's detours) as crosses joined by a dashed line."""
    if len(traj.t) == 0:
        return
    leader = int(flight.get("leader", mission.leader_index))
    for detour in flight.get("detours", []):
        try:
            via = np.array(detour["via"], dtype=float).reshape(-1, 3)
            k = int(np.clip(np.searchsorted(traj.t, float(detour["t_s"])), 0, len(traj.t) - 1))
            index = min(int(detour["waypoint"]), len(mission.waypoints) - 1)
        except (KeyError, TypeError, ValueError):  # a row a hand edit broke: drawn without it
            continue
        path = np.vstack([traj.pos[k, leader, :2], via[:, :2], np.asarray(mission.waypoints[index])[:2]])
        ax.plot(path[:, 0], path[:, 1], "--", color="tab:purple", lw=0.8)
        ax.plot(via[:, 0], via[:, 1], "x", color="tab:purple", ms=6)
        if len(via):
            ax.annotate(
                "round a gap", tuple(via[0, :2]), textcoords="offset points", xytext=(4, -10), fontsize=7,
                color="tab:purple",
            )  # fmt: skip
    if len(mission.waypoints) < 2:
        return
    route = np.vstack([traj.pos[0, mission.leader_index, None, :2], [w[:2] for w in mission.waypoints]])
    ax.plot(route[:, 0], route[:, 1], ":", color="0.3", lw=0.8)
    for when, what in leg_events(flight):
        k = int(np.clip(np.searchsorted(traj.t, when), 0, len(traj.t) - 1))
        x, y = traj.pos[k, leader, 0], traj.pos[k, leader, 1]
        ax.plot(x, y, "D", color="tab:blue", ms=5)
        ax.annotate(what, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7, color="tab:blue")


def _draw_formation_shapes(ax: Any, traj: Trajectories, leader: int, t0: float, t1: float) -> None:
    """The formation's shape at FORMATION_SNAPSHOTS moments of formation flight on the top view: a line from
    the leader to each follower, where they truly were."""
    if len(traj.t) == 0:
        return
    for when in np.linspace(t0, t1, FORMATION_SNAPSHOTS):
        k = int(np.clip(np.searchsorted(traj.t, when), 0, len(traj.t) - 1))
        p = traj.pos[k]
        for i in range(p.shape[0]):
            if i != leader:
                ax.plot([p[leader, 0], p[i, 0]], [p[leader, 1], p[i, 1]], color="0.25", lw=0.6, alpha=0.7)
        ax.plot(p[:, 0], p[:, 1], "o", color="0.25", ms=2.5, alpha=0.8)


def _draw_tilt_commands(ax: Any, commands: CommandLog | None, names: list[str], t0: float) -> None:
    """Commanded roll and pitch of every vehicle over the formation flight: steps and chatter show here."""
    ax.set_title("Commanded roll (dashed) and pitch")
    ax.set_xlabel("time since formation start (s)")
    ax.set_ylabel("angle (deg)")
    if commands is None or len(commands.t) < 2:
        ax.text(0.5, 0.5, "no record of the commands", ha="center", transform=ax.transAxes)
        return
    s = _every(len(commands.t))
    for i, name in enumerate(names):
        color = f"C{i % 10}"
        ax.plot(commands.t[s] - t0, np.degrees(commands.attitude_d[s, i, 1]), lw=0.9, label=name, color=color)
        ax.plot(commands.t[s] - t0, np.degrees(commands.attitude_d[s, i, 0]), lw=0.7, ls="--", color=color)
    if len(names) <= MAX_LEGEND:
        ax.legend(fontsize=7, loc="best")


def _save(plt: ModuleType, fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _sphere(ax: Any, centre: np.ndarray, radius: float) -> None:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
    ax.plot_surface(
        centre[0] + radius * np.cos(u) * np.sin(v),
        centre[1] + radius * np.sin(u) * np.sin(v),
        centre[2] + radius * np.cos(v),
        color="0.4",
        alpha=0.5,
        linewidth=0,
    )


def _trajectories_figure(plt: ModuleType, traj: Trajectories, names: list[str], goal: np.ndarray, path: Path):
    fig = plt.figure(figsize=(14, 6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    s = _every(len(traj.t))
    for i, name in enumerate(names):
        ax3.plot(traj.pos[s, i, 0], traj.pos[s, i, 1], traj.pos[s, i, 2], lw=1.0, label=name)
    for k, r in enumerate(traj.obstacle_radii if len(traj.obstacle_centres) else ()):
        _sphere(ax3, traj.obstacle_centres[0, k], float(r))
    ax3.scatter([goal[0]], [goal[1]], [goal[2]], marker="*", color="k", s=80)
    ax3.set(xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title="Trajectories in O-XYZ")
    _draw_top_view(fig.add_subplot(1, 2, 2), plt, traj, names, goal)
    return _save(plt, fig, path)


def _site_figure(
    plt: ModuleType,
    traj: Trajectories,
    mission: Any,
    flight: dict[str, Any],
    names: list[str],
    window: tuple[float, float],
    path: Path,
) -> Path:
    """The flight over its site, large: the trajectories and the formation's shape at moments of the
    formation flight (window (t0, t1) s) over the fence, zones, buildings and trees, the route and where each
    leg began."""
    fig, ax = plt.subplots(figsize=(11, 9))
    _draw_top_view(ax, plt, traj, names, np.asarray(mission.goal, dtype=float))
    _draw_formation_shapes(ax, traj, int(flight.get("leader", mission.leader_index)), *window)
    _draw_legs(ax, traj, mission, flight)
    draw_site(ax, mission)
    ax.set_title(f"{mission.name}: the flight over its site")
    return _save(plt, fig, path)


def _velocity_figure(plt: ModuleType, traj: Trajectories, names: list[str], t0: float, path: Path) -> Path:
    acc = signals.accelerations(traj.t, traj.vel)
    fig, axes = plt.subplots(3, 2, figsize=(13, 10), sharex=True)
    s = _every(len(traj.t))
    for row, axis in enumerate("XYZ"):
        for i, name in enumerate(names):
            axes[row, 0].plot(traj.t[s] - t0, traj.vel[s, i, row], lw=0.8, label=name)
            axes[row, 1].plot(traj.t[s] - t0, acc[s, i, row], lw=0.8, label=name)
        axes[row, 0].set_ylabel(f"v_{axis.lower()} (m/s)")
        axes[row, 1].set_ylabel(f"a_{axis.lower()} (m/s^2)")
        axes[row, 0].set_title(f"Velocity, {axis}-direction (Figs 14-16)")
        axes[row, 1].set_title(f"Acceleration, {axis}-direction")
    for ax in axes[-1]:
        ax.set_xlabel("time since formation start (s)")
    if len(names) <= MAX_LEGEND:
        axes[0, 0].legend(fontsize=7, loc="best")
    return _save(plt, fig, path)


def _relative_angle_figure(
    plt: ModuleType,
    traj: Trajectories,
    commands: CommandLog,
    mission: Any,
    offsets: np.ndarray,
    t0: float,
    path,
) -> Path:
    leader = mission.leader_index
    psi = signals.held_at(commands.t, commands.psi_l, traj.t)
    desired_rad = signals.desired_relative_angles(offsets, leader)
    reference = np.nan_to_num(desired_rad)
    angles = np.degrees(signals.near(signals.relative_angles(traj.pos, leader, psi), reference))
    desired = np.degrees(desired_rad)
    fig, ax = plt.subplots(figsize=(10, 5))
    s = _every(len(traj.t))
    for i, v in enumerate(mission.vehicles):
        if i == leader:
            continue
        (line,) = ax.plot(traj.t[s] - t0, angles[s, i], lw=0.9, label=v.name)
        ax.axhline(desired[i], color=line.get_color(), ls="--", lw=0.7)
    ax.set_xlabel("time since formation start (s)")
    ax.set_ylabel("angle from the leader's heading (deg)")
    ax.set_title("Relative angle of each follower (Fig 19; dashed: its slot)")
    if len(mission.vehicles) <= MAX_LEGEND:
        ax.legend(fontsize=7, loc="best")
    return _save(plt, fig, path)


def _rates_figure(plt: ModuleType, commands: CommandLog, names: list[str], path: Path) -> Path:
    t = commands.t - commands.t[0]
    rates = signals.attitude_rates(t, commands.attitude_d)
    fig, axes = plt.subplots(2, 1, figsize=(11, 8), sharex=True)
    s = _every(len(t))
    for ax, (label, k) in zip(axes, (("yaw", 2), ("pitch", 1)), strict=True):
        for i, name in enumerate(names):
            ax.plot(t[s], rates[s, i, k], lw=0.7, label=name)
        ax.set_ylabel(f"commanded {label} rate (rad/s)")
        ax.set_title(f"Virtual control signal: {label} angular velocity (Fig 26)")
    axes[-1].set_xlabel("time since formation start (s)")
    if len(names) <= MAX_LEGEND:
        axes[0].legend(fontsize=7, loc="best", ncol=2)
    return _save(plt, fig, path)


def write_run_figures(
    run_dir: Path, mission: Any, flight: dict[str, Any], traj: Trajectories, commands: CommandLog | None
) -> list[Path]:
    """Every run figure that the logs allow (the record gives relative angles and rates); [] without
    matplotlib. flight is flight.json (offsets, t_formation_start). Drawn whatever the logs hold: a vehicle
    without samples (silent, lost, never commanded) leaves its lines out or broken, an empty log empty axes.
    """
    plt = pyplot() if ENABLED else None
    if plt is None:
        return []
    with warnings.catch_warnings():  # all-NaN or empty series: expected, drawn as nothing
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.simplefilter("ignore", UserWarning)
        return _write_run_figures(plt, run_dir, mission, flight, traj, commands)


def _write_run_figures(
    plt: ModuleType,
    run_dir: Path,
    mission: Any,
    flight: dict[str, Any],
    traj: Trajectories,
    commands: CommandLog | None,
) -> list[Path]:
    names = [v.name for v in mission.vehicles]
    goal = np.asarray(mission.goal, dtype=float)
    offsets = np.array(flight["offsets"], dtype=float)
    t_first = float(traj.t[0]) if len(traj.t) else 0.0
    t0 = float(flight.get("t_formation_start") or t_first)
    written = []
    fig, axes = plt.subplots(2, 2, figsize=(14, 10.5))
    _draw_top_view(axes[0, 0], plt, traj, names, goal)
    t1 = float(flight.get("t_formation_end") or (traj.t[-1] if len(traj.t) else t0))
    _draw_formation_shapes(axes[0, 0], traj, int(flight.get("leader", mission.leader_index)), t0, t1)
    _draw_legs(axes[0, 0], traj, mission, flight)
    draw_site(axes[0, 0], mission)
    _draw_distances(axes[0, 1], traj, names, mission, t0)
    _draw_slot_errors(axes[1, 0], traj, commands, flight, mission, names, t0)
    _draw_tilt_commands(axes[1, 1], commands, names, t0)
    written.append(_save(plt, fig, run_dir / "report.png"))
    if has_site(mission):
        written.append(_site_figure(plt, traj, mission, flight, names, (t0, t1), run_dir / "fig_site.png"))
    written.append(_trajectories_figure(plt, traj, names, goal, run_dir / "fig_trajectories.png"))
    written.append(_velocity_figure(plt, traj, names, t0, run_dir / "fig_velocity_acceleration.png"))
    fig, ax = plt.subplots(figsize=(10, 5))
    _draw_distances(ax, traj, names, mission, t0)
    ax.set_title("Inter-vehicle distances (Fig 17)")
    written.append(_save(plt, fig, run_dir / "fig_distances.png"))
    if commands is not None and len(commands.t) > 2:
        if len(names) > 1:
            path = run_dir / "fig_relative_angle.png"
            written.append(_relative_angle_figure(plt, traj, commands, mission, offsets, t0, path))
        written.append(_rates_figure(plt, commands, names, run_dir / "fig_attitude_rates.png"))
    return written


@dataclass(frozen=True)
class CompareRun:
    """One flown variant for the overlaid comparison figures: its label and logs."""

    label: str
    traj: Trajectories
    commands: CommandLog | None
    offsets: np.ndarray  # (N, 3) m, leader frame, the mission's (flight.json "offsets")
    leader: int
    t0: float  # s, formation start
    flight: dict[str, Any]  # the run's flight.json (its formation_timeline: the slots of the moment)


def slot_error_series(run: CompareRun) -> tuple[np.ndarray, np.ndarray] | None:
    """Time since the formation start (T,) s and the worst follower-to-slot error (T,) m over the formation
    phase, against the slots of the moment (flight_quality.scheduled_formation_error: reshaped, re-formed or
    the mission's, as the report and the benchmarks measure it); None without a record (no psi_L) or without
    followers."""
    if run.commands is None or len(run.offsets) < 2:
        return None
    sel = (run.traj.t >= run.t0) & (run.traj.t <= run.commands.t[-1])
    t, p = run.traj.t[sel], run.traj.pos[sel]
    if len(t) == 0:
        return None
    psi = signals.held_at(run.commands.t, run.commands.psi_l, t)
    _, err = flight_quality.scheduled_formation_error(t, p, psi, run.flight, run.leader, run.offsets)
    with np.errstate(invalid="ignore"):
        return t - run.t0, np.fmax.reduce(err, axis=1)


def plot_compare(runs: list[CompareRun], goal: np.ndarray, path: Path) -> bool:
    """Overlaid leader paths (top view, obstacles of the first run), minimum inter-vehicle distance and the
    worst follower-to-slot error over time (`slot_error_series`), one colour per variant; False without
    matplotlib."""
    plt = pyplot()
    if plt is None or not runs:
        return False
    fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(18, 5.5))
    first = runs[0].traj
    for k, r in enumerate(first.obstacle_radii):
        c = first.obstacle_centres[0, k]
        ax1.add_patch(plt.Circle((c[0], c[1]), r, color="0.4", alpha=0.6))
    for run in runs:
        s = _every(len(run.traj.t))
        ax1.plot(run.traj.pos[s, run.leader, 0], run.traj.pos[s, run.leader, 1], lw=1.1, label=run.label)
        if run.traj.pos.shape[1] > 1:
            d, _ = _pair_distances(run.traj)
            ax2.plot(run.traj.t[s] - run.t0, d.min(axis=1)[s], lw=0.9, label=run.label)
        series = slot_error_series(run)
        if series is not None:
            ss = _every(len(series[0]))
            ax3.plot(series[0][ss], series[1][ss], lw=0.9, label=run.label)
    ax1.plot(goal[0], goal[1], "k*", ms=12)
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set(xlabel="East x (m)", ylabel="North y (m)", title="Leader paths")
    ax2.set(xlabel="time since formation start (s)", ylabel="m", title="Minimum inter-vehicle distance")
    ax3.set(xlabel="time since formation start (s)", ylabel="m", title="Worst follower-to-slot error")
    for ax in (ax1, ax2, ax3):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="best")
    _save(plt, fig, path)
    return True


def plot_histograms(values: dict[str, dict[str, list[float]]], labels: dict[str, str], path: Path) -> bool:
    """Histograms of Monte Carlo figures: values[figure][variant] = samples; one panel per figure (titled
    labels[figure]), variants overlaid. False without matplotlib."""
    plt = pyplot()
    if plt is None or not values:
        return False
    fig, axes = plt.subplots(1, len(values), figsize=(5.5 * len(values), 4.5), squeeze=False)
    for ax, (figure, by_variant) in zip(axes[0], values.items(), strict=True):
        finite = [v for samples in by_variant.values() for v in samples if np.isfinite(v)]
        bins = np.histogram_bin_edges(finite, bins=min(20, max(1, len(finite)))) if finite else 10
        for variant, samples in by_variant.items():
            ax.hist([v for v in samples if np.isfinite(v)], bins=bins, alpha=0.55, label=variant)
        ax.set(title=labels.get(figure, figure), ylabel="runs")
        ax.legend(fontsize=7)
    _save(plt, fig, path)
    return True
