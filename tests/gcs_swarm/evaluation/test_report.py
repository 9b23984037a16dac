"""`write_report` on a synthetic run folder: spec-10 figures plus the command-rate and relative-angle keys,
paper figures with matplotlib, text and JSON only without it; and the ground station's own counts that
flight.json carries into the report, e.g. how many vehicle-ticks' commands the final guard changed
(gcs_swarm.link.command_limits)."""

from __future__ import annotations

import builtins
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from gcs_swarm.cli import main
from gcs_swarm.evaluation.report import NO_PLOT_NOTE, render_markdown, report_from, write_report
from gcs_swarm.evaluation.run_data import Trajectories
from gcs_swarm.flight.fly import write_flight
from gcs_swarm.flight.result import FlightResult
from gcs_swarm.mission import Mission
from gcs_swarm.mission.geometry import mission_offsets

PAPER_FIGURES = [
    "report.png",
    "fig_trajectories.png",
    "fig_velocity_acceleration.png",
    "fig_distances.png",
    "fig_relative_angle.png",
    "fig_attitude_rates.png",
]


def _hide_matplotlib(monkeypatch: pytest.MonkeyPatch) -> None:
    real_import = builtins.__import__

    def fake_import(name: str, *args: Any, **kwargs: Any) -> Any:
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError(f"No module named {name!r}")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)


def test_report_without_matplotlib_is_text_and_json(
    run_folder: Path, quickstart_mission: Mission, monkeypatch: pytest.MonkeyPatch
) -> None:
    _hide_matplotlib(monkeypatch)
    report = write_report(run_folder, quickstart_mission)
    assert report["figures"] == []
    assert not list(run_folder.glob("*.png"))
    assert json.loads((run_folder / "report.json").read_text()) == report
    assert NO_PLOT_NOTE in (run_folder / "report.md").read_text()
    assert report["reached"] is True and report["collisions"] == 0
    # The followers sit in their slots: relative angles equal the slots' (+-135 deg for the V's first row).
    angles = {
        v["name"]: (v["relative_angle_deg"], v["relative_angle_desired_deg"]) for v in report["vehicles"]
    }
    assert angles["lead"] == (None, None)
    for name in ("right", "left"):
        assert angles[name][0] == pytest.approx(angles[name][1], abs=0.01)
        assert abs(angles[name][1]) == pytest.approx(135.0, abs=0.01)
    # Commanded pitch ramps 0.1 rad/s for 2 s, then holds: its rate settles at 2 s; yaw is constant.
    rates = report["command_rates"]["vehicles"][0]
    assert rates["pitch_rate"]["settling_s"] == pytest.approx(2.0, abs=0.05)
    assert rates["pitch_rate"]["peak"] == pytest.approx(0.1, abs=1e-3)
    assert rates["yaw_rate"]["peak"] == pytest.approx(0.0, abs=1e-9)
    assert report["command_rate_settling_s"] == pytest.approx(2.0, abs=0.05)
    cruise = report["cruise"]
    assert cruise["speed_median_m_s"] == pytest.approx([5.0, 5.0, 5.0], abs=1e-3)
    assert cruise["spacing_median_m"] == pytest.approx([10.0, 10.0], abs=1e-3)


def test_report_with_matplotlib_draws_the_paper_figures(
    run_folder: Path, quickstart_mission: Mission
) -> None:
    report = write_report(run_folder, quickstart_mission)
    assert report["figures"] == PAPER_FIGURES
    for name in PAPER_FIGURES:
        assert (run_folder / name).stat().st_size > 1000, name
        assert f"]({name})" in (run_folder / "report.md").read_text()


