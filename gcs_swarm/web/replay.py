"""A recorded run folder (truth.csv or record.csv, flight.json, the mission) as the page's messages
(messages.py): the scene once, then the frame of any sample. Every way a run folder can be unreadable is one
`RunFolderError` sentence.

Positions come from the simulator's ground truth (truth.csv) when the run has it, else from the ground
station's record (record.csv); slots and the flight phase from the record (formation ticks only), the leader
from flight.json's formation timeline, events from flight.json. Times are vehicle time, s since the vehicles
booted: the clock of truth.csv, record.csv and flight.json alike.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm.evaluation.run_data import by_vehicle, read_columns
from gcs_swarm.flight.run_folder import FLIGHT_FILE, RECORD_FILE, TRUTH_FILE
from gcs_swarm.link.autopilots import dialect_named
from gcs_swarm.mission import Mission, MissionError, load_mission
from gcs_swarm.web.messages import frame_message, scene_message, view_bounds

# an event's kind, by the first of these phrases its text holds (flight.json events are sentences)
_KINDS = (
    ("reshape", ("formation narrows", "formation restored", "formation widens", "formation re")),
    ("takeover", ("taken over", "handed to the operator", "rejoin")),
    ("lost", (" lost", "lost:")),
    ("safety", ("fence", "guard", "separation", "emergency", "held:", "failsafe")),
    ("link", ("link", "bytes/s", "budget")),
)
_TIMED = re.compile(r"^t=\s*(-?[0-9.]+) s\s+(.*)$", re.DOTALL)


class RunFolderError(Exception):
    """A run folder the replay cannot read; str(e) is one sentence naming the folder or file."""


def event_kind(text: str) -> str:
    """reshape | takeover | lost | safety | link | note: what an event sentence is about."""
    lower = text.lower()
    for kind, phrases in _KINDS:
        if any(p in lower for p in phrases):
            return kind
    return "note"


def event_entry(sentence: object) -> dict[str, Any]:
    """One event sentence of a flight (flight.json's `events`, FlightResult.events) as the page's
    {t (s or None), kind, text}: "t=54.38 s formation narrows: column" carries its time."""
    timed = _TIMED.match(str(sentence))
    t, text = (float(timed.group(1)), timed.group(2)) if timed else (None, str(sentence))
    return {"t": t, "kind": event_kind(text), "text": text}


def flight_events(flight: dict[str, Any], names: list[str]) -> list[dict[str, Any]]:
    """flight.json's events as {t (s or None), kind, text}, untimed ones first, then by time: its event
    sentences ("t=54.38 s formation narrows: column" carry their time), each lost vehicle (lost_at_s), each
    change of leader in the formation timeline."""
    events = [event_entry(sentence) for sentence in flight.get("events") or []]
    for name, t in (flight.get("lost_at_s") or {}).items():
        events.append({"t": float(t), "kind": "lost", "text": f"{name} lost"})
    leader = None
    for entry in flight.get("formation_timeline") or []:
        if leader is not None and entry["leader"] != leader and 0 <= entry["leader"] < len(names):
            events.append(
                {"t": float(entry["t"]), "kind": "leader", "text": f"{names[entry['leader']]} leads"}
            )
        leader = entry["leader"]
    return sorted(events, key=lambda e: (e["t"] is not None, e["t"] or 0.0))


@dataclass(frozen=True)
class Replay:
    """A run folder's samples. t (T,) s; pos (T, N, 3) m ENU; yaw (T, N) rad ENU; mode (T, N) ArduCopter
    custom_mode numbers as the truth log writes them (NaN: unknown); crashed (T, N) bool; tick_t (S,) s the
    record's formation ticks, slots (S, N, 2) m ENU, phases (S,) their flight phase; leader_t (L,) s and
    leaders (L,) the formation timeline; lost_at (N,) s (inf: never lost); events as flight_events."""

    mission: Mission
    source: str  # "truth" | "record"
    t: np.ndarray
    pos: np.ndarray
    yaw: np.ndarray
    mode: np.ndarray
    crashed: np.ndarray
    tick_t: np.ndarray
    slots: np.ndarray
    phases: tuple[str, ...]
    leader_t: np.ndarray
    leaders: np.ndarray
    lost_at: np.ndarray
    events: tuple[dict[str, Any], ...]

    @property
    def t_span(self) -> tuple[float, float]:
        return float(self.t[0]), float(self.t[-1])

    def index_at(self, t: float) -> int:
        """The last sample at or before t s (the first sample before the start)."""
        return max(int(np.searchsorted(self.t, t, side="right")) - 1, 0)

    @cached_property
    def _mode_names(self) -> dict[int, str]:
        dialect = dialect_named("ardupilot")  # the truth log's mode column is ArduCopter's custom_mode
        numbers = np.unique(self.mode[np.isfinite(self.mode)]).astype(int)
        return {int(m): dialect.mode_name(int(m)) for m in numbers}

    @cached_property
    def _moving_obstacles(self) -> bool:
        return any(np.any(o.velocity != 0) for o in self.mission.obstacles)

    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) m ENU around the tracks and the site (messages.view_bounds)."""
        return view_bounds(self.mission, self.pos[..., :2].reshape(-1, 2))

    def scene(self) -> dict[str, Any]:
        return scene_message(self.mission, list(self.events), self.t_span, self.bounds())

    def frame(self, k: int) -> dict[str, Any]:
        """The page's frame of sample k."""
        t = float(self.t[k])
        tick = int(np.searchsorted(self.tick_t, t, side="right")) - 1
        in_record = len(self.tick_t) > 0 and tick >= 0 and t <= self.tick_t[-1]
        n = self.pos.shape[1]
        slots = self.slots[tick] if in_record else np.full((n, 2), np.nan)
        turn = int(np.searchsorted(self.leader_t, t, side="right")) - 1
        leader = int(self.leaders[turn]) if turn >= 0 else self.mission.leader_index
        reshapes = [
            e["text"] for e in self.events if e["kind"] == "reshape" and e["t"] is not None and e["t"] <= t
        ]
        modes = [None if not np.isfinite(m) else self._mode_names[int(m)] for m in self.mode[k]]
        obstacles = (
            np.array([o.center_at(t)[:2] for o in self.mission.obstacles]) if self._moving_obstacles else None
        )
        return frame_message(
            t,
            self.pos[k],
            self.yaw[k],
            slots,
            modes,
            t >= self.lost_at,
            self.crashed[k],
            leader,
            self.phases[tick] if in_record else None,
            reshapes[-1] if reshapes else None,
            obstacles,
        )


def _read_json(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise RunFolderError(f"{path.parent}: not a run folder (no {path.name})") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RunFolderError(f"{path}: unreadable ({exc})") from None
    if not isinstance(data, dict):
        raise RunFolderError(f"{path}: not a flight record (expected a JSON object)")
    return data


def _mission(run_dir: Path, flight: dict[str, Any], mission_path: Path | None) -> Mission:
    """The mission given, else the one flight.json names."""
    path = mission_path or (Path(flight["mission_path"]) if flight.get("mission_path") else None)
    if path is None:
        raise RunFolderError(f"{run_dir / FLIGHT_FILE}: names no mission; give it with --mission")
    try:
        return load_mission(path, to_fly=False)
    except MissionError as exc:
        hint = "" if mission_path else " (give the mission with --mission)"
        raise RunFolderError(f"{exc}{hint}") from None


def _samples(path: Path, columns: list[str], n: int) -> tuple[np.ndarray, np.ndarray]:
    """t (T,) and (T, n, len(columns)) of a truth or record CSV; RunFolderError if it has no sample."""
    try:
        table = read_columns(path, ["t", "vehicle", *columns])
        t, values = by_vehicle(table, "vehicle", columns, n)
    except KeyError as exc:
        raise RunFolderError(f"{path}: not a run's CSV: {exc.args[0]}") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise RunFolderError(f"{path}: unreadable ({exc})") from None
    if len(t) == 0:
        raise RunFolderError(f"{path}: no samples in it")
    return t, values


def _record_ticks(path: Path, n: int) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The record's formation ticks: t (S,), slots (S, n, 2), the phase of each (empty without a record)."""
    if not path.exists() or path.stat().st_size == 0:
        return np.zeros(0), np.zeros((0, n, 2)), ()
    t, slots = _samples(path, ["slot_x", "slot_y"], n)
    phase_of: dict[float, str] = {}
    lines = path.read_text().splitlines()[1:]
    for line in lines:
        fields = line.split(",", 3)
        if len(fields) == 4:
            phase_of.setdefault(round(float(fields[0]), 3), fields[2])
    return t, slots, tuple(phase_of.get(round(float(tt), 3), "") for tt in t)


def load_replay(run_dir: Path, mission_path: Path | None = None) -> Replay:
    """Read a run folder; `mission_path` replaces the mission flight.json names (a moved run folder).
    RunFolderError on anything missing or unreadable."""
    if not run_dir.is_dir():
        raise RunFolderError(f"{run_dir}: no such run folder")
    flight = _read_json(run_dir / FLIGHT_FILE)
    mission = _mission(run_dir, flight, mission_path)
    names = [v.name for v in mission.vehicles]
    n = len(names)
    truth, record = run_dir / TRUTH_FILE, run_dir / RECORD_FILE
    if truth.exists() and truth.stat().st_size > 0:
        t, v = _samples(truth, ["x", "y", "z", "yaw", "mode", "crashed"], n)
        source = "truth"
    elif record.exists() and record.stat().st_size > 0:
        t, v = _samples(record, ["x", "y", "z", "yaw"], n)
        v = np.concatenate([v, np.full(v.shape[:2] + (2,), np.nan)], axis=2)
        source = "record"
    else:
        raise RunFolderError(f"{run_dir}: no {TRUTH_FILE} or {RECORD_FILE} with samples in it")
    try:
        tick_t, slots, phases = _record_ticks(record, n)
        timeline = flight.get("formation_timeline") or []
        leader_t = np.array([float(e["t"]) for e in timeline])
        leaders = np.array([int(e["leader"]) for e in timeline], dtype=int)
        lost = flight.get("lost_at_s") or {}
        lost_at = np.array([float(lost.get(name, np.inf)) for name in names])
        events = tuple(flight_events(flight, names))
    except RunFolderError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise RunFolderError(f"{run_dir / FLIGHT_FILE}: not as a flight writes it ({exc!r})") from None
    return Replay(
        mission=mission,
        source=source,
        t=t,
        pos=v[..., :3],
        yaw=v[..., 3],
        mode=v[..., 4],
        crashed=v[..., 5] > 0.5,
        tick_t=tick_t,
        slots=slots,
        phases=phases,
        leader_t=leader_t,
        leaders=leaders,
        lost_at=lost_at,
        events=events,
    )
