"""Legs the leader flew round a gap in the report: flight.json's detours rows (guidance.route_plan.Detour) as
a table in report.md."""

import numpy as np

from gcs_swarm.evaluation.report import render_markdown
from gcs_swarm.guidance.route_plan import Detour

BASE = {"mission": "m", "source": "ground truth", "vehicles": [], "lost": [], "events": []}


def test_a_detour_reads_as_a_flight_json_row_and_a_report_md_row():
    detour = Detour(0.843, 1, np.array([[56.674, 78.931, 10.0], [57.66, 89.06, 10.0]]))
    row = detour.as_json()
    assert row == {"t_s": 0.843, "waypoint": 1, "via": [[56.67, 78.93, 10.0], [57.66, 89.06, 10.0]]}
    md = render_markdown({**BASE, "detours": [row]})
    assert "| 0.84 | 2 | (57, 79), (58, 89) |" in md


def test_rows_a_hand_edit_broke_read_as_dashes_and_no_detours_no_table():
    md = render_markdown({**BASE, "detours": [{"t_s": 3.0, "waypoint": "first", "via": "trees"}, "x"]})
    assert "| 3.00 | - | - |" in md and "| - | - | - |" in md
    assert "round a gap" not in render_markdown(BASE)
