"""A report that never crashes (issue 38 item 4): `report_from` (and `write_report` with its figures) over run
folders drawn by hypothesis, in which vehicles are taken over, lost, held, silent or crashed at any moment:
truth.csv, record.csv and flight.json as `gcs-swarm run` writes them, with zero rows for a vehicle, no rows at
all, no truth log, and runs that never reached the formation phase. Every figure is a number or None (NaN
becomes None; report.json is strict JSON), report.md renders, and report.png is drawn."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_swarm.evaluation.report import render_markdown, report_from, write_report
from gcs_swarm.evaluation.run_data import load_commands, load_trajectories
from gcs_swarm.flight.run_record import COLUMNS
from gcs_swarm.mission import Mission, parse_mission
from gcs_swarm.mission.geometry import mission_offsets
from tests.gcs_swarm.evaluation.conftest import ROOT, TRUTH_COLUMNS

DT = 0.1  # s between samples of the drawn truth and record
HEADING = math.atan2(120.0, 160.0)  # rad, the quickstart leg's course
SPEED = 5.0  # m/s
FATES = ("flies", "taken_over", "lost", "held", "silent", "crashed", "no_truth_rows", "no_record_rows")
EVENTS = (
    "t=3.10 s formation narrows: column",
    "t=4.00 s formation restored",
    "t=2.00 s left taken over: now in LOITER",
    "lost right at t=1.5 s",
    "interrupted by the operator",
    "t=1.20 s route: round a gap too narrow for the formation, through (40, 30), (60, 45) to waypoint 1",
)
# flight.json's reshapes rows of the EVENTS that are changes of shape
RESHAPES = {
    EVENTS[0]: {"t_s": 3.1, "change": "narrows", "shape": "column", "scale": 0.5},
    EVENTS[1]: {"t_s": 4.0, "change": "restored", "shape": "formation", "scale": 1.0},
}
# flight.json's detours rows of the EVENTS that are legs round a gap, and one a hand edit broke
DETOURS = {
    EVENTS[5]: [
        {"t_s": 1.2, "waypoint": 0, "via": [[40.0, 30.0, 10.0], [60.0, 45.0, 10.0]]},
        {"t_s": 1.3, "waypoint": "first", "via": "round the trees"},
    ],
}
OPTIONAL_FLIGHT_KEYS = (
    "leader",
    "t_formation_end",
    "final_targets",
    "lost",
    "events",
    "reshapes",
    "detours",
    "taken_over",
    "left_to_operator",
    "formation_timeline",
    "autopilots",
    "wall_duration_s",
    "commands_limited",
    "command_mode_changes",
)
# flight.json command_mode_changes of a run whose fleet stepped down once (link.command_mode.change_row)
CHANGES = [
    {
        "t_s": 2.5,
        "from_mode": "attitude",
        "from_hz": 50.0,
        "to_mode": "position",
        "to_hz": 10.0,
        "vehicle": "uav1",
        "reason": "telemetry was 0.35 s old (positions at 40 of 50 Hz)",
        "planned_up_B_s": 671.0,
        "planned_down_B_s": 992.0,
    }
]


@cache
def mission_of(n: int) -> Mission:
    """The quickstart with its first n vehicles (a fourth one behind the V when n = 4)."""
    data = yaml.safe_load((ROOT / "missions" / "quickstart.yaml").read_text())
    tail = {"name": "tail", "sysid": 4, "start": {"position": [-20, -5, 0], "yaw_deg": 37}}
    data["vehicles"] = (data["vehicles"] + [tail])[:n]
    data["vehicles"][0]["role"] = "leader"
    return parse_mission(yaml.safe_dump(data), f"quickstart_{n}.yaml")


@dataclass(frozen=True)
class Fate:
    """What happens to one vehicle: `kind` (FATES) from sample fraction `at` of the flight (until `until`
    for "silent")."""

    kind: str
    at: float
    until: float


@dataclass(frozen=True)
class RunStory:
    """A drawn run: n vehicles, `samples` truth samples DT apart, the formation phase from sample `start`
    (None: never reached) to `end`, each vehicle's fate, and what flight.json and the folder hold."""

    n: int
    samples: int
    start: int | None
    end: int
    fates: tuple[Fate, ...]
    leader: int
    arrived: bool
    with_truth: bool
    with_record: bool
    clock0: float
    dropped_keys: frozenset[str]
    events: tuple[str, ...]


@st.composite
def run_stories(draw: st.DrawFn) -> RunStory:
    n = draw(st.integers(1, 4))
    samples = draw(st.integers(0, 90))
    start = draw(st.none() | st.integers(0, max(0, samples - 1)))
    end = draw(st.integers(start or 0, samples)) if start is not None else samples
    fraction = st.floats(0.0, 1.0)
    fates = tuple(Fate(draw(st.sampled_from(FATES)), draw(fraction), draw(fraction)) for _ in range(n))
    return RunStory(
        n=n,
        samples=samples,
        start=start,
        end=end,
        fates=fates,
        leader=draw(st.integers(0, n - 1)),
        arrived=draw(st.booleans()),
        with_truth=draw(st.booleans()) or samples == 0,
        with_record=draw(st.booleans()),
        clock0=draw(st.sampled_from((0.0, 300.0))),
        dropped_keys=frozenset(draw(st.sets(st.sampled_from(OPTIONAL_FLIGHT_KEYS)))),
        events=tuple(draw(st.lists(st.sampled_from(EVENTS), max_size=3))),
    )


