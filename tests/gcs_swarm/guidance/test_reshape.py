"""Deliberate reshaping around obstacles (gcs_swarm.guidance.reshape): the candidates, the look-ahead, the
choice and the smooth change, on hand-built worlds whose answers follow from their geometry."""

from __future__ import annotations

import copy
import math
import re
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.distance import pdist
from shapely.geometry import Point, Polygon

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.params import PAPER_PLAIN, ReshapeParams
from gcs_swarm.guidance.reshape import (
    MARGIN_SLACK_M,
    MIN_JERK_PEAK_ACCEL,
    MOVE_ORDERS,
    PACE_MARGIN_M_S,
    SETTLE_PEAK_ACCEL,
    UNASSEMBLED_ORDERS,
    FormationShaper,
    Route,
    SlotMove,
    candidate_shapes,
    closest_pair_in,
    closest_pair_sampled,
    goal_eta,
    min_jerk,
    move_duration,
    nearest_slot_spacing,
    pace_speed,
    plan_move,
    route_samples,
    settle_duration,
    shape_clearance,
    straight_for,
    timed_phases,
)
from gcs_swarm.guidance.slot_assignment import assign_moves, closest_approach
from swarm_common.obstacle_shapes import NO_SHAPES, pack_shapes

PARAMS = ReshapeParams(clearance_m=4.0)  # the worlds below are sized for 4 m between slots and surfaces


def _v(followers: int = 4, spacing: float = 10.0) -> np.ndarray:
    out = np.zeros((followers + 1, 3))
    out[1:] = formation_offsets("v", followers, spacing)
    return out


def _gap_world(gap: float, x: float = 60.0, radius: float = 8.0) -> tuple[np.ndarray, np.ndarray]:
    """Two spheres at x m east at the formation's height, their surfaces `gap` m apart across y = 0."""
    centres = np.array([[x, gap / 2 + radius, 10.0], [x, -(gap / 2 + radius), 10.0]])
    return centres, np.array([radius, radius])


def test_candidates_run_from_the_mission_shape_down_to_the_minimum_spacing_then_a_column():
    """A V 10 m apart, min spacing 7 m in 3 steps: spacings 10, 9, 8, 7, then a column 7 m apart."""
    shapes = candidate_shapes(_v(), 0, PARAMS)
    rows = np.ones(5, dtype=bool)
    spacings = [nearest_slot_spacing(s.offsets, rows) for s in shapes]
    assert spacings == pytest.approx([10.0, 9.0, 8.0, 7.0, 7.0])
    assert [s.scale for s in shapes] == pytest.approx([1.0, 0.9, 0.8, 0.7, 0.7])
    column = shapes[-1].offsets
    assert shapes[-1].name == "column"
    np.testing.assert_allclose(column[1:, 1:], 0.0)
    assert sorted(column[1:, 0]) == pytest.approx([-28.0, -21.0, -14.0, -7.0])


def test_lost_followers_rows_stay_out_of_every_candidate():
    nominal = _v()
    nominal[2] = 0.0  # a lost follower's row
    for shape in candidate_shapes(nominal, 0, PARAMS):
        np.testing.assert_array_equal(shape.offsets[2], 0.0)
        assert np.count_nonzero(np.any(shape.offsets != 0.0, axis=1)) == 3


def test_route_samples_follow_the_waypoints_and_stop_at_the_look_ahead():
    points, headings, along = route_samples(
        np.array([0.0, 0.0, 10.0]), 0.3, np.array([[10.0, 0.0, 10.0], [10.0, 100.0, 10.0]]), 20.0
    )
    assert headings[0] == 0.3  # the formation's present heading where the leader is
    np.testing.assert_allclose(points[1:6, 0], [2, 4, 6, 8, 10])
    np.testing.assert_allclose(headings[1:6], 0.0)
    np.testing.assert_allclose(points[6:, 1], [2, 4, 6, 8, 10])  # 10 m along the second leg: 20 m in all
    np.testing.assert_allclose(headings[6:], math.pi / 2)
    np.testing.assert_allclose(along, np.arange(11) * 2.0)


def test_route_samples_keep_the_leaders_heading_within_its_hold_distance_of_the_goal():
    """A leader heading west (psi = pi) that has come to rest 4 m west of its goal keeps its heading there
    (LeaderHeading holds within d_g of the goal), so the formation is checked as it will stand, not turned
    round to face the goal 4 m east. Farther than the hold distance, the route's direction counts."""
    leader, goal = np.array([0.0, 0.0, 10.0]), np.array([[4.0, 0.0, 10.0]])
    _, headings, _ = route_samples(leader, math.pi, goal, 30.0, hold_m=10.0)
    np.testing.assert_allclose(headings, math.pi)
    _, headings, _ = route_samples(leader, math.pi, goal, 30.0, hold_m=3.0)
    np.testing.assert_allclose(headings[1:], 0.0)


def test_clearance_of_a_slot_is_its_distance_to_the_surface():
    """One follower 5 m back and 5 m left of a leader heading east at the origin: its slot (-5, 5) is 3 m
    from a sphere of radius 2 centred at (-5, 10); heading north the slot moves to (-5, -5), 15 m from the
    centre."""
    offsets = np.array([[0.0, 0.0, 0.0], [-5.0, 5.0, 0.0]])
    centre, radius = np.array([[-5.0, 10.0, 0.0]]), np.array([2.0])
    points = np.zeros((2, 3))
    which = np.zeros(2, dtype=np.int64)  # one shape, flown at both points
    gaps = shape_clearance(
        offsets[None], which, np.array([1]), points, np.array([0.0, math.pi / 2]), centre, radius, *NO_SHAPES
    )
    np.testing.assert_allclose(gaps, [3.0, 15.0 - 2.0])
    # a move: the follower's offset (-5, 5) at the first point, (-5, 9) at the second (heading east, 1 m off)
    moving = np.stack([offsets, np.array([[0.0, 0.0, 0.0], [-5.0, 9.0, 0.0]])])
    gaps = shape_clearance(
        moving, np.arange(2), np.array([1]), points, np.zeros(2), centre, radius, *NO_SHAPES
    )
    np.testing.assert_allclose(gaps, [3.0, -1.0])


def test_clearance_of_a_slot_beside_a_building_is_its_distance_to_the_wall():
    """The same follower slot (-5, 5, 10) heading east, beside a building whose south wall is y = 8 (footprint
    x -8..-2, y 8..12, 0..20 m high: the slot is level with the wall, 3 m from it) and 2 m above the roof of
    a second one under it (round the slot, 0..8 m): the nearest surface is then that roof, 2 m off."""
    offsets = np.array([[0.0, 0.0, 0.0], [-5.0, 5.0, 0.0]])
    points, headings, which = np.array([[0.0, 0.0, 10.0]]), np.zeros(1), np.zeros(1, dtype=np.int64)
    wall = np.array([[-8.0, 8.0], [-2.0, 8.0], [-2.0, 12.0], [-8.0, 12.0]])
    under = np.array([[-6.0, 4.0], [-4.0, 4.0], [-4.0, 6.0], [-6.0, 6.0]])
    no_spheres = np.zeros((0, 3)), np.zeros(0)
    for prisms, expected in (([(wall, 0.0, 20.0)], 3.0), ([(wall, 0.0, 20.0), (under, 0.0, 8.0)], 2.0)):
        shapes = pack_shapes(prisms=prisms)
        gap = shape_clearance(offsets[None], which, np.array([1]), points, headings, *no_spheres, *shapes)
        np.testing.assert_allclose(gap, [expected])


def test_min_jerk_profile_starts_and_ends_at_rest():
    assert min_jerk(0.0) == (0.0, 0.0, 0.0)
    assert min_jerk(1.0) == (1.0, 0.0, 0.0)
    assert min_jerk(0.5) == pytest.approx((0.5, 1.875, 0.0))  # the peak rate: 1.875 x the move per unit time
    # the derivatives are those of the quintic, by finite differences
    for tau in (0.1, 0.3, 0.7):
        h = 1e-6
        assert min_jerk(tau)[1] == pytest.approx(
            (min_jerk(tau + h)[0] - min_jerk(tau - h)[0]) / (2 * h), rel=1e-6
        )
        assert min_jerk(tau)[2] == pytest.approx(
            (min_jerk(tau + h)[1] - min_jerk(tau - h)[1]) / (2 * h), rel=1e-5
        )
    # the peak acceleration 10 / sqrt(3) where the jerk 60 (1 - 6 tau + 6 tau^2) is zero
    taus = np.linspace(0.0, 1.0, 100001)
    assert max(min_jerk(t)[2] for t in taus) == pytest.approx(MIN_JERK_PEAK_ACCEL, rel=1e-8)
    assert min_jerk((3 - math.sqrt(3)) / 6)[2] == pytest.approx(10 / math.sqrt(3))


def test_move_duration_keeps_both_limits():
    # 20 m at 2.5 m/s and 1 m/s^2: the rate bounds it (15 s; the acceleration alone: sqrt(5.77 x 20) = 10.7 s)
    assert move_duration(20.0, 2.5, 1.0) == pytest.approx(15.0)
    # 2 m: the acceleration bounds it (sqrt(5.7735 x 2 / 1) = 3.40 s, against 1.5 s at 2.5 m/s)
    assert move_duration(2.0, 2.5, 1.0) == pytest.approx(math.sqrt(20 / math.sqrt(3)))
    assert move_duration(0.0, 2.5, 1.0) == 0.0
    for distance in (0.5, 7.0, 35.0):
        duration = move_duration(distance, 4.0, 1.5)
        taus = np.linspace(0.0, 1.0, 2001)
        assert max(distance * min_jerk(t)[1] / duration for t in taus) <= 4.0 + 1e-9
        assert max(abs(distance * min_jerk(t)[2]) / duration**2 for t in taus) <= 1.5 + 1e-9


def _fly_shaper(
    shaper: FormationShaper, centres, radii, x0: float, x1: float, speed: float = 10.0, shapes=NO_SHAPES
):
    """Move the leader east from x0 to x1 at `speed` (or the shaper's pace cap), deciding every 0.02 s, among
    spheres and the packed `shapes`; the flown offsets per step."""
    flown, t, x = [], 0.0, x0
    wp = np.array([[400.0, 0.0, 10.0]])
    while x < x1:
        shaper.decide(
            t, np.array([x, 0.0, 10.0]), 0.0, wp, speed, min(speed, shaper.pace_cap), centres, radii, shapes
        )
        flown.append((t, x, *shaper.flown(t), shaper.shape_name))
        t += 0.02
        x += min(speed, shaper.pace_cap) * 0.02
    return flown


