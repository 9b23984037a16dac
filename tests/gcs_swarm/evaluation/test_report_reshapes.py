"""The formation's changes of shape in the report: flight.json's reshapes rows (guidance.reshape.ShapeChange)
as a table in report.md and as marks on report.png's slot-error panel."""

from gcs_swarm.evaluation.figures import reshape_events
from gcs_swarm.evaluation.report import render_markdown
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
    assert CHANGES[2].as_json() == {"t_s": 31.457, "change": "restored", "shape": "formation", "scale": 1.0}


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