def _write_csv(path: Path, header: list[str], rows: list[dict[str, Any]]) -> None:
    with path.open("w") as f:
        f.write(",".join(header) + "\n")
        f.writelines(",".join(str(row.get(c, 0)) for c in header) + "\n" for row in rows)


def write_story(run_dir: Path, story: RunStory) -> dict[str, Any]:
    """Write the story's run folder; returns what the test knows independently of the report: the set of
    crashed vehicle indices (a truth row with crashed=1 was written), the names lost and taken over, and
    the indices of vehicles with no finite command in the record."""
    mission = mission_of(story.n)
    names = [v.name for v in mission.vehicles]
    offsets = mission_offsets(mission)
    run_dir.mkdir(parents=True)
    k = np.arange(story.samples)
    t = story.clock0 + k * DT
    direction = np.array([math.cos(HEADING), math.sin(HEADING), 0.0])
    c, s = math.cos(HEADING), math.sin(HEADING)
    rotation = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    lead_path = np.array([0.0, 0.0, 10.0]) + (k * DT * SPEED)[:, None] * direction  # (T, 3)
    pos = lead_path[:, None, :] + (offsets @ rotation.T)[None, :, :]  # (T, N, 3), each in its slot
    vel = np.broadcast_to(direction * SPEED, pos.shape).copy()
    crashed = np.zeros((story.samples, story.n), dtype=bool)
    truth_kept = np.ones((story.samples, story.n), dtype=bool)
    record_nan = np.zeros((story.samples, story.n), dtype=bool)  # telemetry gone
    command_nan = np.zeros((story.samples, story.n), dtype=bool)  # not commanded
    lost, taken = [], []
    for i, fate in enumerate(story.fates):
        at = int(fate.at * story.samples)
        later = k >= at
        if fate.kind in ("taken_over", "held", "lost"):
            pos[later, i] = pos[min(at, story.samples - 1), i] if story.samples else 0.0
            vel[later, i] = 0.0
        if fate.kind == "taken_over":
            command_nan[later, i] = True
            taken.append({"t_s": story.clock0 + at * DT, "vehicle": names[i], "mode": "LOITER"})
        elif fate.kind == "lost":
            command_nan[later, i] = record_nan[later, i] = True
            lost.append(names[i])
        elif fate.kind == "silent":
            quiet = (k >= at) & (k < int(fate.until * story.samples))
            truth_kept[quiet, i] = False
            record_nan[quiet, i] = command_nan[quiet, i] = True
        elif fate.kind == "crashed":
            crashed[later, i] = True
            pos[later, i, 2] = 0.0
        elif fate.kind == "no_truth_rows":
            truth_kept[:, i] = False
        elif fate.kind == "no_record_rows":
            record_nan[:, i] = command_nan[:, i] = True
    if story.with_truth:
        rows = [
            {"t": f"{t[j]:.4f}", "vehicle": i, "sysid": i + 1, "x": pos[j, i, 0], "y": pos[j, i, 1]}
            | {"z": pos[j, i, 2], "vx": vel[j, i, 0], "vy": vel[j, i, 1], "vz": vel[j, i, 2]}
            | {"qw": 1, "crashed": int(crashed[j, i])}
            for j in range(story.samples)
            for i in range(story.n)
            if truth_kept[j, i]
        ]
        _write_csv(run_dir / "truth.csv", TRUTH_COLUMNS, rows)
        (run_dir / "truth.obstacles.csv").write_text("t,obstacle,x,y,z,radius\n")
    formation = range(story.start, story.end) if story.start is not None else range(0)
    pitch = 0.1 * np.sin(k * DT)
    rows = []  # the ground station always writes record.csv: without a record only its header
    if story.with_record:
        for j in formation:
            for i in range(story.n):
                if story.fates[i].kind == "no_record_rows":
                    continue  # zero rows for this vehicle
                telemetry = dict(zip(("x", "y", "z"), pos[j, i], strict=True))
                if record_nan[j, i]:
                    telemetry = dict.fromkeys(("x", "y", "z", "vx", "vy", "vz"), "nan")
                command = {"roll_d": 0.0, "pitch_d": pitch[j], "yaw_d": HEADING}
                if command_nan[j, i]:
                    command = dict.fromkeys(command, "nan")
                rows.append(
                    {"t": f"{t[j]:.6g}", "vehicle": i, "phase": "formation", "psi_l": HEADING}
                    | telemetry
                    | command
                )
    _write_csv(run_dir / "record.csv", list(COLUMNS), rows)
    t_start = None if story.start is None else story.clock0 + story.start * DT
    flight: dict[str, Any] = {
        "mission": mission.name,
        "mission_path": str(mission.path),
        "arrived": story.arrived,
        "t_formation_start": t_start,
        "t_formation_end": None if story.start is None else story.clock0 + story.end * DT,
        "final_targets": (lead_path[-1] + offsets @ rotation.T).tolist() if story.samples else None,
        "leader": story.leader,
        "offsets": offsets.tolist(),
        "lost": lost,
        "events": list(story.events),
        "reshapes": [RESHAPES[e] for e in story.events if e in RESHAPES],
        "detours": [row for e in story.events for row in DETOURS.get(e, [])],
        "taken_over": taken,
        "left_to_operator": [entry["vehicle"] for entry in taken],
        "formation_timeline": [
            {"t": t_start or story.clock0, "leader": story.leader, "offsets": offsets.tolist()},
            {
                "t": (t_start or story.clock0) + 1.0,
                "leader": story.leader,
                "offsets": [
                    None if name in lost else o for name, o in zip(names, offsets.tolist(), strict=True)
                ],
            },
        ],
        "autopilots": dict.fromkeys(names, "ardupilot"),
        "wall_duration_s": 1.0,
        "commands_limited": 0,
        "command_mode_changes": CHANGES,
    }
    for key in story.dropped_keys:
        flight.pop(key)
    (run_dir / "flight.json").write_text(json.dumps(flight))
    in_record = np.zeros((story.samples, story.n), dtype=bool)
    if story.with_record:
        in_record[list(formation)] = True
    uncommanded = {i for i in range(story.n) if not (in_record[:, i] & ~command_nan[:, i]).any()}
    truth_crashed = {i for i in range(story.n) if (crashed[:, i] & truth_kept[:, i]).any()}
    return {
        "names": names,
        "crashed": truth_crashed if story.with_truth else set(),
        "lost": [] if "lost" in story.dropped_keys else lost,
        "taken": [] if "taken_over" in story.dropped_keys else taken,
        "changes": [] if "command_mode_changes" in story.dropped_keys else CHANGES,
        "uncommanded": uncommanded,
    }


