"""A run's report: metrics of spec 10 from ground truth (the simulator's truth log) when there is one, else
from the ground station's own telemetry record, plus the commanded attitude rates (Fig 26) from the record;
written as report.json + report.md, and figures in the paper's style (gcs_swarm.evaluation.figures) when
matplotlib is installed.
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.evaluation import figures, flight_quality, metrics, signals
from gcs_swarm.evaluation.fence_figures import fence_figures
from gcs_swarm.evaluation.metrics import rounded
from gcs_swarm.evaluation.run_data import CommandLog, Trajectories, load_commands, load_trajectories
from gcs_swarm.flight.formation_plan import site_shapes
from gcs_swarm.flight.run_folder import FLIGHT_FILE, RECORD_FILE
from gcs_swarm.guidance.formation import slot_positions


def _reach_time(t: np.ndarray, distance: np.ndarray, tol: float, hold: float, arrived: bool) -> float | None:
    """Spec 10 reach time; when the ground station ended the formation phase on arrival, an interval inside
    the tolerance that lasts to the end of the phase also counts (the landing cut it short, and the ground
    station's own hold, against the moving slots, can begin a little before the truth's)."""
    held = metrics.reach_time(t, distance, tol, hold)
    if held is not None or not arrived or len(t) == 0 or not distance[-1] <= tol:
        return held
    outside = np.flatnonzero(~(distance <= tol))  # NaN (no position) is not inside
    return float(t[outside[-1] + 1]) if len(outside) else float(t[0])


def _finite(x: np.ndarray, reduce: Any) -> float | None:
    """reduce (np.min, np.max) over the finite values of x, None when there are none (no sample, or the
    vehicle silent throughout)."""
    finite = x[np.isfinite(x)]
    return float(reduce(finite)) if finite.size else None


def _deg(x: float) -> float | None:
    return rounded(math.degrees(x)) if math.isfinite(x) else None


def emergency_distance(mission: Any) -> float:
    """D_Emg in m for the safety check: the constant, or in formula mode its floor s_s (Eq 20 at v_re = 0)."""
    sep = mission.safety.separation
    return float(sep.d_emg if sep.mode == "constant" else sep.s_s)


def _commands_between(commands: CommandLog, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    keep = (commands.t >= t0) & (commands.t <= t1)
    return commands.t[keep], commands.attitude_d[keep]


def report_from(
    traj: Trajectories, commands: CommandLog | None, mission: Any, flight: dict[str, Any]
) -> dict[str, Any]:
    """The figures of report.json from loaded trajectories and commands. Any of them may have no sample, or
    NaN where a vehicle was silent, lost or not commanded: such a figure is None ("-" in report.md), never an
    error; numpy's warnings about all-NaN or empty slices are expected there and silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return _report_from(traj, commands, mission, flight)