def test_report_command_rebuilds_and_refuses_a_folder_without_flight_json(
    run_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    _hide_matplotlib(monkeypatch)
    assert main(["report", str(run_folder)]) == 0
    assert "command_rate_settling_s" in capsys.readouterr().out
    assert main(["report", str(tmp_path / "nothing")]) == 2
    assert "not a run folder" in capsys.readouterr().out


def test_a_record_cut_mid_line_is_read_up_to_its_last_full_row(
    run_folder: Path, quickstart_mission: Mission, monkeypatch: pytest.MonkeyPatch
) -> None:
    _hide_matplotlib(monkeypatch)
    record = run_folder / "record.csv"
    text = record.read_text()
    record.write_text(text[: len(text) - 40])  # a killed writer leaves half a line
    report = write_report(run_folder, quickstart_mission)
    assert report["command_rates"] is not None


def test_durations_count_on_the_run_clock_whatever_the_boot_time(
    tmp_path: Path,
    quickstart_mission: Mission,
    make_run_folder: Callable[..., Path],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Vehicles that booted 300 s before the run (real ArduCopters): the same 30 s flight gives the same
    durations as one whose clock starts at 0."""
    _hide_matplotlib(monkeypatch)
    early = write_report(make_run_folder(tmp_path / "at0", quickstart_mission), quickstart_mission)
    late = write_report(make_run_folder(tmp_path / "at300", quickstart_mission, 300.0), quickstart_mission)
    assert early["sim_duration_s"] == pytest.approx(30.0, abs=0.03)
    assert late["sim_duration_s"] == pytest.approx(early["sim_duration_s"])
    assert late["time_to_goal_s"] == pytest.approx(early["time_to_goal_s"])
    assert late["settling_time_s"] == pytest.approx(early["settling_time_s"])
    assert late["whole_flight"]["window_s"][0] == pytest.approx(300.0)


def test_a_pass_inside_d_emg_is_a_safety_event(
    tmp_path: Path,
    quickstart_mission: Mission,
    make_run_folder: Callable[..., Path],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Vehicle 2 spends 1.5 s 2 m from the leader (D_Emg = 3 m): flagged at the top of report.md, in
    safety_events, and timed; the clean flight has none."""
    _hide_matplotlib(monkeypatch)
    clean = write_report(make_run_folder(tmp_path / "clean", quickstart_mission), quickstart_mission)
    assert clean["safety_events"] == [] and clean["whole_flight"]["time_below_d_emg_s"] == 0.0
    run = make_run_folder(tmp_path / "close", quickstart_mission, squeeze=(10.0, 11.5))
    report = write_report(run, quickstart_mission)
    assert report["whole_flight"]["time_below_d_emg_s"] == pytest.approx(1.5, abs=0.03)
    assert report["whole_flight"]["min_separation_whole_flight_m"] == pytest.approx(2.0)
    assert len(report["safety_events"]) == 1 and "D_Emg" in report["safety_events"][0]
    assert "SAFETY EVENTS" in (run / "report.md").read_text().splitlines()[3]


def _hovering(mission: Mission, seconds: float = 2.0) -> Trajectories:
    """Every vehicle still at its start lifted to 10 m, sampled at 50 Hz."""
    t = np.arange(0.0, seconds, 0.02)
    start = np.array([v.start.position for v in mission.vehicles], dtype=float) + [0.0, 0.0, 10.0]
    pos = np.broadcast_to(start, (len(t), *start.shape)).copy()
    n = len(mission.vehicles)
    return Trajectories(
        t,
        pos,
        np.zeros_like(pos),
        np.zeros((len(t), n), dtype=bool),
        np.zeros((len(t), 0, 3)),
        np.zeros(0),
        "truth",
    )


def test_commands_limited_goes_from_flight_json_into_the_report(
    tmp_path: Path, quickstart_mission: Mission
) -> None:
    mission = quickstart_mission
    result = FlightResult(t_formation_start=0.0, t_formation_end=1.9, ticks=95, degraded_s=0.5, holds=2)
    write_flight(tmp_path, mission, str(mission.path), result, 1.5, [0.001, 0.002], commands_limited=7)
    flight = json.loads((tmp_path / "flight.json").read_text())
    assert flight["commands_limited"] == 7
    assert (flight["degraded_s"], flight["holds"], flight["max_telemetry_age_s"]) == (0.5, 2, 0.0)
    report = report_from(_hovering(mission), None, mission, flight)
    assert report["commands_limited"] == 7
    assert "| commands_limited | 7 |" in render_markdown(report)


def test_a_flight_json_without_the_count_reports_none(quickstart_mission: Mission) -> None:
    mission = quickstart_mission
    flight = {"offsets": mission_offsets(mission).tolist(), "t_formation_start": 0.0, "arrived": False}
    report = report_from(_hovering(mission), None, mission, flight)
    assert report["commands_limited"] is None
    assert "| commands_limited | - |" in render_markdown(report)


def test_link_use_goes_from_flight_json_into_the_report(
    run_folder: Path, quickstart_mission: Mission, monkeypatch: pytest.MonkeyPatch
) -> None:
    _hide_matplotlib(monkeypatch)
    flight = json.loads((run_folder / "flight.json").read_text())
    use = {
        "up_mean_B_s": 1668.7,
        "up_peak_B_s": 2592.0,
        "down_mean_B_s": 4756.3,
        "down_peak_B_s": 6860.0,
        "bytes_up": 163532,
        "bytes_down": 466118,
        "measured_s": 98.0,
        "budget_B_s": 1000.0,
        "over_budget_s": 97.0,
        "radio_status": {"txbuf_min_pct": 35},
    }
    flight["link_use"] = {"lead": use}
    (run_folder / "flight.json").write_text(json.dumps(flight))
    report = write_report(run_folder, quickstart_mission)
    assert report["link_use"] == {"lead": use}
    text = (run_folder / "report.md").read_text()
    assert "| lead | 1668.70 | 2592.00 | 4756.30 | 6860.00 | 1000.00 | 97.00 | 35 |" in text
    del flight["link_use"]  # a run folder from before link_use: no section
    (run_folder / "flight.json").write_text(json.dumps(flight))
    assert write_report(run_folder, quickstart_mission)["link_use"] is None
    assert "Link use" not in (run_folder / "report.md").read_text()