def _check(report: dict[str, Any], story: RunStory, known: dict[str, Any]) -> None:
    json.dumps(report, allow_nan=False)  # every figure finite or None: strict JSON
    assert [v["name"] for v in report["vehicles"]] == known["names"]
    # collisions: the vehicles a truth row showed crashed (none without a truth log: telemetry can't say)
    assert report["collisions"] == len(known["crashed"])
    assert {v["name"] for v in report["vehicles"] if v["crashed"]} == {
        known["names"][i] for i in known["crashed"]
    }
    assert report["lost"] == known["lost"] and report["taken_over"] == known["taken"]
    if report["reached"]:  # reached needs an arrival, no crash and every vehicle within tolerance
        assert story.arrived and not known["crashed"] and all(v["reached"] for v in report["vehicles"])
    if report["command_rates"] is not None:
        for i in known["uncommanded"]:  # never commanded: no rate figure can exist
            entry = report["command_rates"]["vehicles"][i]
            assert all(value is None for axis in ("pitch_rate", "yaw_rate") for value in entry[axis].values())
    assert report["command_mode_changes"] == known["changes"]
    text = render_markdown(report)
    assert all(name in text for name in known["names"])
    # the change's row in report.md, or no table without one
    row = "| 2.50 | attitude 50.00 Hz | position 10.00 Hz | 671.00 + 992.00 | uav1 | telemetry was 0.35 s old"
    assert (row in text) == bool(known["changes"])


SETTINGS = settings(
    max_examples=150, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow]
)


@SETTINGS
@given(story=run_stories())
def test_report_from_any_run_data(story: RunStory, tmp_path_factory: pytest.TempPathFactory) -> None:
    run_dir = tmp_path_factory.mktemp("story") / "run"
    known = write_story(run_dir, story)
    mission = mission_of(story.n)
    flight = json.loads((run_dir / "flight.json").read_text())
    traj = load_trajectories(run_dir, mission)
    assert traj.pos.shape[1:] == (story.n, 3)  # every mission vehicle has its column, rows or not
    commands = load_commands(run_dir / "record.csv", story.n)
    _check(report_from(traj, commands, mission, flight), story, known)


@settings(max_examples=10, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(story=run_stories())
def test_write_report_draws_its_figures_for_any_run_data(
    story: RunStory, tmp_path_factory: pytest.TempPathFactory
) -> None:
    pytest.importorskip("matplotlib")
    run_dir = tmp_path_factory.mktemp("story") / "run"
    known = write_story(run_dir, story)
    report = write_report(run_dir, mission_of(story.n))
    _check(report, story, known)
    assert json.loads((run_dir / "report.json").read_text()) == report
    assert (run_dir / "report.md").stat().st_size > 0
    assert "report.png" in report["figures"] and (run_dir / "report.png").stat().st_size > 0
