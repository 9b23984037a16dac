"""The generated-course benchmark's time bound (benchmarks/bench_formation_courses.py): a course's time to
goal against the paper form's, and against the course's time limit where the paper form never arrived."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))

from bench_formation_courses import summarise, time_ratio_to_paper  # noqa: E402

from gcs_swarm.evaluation.courses import course  # noqa: E402


def _row(form: str, time_to_goal: float | None, seed: int = 3) -> dict:
    return {"family": "legs2", "seed": seed, "form": form, "reached": time_to_goal is not None,
            "time_to_goal_s": time_to_goal}  # fmt: skip


def test_the_ratio_is_against_the_papers_time_where_it_arrived():
    assert time_ratio_to_paper(_row("smooth", 44.0), _row("paper", 40.0)) == pytest.approx(1.1)


def test_where_the_paper_never_arrived_the_ratio_is_against_the_courses_time_limit():
    """The paper form that ran out of time would have arrived after the course's time limit (60 s plus the
    route's length at 3 m/s, counted from the formation's start like the time to goal), so 50 s over that
    limit is at least the true ratio, and under 50 / 60."""
    limit = course("legs2", 3)["run"]["time_limit_s"]
    assert limit >= 60.0
    ratio = time_ratio_to_paper(_row("smooth", 50.0), _row("paper", None))
    assert ratio == pytest.approx(50.0 / limit, abs=1e-3)
    assert ratio < 50.0 / 60.0


@pytest.mark.parametrize("mine, paper", [(None, 40.0), (None, None)])
def test_no_ratio_for_a_flight_that_did_not_arrive(mine, paper):
    assert time_ratio_to_paper(_row("smooth", mine), _row("paper", paper)) is None


def test_no_ratio_without_the_papers_flight():
    assert time_ratio_to_paper(_row("smooth", 50.0), None) is None


def test_the_summary_counts_the_courses_the_paper_never_arrived_on():
    """Three courses: the paper form arrived in 40 s on one (smooth 44 s: within 1.1 x), never on another
    (smooth 50 s, within the limit), and on a third smooth did not arrive: the time bound is met on 2 of 3,
    and the paper never arrived on 1 of those smooth reached."""
    results = [
        _row("smooth", 44.0, 0), _row("paper", 40.0, 0),
        _row("smooth", 50.0, 1), _row("paper", None, 1),
        _row("smooth", None, 2), _row("paper", 30.0, 2),
    ]  # fmt: skip
    smooth = next(line for line in summarise(results, ["legs2"]).splitlines() if "| smooth |" in line)
    cells = [cell.strip() for cell in smooth.strip("|").split("|")]
    header = [cell.strip() for cell in summarise(results, ["legs2"]).splitlines()[0].strip("|").split("|")]
    assert cells[header.index("time_ratio_to_paper")].endswith("(2/3)")
    assert cells[header.index("of which paper never arrived")] == "1"
    assert cells[header.index("reached")] == "2"


def test_the_summary_reports_when_the_shape_was_formed_beside_the_bounds():
    """shape_formed_s has no bound: median / 90th percentile / worst of the flights that have it (4 and 8 s:
    6, 4 + 0.9 x 4 = 7.6 and 8 s) and how many lack it (one never formed its shape)."""
    results = [
        _row("smooth", 40.0, seed) | {"shape_formed_s": formed}
        for seed, formed in enumerate((4.0, 8.0, None))
    ]
    table = summarise(results, ["legs2"]).splitlines()
    header = [cell.strip() for cell in table[0].strip("|").split("|")]
    cells = [cell.strip() for cell in table[2].strip("|").split("|")]
    assert cells[header.index("shape_formed_s")] == "6.00 / 7.60 / 8.00 (1 none)"
