"""Generated obstacle courses (gcs_swarm.evaluation.courses) and the figures measured once a formation has
assembled (flight_quality.assembled_figures) or formed its shape (flight_quality.shape_formed)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from gcs_swarm.evaluation import flight_quality as fq
from gcs_swarm.evaluation.courses import FAMILIES, KEEP_OUT_M, course
from gcs_swarm.evaluation.flight_quality import assembled_figures
from gcs_swarm.guidance.formation import ASSEMBLED_M
from gcs_swarm.mission import MissionError, parse_mission
from gcs_swarm.mission.geometry import mission_offsets


@pytest.mark.parametrize("family", FAMILIES)
@pytest.mark.parametrize("seed", range(6))
def test_every_course_is_a_valid_mission_with_obstacles_clear_of_starts_and_goal(family, seed):
    data = course(family, seed)
    mission = parse_mission(yaml.safe_dump(data), f"{family}-{seed}")
    assert 3 <= len(mission.vehicles) <= 9
    assert mission.formation.shape in ("v", "line", "grid")
    starts = np.array([v.start.position for v in mission.vehicles])
    for obstacle in mission.obstacles:
        for point in np.vstack([starts, np.array(mission.waypoints)]):
            assert np.linalg.norm(point[:2] - obstacle.center[:2]) > obstacle.radius + KEEP_OUT_M
    assert mission.run.airborne_start and (seed % 2 == 1) == (mission.wind.speed > 0)


def test_the_same_family_and_seed_give_the_same_course_and_others_differ():
    assert course("slalom", 3) == course("slalom", 3)
    assert course("slalom", 3) != course("slalom", 4)
    assert course("slalom", 3)["world"] != course("gap", 3)["world"]


def test_a_gap_course_is_narrower_than_its_formation():
    """The two large spheres of a gap course leave a gap (surface to surface) of 8 m up to 0.8 times the
    formation's width (the lateral extent of its slots, leader included), never wider than the formation."""
    for seed in range(10):
        data = course("gap", seed)
        mission = parse_mission(yaml.safe_dump(data))
        lateral = mission_offsets(mission)[:, 1]
        width = float(lateral.max() - lateral.min())
        (a, b) = sorted(mission.obstacles, key=lambda o: -o.radius)[:2]
        gap = float(np.linalg.norm(a.center[:2] - b.center[:2])) - a.radius - b.radius
        assert 8.0 - 1e-9 <= gap <= max(8.5, 0.8 * width) + 1e-9


def test_legs_courses_turn_between_legs():
    for family, legs in (("legs2", 2), ("legs3", 3)):
        data = course(family, 1)
        points = np.vstack([[0.0, 0.0], np.array(data["waypoints"])[:, :2]])
        assert len(data["waypoints"]) == legs
        headings = np.arctan2(*np.diff(points, axis=0).T[::-1])
        turns = np.abs((np.diff(headings) + math.pi) % (2 * math.pi) - math.pi)
        assert np.all((turns >= math.radians(30) - 1e-9) & (turns <= math.radians(100) + 1e-9))


def test_an_unknown_family_is_refused_by_name():
    with pytest.raises(ValueError, match="zigzag"):
        course("zigzag", 0)


def test_launch_spots_are_six_metres_apart_behind_the_leader():
    """Rows of four spots 6 m apart behind the leader (positions rounded to 1 mm), all behind it."""
    data = course("slalom", 0)
    starts = np.array([v["start"]["position"] for v in data["vehicles"]])[:, :2]
    gaps = np.linalg.norm(starts[:, None] - starts[None], axis=-1)[np.triu_indices(len(starts), 1)]
    assert gaps.min() == pytest.approx(6.0, abs=2e-3)
    heading = math.radians(data["vehicles"][0]["start"]["yaw_deg"])
    ahead = starts[1:] @ np.array([math.cos(heading), math.sin(heading)])
    assert np.all(ahead < -5.9)