def _report_from(
    traj: Trajectories, commands: CommandLog | None, mission: Any, flight: dict[str, Any]
) -> dict[str, Any]:
    leader = int(flight.get("leader", mission.leader_index))  # the lead may have passed on (vehicle lost)
    names = [v.name for v in mission.vehicles]
    offsets = np.array(flight["offsets"], dtype=float)
    t0 = flight.get("t_formation_start")
    t_end = flight.get("t_formation_end") or (float(traj.t[-1]) if len(traj.t) else math.inf)
    window = (traj.t >= (t0 if t0 is not None else -math.inf)) & (traj.t <= t_end)
    if not window.any():
        window = np.ones_like(traj.t, dtype=bool)
    tw, pw, vw = traj.t[window], traj.pos[window], traj.vel[window]

    psi = None if commands is None else signals.held_at(commands.t, commands.psi_l, tw)
    psi_final = float(psi[-1]) if psi is not None and len(psi) and np.isfinite(psi[-1]) else 0.0
    goals = slot_positions(np.asarray(mission.goal, dtype=float)[None, :], np.array([psi_final]), offsets)[0]
    if flight.get("final_targets") is not None:
        goals = np.array(flight["final_targets"], dtype=float)
    tol, hold = mission.run.goal_tolerance_m, mission.run.hold_s
    arrived = bool(flight.get("arrived"))
    reach = [
        _reach_time(tw, np.linalg.norm(pw[:, i] - goals[i], axis=1), tol, hold, arrived)
        for i in range(len(names))
    ]
    crashed_any = cast(NDArray[np.bool_], traj.crashed.any(axis=0))  # (N,)
    reached = all(r is not None for r in reach) and not crashed_any.any() and arrived
    min_sep = metrics.min_separation(traj.pos, traj.closest_pair)
    shapes = site_shapes(mission)  # the still cylinders and prisms (spec 2.2)
    clearance, _ = metrics.min_obstacle_clearance(
        traj.pos, traj.obstacle_centres, traj.obstacle_radii, shapes=shapes
    )
    cruise = None
    slot_error = None
    formation_rms: float | None
    formation_max: float | None
    settling: float | None
    angles = np.full((len(tw), len(names)), np.nan)
    if psi is not None and len(tw) > 1:
        fe, slot_error = flight_quality.scheduled_formation_error(tw, pw, psi, flight, leader, offsets)
        formation_rms, formation_max = fe.rms, fe.max
        settling = None if fe.t_settle is None else fe.t_settle - tw[0]
        d_g = mission.field.d_g if mission.field.d_g is not None else mission.limits.v_xy_leader
        cruise = signals.cruise_figures(
            tw - tw[0], pw, vw, leader, np.asarray(mission.goal), offsets, fe.error, 2.0 * d_g
        )
        angles = signals.relative_angles(pw, leader, psi)
    else:
        formation_rms = formation_max = settling = None
    desired_angles = signals.desired_relative_angles(offsets, leader)
    last = slice(-max(1, len(tw) // 10), None)
    t_osc, reversals = metrics.oscillation(tw, vw[:, leader, :2])
    per_vehicle = []
    nearest = traj.nearest_neighbour  # (T, N) m
    for i, name in enumerate(names):
        clear_i, _ = metrics.min_obstacle_clearance(
            traj.pos[:, i : i + 1], traj.obstacle_centres, traj.obstacle_radii, shapes=shapes
        )
        final_angle = signals.near(angles[last, i], desired_angles[i] if i != leader else 0.0)
        per_vehicle.append(
            {
                "name": name,
                # the autopilot the ground station spoke to (flight.json "autopilots"; None in older runs)
                "autopilot": flight.get("autopilots", {}).get(name),
                "reached": reach[i] is not None,
                "time_to_goal_s": rounded(None if reach[i] is None or t0 is None else reach[i] - t0),
                "final_error_m": rounded(float(np.linalg.norm(pw[-1, i] - goals[i])) if len(pw) else None),
                "min_separation_m": rounded(_finite(nearest[:, i], np.min) if len(names) > 1 else None),
                "min_obstacle_clearance_m": rounded(clear_i),
                "max_speed_m_s": rounded(_finite(np.linalg.norm(traj.vel[:, i], axis=1), np.max)),
                "relative_angle_deg": _deg(float(np.nanmedian(final_angle)))
                if np.isfinite(final_angle).any()
                else None,
                "relative_angle_desired_deg": _deg(float(desired_angles[i])),
                "crashed": bool(crashed_any[i]),
            }
        )
    times = [r for r in reach if r is not None]
    t_first, t_last = (float(tw[0]), float(tw[-1])) if len(tw) else (math.nan, math.nan)  # nan: no sample
    t_arrival = max(times) if reached and times else t_last
    start = pw[0, leader] if len(pw) else np.full(3, math.nan)
    route = np.vstack([start[None, :], np.asarray(mission.waypoints, dtype=float).reshape(-1, 3)])
    d_emg = emergency_distance(mission)
    below_s, closest = flight_quality.time_below(traj.t, traj.pos, d_emg, traj.closest_pair)
    whole = flight_quality.whole_flight_figures(
        tw,
        pw,
        vw,
        slot_error,
        route,
        leader,
        (t_first, t_arrival),
        mission.formation.altitude + offsets[:, 2],
        (below_s, closest),
        None if commands is None else _commands_between(commands, t_first, t_arrival),
        names,
    )
    if slot_error is not None and len(tw):
        window = (tw >= t_first) & (tw <= t_arrival)
        at_rest = flight_quality.shape_at_rest(flight, tw[window])
        whole |= flight_quality.shape_formed(tw[window], slot_error[window], at_rest)
    safety_events = []
    if crashed_any.any():
        safety_events.append(
            f"collision: {', '.join(n for n, c in zip(names, crashed_any, strict=True) if c)}"
        )
    if below_s > 0.0:
        safety_events.append(
            f"separation below D_Emg ({d_emg:g} m) for {below_s:.2f} s, down to {closest:.2f} m"
        )
    rates = None
    if commands is not None and len(commands.t) > 2:
        t_end_rates = None if cruise is None else cruise["window_s"][1]
        rates = signals.command_rate_figures(
            commands.t - commands.t[0], commands.attitude_d, names, t_end_rates
        )
    return {
        "mission": mission.name,
        "reached": bool(reached),
        "time_to_goal_s": rounded(max(times) - t0) if reached and t0 is not None else None,
        "collisions": int(crashed_any.sum()),
        "min_separation_m": rounded(min_sep),
        "min_obstacle_clearance_m": rounded(clearance),
        **fence_figures(traj.pos, mission),  # fence_breaches, min_fence_margin_m: with a site fence only
        "formation_rms_m": rounded(formation_rms),
        "formation_max_m": rounded(formation_max),
        "oscillation_time_s": rounded(t_osc),
        "heading_reversals": int(reversals),
        "settling_time_s": rounded(settling),
        "command_rate_settling_s": None if rates is None else rates["settling_s"],
        "command_rate_trend_settling_s": None if rates is None else rates["trend_settling_s"],
        "command_rate_first_settled_s": None if rates is None else rates["trend_first_settled_s"],
        "command_chatter_first_20s_rad_s": None if rates is None else rates["chatter_first_20s_rad_s"],
        "command_chatter_last_20s_rad_s": None if rates is None else rates["chatter_last_20s_rad_s"],
        "command_rates": rates,
        "cruise": cruise,
        "whole_flight": whole,
        "safety_events": safety_events,
        # on the run's own clock (docs/metrics.md)
        "sim_duration_s": rounded(float(traj.t[-1] - traj.t[0]) if len(traj.t) else None),
        "wall_duration_s": rounded(flight.get("wall_duration_s")),
        "commands_limited": flight.get("commands_limited"),  # None: a flight.json from before it was kept
        "vehicles": per_vehicle,
        "lost": list(flight.get("lost", [])),
        # vehicles taken over by another controller (docs/reliability.md "Operator takeover")
        "taken_over": list(flight.get("taken_over", [])),
        "left_to_operator": list(flight.get("left_to_operator", [])),
        "events": list(flight.get("events", [])),
        # the formation's changes of shape (flight.json reshapes: t_s, change, shape, scale)
        "reshapes": list(flight.get("reshapes", [])),
        # the legs of the route as the leader started them (flight.json legs: index, name, t_s, shape, ...)
        "legs": list(flight.get("legs", [])),
        # legs the leader flew round a gap (flight.json detours: t_s, waypoint, via; [] in older runs)
        "detours": list(flight.get("detours", [])),
        # bytes/s each way per vehicle and the link budget (flight.json link_use; None in older runs)
        "link_use": flight.get("link_use"),
        # each step down of the command mode in flight (flight.json command_mode_changes; [] in older runs)
        "command_mode_changes": list(flight.get("command_mode_changes") or []),
        "source": traj.source,
    }


SUMMARY_KEYS = (
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
    "command_rate_settling_s",
    "command_rate_trend_settling_s",
    "command_rate_first_settled_s",
    "command_chatter_first_20s_rad_s",
    "command_chatter_last_20s_rad_s",
    "sim_duration_s",
    "wall_duration_s",
    "commands_limited",
)


# Figures measured only once the formation has settled (spec 10): labelled so in report.md.
SETTLED_LABELS = {
    "formation_rms_m": "formation_rms_m (settled only)",
    "formation_max_m": "formation_max_m (settled only)",
}
WHOLE_FLIGHT_KEYS = (
    "slot_error_rms_m",
    "slot_error_p95_m",
    "slot_error_max_m",
    "assembly_s",
    "slot_error_assembled_rms_m",
    "slot_error_assembled_max_m",
    "shape_formed_s",
    "cusps",
    "max_tilt_command_rate_rad_s",
    "max_yaw_command_rate_rad_s",
    "max_yaw_rate_step_rad_s",
    "pitch_command_chatter_max_rad",
    "pitch_rate_chatter_whole_flight_rad_s",
    "jerk_p99_max_m_s3",
    "leader_path_ratio",
    "min_separation_whole_flight_m",
    "time_below_d_emg_s",
    "min_altitude_in_formation_m",
    "max_drop_below_formation_altitude_m",
)


def _fmt(v: Any) -> str:
    return "-" if v is None else (f"{v:.2f}" if isinstance(v, float) else str(v))


def _list(v: Any) -> str:
    return ", ".join(_fmt(x) for x in v) if isinstance(v, list) else _fmt(v)


def _table(title: str, header: list[str], rows: list[list[str]]) -> list[str]:
    """report.md lines of a titled table (none without rows)."""
    if not rows:
        return []
    lines = ["", title, "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def render_markdown(report: dict[str, Any]) -> str:
    """Human-readable report.md."""
    lines = [
        f"# Run report: {report['mission']}",
        "",
        f"Figures from **{report['source']}**.",
        "",
        "| figure | value |",
        "|---|---|",
    ]
    events = report.get("safety_events") or []
    if events:
        lines[3:3] = ["**SAFETY EVENTS**: " + "; ".join(events), ""]
    lines += [f"| {SETTLED_LABELS.get(key, key)} | {_fmt(report.get(key))} |" for key in SUMMARY_KEYS]
    whole = report.get("whole_flight")
    if whole:
        w0, w1 = whole["window_s"]
        lines += ["", f"Whole flight, from the formation start ({_fmt(w0)} s) to arrival ({_fmt(w1)} s):", ""]
        lines += ["| figure | value |", "|---|---|"]
        lines += [f"| {key} | {_list(whole.get(key))} |" for key in WHOLE_FLIGHT_KEYS if key in whole]
    lines += [
        "",
        "| vehicle | autopilot | reached | time to goal s | final error m | min sep m | min clearance m | "
        "relative angle deg (slot) | crashed |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for v in report["vehicles"]:
        lines.append(
            f"| {v['name']} | {v.get('autopilot') or '?'} | {v['reached']} | {_fmt(v['time_to_goal_s'])} | "
            f"{_fmt(v['final_error_m'])} | "
            f"{_fmt(v['min_separation_m'])} | {_fmt(v['min_obstacle_clearance_m'])} | "
            f"{_fmt(v.get('relative_angle_deg'))} ({_fmt(v.get('relative_angle_desired_deg'))}) | "
            f"{v['crashed']} |"
        )
    cruise = report.get("cruise")
    if cruise:
        lines += [
            "",
            f"Cruise {cruise['window_s'][0]}-{cruise['window_s'][1]} s after the formation start: "
            "median speeds "
            f"{', '.join(_fmt(s) for s in cruise['speed_median_m_s'])} m/s; neighbour spacing "
            f"{', '.join(_fmt(s) for s in cruise['spacing_median_m'])} m (slots "
            f"{', '.join(_fmt(s) for s in cruise['spacing_desired_m'])} m, worst error "
            f"{_fmt(cruise['spacing_max_abs_error_m'])} m, all within 1 m "
            f"{_fmt(cruise['spacing_within_1m_fraction'])} of the time).",
        ]
    link_use = report.get("link_use") or {}
    lines += _table(
        "Link use, MAVLink bytes/s (framing and signature included) over the flight:",
        ["vehicle", "up mean", "up peak", "down mean", "down peak", "budget (up + down)", "over budget s"]
        + ["radio txbuf min %"],
        [
            [name]
            + [_fmt(use.get(k)) for k in ("up_mean_B_s", "up_peak_B_s", "down_mean_B_s", "down_peak_B_s")]
            + [_fmt(use.get("budget_B_s")), _fmt(use.get("over_budget_s"))]
            + [_fmt((use.get("radio_status") or {}).get("txbuf_min_pct"))]
            for name, use in link_use.items()
        ],
    )
    lines += _table(
        "Changes of the command mode in flight (docs/command-modes.md):",
        ["vehicle time s", "from", "to", "planned B/s up + down", "vehicle", "because its"],
        [
            [
                _fmt(c.get("t_s")),
                f"{c.get('from_mode')} {_fmt(c.get('from_hz'))} Hz",
                f"{c.get('to_mode')} {_fmt(c.get('to_hz'))} Hz",
                f"{_fmt(c.get('planned_up_B_s'))} + {_fmt(c.get('planned_down_B_s'))}",
                str(c.get("vehicle")),
                str(c.get("reason")),
            ]
            for c in report.get("command_mode_changes") or []
        ],
    )
    lines += _table(
        "Legs of the route, as the leader started them:",
        ["leg", "vehicle time s", "formation", "spacing m", "leader speed cap m/s"],
        [
            [f"{int(row['index']) + 1} ({row.get('name')})", _fmt(row.get("t_s")), str(row.get("shape"))]
            + [_fmt(row.get("spacing_m")), _fmt(row.get("speed_m_s"))]
            for row in report.get("legs") or []
        ],
    )
    lines += _table(
        "Changes of the formation's shape (guidance.reshape):",
        ["vehicle time s", "change", "shape", "spacing of the mission's"],
        [
            [_fmt(r.get("t_s")), str(r.get("change")), str(r.get("shape")), _fmt(r.get("scale"))]
            for r in report.get("reshapes") or []
        ],
    )
    lines += _table(
        "Legs flown round a gap too narrow for the formation (guidance.route_plan):",
        ["vehicle time s", "to waypoint", "via points (x, y) m"],
        [_detour_row(d) for d in report.get("detours") or []],
    )
    figures = report.get("figures")
    if figures is not None:
        lines += ["", "## Figures", ""]
        lines += [f"- [{f}]({f})" for f in figures] if figures else [f"- {NO_PLOT_NOTE}"]
    if report["lost"] or report["events"]:
        lines += ["", "## Events", ""] + [f"- {e}" for e in report["events"]]
    return "\n".join(lines) + "\n"


def _detour_row(detour: Any) -> list[str]:
    """A flight.json detours row (t_s, waypoint 0-based, via [[x, y, z], ...]) as report.md's cells: the
    time, the waypoint counted from 1, the via points as "(x, y), ..." to the metre; "-" for what a hand edit
    broke."""
    row: dict[str, Any] = detour if isinstance(detour, dict) else {}
    try:
        waypoint = str(int(row["waypoint"]) + 1)
    except (KeyError, TypeError, ValueError):
        waypoint = "-"
    try:
        via = ", ".join(f"({float(p[0]):.0f}, {float(p[1]):.0f})" for p in row["via"]) or "-"
    except (KeyError, TypeError, ValueError, IndexError):
        via = "-"
    return [_fmt(row.get("t_s")), waypoint, via]


NO_PLOT_NOTE = (
    "no figures: matplotlib is not installed (pip install 'swarm-gcs[plot]'), or figures were switched off "
    "(Monte Carlo runs); `gcs-swarm report RUN_DIR` draws them"
)


def write_report(run_dir: Path, mission: Any) -> dict[str, Any]:
    """(Re)build report.json and report.md of a run folder, and its figures (report.png and the paper-style
    fig_*.png, gcs_swarm.evaluation.figures) when matplotlib is installed; returns the report."""
    flight = json.loads((run_dir / FLIGHT_FILE).read_text())
    traj = load_trajectories(run_dir, mission)
    commands = load_commands(run_dir / RECORD_FILE, len(mission.vehicles))
    report = report_from(traj, commands, mission, flight)
    written = figures.write_run_figures(run_dir, mission, flight, traj, commands)
    report["figures"] = [p.name for p in written]
    (run_dir / "report.json").write_text(json.dumps(report, indent=2) + "\n")
    (run_dir / "report.md").write_text(render_markdown(report))
    return report
