"""The Monte Carlo command around its flights: one task's result line, the progress lines, user errors as
sentences, and a failing run or worker whose traceback lands in the run folder's errors.log."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from gcs_swarm.evaluation import campaign_store, montecarlo
from gcs_swarm.evaluation.error_log import ERRORS_FILE
from gcs_swarm.evaluation.montecarlo import CampaignOptions, Progress, RunTask, fly_task, montecarlo_command

ROOT = Path(__file__).resolve().parents[3]


def _task(run_dir: Path, mission_yaml: str = "vehicles: []\n", **world: float) -> RunTask:
    return RunTask(
        seed=4,
        variant="apf",
        mission_yaml=mission_yaml,
        vehicles=1,
        run_dir=str(run_dir),
        collision_radius=0.175,
        keep_files=False,
        world={"obstacles": 0, "wind_speed_m_s": 0.0, "link_loss": 0.0} | world,
    )


def test_a_run_that_cannot_start_is_an_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    task = _task(tmp_path / "run")  # "vehicles: []" is refused by the mission loader: the flight never starts
    result = fly_task(task)
    assert (result["seed"], result["variant"], result["status"]) == (4, "apf", 2)
    assert "could not start" in result["error"]
    assert result["world"] == task.world and result["run_dir"] == task.run_dir
    assert "error:" in capsys.readouterr().out
    assert not (tmp_path / "run" / ERRORS_FILE).exists()  # a refused mission is a sentence, not a traceback


def test_a_run_that_raises_leaves_its_traceback_in_errors_log(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bug inside a run (here the flight itself raises) is the run's error line, naming the run folder's
    errors.log, which holds the whole traceback; the campaign goes on."""

    def broken_fly(*_args: object, **_kwargs: object) -> int:
        raise ZeroDivisionError("wind over zero")

    monkeypatch.setattr(montecarlo.flights, "fly", broken_fly)
    run_dir = tmp_path / "run"
    result = fly_task(_task(run_dir))
    errors = run_dir / ERRORS_FILE
    assert result["error"] == f"ZeroDivisionError: wind over zero (traceback in {errors})"
    log = errors.read_text()
    assert "Monte Carlo run seed 4 variant apf failed" in log
    assert "Traceback (most recent call last)" in log and "in broken_fly" in log
    assert log.rstrip().endswith("ZeroDivisionError: wind over zero")


def test_a_worker_that_fails_leaves_its_traceback_in_errors_log(tmp_path: Path) -> None:
    """A task the worker pool cannot even hand to a worker process (here it cannot be pickled) fails its
    future: the result line says so and names errors.log, which holds the traceback."""
    run_dir = tmp_path / "run"
    task = _task(run_dir, link_loss=0.0)
    task.world["unpicklable"] = lambda: None  # type: ignore[assignment]
    results = list(montecarlo._local_results([task], jobs=1))
    errors = run_dir / ERRORS_FILE
    assert len(results) == 1 and (results[0]["seed"], results[0]["variant"]) == (4, "apf")
    assert results[0]["error"].startswith("worker failed: ")
    assert results[0]["error"].endswith(f"(traceback in {errors})")
    log = errors.read_text()
    assert "worker of seed 4 variant apf failed" in log and "Traceback (most recent call last)" in log


def test_progress_is_plain_lines_off_a_terminal() -> None:
    out = io.StringIO()
    progress = Progress(3, out)
    progress.update("seed 0 apf: ok")
    progress.update("seed 1 apf: ok")
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    assert lines[0].startswith("run 1/3 seed 0 apf: ok") and "ETA" in lines[0]


def test_montecarlo_user_errors_are_sentences(tmp_path: Path) -> None:
    said: list[str] = []
    quickstart = str(ROOT / "missions" / "quickstart.yaml")
    assert montecarlo_command(quickstart, CampaignOptions(runs=0), said.append) == 2
    assert said[-1] == "error: --runs and --jobs must be at least 1"
    assert montecarlo_command(str(tmp_path / "none.yaml"), CampaignOptions(runs=1), said.append) == 2
    assert "mission file not found" in said[-1]
    bad = tmp_path / "ranges.yaml"
    bad.write_text("wind: {speed: [5, 1]}\n")
    options = CampaignOptions(runs=1, ranges_path=bad, out_dir=tmp_path / "c")
    assert montecarlo_command(quickstart, options, said.append) == 2
    assert "wind.speed: low 5 is above high 1" in said[-1]
    options = CampaignOptions(runs=1, variants=("rrt",), out_dir=tmp_path / "d")
    assert montecarlo_command(quickstart, options, said.append) == 2
    assert "unknown variant 'rrt'" in said[-1]
    # A refused invocation leaves no campaign behind, so the corrected command starts afresh.
    assert not (tmp_path / "c" / campaign_store.CAMPAIGN_FILE).exists()
    assert not (tmp_path / "d" / campaign_store.CAMPAIGN_FILE).exists()
