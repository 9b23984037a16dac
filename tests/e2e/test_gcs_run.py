"""`gcs-swarm run` end to end: the real ground station flies the real simulator in lockstep over UDP."""

from __future__ import annotations

import json
from pathlib import Path

import yaml
from pymavlink import mavutil

from gcs_swarm.cli import main
from tests.e2e.flights import MISSIONS, derived_mission, fly, static6_short

REPORT_KEYS = {
    "reached",
    "time_to_goal_s",
    "collisions",
    "min_separation_m",
    "min_obstacle_clearance_m",
    "formation_rms_m",
    "oscillation_time_s",
    "settling_time_s",
    "sim_duration_s",
    "wall_duration_s",
    "vehicles",
    "source",
}


def _figures(report: dict) -> dict:
    """The report without the wall-clock figures, which legitimately differ between runs: the wall duration
    and the link use (the ground station's wall-clock heartbeats count in it)."""
    return {k: v for k, v in report.items() if k not in ("wall_duration_s", "link_use")}


def _flies_smoothly(report: dict) -> None:
    """The flight-quality targets of the whole formation flight (docs/metrics.md, "Whole-flight figures"),
    formation start to arrival, from the simulator's truth and the commands sent: no cusp, followers within
    3 m rms and 10 m of their slots, commanded tilt rates within 3 rad/s and no yaw-rate step above 0.1 rad/s
    a tick, never closer than D_Emg (3 m) nor below the 2 m floor, nor more than 2 m below the formation
    altitude (10 m) while avoiding, and no safety event."""
    whole = report["whole_flight"]
    assert whole["cusps_total"] == 0, whole
    assert whole["slot_error_rms_m"] <= 3.0 and whole["slot_error_max_m"] <= 10.0, whole
    assert whole["max_tilt_command_rate_rad_s"] <= 3.0 and whole["max_yaw_rate_step_rad_s"] <= 0.1, whole
    assert whole["min_separation_whole_flight_m"] >= 3.0 and whole["time_below_d_emg_s"] == 0.0, whole
    assert whole["min_altitude_in_formation_m"] >= 2.0, whole
    assert whole["max_drop_below_formation_altitude_m"] <= 2.0, whole
    assert report["safety_events"] == []


def test_quickstart_reaches_goal_and_repeats_exactly(quickstart: Path, tmp_path: Path) -> None:
    first = fly(quickstart, tmp_path / "first")
    assert first.status == 0, first.output[-3000:]
    report = first.report
    assert REPORT_KEYS <= report.keys()
    assert report["source"] == "truth"
    assert report["reached"] is True
    assert report["collisions"] == 0
    assert report["min_separation_m"] > 3.0  # D_Emg of the mission
    assert report["min_obstacle_clearance_m"] > 0.175
    assert report["formation_rms_m"] < 1.5
    assert 5.0 < report["time_to_goal_s"] < 60.0
    assert all(v["reached"] for v in report["vehicles"])
    _flies_smoothly(report)
    for name in ("truth.csv", "record.csv", "report.md", "telemetry.tlog"):
        assert (first.run_dir / name).stat().st_size > 0, name
    simulator_log = (first.run_dir / "simulator.log").read_text()
    assert "Traceback" not in simulator_log and "Fatal Python error" not in simulator_log  # a clean exit
    # The telemetry log is a standard tlog that pymavlink reads back.
    log = mavutil.mavlink_connection(str(first.run_dir / "telemetry.tlog"))
    types = set()
    while (msg := log.recv_match()) is not None:
        types.add(msg.get_type())
    assert {"HEARTBEAT", "GLOBAL_POSITION_INT", "SET_ATTITUDE_TARGET"} <= types

    # flight.json ties the run folder to its mission: `gcs-swarm report` rebuilds the same report.
    flight = json.loads((first.run_dir / "flight.json").read_text())
    assert flight["arrived"] is True and flight["ticks"] > 100
    (first.run_dir / "report.json").unlink()
    assert main(["report", str(first.run_dir)]) == 0
    assert _figures(first.report) == _figures(report)

    second = fly(quickstart, tmp_path / "second")
    assert second.status == 0, second.output[-3000:]
    assert _figures(second.report) == _figures(report)
    assert (second.run_dir / "truth.csv").read_bytes() == (first.run_dir / "truth.csv").read_bytes()


