"""The `plan` subcommand's logic: planning a mission's leader path, its JSON figures and the plot."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from gcs_swarm.evaluation.planning import JSON_KEYS, plan_json, plan_mission, plot_plan
from gcs_swarm.guidance.params import FieldParams, Limits, ReferenceParams
from gcs_swarm.mission import load_mission

ROOT = Path(__file__).resolve().parents[3]


def table1_mission(
    step: str = "proportional", start=None, velocity=None, trees: bool = False
) -> SimpleNamespace:
    """A stand-in with the attributes of gcs_swarm.mission.Mission that planning reads (Table 1, spec 9.1);
    `trees`: the circles given as cylinders 0..10 m high instead of spheres."""
    circles = [((25, 75, 0), 9), ((81, 30, 0), 8), ((70, 70, 0), 18), ((32, 27, 0), 14)]
    obstacles = [
        SimpleNamespace(
            center=np.array(c, float), radius=float(r), velocity=np.zeros(3) if velocity is None else velocity
        )
        for c, r in circles
    ]
    cylinders = [
        SimpleNamespace(center=np.array(c[:2], float), radius=float(r), bottom=0.0, top=10.0)
        for c, r in circles
    ]
    leader = SimpleNamespace(start=SimpleNamespace(position=np.array([5.0, 5.0, 0.0])))
    return SimpleNamespace(
        vehicles=(leader,),
        leader_index=0,
        goal=np.array([95.0, 70.0, 0.0]),
        obstacles=() if trees else tuple(obstacles),
        cylinders=tuple(cylinders) if trees else (),
        prisms=(),
        field=FieldParams(k_att=100.0, k_rep=1e5, l0=20.0, n=0.8, d_g=None),
        limits=Limits(),
        reference=ReferenceParams(),
        planner=SimpleNamespace(
            dimensions=2, dt=0.01, time_limit_s=60.0, speed=15.0, goal_radius=0.5, step=step, start=start
        ),
    )


def free_field_reach_time(distance: float, speed: float, d_g: float, k_v: float, dt: float, r_goal: float):
    """Reach time (s) of the proportional step rule with no obstacles, by hand.

    Without obstacles the force is IAAPF's attraction alone, |F| = k_att min(rho, d_g) (spec 3.1), so the
    step speed is min(speed, K_v min(rho, d_g)). Far out, rho > d_g' = min(d_g, speed / K_v): the point
    moves straight at v1 = K_v d_g' (or the speed cap), v1 dt per step, until rho <= d_g'; then each step
    shrinks rho by the factor (1 - K_v dt). The goal counts as reached at the first sample with rho <= r_goal.
    """
    v1 = min(speed, k_v * d_g)
    boundary = v1 / k_v
    n1 = math.ceil((distance - boundary) / (v1 * dt))
    rho1 = distance - n1 * v1 * dt
    n2 = math.ceil(math.log(r_goal / rho1) / math.log(1.0 - k_v * dt))
    return (n1 + n2) * dt


def test_plan_mission_in_a_free_field_matches_the_closed_form():
    """Table 1's start (5, 5) and goal (95, 70) with the obstacles removed: a straight run of
    |(90, 65)| = 111.02 m, at 15 m/s until 15 m out (d_g defaults to speed / K_v = 15 m), then exponentially
    (rate K_v = 1/s) into the 0.5 m goal circle: 641 steps + 338 steps of 0.01 s = 9.79 s (continuous
    limit (111.02 - 15) / 15 + ln(15 / 0.5) = 9.80 s). Path length: the straight line up to the goal
    circle."""
    mission = table1_mission()
    mission.obstacles = ()
    distance = math.hypot(95.0 - 5.0, 70.0 - 5.0)
    figures = plan_json(plan_mission(mission, "iaapf"))
    assert figures["reached"] is True
    assert figures["time_s"] == pytest.approx(free_field_reach_time(distance, 15.0, 15.0, 1.0, 0.01, 0.5))
    assert figures["time_s"] == pytest.approx(9.79)
    assert figures["path_length_m"] == pytest.approx(distance - 0.5, abs=0.01)
    assert figures["min_clearance_m"] is None
    assert (figures["oscillation_time_s"], figures["heading_reversals"]) == (0.0, 0)


def test_plan_mission_uses_the_fields_own_d_g():
    """d_g = 5 m set in the field: 5 m/s out to 5 m from the goal, then the same exponential approach:
    (111.02 - 5) / 5 + ln(5 / 0.5) = 23.51 s in the continuous limit, 23.50 s in steps of 0.01 s."""
    mission = table1_mission()
    mission.obstacles = ()
    mission.field = dataclasses.replace(mission.field, d_g=5.0)
    distance = math.hypot(95.0 - 5.0, 70.0 - 5.0)
    figures = plan_json(plan_mission(mission, "iaapf"))
    assert figures["time_s"] == pytest.approx(free_field_reach_time(distance, 15.0, 5.0, 1.0, 0.01, 0.5))
    assert figures["time_s"] == pytest.approx((distance - 5.0) / 5.0 + math.log(10.0), abs=0.02)


def test_plan_mission_through_table1_keeps_to_the_geometry_and_exact_json_keys():
    """Bounds that follow from Table 1's geometry, not from a run: the goal (95, 70) lies 25 - 18 = 7 m from
    the surface of obstacle (70, 70) r 18, and the path ends within 0.5 m of the goal, so its minimum
    clearance is above 0 (no collision) and at most 7.5 m; the path is no shorter than the straight line to
    the goal circle (110.52 m) and, at most 15 m/s, takes at least path length / 15 m/s. APF stalls beside
    the goal (its repulsion balances the attraction beyond the goal, spec 11.3)."""
    apf = plan_mission(table1_mission(), "apf")
    iaapf = plan_mission(table1_mission(), "iaapf")
    for result in (apf, iaapf):
        figures = plan_json(result)
        assert tuple(figures) == JSON_KEYS
        json.dumps(figures, allow_nan=False)  # strict JSON: no NaN or Infinity
    assert plan_json(apf)["reached"] is False and plan_json(apf)["time_s"] is None
    figures = plan_json(iaapf)
    assert figures["reached"] is True
    straight = math.hypot(95.0 - 5.0, 70.0 - 5.0) - 0.5
    assert figures["path_length_m"] >= straight
    assert figures["path_length_m"] / 15.0 <= figures["time_s"] <= 60.0
    assert 0.0 < figures["min_clearance_m"] <= 7.5
    assert isinstance(figures["heading_reversals"], int)


def test_a_2d_plan_sees_cylinders_as_their_circles():
    """Spec 2.2: in the 2-D plane a cylinder is its footprint circle, whose distance |q - c| - r and normal
    (q - c)/|q - c| are the sphere's of the same centre and radius in that plane (spec 2.1), so the plan
    through Table 1 with trees instead of spheres is the same path, with the same clearance."""
    spheres = plan_mission(table1_mission(), "iaapf")
    trees = plan_mission(table1_mission(trees=True), "iaapf")
    np.testing.assert_allclose(trees.path, spheres.path, atol=1e-9)
    assert trees.min_clearance_m == pytest.approx(spheres.min_clearance_m, abs=1e-9)
    assert trees.reached and not trees.collision


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
    mission = table1_mission()
    results = {m: plan_mission(mission, m) for m in ("apf", "iaapf")}
    out = tmp_path / "plan.png"
    assert plot_plan(results, mission.obstacles, out) is True
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bundled_table1_mission_file():
    mission = load_mission(ROOT / "missions" / "paper_table1_2d.yaml")
    assert plan_json(plan_mission(mission, "apf"))["reached"] is False
    assert plan_json(plan_mission(mission, "iaapf"))["reached"] is True
