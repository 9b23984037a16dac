"""`write_report` on a synthetic run folder: spec-10 figures plus the command-rate and relative-angle keys,
paper figures with matplotlib, text and JSON only without it."""

from __future__ import annotations

import builtins
import json
from pathlib import Path
from typing import Any

import pytest

from gcs_swarm.cli import main
from gcs_swarm.mission import Mission
from gcs_swarm.report import NO_PLOT_NOTE, write_report

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
    pytest.importorskip("matplotlib")
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