def test_a_v_wider_than_a_gap_narrows_or_falls_into_a_column_before_it_and_is_restored_after():
    """A V of four 10 m apart (28 m wide) meets a gap 12 m wide at x = 60: before its slots reach the gap the
    shape flown fits through it with 4 m to spare (every slot >= 4 m from both spheres), the slots never move
    faster than speed_m_s relative to the leader nor bring two followers within D_Emg + 1 m, and once the
    gap is behind the whole shape the V is restored. The leader flies at 10 m/s or the reshape's pace."""
    centres, radii = _gap_world(12.0)
    shaper = FormationShaper(PARAMS, _v(), 0, 4.0)
    steps = _fly_shaper(shaper, centres, radii, -100.0, 160.0)
    for t, x, offsets, rate, accel, name in steps:
        slots = np.array([x, 0.0, 10.0]) + offsets[1:]
        if 40.0 <= x <= 65.0 and name != "formation":
            gap = np.linalg.norm(slots[:, None, :] - centres[None], axis=-1) - radii
            assert gap.min() >= PARAMS.clearance_m - 1e-9, (t, x, name)
        assert np.linalg.norm(rate, axis=1).max() <= PARAMS.speed_m_s + 1e-9
        assert np.linalg.norm(accel, axis=1).max() <= PARAMS.accel_m_s2 + 1e-9
        d = np.linalg.norm(offsets[1:, None] - offsets[None, 1:], axis=-1)
        assert d[np.triu_indices(4, 1)].min() >= 4.0 - 1e-9
    names = [s[-1] for s in steps]
    assert names[0] == "formation"
    assert any(n != "formation" for n in names)
    assert names[-1] == "formation"
    changes = [(c.change, c.shape) for c in shaper.changes]
    assert changes[-1] == ("restored", "formation")
    assert any(change == "narrows" for change, _ in changes)
    assert shaper.changes[-1].sentence.endswith("s formation restored")


def test_a_v_wider_than_a_gap_between_two_buildings_narrows_before_it():
    """The same V and the same 12 m gap at x = 60, between two buildings instead of two spheres (footprints x
    52..68, |y| 6..22, 0..30 m high): the shaper sees the walls (spec 2.2) and, between x = 40 and 65, flies a
    narrower shape whose every slot keeps clearance_m from both, measured by shapely (the slots fly at 10 m,
    below the roofs, so the distance is the footprint's); and it is restored after."""
    walls = [
        np.array([[52.0, y0], [68.0, y0], [68.0, y1], [52.0, y1]]) for y0, y1 in ((6.0, 22.0), (-22.0, -6.0))
    ]
    shapes = pack_shapes(prisms=[(footprint, 0.0, 30.0) for footprint in walls])
    shaper = FormationShaper(PARAMS, _v(), 0, 4.0)
    steps = _fly_shaper(shaper, np.zeros((0, 3)), np.zeros(0), -100.0, 160.0, shapes=shapes)
    footprints = [Polygon(footprint) for footprint in walls]
    checked = 0
    for _, x, offsets, _, _, name in steps:
        if 40.0 <= x <= 65.0:
            assert name != "formation", x
            slots = [Point(x + o[0], o[1]) for o in offsets[1:]]
            assert min(f.distance(p) for f in footprints for p in slots) >= PARAMS.clearance_m - 1e-6, x
            checked += 1
    assert checked > 0 and steps[-1][-1] == "formation"


def test_a_column_whose_tail_is_short_of_a_gap_waits_to_open_until_the_way_is_clear():
    """A line abreast of four 10 m apart flown as a column 7 m apart (tail 28 m behind the leader), the
    leader 20 m past a 12 m gap at x = 60 (spheres of radius 8 at (60, +-14)). The line itself would fit
    where the leader is (its nearest slot (80, +-10) is 12.4 m from a sphere's surface), but its tail is at
    x = 52, still short of the gap: opening across first would carry the tail slots through the spheres. So
    the shaper keeps the column while the leader hovers there, and opens once the tail is through (leader at
    x = 110); the slots of the move it then flies, with the leader going on east at 10 m/s, keep clearance_m
    from both spheres at every moment (checked here by stepping the move in time)."""
    nominal = np.zeros((5, 3))
    nominal[1:] = formation_offsets("line", 4, 10.0)
    centres, radii = _gap_world(12.0)
    shaper = FormationShaper(PARAMS, nominal, 0, 4.0)
    column = len(shaper.shapes) - 1
    shaper._change_to(column, nominal, -100.0, announce=False)  # settled in the column long before t = 0
    assert shaper.move.duration < 100.0
    east = np.array([[400.0, 0.0, 10.0]])
    for t in np.arange(0.0, 3 * PARAMS.restore_after_s, PARAMS.decide_every_s):
        shaper.decide(t, np.array([80.0, 0.0, 10.0]), 0.0, east, 10.0, 0.0, centres, radii)
    assert shaper.current == column  # the line fits here, but the way there does not
    t0 = 10.0
    for t in np.arange(t0, t0 + 3 * PARAMS.restore_after_s, PARAMS.decide_every_s):
        shaper.decide(
            t, np.array([110.0 + 10.0 * (t - t0), 0.0, 10.0]), 0.0, east, 10.0, 10.0, centres, radii
        )
    assert shaper.current == 0
    move = shaper.move
    for t in np.arange(move.t0, move.t0 + move.duration, 0.05):
        leader = np.array([110.0 + 10.0 * (t - t0), 0.0, 10.0])
        slots = leader + move.at(t)[0][1:]  # heading east: leader frame = world frame
        gap = np.linalg.norm(slots[:, None, :] - centres[None], axis=-1) - radii
        assert gap.min() >= PARAMS.clearance_m - 1e-6, t


def _restore_x(widen_after_move: bool) -> tuple[float, float, FormationShaper]:
    """The V of four 10 m apart flown east at 10 m/s through the 12 m gap at x = 60 (_fly_shaper): the
    leader's x when the V is restored, and the smallest distance m from a flown slot to a sphere's surface
    with the leader at x >= 40 (from where the shape flown must fit through the gap)."""
    centres, radii = _gap_world(12.0)
    shaper = FormationShaper(replace(PARAMS, widen_after_move=widen_after_move), _v(), 0, 4.0)
    steps = _fly_shaper(shaper, centres, radii, -100.0, 200.0)
    restored = [c.t for c in shaper.changes if c.change == "restored"]
    assert len(restored) == 1
    x_at = {round(t, 6): x for t, x, *_ in steps}
    worst = min(
        float(
            (
                np.linalg.norm((np.array([x, 0.0, 10.0]) + offsets[1:])[:, None] - centres[None], axis=-1)
                - radii
            ).min()
        )
        for _, x, offsets, *_ in steps
        if x >= 40.0
    )
    return x_at[round(restored[0], 6)], worst, shaper


def test_a_formation_past_its_last_obstacle_opens_out_as_soon_as_the_move_keeps_clear():
    """Judged from where the leader is, the V is restored only once it fits there, its arms (15 m back and
    abeam) clear of both spheres by clearance_m + WIDEN_MARGIN_M (5 m): the leader some 40 m past the gap.
    Judged from where the leader will be when the move to it is over (widen_after_move, the default), it
    opens once the way there has kept clearance_m + 1 m for restore_after_s: more than 10 m sooner, while
    the V itself would still not fit where the leader then is, and no flown slot comes closer than
    clearance_m (4 m) to a sphere."""
    late, worst_late, _ = _restore_x(False)
    early, worst_early, shaper = _restore_x(True)
    assert early <= late - 10.0
    v_there = np.array([early, 0.0, 10.0]) + _v()[1:]
    centres, radii = _gap_world(12.0)
    gaps = np.linalg.norm(v_there[:, None] - centres[None], axis=-1) - radii
    assert gaps.min() < PARAMS.clearance_m + 1.0  # the V does not fit where the leader is when it opens
    assert min(worst_late, worst_early) >= PARAMS.clearance_m - 1e-6


def test_a_widening_under_way_is_given_up_when_an_obstacle_appears_on_its_way():
    """The V opening out early past the gap (as above), flown until just after it starts opening: at the
    next decision, with the leader flown on at 10 m/s, it keeps opening; but a sphere of radius 2 m
    appearing where the slot that moves farthest will be halfway through the rest of the move (with the
    leader where it will be then) makes the formation narrow again at once, rather than open into it."""
    early, _, _ = _restore_x(True)
    centres, radii = _gap_world(12.0)
    shaper = FormationShaper(replace(PARAMS, widen_after_move=True), _v(), 0, 4.0)
    steps = _fly_shaper(shaper, centres, radii, -100.0, early + 1.0)
    t_last, x_last = steps[-1][0], steps[-1][1]
    move = shaper.move
    t_next = shaper.next_decision
    x_next = x_last + 10.0 * (t_next - t_last)
    assert shaper.current == 0 and shaper.opening_early and t_next < move.t0 + move.duration
    t_mid = 0.5 * (t_next + move.t0 + move.duration)  # halfway through the rest of the move
    row = int(np.argmax(np.linalg.norm(move.end - move.start, axis=1)))  # the slot that moves farthest
    in_the_way = np.array([x_next + 10.0 * (t_mid - t_next), 0.0, 10.0]) + move.at(t_mid)[0][row]
    east = np.array([[400.0, 0.0, 10.0]])
    for extra, keeps_opening in ((None, True), (in_the_way, False)):
        probe = copy.deepcopy(shaper)
        c, r = (centres, radii) if extra is None else (np.vstack([centres, extra]), np.append(radii, 2.0))
        probe.decide(t_next, np.array([x_next, 0.0, 10.0]), 0.0, east, 10.0, 10.0, c, r)
        assert (probe.current == 0) is keeps_opening


