"""The `plan` subcommand's logic: planning a mission's leader path, its JSON figures and the plot."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gcs_swarm.evaluation.planning import JSON_KEYS, plan_json, plan_mission, plot_plan
from gcs_swarm.guidance.params import FieldParams, Limits, ReferenceParams

ROOT = Path(__file__).resolve().parents[2]


def table1_mission(step: str = "proportional", start=None, velocity=None) -> SimpleNamespace:
    """A stand-in with the attributes of gcs_swarm.mission.Mission that planning reads (Table 1, spec 9.1)."""
    circles = [((25, 75, 0), 9), ((81, 30, 0), 8), ((70, 70, 0), 18), ((32, 27, 0), 14)]
    obstacles = [
        SimpleNamespace(
            center=np.array(c, float), radius=float(r), velocity=np.zeros(3) if velocity is None else velocity
        )
        for c, r in circles
    ]
    leader = SimpleNamespace(start=SimpleNamespace(position=np.array([5.0, 5.0, 0.0])))
    return SimpleNamespace(
        vehicles=(leader,),
        leader_index=0,
        goal=np.array([95.0, 70.0, 0.0]),
        obstacles=tuple(obstacles),
        field=FieldParams(k_att=100.0, k_rep=1e5, l0=20.0, n=0.8, d_g=None),
        limits=Limits(),
        reference=ReferenceParams(),
        planner=SimpleNamespace(
            dimensions=2, dt=0.01, time_limit_s=60.0, speed=15.0, goal_radius=0.5, step=step, start=start
        ),
    )


def test_plan_mission_reproduces_table1_and_reports_exact_json_keys():
    apf = plan_mission(table1_mission(), "apf")
    iaapf = plan_mission(table1_mission(), "iaapf")
    for result in (apf, iaapf):
        figures = plan_json(result)
        assert tuple(figures) == JSON_KEYS
        json.dumps(figures, allow_nan=False)  # strict JSON: no NaN or Infinity
    assert plan_json(apf)["reached"] is False and plan_json(apf)["time_s"] is None
    figures = plan_json(iaapf)
    assert figures["reached"] is True
    assert figures["time_s"] == pytest.approx(15.9, abs=0.1)  # d_g defaults to speed / K_v = 15 m
    assert figures["min_clearance_m"] == pytest.approx(7.2, abs=0.05)
    assert isinstance(figures["heading_reversals"], int)


def test_planner_start_overrides_the_leader_start():
    moved = plan_mission(table1_mission(start=np.array([10.0, 5.0, 0.0])), "iaapf")
    np.testing.assert_allclose(moved.path[0], [10.0, 5.0])


def test_moving_obstacles_are_planned_where_they_will_be():
    static = plan_mission(table1_mission(), "iaapf")
    drifting = plan_mission(table1_mission(velocity=np.array([0.0, -1.0, 0.0])), "iaapf")
    n = min(len(static.path), len(drifting.path))
    assert np.abs(static.path[:n] - drifting.path[:n]).max() > 1.0


def test_bad_method_and_dimensions_are_clear_errors():
    with pytest.raises(ValueError, match="apf, iaapf"):
        plan_mission(table1_mission(), "rrt")
    mission = table1_mission()
    mission.planner.dimensions = 4
    with pytest.raises(ValueError, match="dimensions"):
        plan_mission(mission, "iaapf")


def test_json_without_obstacles_has_null_clearance():
    mission = table1_mission()
    mission.obstacles = ()
    figures = plan_json(plan_mission(mission, "iaapf"))
    assert figures["min_clearance_m"] is None and figures["reached"] is True


def test_plot_plan_writes_a_png(tmp_path):
    pytest.importorskip("matplotlib")
    mission = table1_mission()
    results = {m: plan_mission(mission, m) for m in ("apf", "iaapf")}
    out = tmp_path / "plan.png"
    assert plot_plan(results, mission.obstacles, out) is True
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bundled_table1_mission_file():
    mission_mod = pytest.importorskip("gcs_swarm.mission")
    path = ROOT / "missions" / "paper_table1_2d.yaml"
    if not path.exists():
        pytest.skip("missions/paper_table1_2d.yaml not present")
    mission = mission_mod.load_mission(path)
    assert plan_json(plan_mission(mission, "apf"))["reached"] is False
    assert plan_json(plan_mission(mission, "iaapf"))["reached"] is True
