"""The kinematic planner on the Table 1 scenario (spec 9.1 reproduction default, 11.3) and in 3-D."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_swarm.evaluation.planner import PlannerSettings, plan_path
from gcs_swarm.guidance.params import FieldParams

TABLE1_CENTRES = np.array([[25.0, 75.0], [81.0, 30.0], [70.0, 70.0], [32.0, 27.0]])
TABLE1_RADII = np.array([9.0, 8.0, 18.0, 14.0])
START, GOAL = np.array([5.0, 5.0]), np.array([95.0, 70.0])


def table1(method: str, step: str):
    fp = FieldParams(method=method, k_att=100.0, k_rep=1e5, l0=20.0, n=0.8, d_g=15.0)
    return plan_path(START, GOAL, TABLE1_CENTRES, TABLE1_RADII, None, fp, 15.0, PlannerSettings(step=step))


def test_table1_proportional_apf_stalls_beside_the_goal():
    """Spec 11.3: APF stalls at (96.1, 70), 1.11 m short (the GNRON offset of the goal-near obstacle)."""
    r = table1("apf", "proportional")
    assert not r.reached and r.time_s is None
    np.testing.assert_allclose(r.path[-1], [96.1, 70.0], atol=0.05)
    assert r.final_distance_m == pytest.approx(1.11, abs=0.02)
    assert not r.collision


def test_table1_proportional_iaapf_reaches():
    """Spec 11.3: IAAPF reaches in 15.9 s with 7.2 m clearance."""
    r = table1("iaapf", "proportional")
    assert r.reached
    assert r.time_s == pytest.approx(15.9, abs=0.1)
    assert r.min_clearance_m == pytest.approx(7.2, abs=0.05)
    assert r.final_distance_m < 0.5 and not r.collision


def test_table1_constant_step_apf_circles_and_iaapf_arrives():
    """Spec 11.3, 15 m/s along F: APF circles about 1 m east of the goal for all 60 s (T_osc 58.7 s, about
    2600 reversals, clearance 2.1 m); IAAPF arrives in 9.2 s with 7.2 m clearance and far less oscillation."""
    apf = table1("apf", "constant")
    assert not apf.reached
    assert apf.oscillation_time_s == pytest.approx(58.7, abs=0.1)
    assert 2500 < apf.heading_reversals < 2700
    assert apf.min_clearance_m == pytest.approx(2.1, abs=0.05)
    assert 0.5 < np.linalg.norm(apf.path[-1000:] - GOAL, axis=1).mean() < 1.5
    iaapf = table1("iaapf", "constant")
    assert iaapf.reached
    assert iaapf.time_s == pytest.approx(9.2, abs=0.1)
    assert iaapf.min_clearance_m == pytest.approx(7.2, abs=0.05)
    assert iaapf.oscillation_time_s < 0.2 * apf.oscillation_time_s
    assert iaapf.heading_reversals < 10


def test_3d_spheres_of_section_5_1():
    centres = np.array(
        [[80, 85, 100], [175, 135, 100], [225, 200, 100], [300, 320, 100], [370, 350, 100]], float
    )
    radii = np.full(5, 3.0)
    fp = FieldParams(method="iaapf", k_att=100.0, k_rep=1e5, l0=20.0, n=0.8, d_g=15.0)
    start, goal = np.array([0.0, 0.0, 100.0]), np.array([400.0, 400.0, 100.0])
    r = plan_path(start, goal, centres, radii, None, fp, 15.0, PlannerSettings(time_limit_s=60.0, dt=0.02))
    assert r.reached and not r.collision
    assert r.path.shape[1] == 3
    assert r.path_length_m >= np.linalg.norm(goal - start)


def test_moving_obstacle_is_avoided_where_it_is():
    """An obstacle crossing the straight path: clearance is measured against its moving centre."""
    fp = FieldParams(method="iaapf", k_att=100.0, k_rep=1e5, l0=10.0, n=0.8, d_g=10.0)
    centres, radii = np.array([[50.0, -30.0]]), np.array([4.0])
    velocity = np.array([[0.0, 6.0]])  # reaches the line y = 0 after about 5 s, as the point passes x = 50
    settings = PlannerSettings(speed=10.0, time_limit_s=30.0)
    moving = plan_path([0.0, 0.0], [100.0, 0.0], centres, radii, velocity, fp, 10.0, settings)
    assert moving.reached and not moving.collision
    track = centres + velocity * moving.times[:, None]
    gap = np.linalg.norm(moving.path - track, axis=1) - radii[0]
    t_end = int(np.searchsorted(moving.times, moving.time_s)) + 1
    assert moving.min_clearance_m == pytest.approx(gap[:t_end].min())
    static = plan_path([0.0, 0.0], [100.0, 0.0], centres, radii, None, fp, 10.0, settings)
    assert static.min_clearance_m > moving.min_clearance_m  # the static one never comes near


def test_planner_settings_and_inputs_are_validated():
    with pytest.raises(ValueError, match="step"):
        PlannerSettings(step="adaptive")
    with pytest.raises(ValueError, match="dt"):
        PlannerSettings(dt=0.0)
    with pytest.raises(ValueError, match="2-D or 3-D"):
        plan_path([0.0], [1.0], np.zeros((0, 1)), np.zeros(0), None, FieldParams(), 15.0, PlannerSettings())


def test_without_obstacles_the_path_is_straight():
    r = plan_path([0.0, 0.0], [30.0, 40.0], np.zeros((0, 2)), np.zeros(0), None, FieldParams(), 15.0,
                  PlannerSettings())  # fmt: skip
    assert r.reached and r.min_clearance_m == np.inf
    assert r.path_length_m == pytest.approx(50.0, abs=0.5)
    assert r.heading_reversals == 0