def test_six_uav_static_paper_scenario_shortened(tmp_path: Path) -> None:
    """Section 5.2.1, shortened (conftest.static6_short)."""
    mission = static6_short(tmp_path, "static6_short")
    outcome = fly(mission, tmp_path / "run", timeout_s=500)
    assert outcome.status == 0, outcome.output[-3000:]
    report = outcome.report
    assert report["reached"] and report["collisions"] == 0
    assert report["min_separation_m"] > 10.0  # D_max: no pair ever inside the safe distance
    assert report["min_obstacle_clearance_m"] > 0.175


def test_bad_mission_is_refused_with_its_sentence(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("vehicles:\n  - {name: a, role: leader, start: {position: [0, 0, 0]}}\ngoal: [10, 10]\n")
    outcome = fly(bad, tmp_path / "run", timeout_s=60)
    assert outcome.status == 2
    line = next(ln for ln in outcome.output.splitlines() if ln.startswith("error:"))
    assert "bad.yaml:3" in line and "goal" in line
    assert "Traceback" not in outcome.output
    assert not (tmp_path / "run" / "report.json").exists()


def test_v_of_four_started_on_the_wrong_sides_assembles_without_crossing(tmp_path: Path) -> None:
    """Issue 13's V of four: the first two followers stand at each other's slots (slots go in vehicle order,
    the first follower's on the right). Least-travel slot assignment gives each the slot it stands at, so
    nobody crosses: the whole flight keeps the same targets as the quickstart."""
    data = yaml.safe_load((MISSIONS / "quickstart.yaml").read_text())
    vehicles = data["vehicles"]
    for v in vehicles:
        v.pop("connection", None)
        v.pop("sysid", None)
    vehicles[1].update(name="f1", start={"position": [-10, 1.5, 0], "yaw_deg": 37})  # at the left slot
    vehicles[2].update(name="f2", start={"position": [-1.5, -10, 0], "yaw_deg": 37})  # at the right slot
    vehicles.append({"name": "f3", "start": {"position": [-3, -20, 0], "yaw_deg": 37}})  # second right
    mission = derived_mission(tmp_path, "quickstart.yaml", "v4_swapped", vehicles=vehicles)
    run = fly(mission, tmp_path / "run")
    assert run.status == 0, run.output[-3000:]
    report = run.report
    assert report["reached"] and report["collisions"] == 0
    _flies_smoothly(report)


def test_a_v_on_a_low_tilt_limit_assembles_outside_the_emergency_range(tmp_path: Path) -> None:
    """px4_sitl_3's route in the embedded simulator with a 15 deg tilt limit. The closing-speed cap used to
    assume 2 m/s^2 of braking, more than a 15 deg tilt leaves once drag and the jerk ramp are paid: while the
    V assembled from the line start, a follower passed 1.34 m from the leader (D_Emg 3 m). Bounded by 0.3 x
    g tan 15 deg = 0.79 m/s^2 (safety.separation.closing_brake_tilt_share) it keeps 4.5 m."""
    data = yaml.safe_load((MISSIONS / "px4_sitl_3.yaml").read_text())
    vehicles = data["vehicles"]
    for v in vehicles:
        for key in ("connection", "sysid", "autopilot"):
            v.pop(key)
    mission = derived_mission(
        tmp_path, "px4_sitl_3.yaml", "v3_low_tilt", vehicles=vehicles, limits={"tilt_max_deg": 15.0},
        run={"simulator": {"embedded": True}, "time_limit_s": 120},
    )  # fmt: skip
    run = fly(mission, tmp_path / "run")
    assert run.status == 0, run.output[-3000:]
    report = run.report
    assert report["reached"] and report["collisions"] == 0
    assert not report["safety_events"], report["safety_events"]
    assert report["whole_flight"]["min_separation_whole_flight_m"] > 3.0