def test_assembled_figures_start_when_every_follower_is_first_within_two_metres():
    """Followers 10, 6 m from their slots closing at 1 m/s: both are within ASSEMBLED_M = 2 m from t = 8 s
    (the farther one reaches 2 m then); from there the errors are 2, 1, 0 m then a 3 m excursion: RMS over
    the finite entries, maximum 3 m. The leader's column (NaN) is left out."""
    assert ASSEMBLED_M == 2.0
    t = np.arange(0.0, 12.0)
    far = np.array([10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0, 3], dtype=float)
    near = np.array([6, 5, 4, 3, 2, 1, 0, 0, 0, 0, 0, 0], dtype=float)
    err = np.column_stack([np.full(12, np.nan), far, near])
    out = assembled_figures(t, err)
    assert out["assembly_s"] == 8.0
    rest = np.array([2, 1, 0, 3, 0, 0, 0, 0], dtype=float)
    assert out["slot_error_assembled_rms_m"] == pytest.approx(math.sqrt(np.mean(rest**2)), abs=1e-4)
    assert out["slot_error_assembled_max_m"] == 3.0


def test_the_shape_is_formed_once_every_follower_is_on_its_slot_with_no_change_of_shape_under_way():
    """The formation starts at t = 0 and changes shape from 1 s to 3 s (a timeline entry every 0.02 s, the
    last at 3 s where the slots reach their new places): with SHAPE_AT_REST_S = 0.5 s its shape is at rest
    up to 0.5 s before the first entry of the change and from its last on (t < 0.5 and t >= 3 at these
    samples: a formation that has just finished a change is at rest, one about to start one is not). The
    follower is within 2 m of the slots of the moment from 0.5 s on, but 2.5 m off at 3 s: assembled at
    0.5 s, its shape formed at 3.5 s. A flight without a timeline is at rest throughout."""
    assert fq.SHAPE_AT_REST_S == 0.5
    start = {"t": 0.0, "leader": 0, "offsets": [[0, 0, 0], [-7, 0, 0]]}
    moving = [{"t": 1.0 + 0.02 * k, "leader": 0, "offsets": [[0, 0, 0], [-7, k, 0]]} for k in range(101)]
    flight = {"formation_timeline": [start, *moving]}
    t = np.arange(0.0, 6.0, 0.5)
    at_rest = fq.shape_at_rest(flight, t)
    np.testing.assert_array_equal(at_rest, (t < 0.5) | (t >= 3.0))
    follower = np.where(t < 0.5, 5.0, 1.0)
    follower[t == 3.0] = 2.5
    err = np.column_stack([np.full(len(t), np.nan), follower])
    assert assembled_figures(t, err)["assembly_s"] == 0.5
    assert fq.shape_formed(t, err, at_rest) == {"shape_formed_s": 3.5}
    assert fq.shape_at_rest({}, t).all()
    assert fq.shape_formed(t, np.column_stack([np.full(len(t), np.nan), np.full(len(t), 3.0)]), at_rest) == {
        "shape_formed_s": None
    }


def test_a_formation_that_never_assembles_has_no_assembled_figures():
    t = np.arange(5.0)
    out = assembled_figures(t, np.column_stack([np.full(5, np.nan), np.full(5, 3.0)]))
    assert out == {"assembly_s": None}


def test_reshape_settings_are_read_and_a_bad_one_is_refused_with_its_key():
    base = (
        "vehicles:\n  - {role: leader, start: {position: [0, 0, 0]}}\n"
        "  - {start: {position: [-5, 5, 0]}}\ngoal: [50, 0, 10]\n"
    )
    mission = parse_mission(base + "guidance: {reshape: {min_spacing_m: 8, column: false}}\n")
    assert mission.reshape.min_spacing_m == 8.0 and mission.reshape.column is False
    assert mission.reshape.enabled
    with pytest.raises(MissionError, match="speed_m_s"):
        parse_mission(base + "guidance: {reshape: {speed_m_s: 0}}\n")
    with pytest.raises(MissionError, match="reshape"):
        parse_mission(base + "guidance: {reshape: {colum: true}}\n")
