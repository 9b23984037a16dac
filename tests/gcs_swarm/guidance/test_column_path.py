"""A column that follows the leader's path (gcs_swarm.guidance.column_path, spec 6a.9): which formations are
columns, the path kept and the points behind the leader on it, checked against an L-shaped path worked by
hand, the evaluation's slots over a flight, and the controller's slots in closed loop round a corner."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.evaluation import metrics
from gcs_swarm.guidance.column_path import LeaderTrail, column_rows, path_motion, slots_along_path
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.params import ReshapeParams
from tests.gcs_swarm.guidance.test_fleet_controller import DT, PointMassFleet

STEP = 0.25  # m between the positions fed to the trail (exact in binary: the kept points fall on 0.5 m)


def _column(followers: int, spacing: float) -> np.ndarray:
    out = np.zeros((followers + 1, 3))
    out[1:, 0] = -spacing * np.arange(1, followers + 1)
    return out


def test_a_column_is_every_follower_astern_on_the_leaders_line():
    column = _column(3, 7.0)
    assert column_rows(column).tolist() == [1, 2, 3]
    lost = column.copy()
    lost[2] = np.nan  # a vehicle out of the formation does not make it something else
    assert column_rows(lost).tolist() == [1, 3]
    v = np.zeros((4, 3))
    v[1:] = formation_offsets("v", 3, 7.0)
    assert column_rows(v) is None
    ahead = column.copy()
    ahead[1, 0] = 7.0  # a slot ahead of the leader: not a column astern
    assert column_rows(ahead) is None
    stepped = column.copy()
    stepped[3, 2] = 2.0  # a slot 2 m up: not on the line
    assert column_rows(stepped) is None
    assert column_rows(np.zeros((3, 3))) is None  # the leader alone


EAST, NORTH, STILL = np.array([5.0, 0.0]), np.array([0.0, 2.0]), np.zeros(2)


def _l_path_trail(keep_m: float = 1000.0) -> LeaderTrail:
    """The leader starts at (0, 0, 10) heading east, flies east to (20, 0) at 5 m/s, then north to (20, 10)
    at 2 m/s, without accelerating, fed every STEP m."""
    trail = LeaderTrail(np.array([0.0, 0.0, 10.0]), EAST, STILL, 0.0, keep_m)
    for x in np.arange(STEP, 20.0 + STEP / 2, STEP):
        trail.record(np.array([x, 0.0, 10.0]), EAST, STILL)
    for y in np.arange(STEP, 10.0 + STEP / 2, STEP):
        trail.record(np.array([20.0, y, 10.0]), NORTH, STILL)
    return trail


def test_when_the_column_forms_its_path_is_the_line_astern():
    """Nothing flown yet: the points behind are the rigid column's slots, the leader (3, 4, 10) heading north
    (psi 90 deg), 7 and 14 m astern at (3, -3) and (3, -10); the way forward is north; nobody flew it, so
    it tells no turn."""
    here = np.array([3.0, 4.0, 10.0])
    trail = LeaderTrail(here, STILL, STILL, math.pi / 2, 50.0)
    points, velocities, accelerations, arcs = trail.behind(here, STILL, STILL, np.array([7.0, 14.0]))
    np.testing.assert_allclose(points, [[3.0, -3.0], [3.0, -10.0]], atol=1e-12)
    np.testing.assert_allclose(velocities, [[0.0, 1.0], [0.0, 1.0]], atol=1e-12)
    np.testing.assert_allclose(accelerations, 0.0)
    np.testing.assert_allclose(arcs, [7.0, 14.0], atol=1e-12)


@pytest.mark.parametrize(
    ("distance", "point", "velocity", "arc"),
    [
        (5.0, (20.0, 5.0), (0.0, 2.0), 5.0),  # on the north stretch, flown at 2 m/s
        # 10 m south to the corner, then west to where the straight line back is 12 m: 20 - sqrt(12^2 - 10^2)
        (12.0, (20.0 - math.sqrt(44.0), 0.0), (5.0, 0.0), 10.0 + math.sqrt(44.0)),
        (20.0, (20.0 - math.sqrt(300.0), 0.0), (5.0, 0.0), 10.0 + math.sqrt(300.0)),
        # the start (0, 0) is only sqrt(500) = 22.4 m away: on the line astern west of it (a unit velocity)
        (35.0, (20.0 - math.sqrt(1125.0), 0.0), (1.0, 0.0), 10.0 + math.sqrt(1125.0)),
    ],
)
def test_a_slot_is_the_first_point_back_along_the_path_at_its_distance_astern(distance, point, velocity, arc):
    trail = _l_path_trail()
    got = trail.behind(np.array([20.0, 10.0, 10.0]), NORTH, STILL, np.array([distance]))
    np.testing.assert_allclose(got[0][0], point, atol=1e-9)
    np.testing.assert_allclose(got[1][0], velocity, atol=1e-9)
    np.testing.assert_allclose(got[2][0], 0.0)
    assert got[3][0] == pytest.approx(arc)


def test_round_a_corner_neighbours_keep_their_spacing_as_a_straight_line():
    """A column 7 m apart behind the leader at (20, 10): the first slot 7 m back down the north stretch at
    (20, 3); the second 7 m from it in a straight line, 3 m on to the corner and then west: (20 - sqrt(40),
    0), 16.3 m of path behind the leader, not 14 (which would put it 5.4 m from the first). Given in any
    order."""
    trail = _l_path_trail()
    points = trail.behind(np.array([20.0, 10.0, 10.0]), NORTH, STILL, np.array([14.0, 7.0]))[0]
    np.testing.assert_allclose(points, [[20.0 - math.sqrt(40.0), 0.0], [20.0, 3.0]], atol=1e-9)
    assert np.hypot(*(points[0] - points[1])) == pytest.approx(7.0)


def test_a_path_trimmed_to_keep_m_goes_on_straight_back_along_its_oldest_piece():
    """Keeping 10 m, the east stretch is forgotten but for its last metre or so; the slot 25 m astern is then
    found straight back west from there, where the whole path has it too, (20 - sqrt(25^2 - 10^2), 0), as
    far along the path."""
    trail = _l_path_trail(keep_m=10.0)
    assert len(trail.points) <= 10.0 / 0.5 + 2
    leader = np.array([20.0, 10.0, 10.0])
    points, velocities, _, arcs = trail.behind(leader, NORTH, STILL, np.array([25.0]))
    np.testing.assert_allclose(points[0], [20.0 - math.sqrt(525.0), 0.0], atol=1e-9)
    np.testing.assert_allclose(velocities[0], [1.0, 0.0], atol=1e-9)
    assert arcs[0] == pytest.approx(10.0 + math.sqrt(525.0))


def _bend_trail() -> LeaderTrail:
    """The leader flew east from (0, 0) to (20, 0) at 5 m/s, then a quarter circle to the left round (20, 10)
    of radius 10 m at 5 m/s (2.5 m/s^2 towards the centre), then north to (30, 20), fed every 0.05 m."""
    trail = LeaderTrail(np.array([0.0, 0.0, 10.0]), EAST, STILL, 0.0, 1000.0)
    for x in np.arange(0.05, 20.0, 0.05):
        trail.record(np.array([x, 0.0, 10.0]), EAST, STILL)
    for angle in np.arange(0.005, math.pi / 2, 0.005):
        radial = np.array([math.sin(angle), -math.cos(angle)])  # from the centre out
        tangent = np.array([math.cos(angle), math.sin(angle)])
        where = np.array([20.0, 10.0]) + 10.0 * radial
        trail.record(np.array([where[0], where[1], 10.0]), 5.0 * tangent, -2.5 * radial)
    for y in np.arange(10.0, 20.0 + 0.025, 0.05):
        trail.record(np.array([30.0, y, 10.0]), np.array([0.0, 5.0]), STILL)
    return trail


@pytest.mark.parametrize(
    ("arc", "low", "high"),
    [
        # 10 m of path before the bend: braking at 1.5 m/s^2 from sqrt(2 x 1.5 x 10 + 2 x 10) = 7.07 m/s
        # to the bend's sqrt(2.0 x 10) = 4.47 m/s (the first bend point kept lies up to 0.5 m further on)
        (10.0 + 5 * math.pi + 10.0, math.sqrt(50.0), math.sqrt(50.0 + 3.0 * 0.5)),
        (10.0 + 2.5 * math.pi, math.sqrt(20.0), math.sqrt(20.0 + 3.0 * 0.5)),  # in the bend
        (5.0, math.inf, math.inf),  # past the bend: nothing to turn for
    ],
)
def test_the_leader_paces_its_column_so_that_each_slot_can_turn_round_the_bends_ahead(arc, low, high):
    """Turning at up to 2 m/s^2 round the bend of radius 10 m allows sqrt(2 x 10) m/s; braking for it at
    1.5 m/s^2 from `arc` m of path behind the leader (at (30, 20)) allows more farther back."""
    trail = _bend_trail()
    north = np.array([0.0, 5.0])
    pace = trail.pace(np.array([30.0, 20.0, 10.0]), north, STILL, np.array([arc]), 2.0, 1.5)
    assert low - 1e-6 <= pace <= high + 1e-6


def test_a_point_on_the_path_turns_as_the_leader_turned_there_at_its_own_speed():
    """The leader flew north at 5 m/s round a left turn of radius 20 m (centripetal 5^2 / 20 = 1.25 m/s^2,
    west): a point moving along it at 10 m/s, speeding up at 1 m/s^2, flies north at 10 m/s and needs 1 m/s^2
    north and 10^2 / 20 = 5 m/s^2 west. Where the leader's motion tells no turn (a unit velocity, no
    acceleration, as `behind` gives on the line astern) it flies straight."""
    velocity, acceleration = path_motion(
        np.array([[0.0, 5.0], [1.0, 0.0]]), np.array([[-1.25, 0.0], [0.0, 0.0]]),
        np.array([10.0, 3.0]), np.array([1.0, 0.0]),
    )  # fmt: skip
    np.testing.assert_allclose(velocity, [[0.0, 10.0], [3.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(acceleration, [[-5.0, 1.0], [0.0, 0.0]], atol=1e-12)


def _chain_on_l_path(leader_arc: float, spacing: float, count: int) -> list[np.ndarray]:
    """The column's slots behind a leader `leader_arc` m along the L path (east 20 m from (0, 0), then north;
    west of the start, the line astern), each `spacing` m in a straight line from the one before, worked out
    in closed form: from (20, y) the next is (20, y - spacing) if y >= spacing, else (20 - sqrt(spacing^2 -
    y^2), 0); from (x, 0) it is (x - spacing, 0)."""
    here = np.array([leader_arc, 0.0]) if leader_arc <= 20.0 else np.array([20.0, leader_arc - 20.0])
    out = [here]
    for _ in range(count):
        x, y = out[-1]
        if x == 20.0 and y >= spacing:
            out.append(np.array([20.0, y - spacing]))
        elif x == 20.0 and y > 0.0:
            out.append(np.array([20.0 - math.sqrt(spacing**2 - y**2), 0.0]))
        else:
            out.append(np.array([x - spacing, 0.0]))
    return out


def test_the_evaluation_measures_a_column_that_follows_the_path_against_the_path_flown():
    """Followers flown exactly in a column 7 m apart along the L path (placed by `_chain_on_l_path`, not by
    the trail) have no slot error where the flight says the column followed the path; measured against the
    rigid column turned to psi_L they would be metres off round the corner."""
    arcs = np.arange(0.0, 30.0 + STEP / 2, STEP)
    pos = np.zeros((len(arcs), 3, 3))
    pos[:, :, 2] = 10.0
    for k, s in enumerate(arcs):
        pos[k, :, :2] = _chain_on_l_path(s, 7.0, 2)
    psi = np.where(arcs < 20.0, 0.0, math.pi / 2)  # psi_L turns at the corner
    t = arcs / 5.0
    offsets = _column(2, 7.0)
    follows = np.ones(len(t), dtype=bool)
    along = metrics.formation_error(t, pos, 0, psi, offsets, follows_path=follows)
    np.testing.assert_allclose(along.error[:, 1:], 0.0, atol=1e-9)
    rigid = metrics.formation_error(t, pos, 0, psi, offsets)
    # just past the corner psi_L points north: the rigid tail slot is at (20, -13.75), the tail at (6.0, 0)
    assert rigid.error[:, 2].max() > 19.0
    leaders, table = np.zeros(len(t), dtype=int), np.broadcast_to(offsets, pos.shape)
    slots = slots_along_path(pos[:, 0], psi, leaders, table, ~follows)
    assert np.isnan(slots).all()  # not following: no path slots


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Horizontal distance (P,) m from each of points (P, 2) to the polyline line (L, 2)."""
    a, b = line[:-1], line[1:]
    ab = b - a
    length_sq = np.maximum((ab * ab).sum(axis=1), 1e-12)
    out = np.full(len(points), np.inf)
    for i, p in enumerate(points):
        s = np.clip(((p - a) * ab).sum(axis=1) / length_sq, 0.0, 1.0)
        out[i] = np.hypot(*(a + s[:, None] * ab - p).T).min()
    return out


