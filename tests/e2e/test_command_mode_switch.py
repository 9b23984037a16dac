"""The in-flight change of command mode (issue 38 item 3, docs/command-modes.md "In flight"), end to end: the
quickstart behind the simulator's SiK radio at 250 kbit/s, which carries the paper's 50 Hz attitude targets
(6934 B/s of 250000 / 13.5 = 18519 B/s, within the 50 % margin), flown by the real `gcs-swarm run` in
lockstep; 20 simulated seconds after power-on, in formation flight, the radios drop to 80 kbit/s (5926 B/s:
less than attitude targets need, more than position targets at 10 Hz need, 1663 B/s). The downlink queues;
the ground station steps once to position targets at 10 Hz with the telemetry slowed, the targets carrying
on from the guidance's reference, and the formation reaches its goal."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.e2e.flights import SHORT_BOOT, derived_mission, fly

DROP_S = 20.0  # simulated s of the capacity drop (formation flight starts at about 12.5 s with SHORT_BOOT)
D_EMG_M = 3.0  # the quickstart's safety.separation.d_emg
JUMP_M = 0.5  # m in one 20 ms tick: 25 m/s, faster than the quickstart's references move (under 20 m/s),
# while a reference set elsewhere moves metres at once


@pytest.mark.parametrize("persona", ["ardupilot", "px4"])
def test_a_capacity_drop_in_flight_switches_to_position_targets_once_and_the_formation_reaches(
    tmp_path: Path, persona: str
) -> None:
    """Both simulated autopilots: ArduCopter in GUIDED, PX4 in OFFBOARD (which takes both setpoint types; its
    unasked default streams are stopped with the step)."""
    mission = derived_mission(tmp_path, "quickstart.yaml", "drop", world={"link": {"radio": "sik250"}})
    data = yaml.safe_load(mission.read_text())
    data["run"]["simulator"]["autopilot"] = persona
    mission.write_text(yaml.safe_dump(data, sort_keys=False))
    extra = ["--time-mode", "lockstep", SHORT_BOOT, f"--sim-arg=--link-capacity-change={DROP_S:g}:80000"]
    run = fly(mission, tmp_path / "run", timeout_s=600, extra=extra)
    assert "Traceback" not in run.output, run.output[-3000:]
    assert run.status == 0, run.output[-3000:]
    report = run.report
    assert report["reached"] and report["collisions"] == 0, report
    assert report["min_separation_m"] >= D_EMG_M
    assert report["safety_events"] == [] and report["lost"] == []
    flight = json.loads((run.run_dir / "flight.json").read_text())
    assert flight["command_mode"]["mode"] == "attitude"  # the choice before take-off
    assert flight["t_formation_start"] < DROP_S
    changes = [e for e in flight["events"] if re.match(r"t=[\d.]+ s command mode: ", e)]
    assert len(changes) == 1, changes  # once: no step further down, none back up
    t_switch = float(changes[0].split()[0][2:])
    assert t_switch > DROP_S
    head = "command mode: position targets at 10 Hz (1663 B/s), telemetry at 10 Hz, instead of attitude"
    assert head in changes[0] and "because" in changes[0]
    assert "position targets 10 Hz" in run.output  # the progress line
    # the step as data (flight.json command_mode_changes, report.json, report.md): the event's time, the
    # bytes of position targets at 10 Hz (671 up + 992 down, by hand in test_command_mode_watch.py's doc)
    (row,) = flight["command_mode_changes"]
    assert abs(row["t_s"] - t_switch) < 0.01  # the event's t is printed to 2 decimals
    assert (row["from_mode"], row["from_hz"], row["to_mode"], row["to_hz"]) == (
        "attitude",
        50.0,
        "position",
        10.0,
    )
    assert (row["planned_up_B_s"], row["planned_down_B_s"]) == (671.0, 992.0)
    assert f"because {row['vehicle']}'s {row['reason']} for 2 s" in changes[0]
    assert report["command_mode_changes"] == [row]
    assert "Changes of the command mode in flight" in (run.run_dir / "report.md").read_text()
    # the simulator's radios carried the drop: something waited or was dropped on the air after it
    log = (run.run_dir / "simulator.log").read_text()
    assert max(float(x) for x in re.findall(r"radio_down_delay_max_ms=([\d.]+)", log)) > 100.0
    # no jump in any vehicle's reference across the switch (the position targets are that reference)
    with (run.run_dir / "record.csv").open() as fh:
        rows = [r for r in csv.DictReader(fh) if r["phase"] == "formation"]
    for vehicle in {r["vehicle"] for r in rows}:
        mine = [r for r in rows if r["vehicle"] == vehicle]
        t = np.array([float(r["t"]) for r in mine])
        ref = np.array([[float(r[k]) for k in ("ref_x", "ref_y", "ref_z")] for r in mine])
        near = (t[1:] > t_switch - 0.5) & (t[1:] < t_switch + 0.5)
        steps = np.linalg.norm(np.diff(ref, axis=0), axis=1)[near]
        assert steps.size > 0 and steps.max() < JUMP_M, (vehicle, steps.max())