def _turning_route(turn_at: float, turn_rad: float):
    """A route east from the origin at 10 m height, sampled every 2 m, whose heading steps to `turn_rad`
    `turn_at` m along (the points themselves run on east: no obstacle is near them)."""

    def route(length: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        along = np.arange(0.0, length + 2.0, 2.0)
        points = np.stack([along, np.zeros_like(along), np.full_like(along, 10.0)], axis=1)
        return points, np.where(along < turn_at, 0.0, turn_rad), along

    return route


@pytest.mark.parametrize(
    "turn_at, turn_deg, widens",
    [
        (20.0, 45.0, False),  # a corner 20 m ahead: the leader turns 45 deg while the V opens
        (20.0, 15.0, True),  # a bend of 15 deg is straight enough (straight_for: 20 deg)
        (2000.0, 45.0, True),  # the corner lies beyond the leader's travel while the V opens
    ],
)
def test_a_column_widens_only_where_the_route_runs_straight_while_it_opens(turn_at, turn_deg, widens):
    """A column of four, settled, nothing near, its V fitting since long before: at 10 m/s the V opens at
    once where the route runs straight over the leader's travel while it opens (its move takes seconds:
    tens of metres, more than 20 m and less than 2000 m), and waits where the route turns more than 20 deg
    within that travel (in a turn the slots would sweep round the leader as they move), without the way
    being taken as blocked."""
    shaper = FormationShaper(PARAMS, _v(), 0, 4.0)
    column = len(shaper.shapes) - 1
    shaper._change_to(column, shaper.shapes[column].offsets, -100.0, announce=False)
    shaper.wider_since = -10.0
    far = np.array([[0.0, 5000.0, 10.0]]), np.array([1.0])
    east = np.array([[3000.0, 0.0, 10.0]])
    route = _turning_route(turn_at, math.radians(turn_deg))
    shaper.decide(0.0, np.array([0.0, 0.0, 10.0]), 0.0, east, 10.0, 10.0, *far, route=route)
    assert (shaper.current == 0) is widens
    assert not shaper.widen_blocked
    if not widens:
        assert shaper.current == column and shaper.widening_due


def test_the_route_is_straight_while_its_heading_turns_at_most_20_deg():
    along = np.array([0.0, 2.0, 4.0, 6.0])
    headings = np.array([0.0, 0.1, 0.2, 0.5])  # rad: 11.5 deg over the first 4 m, 28.6 deg over 6 m
    assert straight_for(headings, along, 4.0)
    assert not straight_for(headings, along, 6.0)
    assert straight_for(np.array([3.1, -3.1, 3.12]), along[:3], 6.0)  # across +-pi: a turn of 0.08 rad


def _standing_route(length: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The leader's way ahead when it holds at (0, 0, 10) heading east: one point."""
    return np.array([[0.0, 0.0, 10.0]]), np.zeros(1), np.zeros(1)


@pytest.mark.parametrize(
    ("start_x", "end", "clear"),
    [
        (-28.0, (-20.0, 0.0), True),  # 2 m from the surface, moving straight away from it
        (-28.0, (-28.0, 10.0), True),  # 2 m, moving sideways: the sphere is right behind, so farther
        (-28.0, (-29.5, 0.0), False),  # 2 m, backing to 0.5 m: closer than it already was
        (-28.0, (-28.3, 0.0), True),  # 2 m, backing to 1.7 m: within MARGIN_SLACK_M (0.5 m) of its start
        (-20.0, (-25.0, 0.0), True),  # 10 m, ending 5 m off: clearance_m (4) kept
        (-20.0, (-28.0, 0.0), False),  # 10 m, ending 2 m off: inside clearance_m
    ],
)
def test_a_move_is_clear_if_no_slot_comes_closer_than_clearance_m_or_than_it_already_was(start_x, end, clear):
    """One follower slot moving straight along +-x / y in the leader frame, the leader holding at (0, 0, 10)
    heading east, a sphere of radius 1 m at (-31, 0, 10): a slot at x = -28 is 2 m from its surface (inside
    PARAMS.clearance_m, 4 m), one at x = -20 is 10 m. A move may take a slot out of the margin or along it,
    never deeper into it than MARGIN_SLACK_M; a slot outside the margin must stay outside it."""
    shaper = FormationShaper(PARAMS, np.zeros((2, 3)), 0, 4.0)
    start, stop = np.zeros((2, 3)), np.zeros((2, 3))
    start[1] = [start_x, 0.0, 0.0]
    stop[1] = [end[0], end[1], 0.0]
    move = plan_move(start, stop, np.ones(2, dtype=bool), 0.0, PARAMS.speed_m_s)
    sphere = np.array([[-31.0, 0.0, 10.0]]), np.array([1.0])
    assert (shaper.clear_floor(move, _standing_route, 0.0, *sphere) is not None) is clear


@pytest.mark.parametrize(
    ("end", "clear"),
    [
        ((-27.0, 2.0), False),  # hypot(4, 2) - 1 = 3.47 m from the surface: inside clearance_m (4 m)
        ((-25.0, 3.0), True),  # hypot(6, 3) - 1 = 5.71 m: outside it
    ],
)
def test_one_slot_in_an_obstacles_margin_does_not_let_another_into_it(end, clear):
    """As above, with two follower slots: one holds at x = -28, 2 m from the sphere's surface (inside the
    margin already); the other moves from (-20, 10), hypot(11, 10) - 1 = 13.87 m from the surface, straight
    toward it. Its own floor is clearance_m, not the 2 m of the slot beside it (legs3-2 re-formed at its goal
    with one slot passing 1.6 m from a sphere because another had started 1.6 m from it)."""
    shaper = FormationShaper(PARAMS, np.zeros((3, 3)), 0, 4.0)
    start, stop = np.zeros((3, 3)), np.zeros((3, 3))
    start[1] = stop[1] = [-28.0, 0.0, 0.0]
    start[2] = [-20.0, 10.0, 0.0]
    stop[2] = [end[0], end[1], 0.0]
    move = plan_move(start, stop, np.ones(3, dtype=bool), 0.0, PARAMS.speed_m_s)
    sphere = np.array([[-31.0, 0.0, 10.0]]), np.array([1.0])
    floor = shaper.clear_floor(move, _standing_route, 0.0, *sphere)
    assert (floor is not None) is clear
    if clear:  # the least floor of the two: the holding slot's 2 m, less the slack of a slot in the margin
        assert floor == pytest.approx(2.0 - MARGIN_SLACK_M)


def test_a_column_whose_tail_came_to_rest_in_an_obstacles_margin_still_opens_at_the_goal():
    """The leader holds at its last waypoint (0, 0, 10) heading east with a column 7 m apart behind it; a
    sphere of radius 1 m right behind the tail slot (-28, 0) leaves it 2 m from the surface, inside
    clearance_m (4 m). The mission's line (slots abeam the leader, 31 m or more from the sphere) fits there,
    and every way from the column to the line takes the tail forward or sideways, away from the sphere: the
    formation re-forms once the line has kept fitting for restore_after_s instead of staying a column for
    good, and no slot gets closer to the sphere than the tail was."""
    nominal = np.zeros((5, 3))
    nominal[1:] = formation_offsets("line", 4, 10.0)
    centres, radii = np.array([[-31.0, 0.0, 10.0]]), np.array([1.0])
    shaper = FormationShaper(PARAMS, nominal, 0, 4.0)
    column = len(shaper.shapes) - 1
    shaper._change_to(column, nominal, -100.0, announce=False)  # settled in the column long before t = 0
    tail = shaper.flown(0.0)[0][:, 0].min()
    assert tail == pytest.approx(-28.0)
    goal = np.array([[0.0, 0.0, 10.0]])
    for t in np.arange(0.0, PARAMS.restore_after_s + 1.0, PARAMS.decide_every_s):
        shaper.decide(t, goal[0], 0.0, goal, 10.0, 0.0, centres, radii)
    assert shaper.current == 0
    move = shaper.move
    for t in np.arange(move.t0, move.t0 + move.duration + 0.05, 0.05):
        slots = shaper.flown(t)[0] + [0.0, 0.0, 10.0]  # leader frame = ENU here (heading east, at origin)
        gaps = np.linalg.norm(slots[1:] - centres[0], axis=1) - radii[0]
        assert gaps.min() >= 2.0 - 1e-6


def _column_at_goal(
    centres: np.ndarray, radii: np.ndarray, params: ReshapeParams = PARAMS
) -> tuple[FormationShaper, list[bool]]:
    """A line of four 10 m apart flown as a column 7 m apart, settled, the leader holding at its last
    waypoint (0, 0, 10) heading east among spheres (K, 3), (K,): decisions every decide_every_s for
    restore_after_s + 1 s; the shaper and whether a widening was due after each."""
    nominal = np.zeros((5, 3))
    nominal[1:] = formation_offsets("line", 4, 10.0)
    shaper = FormationShaper(params, nominal, 0, 4.0)
    shaper._change_to(len(shaper.shapes) - 1, nominal, -100.0, announce=False)
    goal = np.array([[0.0, 0.0, 10.0]])
    due = []
    for t in np.arange(0.0, PARAMS.restore_after_s + 1.0, PARAMS.decide_every_s):
        shaper.decide(t, goal[0], 0.0, goal, 10.0, 0.0, centres, radii)
        due.append(shaper.widening_due)
    return shaper, due


def test_a_widening_is_due_while_a_wider_shape_fits_at_the_goal_until_it_starts():
    """No obstacle: the line fits at once, so a widening is due from the first decision (the runner's
    arrival waits for it, FleetController.shape_settled) until restore_after_s has passed and the move to
    the line starts; then the move is under way and nothing more is due."""
    far = np.array([[1000.0, 0.0, 10.0]]), np.array([1.0])
    shaper, due = _column_at_goal(*far)
    waits = math.ceil(PARAMS.restore_after_s / PARAMS.decide_every_s - 1e-9)  # decisions before it starts
    assert due[:waits] == [True] * waits
    assert not any(due[waits + 1 :])
    assert shaper.current == 0 and shaper.move.duration > 0.0


def test_a_widening_whose_every_way_is_blocked_is_not_due_so_the_formation_still_arrives():
    """Spheres of radius 1 m 9 m to either side of the column, level with its third and fourth slots
    (x = -21, -28): each slot is 8 m or more from them (clearance_m is 4 m), and the line abeam the leader
    fits, but the move to it (across, then along: straight moves would pass closer than move_gap_m to each
    other) sweeps the tail slots sideways past the spheres, 2.5 m from their surfaces. The line stays due
    while it waits restore_after_s, then is found blocked: nothing is due and the column stays, so the
    runner's arrival is not held for good. (No turns at the goal: turned, the line has a clear way.)"""
    centres = np.array([[-24.5, 9.0, 10.0], [-24.5, -9.0, 10.0]])
    shaper, due = _column_at_goal(centres, np.array([1.0, 1.0]), replace(PARAMS, goal_turn_step_deg=0.0))
    assert due[0]
    assert shaper.current == len(shaper.shapes) - 1
    assert shaper.widen_blocked and not shaper.widening_due


def test_the_fleet_has_not_arrived_while_a_widening_is_due_unless_arrive_in_shape_is_off():
    """FleetController.shape_settled: false while a widening is due and reshape.arrive_in_shape is on (the
    default), true when it is off; false in both while a move is under way."""
    far = np.array([[1000.0, 0.0, 10.0]]), np.array([1.0])
    shaper, _ = _column_at_goal(*far)
    column = len(shaper.shapes) - 1
    for arrive_in_shape in (True, False):
        ctl = FleetController.__new__(FleetController)  # only the two attributes shape_settled reads
        ctl.reshape = replace(PARAMS, arrive_in_shape=arrive_in_shape)
        ctl.shaper = copy.deepcopy(shaper)
        ctl.shaper._change_to(column, ctl.shaper.shapes[column].offsets, -100.0, announce=False)
        ctl.shaper.wider_since = 0.0  # the line has fitted since t = 0: due
        assert ctl.shape_settled(1.0) is (not arrive_in_shape)
        ctl.shaper.wider_since = None
        assert ctl.shape_settled(1.0)
        ctl.shaper._change_to(0, ctl.shaper.shapes[column].offsets, 1.0, announce=False)
        assert not ctl.shape_settled(1.5)


@pytest.mark.parametrize(
    ("top_speed", "goal_move_speed"),
    [
        (None, 9.0),  # the pace off, nothing measured: goal_speed_m_s
        (math.inf, 6.0),  # not yet measured: speed_m_s
        (20.0, 9.0),  # fast followers: goal_speed_m_s
        (10.0, 8.5),  # their top speed less 1.5 m/s
        (6.9, 6.0),  # PX4 SIH's 6.9 m/s: 5.4 m/s is under speed_m_s, which stays
    ],
)
def test_a_formation_widening_at_its_goal_moves_its_slots_as_fast_as_the_followers_can_fly(
    top_speed, goal_move_speed
):
    """The column of `_column_at_goal` re-forms into the line with its leader holding at the goal: its slots
    move at up to goal_speed_m_s (9 m/s) within the slowest follower's measured top speed less 1.5 m/s, never
    under speed_m_s (6 m/s), and accelerate at up to accel_m_s2 + pace_decel_m_s2 (3.5 m/s^2) once that
    speed is above speed_m_s; the move is then quicker than at speed_m_s and accel_m_s2."""
    far = np.array([[1000.0, 0.0, 10.0]]), np.array([1.0])
    params = replace(PARAMS, goal_speed_m_s=9.0)
    slow, _ = _column_at_goal(*far, params)
    nominal = np.zeros((5, 3))
    nominal[1:] = formation_offsets("line", 4, 10.0)
    shaper = FormationShaper(params, nominal, 0, 4.0)
    shaper.followers_can_fly(top_speed)
    assert shaper.goal_move_speed == pytest.approx(goal_move_speed)
    shaper._change_to(len(shaper.shapes) - 1, nominal, -100.0, announce=False)
    goal = np.array([[0.0, 0.0, 10.0]])
    for t in np.arange(0.0, params.restore_after_s + 1.0, params.decide_every_s):
        shaper.decide(t, goal[0], 0.0, goal, 10.0, 0.0, *far)
    assert shaper.current == 0 == slow.current
    rate, accel = _peaks_sampled(shaper.move)
    assert rate <= goal_move_speed + 1e-6
    if goal_move_speed > params.speed_m_s:
        assert accel <= params.accel_m_s2 + params.pace_decel_m_s2 + 1e-6
        assert rate > params.speed_m_s  # the faster limit is used, not merely allowed
        assert shaper.move.duration < slow.move.duration - 1.0
    else:
        assert accel <= params.accel_m_s2 + 1e-6
        assert shaper.move.duration == pytest.approx(slow.move.duration)


def test_only_a_widening_whose_leader_stops_before_half_of_it_moves_the_slots_faster():
    """The leader flying east at 10 m/s toward its goal 40 m off (goal_eta: 4 s) or 400 m off (40 s: beyond
    GOAL_MOVE_HORIZON_S, not estimated). The column's move to the line, 9 m/s allowed, runs at the faster
    limit only when the leader is there before half of that move is over; else at speed_m_s, as away from
    the goal. The line's move into the column (a narrowing) keeps speed_m_s even at the goal: a column
    turned there at the faster limit while its followers still braked behind the leader swung two of them
    onto its new way at over 2 m/s (gap-16)."""
    assert goal_eta(np.zeros(3), np.array([[30.0, 0.0, 0.0], [30.0, 10.0, 0.0]]), 10.0) == pytest.approx(4.0)
    assert goal_eta(np.zeros(3), np.array([[400.0, 0.0, 0.0]]), 10.0) == math.inf
    assert goal_eta(np.zeros(3), np.array([[40.0, 0.0, 0.0]]), 0.0) == math.inf
    nominal = np.zeros((5, 3))
    nominal[1:] = formation_offsets("line", 4, 10.0)
    shaper = FormationShaper(replace(PARAMS, goal_speed_m_s=9.0), nominal, 0, 4.0)
    shaper.followers_can_fly(20.0)
    column_index = len(shaper.shapes) - 1
    column = shaper.shapes[column_index].offsets
    shaper.goal_eta_s = 0.0
    narrowing_at_goal = shaper._plan(column_index, nominal, 0.0)
    shaper.goal_eta_s = math.inf
    narrowing = shaper._plan(column_index, nominal, 0.0)
    assert narrowing_at_goal.duration == pytest.approx(narrowing.duration)
    shaper._change_to(column_index, nominal, -100.0, announce=False)
    slow = shaper._plan(0, column, 0.0)
    shaper.goal_eta_s = 0.0
    quick = shaper._plan(0, column, 0.0)
    assert quick.duration < slow.duration
    for eta, expected in ((quick.duration / 2 - 0.01, quick), (quick.duration / 2 + 0.01, slow)):
        shaper.goal_eta_s = eta
        assert shaper._plan(0, column, 0.0).duration == pytest.approx(expected.duration)


def _column_beside_obstacles_at_goal(step_deg: float) -> tuple[FormationShaper, np.ndarray, np.ndarray]:
    """The column of `_column_at_goal` (slots 7, 14, 21, 28 m astern of the leader holding at (0, 0, 10)
    heading east) with a sphere of radius 1 m at (-28, -3), 2 m from its tail slot, and a sphere of radius
    1000 m whose surface runs 4.5 m to the right of the leader's line (centre (0, -1004.5)): decisions for
    restore_after_s + 1 s with turns every `step_deg` deg at the goal; the shaper and the two spheres."""
    centres = np.array([[-28.0, -3.0, 10.0], [0.0, -1004.5, 10.0]])
    radii = np.array([1.0, 1000.0])
    nominal = np.zeros((5, 3))
    nominal[1:] = formation_offsets("line", 4, 10.0)
    params = replace(PARAMS, goal_turn_step_deg=step_deg)
    shaper = FormationShaper(params, nominal, 0, 4.0)
    shaper._change_to(len(shaper.shapes) - 1, nominal, -100.0, announce=False)
    goal = np.array([[0.0, 0.0, 10.0]])
    for t in np.arange(0.0, PARAMS.restore_after_s + 1.0, PARAMS.decide_every_s):
        shaper.decide(t, goal[0], 0.0, goal, 10.0, 0.0, centres, radii)
    return shaper, centres, radii


def test_a_column_whose_tail_stands_beside_an_obstacle_at_the_goal_turns_to_where_it_fits():
    """`_column_beside_obstacles_at_goal`, worked by hand (clearance_m 4 m, 5 m for a wider shape):
    - every line or narrowed line, however turned, has one slot on the right of the leader's line or on
      it, within 4.5 + 0.2 m of the big sphere (|x| <= 20 m: its surface bulges at most 20^2 / 2009 m), so
      none fits; nor does the column unturned (its tail 2 m from the small sphere);
    - turned +15 deg (counter-clockwise) the tail slot swings right to (-27.05, -7.25), inside the big
      sphere; turned -15 deg it swings left to (-27.05, 7.25), 9.29 m from the small sphere's surface and its
      other slots farther, so the column turned -15 deg is the least turned that fits;
    - its move (each slot straight to its turned place, the tail 2 x 28 sin 7.5 deg = 7.31 m, neighbours
      at least 7 cos 7.5 deg = 6.94 m apart) takes the tail away from the small sphere, so it keeps the 2 m
      it starts with.
    The formation turns at once (no wider shape), the event says so, and no slot comes closer than 2 m."""
    shaper, centres, radii = _column_beside_obstacles_at_goal(15.0)
    column = len(shaper.shapes) - 1
    assert shaper.current == column and shaper.turn == pytest.approx(math.radians(-15.0))
    (change,) = shaper.changes
    assert change.t == 0.0 and change.change == "turns" and change.turn_deg == pytest.approx(-15.0)
    assert change.sentence == "t=0.00 s formation turns: column turned -15 deg"
    assert change.as_json()["turn_deg"] == -15.0
    assert shaper.shape_name == "column turned -15 deg"
    move = shaper.move
    end = shaper.flown(move.t0 + move.duration)[0]
    c, s = math.cos(math.radians(15)), math.sin(math.radians(15))
    expected = [(-7 * k * c, 7 * k * s) for k in range(1, 5)]
    assert sorted(map(tuple, end[1:, :2].round(2))) == sorted(tuple(np.round(e, 2)) for e in expected)
    for t in np.arange(move.t0, move.t0 + move.duration + 0.05, 0.05):
        slots = shaper.flown(t)[0][1:] + [0.0, 0.0, 10.0]  # leader frame = ENU here (heading east, at origin)
        assert (np.linalg.norm(slots - centres[0], axis=1) - radii[0]).min() >= 2.0 - 1e-6
    assert not shaper.widening_due


def test_with_no_turns_at_the_goal_the_column_stays_beside_the_obstacle():
    """goal_turn_step_deg 0: the same world, nothing fits, and no unturned shape clears the obstacles by
    CLEARER_M more than the column (every line reaches into the big sphere), so the column stays as it is."""
    shaper, _, _ = _column_beside_obstacles_at_goal(0.0)
    assert shaper.current == len(shaper.shapes) - 1 and shaper.turn == 0.0 and not shaper.changes


def test_a_formation_turned_at_the_goal_is_unturned_as_soon_as_the_leader_leaves_it():
    """A console goto after the turn above: the leader 50 m from its new waypoint, out in the open to the
    north-west (no obstacle within reach of any slot); the first decision unturns the column at once (the
    turn is for the goal only), and the wider shapes follow as they fit."""
    shaper, centres, radii = _column_beside_obstacles_at_goal(15.0)
    t = shaper.move.t0 + shaper.move.duration + 1.0
    here, far = np.array([-500.0, 500.0, 10.0]), np.array([[-550.0, 500.0, 10.0]])
    shaper.decide(t, here, math.pi, far, 10.0, 0.0, centres, radii)
    assert shaper.turn == 0.0
    assert shaper.changes[-1].change == "turns" and shaper.changes[-1].shape == "column"


def test_a_wider_shape_waits_restore_after_s_before_the_formation_widens():
    centres, radii = _gap_world(12.0)
    shaper = FormationShaper(PARAMS, _v(), 0, 4.0)
    shaper.decide(
        0.0, np.array([30.0, 0.0, 10.0]), 0.0, np.array([[400.0, 0.0, 10.0]]), 10.0, 10.0, centres, radii
    )
    narrowed = shaper.current
    assert narrowed > 0
    far = centres + [1000.0, 0.0, 0.0]  # the obstacles gone: the V fits again
    shaper.decide(
        1.0, np.array([30.0, 0.0, 10.0]), 0.0, np.array([[400.0, 0.0, 10.0]]), 10.0, 10.0, far, radii
    )
    shaper.decide(
        1.0 + PARAMS.restore_after_s / 2,
        np.zeros(3),
        0.0,
        np.array([[400.0, 0.0, 10.0]]),
        10.0,
        10.0,
        far,
        radii,
    )
    assert shaper.current == narrowed
    shaper.decide(
        1.0 + PARAMS.restore_after_s + 0.01,
        np.zeros(3),
        0.0,
        np.array([[400.0, 0.0, 10.0]]),
        10.0,
        10.0,
        far,
        radii,
    )
    assert shaper.current == 0


def test_paper_plain_turns_reshaping_off_and_the_controller_flies_the_mission_offsets():
    assert PAPER_PLAIN["guidance.reshape"] == {"enabled": False}
    paper = ReshapeParams(**PAPER_PLAIN["guidance.reshape"])
    off = FleetController(5, 0, _v(), np.array([[100.0, 0.0, 10.0]]), reshape=paper)
    on = FleetController(5, 0, _v(), np.array([[100.0, 0.0, 10.0]]), reshape=ReshapeParams())
    assert off.shaper is None and on.shaper is not None
    np.testing.assert_array_equal(off.flown_offsets, _v())


@pytest.mark.parametrize(
    "bad",
    [{"speed_m_s": 0.0}, {"min_spacing_m": -1.0}, {"steps": 0}, {"lookahead_s": 0.0}, {"clearance_m": -1.0}],
)
def test_impossible_settings_are_refused(bad):
    with pytest.raises(ValueError):
        ReshapeParams(**bad)


def _closest_pair_sampled(move: SlotMove, moments: int = 2001) -> float:
    """m, the closest two slots of `move` come at any of `moments` evenly spaced moments of it."""
    gaps = [
        float(np.min(np.linalg.norm(o[:, None] - o[None], axis=-1)[np.triu_indices(len(o), 1)]))
        for o in (move.at(t)[0] for t in np.linspace(move.t0, move.t0 + move.duration, moments))
    ]
    return min(gaps)


def _peaks_sampled(move: SlotMove, moments: int = 2001) -> tuple[float, float]:
    """The fastest m/s and hardest m/s^2 any slot of `move` moves relative to the leader, sampled."""
    rates, accels = zip(
        *(move.at(t)[1:] for t in np.linspace(move.t0, move.t0 + move.duration, moments)), strict=True
    )
    return (
        max(float(np.linalg.norm(r, axis=1).max()) for r in rates),
        max(float(np.linalg.norm(a, axis=1).max()) for a in accels),
    )


def test_a_column_opens_into_a_line_cutting_the_corner_where_straight_moves_would_pass_too_close():
    """Column 7 m apart -> line abreast 10 m apart at 2.5 m/s. Straight diagonal moves would pass 7 x 10 /
    sqrt(149) = 5.73 m apart, closer than move_gap_m (6 m). Across then along keeps them 7 m apart (each
    spreads to its own lane at its column place, then moves forward in it) but takes 1.875 x 20 / 2.5 +
    1.875 x 28 / 2.5 = 36 s. The plan starts forward while the slots are still spreading: quicker than that,
    no closer than move_gap_m, no slot faster than 2.5 m/s, and it ends on the line."""
    column = np.zeros((5, 3))
    column[1:, 0] = [-7.0, -14.0, -21.0, -28.0]
    line = np.zeros((5, 3))
    line[1:] = formation_offsets("line", 4, 10.0)
    rows = np.ones(5, dtype=bool)
    assert closest_approach(column, line) == pytest.approx(70.0 / math.sqrt(149.0))
    move = plan_move(column, line, rows, 0.0, 2.5, keep_apart=PARAMS.move_gap_m)
    assert len(move.phases) == 2
    assert move.duration < 1.875 * 20 / 2.5 + 1.875 * 28 / 2.5 - 1.0
    assert _closest_pair_sampled(move) >= PARAMS.move_gap_m - 1e-6
    assert _peaks_sampled(move)[0] <= 2.5 + 1e-6
    np.testing.assert_allclose(move.at(move.duration)[0], line)
    assert closest_pair_in(move, rows) == pytest.approx(_closest_pair_sampled(move), abs=0.01)


def test_phases_of_a_move_may_overlap_and_each_axis_follows_its_own_profile():
    """A slot moving 10 m across in 4 s from t0 = 1 s and 20 m along in 5 s from 3 s after t0: at 3 s after
    t0 the across profile is at tau = 0.75 (min_jerk 0.896) and the along one not started; at 5 s across has
    arrived and along is at tau = 0.4 (0.317); the move lasts 8 s, and is cut into three stretches, the middle
    one (3-4 s) with both phases running."""
    start, end = np.zeros((2, 3)), np.zeros((2, 3))
    end[1] = [-20.0, 10.0, 0.0]
    move = SlotMove(start, end, 1.0, (((1, 2), 0.0, 4.0), ((0,), 3.0, 5.0)))
    assert move.duration == 8.0
    assert [(a, b, running) for a, b, running in move.stretches()] == [
        (0.0, 3.0, [0]),
        (3.0, 4.0, [0, 1]),
        (4.0, 8.0, [1]),
    ]
    at3 = move.at(4.0)[0][1]
    assert at3 == pytest.approx([0.0, 10.0 * min_jerk(0.75)[0], 0.0])
    at5, rate5, _ = move.at(6.0)
    assert at5[1] == pytest.approx([-20.0 * min_jerk(0.4)[0], 10.0, 0.0])
    assert rate5[1] == pytest.approx([-20.0 * min_jerk(0.4)[1] / 5.0, 0.0, 0.0])
    # 2 s in, the three stretches are left: 1 s of the first, all of the other two
    assert [d for d, _ in move.phases_left(3.0)] == pytest.approx([1.0, 1.0, 4.0])


@pytest.mark.parametrize("keep_apart", [6.0, 7.0])
def test_a_move_is_the_quickest_that_keeps_the_slots_far_enough_apart(keep_apart):
    """Column 7 m apart -> line abreast 12 m apart, the column's followers to y = 12, -12, 24, -24. Straight,
    two slots whose separation turns from a (along) to b (across) pass at |a| |b| / sqrt(|a|^2 + |b|^2): the
    closest pair is the leader and the first follower (a = 7, b = 12: 84 / sqrt(193) = 6.05 m). Straight, the
    longest move is the tail's (28 m back, 24 m across: sqrt(1360) = 36.9 m), 1.875 x 36.9 / 6 = 11.5 s at
    6 m/s (its acceleration, sqrt(5.77 x 36.9 / 2) = 10.3 s, binds less). Across then along keeps 7 m (each
    slot spreads at its column place, then moves forward in its own lane), 24 m then 28 m, each bound by the
    acceleration: sqrt(5.77 x 24 / 2) + sqrt(5.77 x 28 / 2) = 8.3 + 9.0 s. Asked to keep 6 m, the plan is no
    slower than straight; asked to keep 7 m, where straight does not, it keeps 7 m and cuts the corner (its
    forward moves start before the spreading ends), quicker than across then along. Always within 6 m/s and
    2 m/s^2."""
    column = np.zeros((5, 3))
    column[1:, 0] = [-7.0, -14.0, -21.0, -28.0]
    line = np.zeros((5, 3))
    line[1:, 1] = [12.0, -12.0, 24.0, -24.0]
    assert closest_approach(column, line) == pytest.approx(84.0 / math.sqrt(193.0))
    move = plan_move(column, line, np.ones(5, dtype=bool), 0.0, 6.0, 2.0, keep_apart)
    if keep_apart == 6.0:
        assert move.duration <= 1.875 * math.sqrt(28.0**2 + 24.0**2) / 6.0 + 1e-9
    else:
        sequential = math.sqrt(MIN_JERK_PEAK_ACCEL * 24.0 / 2.0) + math.sqrt(MIN_JERK_PEAK_ACCEL * 28.0 / 2.0)
        assert move.duration < sequential - 1.0
    fastest, hardest = _peaks_sampled(move)
    assert fastest <= 6.0 + 1e-6 and hardest <= 2.0 + 1e-3
    assert _closest_pair_sampled(move) >= keep_apart - 1e-3
    np.testing.assert_allclose(move.at(move.duration)[0], line)


@pytest.mark.parametrize("moments, rows", [(1, 2), (7, 3), (128, 60)])
def test_the_closest_pair_sampled_is_scipys_smallest_pairwise_distance(moments, rows):
    """closest_pair_sampled (compiled) against scipy's pdist at each moment, on random positions with one
    pair placed 0.37 m apart at one moment; and inf for a single row."""
    rng = np.random.default_rng(moments)
    positions = rng.uniform(-40.0, 40.0, (moments, rows, 3))
    positions[moments // 2, rows - 1] = positions[moments // 2, 0] + [0.0, 0.37, 0.0]
    expected = min(float(pdist(here).min()) for here in positions)
    assert closest_pair_sampled(positions) == pytest.approx(expected, rel=1e-12)
    assert expected <= 0.37 + 1e-12
    assert closest_pair_sampled(positions[:, :1]) == math.inf


def _plan_move_every_order(start, end, rows, speed, accel, keep_apart, orders, rate):
    """The choice plan_move's docstring states, made by timing every order and finding every closest
    approach: the quickest that keeps the rows apart (the first of equals), else the one that passes
    farthest apart (the first of equals)."""
    floor = min(
        keep_apart, closest_approach(start[rows], start[rows]), closest_approach(end[rows], end[rows])
    )
    settle_s = 0.0 if rate is None else settle_duration(rate, PARAMS.settle_accel_m_s2)
    carried = rate if settle_s > 0.0 else None
    moves = [
        SlotMove(start, end, 0.0, timed_phases(start, end, o, speed, accel), carried, settle_s)
        for o in orders
    ]
    gaps = [closest_pair_in(m, rows) for m in moves]
    kept = [k for k, gap in enumerate(gaps) if gap >= floor - 1e-6]
    if kept:
        return moves[min(kept, key=lambda k: (moves[k].duration, k))]
    return moves[min(range(len(moves)), key=lambda k: (-gaps[k], k))]


@pytest.mark.parametrize("seed", range(12))
@pytest.mark.parametrize("assembled", [True, False])
def test_a_planned_move_is_the_one_every_order_timed_and_checked_would_give(seed, assembled):
    """plan_move finds the closest approach quickest order first and stops at the first that keeps the
    slots apart; on random starts and ends of three to eight followers (assigned by the shortest longest
    move or as drawn, crossing; at rest or moving), it picks exactly the move that timing and checking every
    order picks, whether some order keeps them apart or none does."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 10))
    start, end = np.zeros((n, 3)), np.zeros((n, 3))
    start[1:, :2] = rng.uniform(-25.0, 25.0, (n - 1, 2))
    end[1:, :2] = rng.uniform(-25.0, 25.0, (n - 1, 2))
    if seed % 3:  # assigned as a change of shape assigns them (FormationShaper._plan); else as drawn
        order, _ = assign_moves(start[1:], end[1:], PARAMS.move_gap_m)
        end[1:] = end[1:][order]
    rate = rng.uniform(-3.0, 3.0, (n, 3)) * [1.0, 1.0, 0.0] if seed % 2 else None
    if rate is not None:
        rate[0] = 0.0
    rows = np.ones(n, dtype=bool)
    orders = tuple(MOVE_ORDERS.values()) if assembled else UNASSEMBLED_ORDERS
    keep_apart = PARAMS.move_gap_m if assembled else math.inf
    expected = _plan_move_every_order(start, end, rows, 6.0, 2.0, keep_apart, orders, rate)
    move = plan_move(start, end, rows, 0.0, 6.0, 2.0, keep_apart, orders, rate, PARAMS.settle_accel_m_s2)
    assert move.phases == expected.phases
    assert move.settle_s == expected.settle_s


def test_a_move_begun_while_the_slots_move_carries_their_rate_on_and_brings_it_to_rest():
    """A slot moving across at 3 m/s when a move that leaves it where it is starts: it starts at 3 m/s and
    no acceleration, and comes to rest within 2 m/s^2 after 3.94 x 3 / 2 = 5.91 s (the settling quintic
    tau (1 - tau)^3 (1 + 3 tau) bends hardest, 3.94 per unit, at tau = (16 - sqrt 76) / 30 = 0.243), having
    carried on 16 / 81 x 3 x 5.91 = 3.50 m at most (at tau = 1/3: 1/3 x (2/3)^3 x 2 = 16/81), then back."""
    start = np.zeros((2, 3))
    start[1] = [-7.0, 0.0, 0.0]
    rate = np.zeros((2, 3))
    rate[1] = [0.0, 3.0, 0.0]
    move = plan_move(start, start, np.ones(2, dtype=bool), 10.0, 6.0, 2.0, start_rate=rate)
    assert SETTLE_PEAK_ACCEL == pytest.approx(3.9402, abs=1e-4)
    assert move.duration == pytest.approx(3.9402 * 3.0 / 2.0, abs=1e-3)
    offsets, moving, accel = move.at(10.0)
    np.testing.assert_allclose(offsets, start, atol=1e-12)
    np.testing.assert_allclose(moving, rate, atol=1e-12)
    np.testing.assert_allclose(accel, 0.0, atol=1e-12)
    fastest, hardest = _peaks_sampled(move)
    assert fastest == pytest.approx(3.0) and hardest == pytest.approx(2.0, abs=1e-4)
    across = [move.at(t)[0][1, 1] for t in np.linspace(10.0, 10.0 + move.duration, 2001)]
    assert max(across) == pytest.approx(16.0 / 81.0 * 3.0 * move.duration, abs=1e-4)
    end = move.at(10.0 + move.duration)
    np.testing.assert_allclose(end[0], start, atol=1e-9)
    np.testing.assert_allclose(end[1], 0.0, atol=1e-9)
    np.testing.assert_allclose(end[2], 0.0, atol=1e-9)


def test_a_change_taking_over_from_a_move_under_way_keeps_the_slots_velocity():
    """A V of four ordered into a line (a console reshape) and, 2 s into that move, into a column: the
    slots' rate just after the second change is their rate just before it (the old move's), where it was a
    step to rest before; the column is reached, at rest."""
    shaper = FormationShaper(PARAMS, _v(), 0, 4.0)
    shaper.set_nominal(_line(4, 10.0), 0, 0.0)
    before = shaper.flown(2.0)[1]
    assert np.linalg.norm(before, axis=1).max() > 1.0  # the slots are moving
    column = np.zeros((5, 3))
    column[1:, 0] = [-7.0, -14.0, -21.0, -28.0]
    shaper.set_nominal(column, 0, 2.0)
    np.testing.assert_allclose(shaper.flown(2.0)[1], before, atol=1e-9)
    offsets, rate, _ = shaper.flown(2.0 + shaper.move.duration)
    np.testing.assert_allclose(np.sort(offsets[:, 0]), np.sort(column[:, 0]), atol=1e-9)
    np.testing.assert_allclose(rate, 0.0, atol=1e-9)


def _line(followers: int, spacing: float) -> np.ndarray:
    out = np.zeros((followers + 1, 3))
    out[1:] = formation_offsets("line", followers, spacing)
    return out


@pytest.mark.parametrize(
    "phases, room, speed",
    [
        ([(20.0, 0.0)], 50.0, 2.5),  # no floor: 50 m in 20 s
        ([(10.0, 2.0), (20.0, 0.0)], 300.0, 10.0),  # 300 m in 30 s: 10 m/s, above the floor
        # at v >= 2 the 30 s would take 30 v >= 60 m > 50: so v < 2, the floored phase at 2 m/s (20 m) and the
        # other at v: 20 + 20 v = 50, v = 1.5
        ([(10.0, 2.0), (20.0, 0.0)], 50.0, 1.5),
        ([(20.0, 0.0), (10.0, 2.0)], 50.0, 1.5),  # the order of the phases does not matter
        ([(10.0, 2.0), (20.0, 0.0)], 10.0, 0.0),  # the floor alone takes it 20 m: hover outside it
        # floors 0, 1 and 3: below 1 m/s the travel is 20 v + 10 + 30 (50 m at v = 0.5); between 1 and 3 it is
        # 20 v + 10 v + 30 (70 m at v = 4/3)
        ([(10.0, 1.0), (10.0, 3.0), (20.0, 0.0)], 50.0, 0.5),
        ([(10.0, 1.0), (10.0, 3.0), (20.0, 0.0)], 70.0, 4.0 / 3.0),
    ],
)
def test_pace_speed_covers_the_room_with_each_phase_at_least_at_its_floor(phases, room, speed):
    assert pace_speed(phases, room) == pytest.approx(speed)


def test_only_a_phase_in_which_slots_fall_back_has_a_pace_floor():
    """Line abreast of four 12 m apart -> column 7 m apart: the slots fall back 7..28 m along the heading in
    one phase and close in across in the other. The floor of the fall-back phase is the fastest a slot
    falls back in it (sampled from the move itself: speed_m_s, the profile's peak) less PACE_MARGIN_M_S; the
    phase across has none. The way back (column -> line) moves the slots forward: no floor at all."""
    line = _line(4, 12.0)
    column = np.zeros((5, 3))
    column[1:, 0] = [-7.0, -14.0, -21.0, -28.0]
    rows = np.ones(5, dtype=bool)
    move = plan_move(line, column, rows, 0.0, PARAMS.speed_m_s)
    fastest_back = max(-move.at(t)[1][:, 0].min() for t in np.linspace(0.0, move.duration, 2001))
    assert 0.0 < fastest_back <= PARAMS.speed_m_s + 1e-3
    along = next(i for i, (axes, _, _) in enumerate(move.phases) if 0 in axes)
    floors = [floor for _, floor in move.phases_left(0.0)]
    for (_, _, running), floor in zip(move.stretches(), floors, strict=True):
        expected = fastest_back - PACE_MARGIN_M_S if along in running else 0.0
        assert floor == pytest.approx(expected, rel=1e-4)
    assert any(floor > 0.0 for floor in floors) and any(floor == 0.0 for floor in floors)
    back = plan_move(column, line, rows, 0.0, PARAMS.speed_m_s)
    assert all(floor == 0.0 for _, floor in back.phases_left(0.0))
    # halfway through its first stretch, only that stretch's remaining half and the whole of the rest are left
    lengths = [b - a for a, b, _ in move.stretches()]
    assert [d for d, _ in move.phases_left(lengths[0] / 2)] == pytest.approx([lengths[0] / 2, *lengths[1:]])


def test_a_line_wider_than_a_gap_is_a_column_before_it_and_no_follower_reverses_at_speed():
    """A line abreast of four 12 m apart (48 m wide) meets a gap 16 m wide at x = 80, seen from x = -60 with
    the leader at 10 m/s: the change to a column (about 30 s of moves at speed_m_s) takes longer than the
    leader's 14 s to the gap, so the leader slows and, while the slots cross, waits. Before any slot reaches
    the spheres' span (x >= 72 - 4) the shape flown keeps clearance_m from both; and no follower ever moves
    backwards along the route faster than PACE_MARGIN_M_S (its slot's ground speed: the leader's plus the
    slot's rate), under the 2 m/s of a cusp."""
    centres, radii = _gap_world(16.0, x=80.0)
    shaper = FormationShaper(PARAMS, _line(4, 12.0), 0, 4.0)
    steps = _fly_shaper(shaper, centres, radii, -60.0, 140.0)
    previous_x = None
    for t, x, offsets, rate, _, name in steps:
        slots = np.array([x, 0.0, 10.0]) + offsets[1:]
        if slots[:, 0].max() >= 80.0 - 8.0 - PARAMS.clearance_m and slots[:, 0].min() <= 80.0 + 8.0:
            gap = np.linalg.norm(slots[:, None, :] - centres[None], axis=-1) - radii
            assert gap.min() >= PARAMS.clearance_m - 1e-9, (t, x, name)
        if previous_x is not None:
            leader_speed = (x - previous_x) / 0.02
            assert (leader_speed + rate[1:, 0]).min() >= -PACE_MARGIN_M_S - 1e-6, (t, x, name)
        previous_x = x
    assert "column" in [s[-1] for s in steps]
    assert steps[-1][-1] == "formation"


def test_the_leaders_pace_cap_falls_no_faster_than_pace_decel():
    """The same line and gap: the leader at 10 m/s is slowed by the pace, but its cap falls by at most
    pace_decel_m_s2 x the time between two decisions, starting from its speed, so followers whose slots
    brake with it are not asked to brake harder; and the pace does bind (the cap goes below 5 m/s: the slots
    move at 2.5 m/s, so the change takes long enough)."""
    centres, radii = _gap_world(16.0, x=80.0)
    params = replace(PARAMS, speed_m_s=2.5)
    shaper = FormationShaper(params, _line(4, 12.0), 0, 4.0)
    wp, x, t, speed = np.array([[400.0, 0.0, 10.0]]), -60.0, 0.0, 10.0
    decisions = []  # (t, cap) at every decision
    while x < 140.0:
        shaper.decide(t, np.array([x, 0.0, 10.0]), 0.0, wp, 10.0, speed, centres, radii)
        if shaper.paced_at == t:
            decisions.append((t, shaper.pace_cap))
        speed = min(10.0, shaper.pace_cap)
        x += speed * 0.02
        t += 0.02
    assert min(cap for _, cap in decisions) < 5.0
    for (t0, before), (t1, after) in zip(decisions, decisions[1:], strict=False):
        if math.isfinite(after):  # from the leader's speed (10 m/s, or the cap before where that bound it)
            start = min(before, 10.0)
            assert start - after <= params.pace_decel_m_s2 * (t1 - t0) + 1e-9, t1


def test_a_pace_cap_above_the_leaders_speed_does_not_delay_its_braking():
    """The same line and gap. A change with room to spare leaves a pace cap above the leader's speed (on
    gap-8 of the generated courses a narrowing to 60 % left 20.5 m/s, and the column decided 0.2 s later
    needed 6 m/s): the next cap falls from the leader's speed, exactly as when the cap before was that speed,
    not from the cap before (from 20.5 m/s at pace_decel_m_s2 the cap stayed above the leader's 10 m/s for
    7 s, and the leader reached the gap with the column half formed)."""
    centres, radii = _gap_world(16.0, x=80.0)
    params = replace(PARAMS, speed_m_s=2.5)
    shaper = FormationShaper(params, _line(4, 12.0), 0, 4.0)
    wp, x, t = np.array([[400.0, 0.0, 10.0]]), -60.0, 0.0
    while not shaper.pace_cap < 10.0:  # fly at 10 m/s until the pace binds
        shaper.decide(t, np.array([x, 0.0, 10.0]), 0.0, wp, 10.0, 10.0, centres, radii)
        x += 10.0 * 0.02
        t += 0.02
        assert x < 80.0
    t = shaper.next_decision
    capped = {}
    for before in (10.0, 25.0):
        twin = copy.deepcopy(shaper)
        twin.pace_cap = before
        twin.decide(t, np.array([x, 0.0, 10.0]), 0.0, wp, 10.0, 10.0, centres, radii)
        capped[before] = twin.pace_cap
    assert capped[25.0] == capped[10.0]
    assert capped[25.0] < 10.0


@pytest.mark.parametrize(
    "on_slots, assembly_move_max_s",
    [(True, 10.0), (False, 5.0), (False, 12.0)],
    ids=["on", "pursuing", "carried"],
)
def test_a_change_before_the_formation_has_assembled_starts_where_the_followers_stand(
    on_slots, assembly_move_max_s
):
    """A line abreast of four 12 m apart, a gap 16 m wide 60 m ahead: the column fits it, the line does not,
    and the first decision (the first tick) starts the change. Assembled (followers on their line slots from
    the start), the slots move from the line the quickest way that keeps move_gap_m: straight, one phase,
    at the line's spacing (scale 1). Not yet assembled (followers still in their launch row 5 m behind the
    leader, 4 m apart, 7-25 m from their line slots), the slots start where the followers stand, not from
    the line they were flying to (spec 6a.4): the move's start is the launch row, its spacing scale 4 / 12
    (so the repulsion range starts at min_spacing_m - 1 m, spec 6a.6, not at D_max), and the followers, on
    the slots of that moment, have assembled. Where the launch row's assembly move into the line (7.34-11.01
    s) and into every narrower candidate is over assembly_move_max_s (5 s: the narrowest line, 7 m apart,
    has a slot 14 m across, 9.43 m from every follower, no sooner than sqrt(5.7735 x 9.43 / 2) = 5.22 s;
    the column's last slot, 28 m astern, is 23.09 m from every follower, 8.16 s), the followers were
    pursuing their slots: the change's phases come one after the other (back, then across: the followers
    still converge on the slots; starting across half way back would be quicker and pass no closer). Where
    it is not (12 s), the assembly carried them on their
    slots from the first tick, so the change is planned as one after assembly: the second phase starts
    while the first runs, the quickest way that keeps them move_gap_m (6 m) apart, or as far as they stand
    (4 m) where that is less."""
    from tests.gcs_swarm.guidance.test_fleet_controller import DT, PointMassFleet

    line = _line(4, 12.0)
    centres, radii = _gap_world(16.0, x=60.0)
    params = replace(PARAMS, assembly_move_max_s=assembly_move_max_s)
    ctl = FleetController(5, 0, line, np.array([[300.0, 0.0, 10.0]]), control_dt=DT, reshape=params)
    launch_row = np.array([[0, 0, 0], [-5, -6, 0], [-5, -2, 0], [-5, 2, 0], [-5, 6, 0]], dtype=float)
    start = line.copy() if on_slots else launch_row
    plant = PointMassFleet(start + np.array([0.0, 0.0, 10.0]))
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    assert ctl.assembled is on_slots
    active = np.ones(5, dtype=bool)
    cmd = ctl.tick(0.0, plant.pos, plant.vel, plant.att, centres, radii, active)
    shaper = ctl.shaper
    assert shaper is not None and shaper.shape_name == "column"
    move = shaper.move
    np.testing.assert_allclose(move.start, start, atol=1e-9)
    np.testing.assert_allclose(cmd.slots[1:], start[1:] + np.array([0.0, 0.0, 10.0]), atol=1e-9)  # followers
    assert shaper.start_scale == pytest.approx(1.0 if on_slots else 4.0 / 12.0)
    ends = [begin + duration for _, begin, duration in move.phases]
    if on_slots:
        assert [axes for axes, _, _ in move.phases] == [(0, 1, 2)]
    elif assembly_move_max_s < 5.22:  # pursuing: one phase after the other
        assert [begin for _, begin, _ in move.phases[1:]] == pytest.approx(ends[:-1])
    else:  # carried on their slots: overlapping phases, apart as far as they stand
        assert len(move.phases) == 2 and move.phases[1][1] < ends[0] - 1e-6
        assert closest_pair_in(move, np.ones(5, dtype=bool)) >= 4.0 - 1e-6
    plant.step(cmd, active)
    ctl.tick(DT, plant.pos, plant.vel, plant.att, centres, radii, active)
    assert ctl.assembled


def test_a_change_before_the_formation_has_assembled_starts_at_the_rate_the_followers_fly():
    """As above, not yet assembled, the followers of the launch row flying at (1, 2), (0, -3), (2, 0) and
    (-1, 1) m/s with the leader at rest heading east: the change starts at their rate (the leader's frame is
    ENU's turned by psi_L = 0, and does not turn), so their slots do not stop dead under them while they
    fly on (gap-19: a follower crossing at 5 m/s overshot its slot by 8.7 m, docs/metrics.md)."""
    from tests.gcs_swarm.guidance.test_fleet_controller import PointMassFleet

    line = _line(4, 12.0)
    centres, radii = _gap_world(16.0, x=60.0)
    ctl = FleetController(5, 0, line, np.array([[300.0, 0.0, 10.0]]), reshape=PARAMS)
    launch_row = np.array([[0, 0, 0], [-5, -6, 0], [-5, -2, 0], [-5, 2, 0], [-5, 6, 0]], dtype=float)
    plant = PointMassFleet(launch_row + np.array([0.0, 0.0, 10.0]))
    plant.vel[1:] = [[1.0, 2.0, 0.0], [0.0, -3.0, 0.0], [2.0, 0.0, 0.0], [-1.0, 1.0, 0.0]]
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    active = np.ones(5, dtype=bool)
    ctl.tick(0.0, plant.pos, plant.vel, plant.att, centres, radii, active)
    shaper = ctl.shaper
    assert shaper is not None and shaper.shape_name == "column"
    np.testing.assert_allclose(shaper.flown(0.0)[0][1:], launch_row[1:], atol=1e-9)
    np.testing.assert_allclose(shaper.flown(0.0)[1][1:], plant.vel[1:], atol=1e-9)


def _launch_row_fleet(params: ReshapeParams) -> tuple[FleetController, np.ndarray, np.ndarray]:
    """A line abreast of four 12 m apart (slots at -24, -12, 12, 24 m across) with nothing near, its followers
    in the launch row (5 m behind the leader, 4 m apart, flying at the velocities below), after the first
    tick: the controller, the launch row (5, 3) leader-frame m and the followers' velocities (5, 3) m/s."""
    from tests.gcs_swarm.guidance.test_fleet_controller import PointMassFleet

    far = np.array([[0.0, 5000.0, 10.0]]), np.array([1.0])
    ctl = FleetController(5, 0, _line(4, 12.0), np.array([[300.0, 0.0, 10.0]]), reshape=params)
    launch_row = np.array([[0, 0, 0], [-5, -6, 0], [-5, -2, 0], [-5, 2, 0], [-5, 6, 0]], dtype=float)
    plant = PointMassFleet(launch_row + np.array([0.0, 0.0, 10.0]))
    plant.vel[1:] = [[1.0, -1.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 0.0], [0.0, -0.5, 0.0]]
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    assert not ctl.assembled
    ctl.tick(0.0, plant.pos, plant.vel, plant.att, *far, np.ones(5, dtype=bool))
    return ctl, launch_row, plant.vel


# The launch row's move into the line, by hand: the longest move is 18 m across (-6 to -24) and 5 m along;
# no slot faster than 6 m/s nor harder than 2 m/s^2 (PARAMS); a minimum-jerk phase over D m peaks at
# 10 / sqrt(3) D / T^2. The quickest possible is one straight phase, max(1.875 x 18.68 / 6,
# sqrt(5.77 x 18.68 / 2)) = 7.34 s; across, then along keeps the followers as far apart as they stand (4 m:
# each spreads in its own row, then all move forward together) in sqrt(5.77 x 18 / 2) + sqrt(5.77 x 5 / 2)
# = 7.21 + 3.80 = 11.01 s, so the planner (the quickest way that keeps them that far apart) takes no longer
QUICKEST_LAUNCH_ROW_MOVE_S = math.sqrt(MIN_JERK_PEAK_ACCEL * math.hypot(18.0, 5.0) / 2)
SEQUENTIAL_LAUNCH_ROW_MOVE_S = math.sqrt(MIN_JERK_PEAK_ACCEL * 18 / 2) + math.sqrt(
    MIN_JERK_PEAK_ACCEL * 5 / 2
)


def test_a_formation_that_has_not_assembled_assembles_along_a_move_from_where_its_followers_stand():
    """With assembly_move_max_s over the launch row's move (at most 11.01 s), the first tick starts that
    move to the line from where the followers stand, at their rate, its spacing scale 4 / 12 (spec 6a.4), so
    they are on the slots of that moment and have assembled; the move ends in the line (each follower on one
    of its slots), at rest, and an event says so."""
    ctl, launch_row, vel = _launch_row_fleet(replace(PARAMS, assembly_move_max_s=12.0))
    shaper = ctl.shaper
    assert shaper is not None and shaper.shape_name == "formation" and not shaper.changes
    offsets, rate, _ = shaper.flown(0.0)
    np.testing.assert_allclose(offsets, launch_row, atol=1e-9)
    np.testing.assert_allclose(rate[1:], vel[1:], atol=1e-9)
    assert shaper.start_scale == pytest.approx(4.0 / 12.0)
    assert ctl.assembled
    assert QUICKEST_LAUNCH_ROW_MOVE_S - 1e-6 <= shaper.move.duration <= SEQUENTIAL_LAUNCH_ROW_MOVE_S + 1e-6
    end, end_rate, _ = shaper.flown(shaper.move.t0 + shaper.move.duration)
    np.testing.assert_allclose(sorted(map(tuple, end[1:])), sorted(map(tuple, _line(4, 12.0)[1:])), atol=1e-9)
    np.testing.assert_allclose(end_rate, 0.0, atol=1e-9)
    assert ctl.drain_events() == [
        f"t=0.00 s formation assembles along a planned move of {shaper.move.duration:.1f} s"
    ]


def test_followers_whose_assembly_move_would_take_too_long_fly_to_their_slots_on_their_own():
    """With assembly_move_max_s 7 s, under the quickest the launch row's move can be (7.34 s): the slots
    stay in the line, the followers fly to them (not assembled yet), and an event says why."""
    ctl, launch_row, _ = _launch_row_fleet(replace(PARAMS, assembly_move_max_s=7.0))
    shaper = ctl.shaper
    assert shaper is not None and not shaper.changes
    offsets, rate, _ = shaper.flown(0.0)
    np.testing.assert_allclose(offsets, _line(4, 12.0), atol=1e-9)
    np.testing.assert_allclose(rate, 0.0, atol=1e-12)
    assert not ctl.assembled
    (event,) = ctl.drain_events()
    taken = re.fullmatch(
        r"t=0\.00 s followers fly to their slots on their own \(a planned move would take ([\d.]+) s, over "
        r"assembly_move_max_s 7 s\)",
        event,
    )
    assert (
        taken
        and QUICKEST_LAUNCH_ROW_MOVE_S - 0.05 <= float(taken.group(1)) <= SEQUENTIAL_LAUNCH_ROW_MOVE_S + 0.05
    )


@pytest.mark.parametrize(
    "d_max, spacing, scale, expected",
    [
        (10.0, 10.0, 0.8, 8.0),  # the quickstart's V 10 m apart at 80 %: neighbours 8 m apart, the range 8 m
        (10.0, 10.0, 0.5, 6.0),  # 5 m apart would be under min_spacing_m (7) less the 1 m cushion: 6 m
        # legs2-10: a grid 8.106 m apart in a column 7 m apart (scale 7 / 8.106); the range was 10 x scale =
        # 8.64 m, so the first follower, on its slot 7 m astern, pushed the leader 1.2 m past its goal
        (10.0, 8.106, 7.0 / 8.106, 7.0),
        (10.0, 14.0, 0.9, 9.0),  # a spacing over D_max: D_max scaled, 9 m (neighbours 12.6 m apart, beyond)
    ],
)
def test_a_tighter_shapes_repulsion_range_is_its_own_spacing_at_most(d_max, spacing, scale, expected):
    """Spec 6a.6: min(D_max, max(min(D_max, L) s, min_spacing_m - 1)), L the mission's nearest spacing."""
    from gcs_swarm.guidance.reshape import shape_repulsion_range

    assert shape_repulsion_range(d_max, spacing, scale, 7.0) == pytest.approx(expected)


def _lagging_route(lag_per_m_s: float) -> Callable[[float], Route]:
    """The leader's path predicted at a speed cap v m/s: east from x = 0 along y = 0, every 2 m, the
    formation's heading lagging the path by lag_per_m_s x v rad (turned left: its astern slots swing
    right)."""

    def at(speed_cap: float) -> Route:
        def route(length: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            along = np.arange(0.0, length + 1e-9, 2.0)
            points = np.stack([along, np.zeros_like(along), np.full_like(along, 10.0)], axis=1)
            return points, np.full(len(along), lag_per_m_s * speed_cap), along

        return route

    return at


@pytest.mark.parametrize("lag_per_m_s, paced", [(0.04, 6.0), (0.0, math.inf)], ids=["lagging", "no-lag"])
def test_a_column_that_does_not_fit_its_path_at_speed_paces_the_leader_to_the_speed_at_which_it_does(
    lag_per_m_s, paced
):
    """A V of four 10 m apart; a sphere of radius 2 at (20, -14), 12 m right of the leader's path east: no
    V fits past it (a slot of the 10 m V flies at y = -14.1, of the 7 m one at y = -9.9, 2.1 m from its
    surface), the column, astern along the path, does (12 m): the shaper falls into the column 7 m apart
    (tail 28 m astern). Then the formation's heading lags the path by 0.04 rad per m/s of the leader's cap
    (spec 6a.10): the column's tail swings 28 sin(0.04 v) m right, 10.9 m at 10 m/s, so as the path goes
    past the sphere the tail comes within 14 - 10.9 - 2 = 1.1 m of its surface (8 m/s: 3.2 m; 6 m/s: 5.4
    m; 4 m/s: 7.5 m). No shape fits; the leader, at 10 m/s, is paced to 6 m/s, the fastest at which the
    column keeps clearance_m (4 m); the cap falls to it at pace_decel_m_s2. Without the lag (the column
    always fits) there is no such cap."""
    shaper = FormationShaper(PARAMS, _v(), 0, 4.0)
    centres, radii = np.array([[20.0, -14.0, 10.0]]), np.array([2.0])
    route_at = _lagging_route(lag_per_m_s)
    straight = _lagging_route(0.0)(10.0)  # the path at any speed, the heading along it
    wp = np.array([[400.0, 0.0, 10.0]])
    p_leader = np.array([0.0, 0.0, 10.0])
    shaper.decide(
        0.0, p_leader, 0.0, wp, 10.0, 10.0, centres, radii, route=straight, route_at=_lagging_route(0.0)
    )
    assert shaper.shape_name == "column" and math.isinf(shaper.footprint_cap)
    t = shaper.move.t0 + shaper.move.duration + 0.1  # the column at rest
    at_cap = route_at(10.0)
    shaper.decide(t, p_leader, 0.0, wp, 10.0, 10.0, centres, radii, route=at_cap, route_at=route_at)
    assert shaper.shape_name == "column"
    assert shaper.footprint_cap == pytest.approx(paced)
    assert shaper.pace_cap == pytest.approx(max(paced, 10.0 - PARAMS.pace_decel_m_s2 * (t - shaper.move.t0)))
    later = t + 10.0
    shaper.decide(
        later, p_leader, 0.0, wp, 10.0, 10.0, centres, radii, route=route_at(10.0), route_at=route_at
    )
    assert shaper.pace_cap == pytest.approx(paced)


LAUNCH_ROW = np.array([[0, 0, 0], [-5, -6, 0], [-5, -2, 0], [-5, 2, 0], [-5, 6, 0]], dtype=float)


def _first_tick_from_the_launch_row(goal_xy: tuple[float, float], params: ReshapeParams):
    """The line of four 12 m apart flying to goal_xy (ENU m, 10 m up), nothing near, its leader facing east
    (yaw 0) and its followers at rest in LAUNCH_ROW (5 m behind, 4 m apart, world axes): the controller, the
    point masses, the active mask, the far-off obstacle and the command, after the first tick."""
    from tests.gcs_swarm.guidance.test_fleet_controller import DT, PointMassFleet

    far = np.array([[0.0, -5000.0, 10.0]]), np.array([1.0])
    goal = np.array([[goal_xy[0], goal_xy[1], 10.0]])
    ctl = FleetController(5, 0, _line(4, 12.0), goal, control_dt=DT, reshape=params)
    plant = PointMassFleet(LAUNCH_ROW + np.array([0.0, 0.0, 10.0]))
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    active = np.ones(5, dtype=bool)
    cmd = ctl.tick(0.0, plant.pos, plant.vel, plant.att, *far, active)
    return ctl, plant, active, far, cmd


def test_a_formation_that_has_not_assembled_is_formed_facing_its_route():
    """The leader faces east (yaw 0) but its goal lies north, at (0, 300): the first tick turns psi_L to the
    route's bearing, pi/2, before it plans the assembly (spec 6a.4), and says so; the move starts from the
    launch row as a leader facing north sees it (x forward = north, y left = west: the follower 5 m west of
    the leader and 6 m south of it stands 6 m astern and 5 m to its left). Flown 8 s,
    psi_L stays at pi/2 while the leader gains speed north: the slots never swing round it."""
    from tests.gcs_swarm.guidance.test_fleet_controller import DT

    params = replace(PARAMS, assembly_move_max_s=60.0)  # the move is taken, however long
    ctl, plant, active, far, cmd = _first_tick_from_the_launch_row((0.0, 300.0), params)
    launch_row = LAUNCH_ROW
    assert ctl.heading is not None and ctl.heading.psi == pytest.approx(math.pi / 2)
    assert ctl.drain_events()[0] == "t=0.00 s formation faces its route: psi_L turned +90 deg"
    shaper = ctl.shaper
    assert shaper is not None
    seen_facing_north = np.stack([launch_row[:, 1], -launch_row[:, 0], launch_row[:, 2]], axis=1)
    np.testing.assert_allclose(shaper.move.start, seen_facing_north, atol=1e-9)
    headings, speeds = [], []
    for k in range(1, int(8.0 / DT)):
        plant.step(cmd, active)
        cmd = ctl.tick(k * DT, plant.pos, plant.vel, plant.att, *far, active)
        headings.append(ctl.heading.psi)
        speeds.append(plant.vel[0, 1])
    assert max(speeds) > ctl.reference.heading_min_speed  # psi_L would have turned by now
    assert np.abs(np.array(headings) - math.pi / 2).max() < math.radians(2.0)


def test_a_formation_on_its_slots_keeps_the_leaders_yaw_at_the_start():
    """The same leader and goal, its followers on their slots of the line (east-facing, the leader's yaw):
    psi_L starts at the yaw, so no slot moves at once, and no event says it turned."""
    from tests.gcs_swarm.guidance.test_fleet_controller import PointMassFleet

    far = np.array([[0.0, -5000.0, 10.0]]), np.array([1.0])
    line = _line(4, 12.0)
    ctl = FleetController(5, 0, line, np.array([[0.0, 300.0, 10.0]]), reshape=PARAMS)
    plant = PointMassFleet(line + np.array([0.0, 0.0, 10.0]))
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    assert ctl.assembled
    cmd = ctl.tick(0.0, plant.pos, plant.vel, plant.att, *far, np.ones(5, dtype=bool))
    assert ctl.heading is not None and ctl.heading.psi == 0.0
    np.testing.assert_allclose(cmd.slots[1:], plant.pos[1:], atol=1e-9)
    assert not any("faces its route" in event for event in ctl.drain_events())


def test_a_formation_whose_move_facing_its_route_is_too_long_assembles_facing_the_leaders_yaw():
    """The same launch row, goal north, assembly_move_max_s 9 s. Facing north, the line's slots lie east and
    west of the leader and the launch row 5 m west of it: some follower must go to the slot 24 m east, at
    least sqrt(2^2 + 29^2) = 29.07 m from every follower, which no minimum-jerk phase at 2 m/s^2 covers in
    under sqrt(5.7735 x 29.07 / 2) = 9.16 s. Facing the leader's yaw (east) the move takes 7.34 s (above).
    So psi_L stays at the yaw, the assembly is planned in that frame (spec 6a.4; real PX4 SIH, 53 deg off
    its goal: 8.4 s so against 11.4 s turned), and no event says it turned."""
    ctl, *_ = _first_tick_from_the_launch_row((0.0, 300.0), replace(PARAMS, assembly_move_max_s=9.0))
    assert ctl.heading is not None and ctl.heading.psi == 0.0
    shaper = ctl.shaper
    assert shaper is not None and shaper.shape_name == "formation"
    np.testing.assert_allclose(shaper.move.start, LAUNCH_ROW, atol=1e-9)
    assert shaper.move.duration <= 9.0
    assert ctl.drain_events() == [
        f"t=0.00 s formation assembles along a planned move of {shaper.move.duration:.1f} s"
    ]


def test_a_formation_whose_move_into_its_shape_is_too_long_assembles_into_a_narrower_one():
    """The launch row at rest and the line of four 12 m apart, assembly_move_max_s 7 s: the move into the
    line itself takes at least 7.34 s (above), so the first tick carries the followers from where they
    stand into the widest narrower candidate whose move takes at most 7 s, the line 86 % as wide (10.33 m
    apart), and the formation has assembled: no follower pursues a slot standing elsewhere (gap-6: a
    follower deflected round another's launch spot overshot its slot, a cusp). Both are events. With
    nothing near, the shaper then restores the line along a planned move while the leader flies east."""
    from tests.gcs_swarm.guidance.test_fleet_controller import DT

    ctl, plant, active, far, cmd = _first_tick_from_the_launch_row(
        (300.0, 0.0), replace(PARAMS, assembly_move_max_s=7.0)
    )
    launch_row = LAUNCH_ROW
    shaper = ctl.shaper
    assert shaper is not None and ctl.assembled
    assert shaper.current == 1 and shaper.shapes[1].scale == pytest.approx(31.0 / 36.0)
    assert shaper.move.duration <= 7.0
    np.testing.assert_allclose(shaper.move.start, launch_row, atol=1e-9)
    assert ctl.drain_shape_changes()[0].sentence == f"t=0.00 s formation narrows: {shaper.shape_name}"
    duration = shaper.move.duration
    assert ctl.drain_events() == [f"t=0.00 s formation assembles along a planned move of {duration:.1f} s"]
    for k in range(1, int(40.0 / DT)):
        plant.step(cmd, active)
        cmd = ctl.tick(k * DT, plant.pos, plant.vel, plant.att, *far, active)
    assert shaper.shape_name == "formation"
    end = shaper.flown(k * DT)[0]
    np.testing.assert_allclose(sorted(map(tuple, end[1:])), sorted(map(tuple, _line(4, 12.0)[1:])), atol=1e-9)
