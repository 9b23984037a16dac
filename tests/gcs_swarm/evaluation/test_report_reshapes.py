"""The formation's changes of shape in the report: flight.json's reshapes rows (guidance.reshape.ShapeChange)
as a table in report.md and as marks on report.png's slot-error panel; the compare figure's slot error
against the slots of the moment."""

import numpy as np

from gcs_swarm.evaluation.figures import CompareRun, reshape_events, slot_error_series
from gcs_swarm.evaluation.report import render_markdown
from gcs_swarm.evaluation.run_data import CommandLog, Trajectories
from gcs_swarm.guidance.reshape import ShapeChange

CHANGES = (
    ShapeChange(12.3, "narrows", "column", 0.5),
    ShapeChange(20.0, "widens", "formation x0.71", 0.71),
    ShapeChange(31.456789, "restored", "formation", 1.0),
)


def test_a_shape_change_reads_as_the_event_line_and_as_a_flight_json_row():
    assert [c.sentence for c in CHANGES] == [
        "t=12.30 s formation narrows: column",
        "t=20.00 s formation widens: formation x0.71",
        "t=31.46 s formation restored",
    ]
    assert CHANGES[2].as_json() == {
        "t_s": 31.457, "change": "restored", "shape": "formation", "scale": 1.0, "turn_deg": 0.0
    }  # fmt: skip


def test_report_md_lists_every_change_of_shape_and_the_figure_marks_them():
    rows = [c.as_json() for c in CHANGES]
    report = {
        "mission": "m",
        "source": "ground truth",
        "vehicles": [],
        "lost": [],
        "events": [],
        "reshapes": rows,
    }
    md = render_markdown(report)
    assert "| 12.30 | narrows | column | 0.50 |" in md
    assert "| 20.00 | widens | formation x0.71 | 0.71 |" in md
    assert "| 31.46 | restored | formation | 1.00 |" in md
    assert reshape_events({"reshapes": rows}) == [
        (12.3, "narrows: column"),
        (20.0, "widens: formation x0.71"),
        (31.457, "restored"),
    ]


def test_a_flight_without_reshapes_has_no_table_and_no_marks():
    report = {"mission": "m", "source": "ground truth", "vehicles": [], "lost": [], "events": []}
    assert "shape" not in render_markdown(report)
    assert reshape_events({}) == []


def test_the_compare_figure_measures_followers_against_the_slots_of_the_moment():
    """A leader flying east at 5 m/s (psi_L 0) with one follower: 10 m abeam on the left (the mission's slot)
    for the first 10 s, then 10 m astern, where flight.json's formation_timeline puts its slot from t = 10 s
    (a column). The follower is 1 m off each slot in turn, so the worst error is 1 m throughout; against the
    mission's abeam slot alone it is |(-11, -10)| = 14.9 m after the change."""
    t = np.arange(0.0, 20.0, 0.5)
    leader = np.stack([5.0 * t, np.zeros_like(t), np.full_like(t, 10.0)], axis=1)
    abeam, astern = np.array([0.0, 10.0 + 1.0, 0.0]), np.array([-10.0 - 1.0, 0.0, 0.0])
    follower = leader + np.where((t < 10.0)[:, None], abeam, astern)
    pos = np.stack([leader, follower], axis=1)
    traj = Trajectories(
        t, pos, np.zeros_like(pos), np.zeros((len(t), 2), dtype=bool), np.zeros((len(t), 0, 3)), np.zeros(0),
        "ground truth",
    )  # fmt: skip
    mission_offsets = [[0.0, 0.0, 0.0], [0.0, 10.0, 0.0]]
    flight = {
        "offsets": mission_offsets,
        "formation_timeline": [
            {"t": 0.0, "leader": 0, "offsets": mission_offsets},
            {"t": 10.0, "leader": 0, "offsets": [[0.0, 0.0, 0.0], [-10.0, 0.0, 0.0]]},
        ],
    }
    commands = CommandLog(t, np.zeros((len(t), 2, 3)), np.zeros(len(t)))
    run = CompareRun("v", traj, commands, np.array(mission_offsets), 0, 0.0, flight)
    series = slot_error_series(run)
    assert series is not None
    since, worst = series
    np.testing.assert_allclose(since, t)
    np.testing.assert_allclose(worst, 1.0, atol=1e-9)
    without_timeline = CompareRun("v", traj, commands, np.array(mission_offsets), 0, 0.0, {})
    mission_series = slot_error_series(without_timeline)
    assert mission_series is not None
    np.testing.assert_allclose(mission_series[1][t >= 10.0], np.hypot(11.0, 10.0))
