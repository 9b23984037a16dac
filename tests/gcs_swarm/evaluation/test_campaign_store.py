"""The campaign folder: append + resume, summaries and Wilson intervals on known inputs."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_swarm.evaluation import campaign_store
from gcs_swarm.evaluation.campaign_store import CampaignError, CampaignStore, summarise, wilson_interval


def _result(seed: int, variant: str, success: bool, collision: bool = False, **figures) -> dict:
    return {"seed": seed, "variant": variant, "success": success, "collision": collision} | figures


@pytest.mark.parametrize(
    ("successes", "n", "low", "high"),
    [(8, 10, 0.4902, 0.9433), (0, 10, 0.0, 0.2775), (10, 10, 0.7225, 1.0), (50, 100, 0.4038, 0.5962)],
)
def test_wilson_interval_matches_published_values(successes: int, n: int, low: float, high: float) -> None:
    lo, hi = wilson_interval(successes, n)
    assert lo == pytest.approx(low, abs=1e-4)
    assert hi == pytest.approx(high, abs=1e-4)


def test_wilson_interval_without_runs_is_uninformative() -> None:
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_append_resume_and_latest_line_wins(tmp_path: Path) -> None:
    store = CampaignStore(tmp_path / "c")
    assert store.results() == [] and store.finished() == set()
    store.append(_result(0, "apf", True))
    store.append(_result(1, "apf", False) | {"error": "the flight could not start"})
    store.append(_result(0, "iaapf", True))
    # An error line is not finished: a resumed campaign flies it again.
    assert store.finished() == {(0, "apf"), (0, "iaapf")}
    store.append(_result(1, "apf", False))
    assert store.finished() == {(0, "apf"), (0, "iaapf"), (1, "apf")}
    assert len(store.results()) == 3
    # A line cut short by a crash is skipped, the others kept.
    with store.results_path.open("a") as f:
        f.write('{"seed": 2, "variant": "ap')
    assert len(store.results()) == 3
    reopened = CampaignStore(tmp_path / "c")
    assert reopened.finished() == store.finished()


def test_bind_refuses_another_campaign_in_the_same_folder(tmp_path: Path) -> None:
    store = CampaignStore(tmp_path / "c")
    store.bind({"mission_sha256": "a", "first_seed": 0})
    store.bind({"mission_sha256": "a", "first_seed": 0})  # same campaign: resume
    with pytest.raises(CampaignError, match="another first_seed"):
        store.bind({"mission_sha256": "a", "first_seed": 5})


def test_summary_numbers_on_known_results() -> None:
    results = [
        _result(0, "apf", True, min_separation_m=5.0, time_to_goal_s=20.0, formation_rms_m=0.5),
        _result(
            1, "apf", False, collision=True, min_separation_m=1.0, time_to_goal_s=None, formation_rms_m=3.0
        ),
        _result(0, "iaapf", True, min_separation_m=6.0, time_to_goal_s=22.0, formation_rms_m=0.4),
        _result(1, "iaapf", True, min_separation_m=7.0, time_to_goal_s=24.0, formation_rms_m=0.6),
        _result(2, "iaapf", False) | {"error": "worker failed"},
    ]
    summary = summarise(results, ["apf", "iaapf"])
    assert summary["runs"] == 4 and summary["errors"] == 1
    assert summary["success_rate"] == 0.75
    assert summary["collision_rate"] == 0.25
    assert summary["success_ci95"] == pytest.approx(list(wilson_interval(3, 4)), abs=1e-4)
    apf, iaapf = summary["variants"]["apf"], summary["variants"]["iaapf"]
    assert (apf["runs"], apf["success_rate"], apf["collision_rate"]) == (2, 0.5, 0.5)
    assert (iaapf["runs"], iaapf["success_rate"], iaapf["collision_rate"]) == (2, 1.0, 0.0)
    assert apf["time_to_goal_s"]["n"] == 1  # over successful runs only
    assert iaapf["time_to_goal_s"]["median"] == 23.0
    assert summary["min_separation_m"]["min"] == 1.0 and summary["min_separation_m"]["max"] == 7.0
    assert iaapf["formation_rms_m"]["mean"] == 0.5
    text = campaign_store.render_summary(summary, "test")
    assert "| success rate | 0.5 | 1 | 0.75 |" in text
