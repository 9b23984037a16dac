"""Text rendering of a Snapshot: the fleet table, the mission line, event lines and `status` details.

Every renderer returns lines as lists of (style, text) fragments, prompt_toolkit's formatted-text form;
`plain()` joins a line's text for the plain (non-terminal) mode. Style names are prompt_toolkit classes
("class:stale", "class:emergency", ...) that `app.STYLE` colours; plain mode prints the same words.
"""

from __future__ import annotations

import math

from gcs_swarm.console.session import ConsoleEvent
from gcs_swarm.console.snapshot import MissionLine, Snapshot, VehicleRow
from gcs_swarm.flight.phase import Phase

Fragment = tuple[str, str]
Line = list[Fragment]

WARNING_STYLE = {
    "LOST": "class:crashed",
    "CRASHED": "class:crashed",
    "FAILSAFE": "class:failsafe",
    "EMERGENCY": "class:emergency",
    "STALE": "class:stale",
    "TAKEN": "class:failsafe",  # taken over by another controller: the formation does not fly it
}
LEVEL_STYLE = {"info": "", "warning": "class:warning", "error": "class:error"}
_COLUMNS = (  # header, width (right-aligned unless the header starts with "<")
    ("<name", 0),
    ("sysid", 5),
    ("age s", 6),
    ("loss", 5),
    ("rtt ms", 6),
    ("<mode", 10),
    ("<armed", 6),
    ("alt m", 6),
    ("m/s", 5),
    ("slot m", 7),
    ("obst m", 7),
    ("near m", 7),
    ("up B/s", 7),
    ("dn B/s", 7),
    ("budget", 7),
    ("<warnings", 0),
)


def plain(line: Line) -> str:
    return "".join(text for _, text in line).rstrip()


def fleet_table(snapshot: Snapshot) -> list[Line]:
    """Header line and one line per vehicle."""
    name_width = max([4, *(len(r.name) for r in snapshot.rows)])
    header: Line = [("class:header", _cells([h.lstrip("<") for h, _ in _COLUMNS], name_width))]
    return [header, *(_vehicle_line(row, name_width, snapshot.mission.phase) for row in snapshot.rows)]


def _cells(values: list[str], name_width: int) -> str:
    out = []
    for (header, width), value in zip(_COLUMNS, values, strict=True):
        w = name_width if header == "<name" else width
        out.append(value.ljust(w) if header.startswith("<") else value.rjust(w))
    return " ".join(out)


def _vehicle_line(row: VehicleRow, name_width: int, phase: Phase) -> Line:
    leader_slot = "lead" if row.slot_error is None and phase.in_formation else None
    values = [
        row.name,
        "-" if row.sysid is None else str(row.sysid),
        _num(row.age_s, 1) if math.isfinite(row.age_s) else "-",
        "-" if row.loss is None else f"{100 * row.loss:.0f}%",
        _num(row.rtt_ms, 1) if math.isfinite(row.rtt_ms) else "-",
        row.mode,
        "ARMED" if row.armed else "-",
        _num(row.altitude, 1),
        _num(row.speed, 1),
        leader_slot or _num(row.slot_error, 2),
        _num(row.obstacle, 1),
        _num(row.neighbour, 1),
        _num(row.up_B_s, 0),
        _num(row.down_B_s, 0),
        _num(row.budget_B_s, 0),
        "",
    ]
    base = "class:stale" if ("STALE" in row.warnings or "LOST" in row.warnings) else ""
    line: Line = [(base, _cells(values, name_width))]
    for word in row.warnings:
        line += [("", " "), (WARNING_STYLE[word], word)]
    if row.over_budget:  # the link carries more than its budget (docs/mission-schema.md link.budget_bps)
        line += [("", " "), ("class:failsafe", "OVER BUDGET")]
    return line


def _num(value: float | None, digits: int) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def mission_line(snapshot: Snapshot) -> Line:
    """phase, the command in progress (with its wall seconds), vehicle time, leader's distance to goal,
    formation RMS, minimum separation so far."""
    m: MissionLine = snapshot.mission
    if snapshot.state == "connecting":
        return [("class:warning", "connecting to the vehicles ...")]
    if snapshot.state == "failed":
        return [("class:error", f"session failed: {snapshot.error}")]
    phase = m.phase if m.started or m.phase is not Phase.CONNECT else "ready"
    goal = ", ".join(f"{c:g}" for c in m.goal)
    line: Line = [("class:phase", f"phase {phase}")]
    if m.busy:  # early in the line, so a narrow terminal does not cut it off
        line.append(("class:warning", f"  [busy {m.busy_s:.1f} s: {m.busy}]"))
    line += [
        ("", f"  t {m.vehicle_time:.1f} s  leader to goal {_num(m.leader_goal_distance, 1)} m ({goal})"),
        ("", f"  formation rms {_num(m.formation_rms, 2)} m  min separation {_num(m.min_separation, 2)} m"),
    ]
    if snapshot.state == "stopped":
        line.append(("class:error", "  [flight session stopped]"))
    return line


def event_line(event: ConsoleEvent) -> Line:
    """`[  12.34] source: text`, styled by level."""
    prefix = "error: " if event.level == "error" else ""
    return [
        ("class:time", f"[{event.time_s:8.2f}] "),
        (LEVEL_STYLE[event.level], f"{event.source}: {prefix}{event.text}"),
    ]


def status_lines(snapshot: Snapshot) -> list[str]:
    """`status`: the mission line, then each vehicle's position, speed, mode and link in full."""
    lines = [plain(mission_line(snapshot))]
    for r in snapshot.rows:
        x, y, z = (_num(c, 1) for c in r.position)
        loss = "-" if r.loss is None else f"{100 * r.loss:.0f}%"
        flags = " ".join(r.warnings) or "ok"
        lines.append(
            f"{r.name} (sysid {r.sysid if r.sysid is not None else '-'}): {r.mode} "
            f"{'armed' if r.armed else 'disarmed'}{', airborne' if r.airborne else ''}, "
            f"at ({x}, {y}, {z}) m, {_num(r.speed, 1)} m/s, last packet {_num(r.age_s, 1)} s ago, "
            f"position loss {loss}, link {_num(r.up_B_s, 0)} B/s up {_num(r.down_B_s, 0)} B/s down "
            f"(budget {_num(r.budget_B_s, 0)} B/s): {flags}"
        )
    return lines