@pytest.mark.parametrize("follows", [True, False])
def test_in_flight_a_columns_slots_stay_on_the_path_its_leader_flew_round_a_corner(follows):
    """A column of three, 10 m apart, flies east 80 m and then north 60 m (a 90 deg corner), its followers
    placed on their slots: with column_follows_path every follower slot the controller commands lies on the
    leader's own flown path (within 0.3 m: the path is kept every 0.5 m), including round the corner.
    Without it (the default) the column is the rigid stick astern of psi_L: once psi_L has turned by 45 deg
    the tail slot, 30 m astern, is 30 sin(45 deg) = 21 m off the east leg the path was, minus what the
    leader has flown north since, so metres off the path."""
    offsets = _column(3, 10.0)
    waypoints = np.array([[80.0, 0.0, 20.0], [80.0, 60.0, 20.0]])
    reshape = ReshapeParams(column_follows_path=follows)
    ctl = FleetController(4, 0, offsets, waypoints, control_dt=DT, reshape=reshape)
    plant = PointMassFleet(offsets + np.array([0.0, 0.0, 20.0]))
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    active = np.ones(4, dtype=bool)
    none_c, none_r = np.zeros((0, 3)), np.zeros(0)
    flown, slots = [plant.pos[0, :2].copy()], []
    for k in range(int(40.0 / DT)):
        cmd = ctl.tick(k * DT, plant.pos, plant.vel, plant.att, none_c, none_r, active)
        assert ctl.follows_path == follows  # a column from the start
        slots.append(cmd.slots[1:, :2].copy())
        plant.step(cmd, active)
        flown.append(plant.pos[0, :2].copy())
    assert plant.pos[0, 1] > 30.0  # the leader went round the corner
    path = np.vstack([np.array([[-40.0, 0.0]]), np.array(flown)])  # the line astern at the start, then flown
    gaps = _distance_to_polyline(np.concatenate(slots), path)
    assert gaps.max() < 0.3 if follows else gaps.max() > 5.0
