"""The leader's route round a gap its formation cannot fly (gcs_swarm.guidance.route_plan, the stall test of
gcs_swarm.guidance.leader_path and FleetController's via points, spec 6a.8)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.leader_path import leader_stalls
from gcs_swarm.guidance.params import ReshapeParams
from gcs_swarm.guidance.route_plan import detour, footprints
from swarm_common.obstacle_shapes import pack_shapes

START = np.array([0.0, 0.0, 10.0])
GOAL = np.array([200.0, 0.0, 10.0])
RADIUS = 8.0  # m, each of the two spheres of a gap
CLEARANCE = 7.0  # m, ReshapeParams.gap_clearance_m's default
TOLERANCE = 2.0  # m, the corner thinning FleetController uses


def _gap(width: float, shift: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Two spheres of RADIUS at x = 100 m, `width` m apart surface to surface, centred on y = shift."""
    centres = np.array([[100.0, shift + width / 2 + RADIUS, 10.0], [100.0, shift - width / 2 - RADIUS, 10.0]])
    return centres, np.full(2, RADIUS)


def _route_length(points: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(points[:, :2], axis=0), axis=1)))


def _over_the_top(centre: np.ndarray, r: float) -> float:
    """Shortest way from START to GOAL over a circle (centre (2,), radius r) that blocks the line between them
    (by hand: the two tangents and the arc between their touching points)."""
    length = 0.0
    directions = []
    for end in (START[:2], GOAL[:2]):
        d = float(np.linalg.norm(centre - end))
        length += math.sqrt(d * d - r * r)  # tangent from the end to the circle
        to_centre = math.atan2(centre[1] - end[1], centre[0] - end[0])
        directions.append(to_centre)
    # the upper tangents leave START at to_centre + asin(r/d) and reach GOAL at (from GOAL) to_centre - asin;
    # the radii to the touching points are perpendicular to them: the arc is the angle between those radii
    d0, d1 = (float(np.linalg.norm(centre - e)) for e in (START[:2], GOAL[:2]))
    leave = directions[0] + math.asin(r / d0) + math.pi / 2
    arrive = directions[1] - math.asin(r / d1) - math.pi / 2
    arc = abs(math.remainder(leave - arrive, 2 * math.pi))
    return length + r * arc


def test_a_narrow_gap_is_flown_round_clear_of_both_spheres_the_short_way():
    """An 8 m gap across the leg: the grown circles (8 + 7 m) overlap, so the leg goes round both; every
    segment of the route keeps the clearance from both surfaces, and the route is no more than 2 % longer than
    the shortest way over the grown circle on the side it takes (worked by hand)."""
    centres, radii = _gap(8.0)
    obstacles = pack_shapes(spheres=zip(centres, radii, strict=True))
    via = detour(START, GOAL, obstacles, CLEARANCE, 0.0, TOLERANCE)
    assert via is not None and 1 <= len(via) <= 4
    route = np.vstack([START, via, GOAL])
    np.testing.assert_allclose(route[:, 2], 10.0)
    for a, b in zip(route[:-1], route[1:], strict=True):
        segment = shapely.LineString([a[:2], b[:2]])
        for c, r in zip(centres, radii, strict=True):
            assert segment.distance(shapely.Point(*c[:2])) - r >= CLEARANCE - 1e-6
    side = 0 if via[0, 1] > 0 else 1  # over the left sphere or under the right one
    shortest = _over_the_top(centres[side, :2], RADIUS + CLEARANCE)
    assert shortest <= _route_length(route) <= 1.02 * shortest


@pytest.mark.parametrize(
    ("centres", "radii", "start"),
    [
        (np.array([[100.0, 30.0, 10.0], [100.0, -30.0, 10.0]]), np.full(2, RADIUS), START),  # 44 m gap
        (np.array([[100.0, 2.0, 10.0]]), np.array([RADIUS]), START),  # one sphere: the field goes round
        (np.array([[100.0, 2.0, 10.0], [100.0, 60.0, 10.0]]), np.full(2, RADIUS), START),  # apart, not a gap
        (*_gap(8.0), np.array([100.0, 0.0, 10.0])),  # starting in the gap: no way round to plan
        (_gap(8.0)[0] + [0.0, 0.0, 30.0], np.full(2, RADIUS), START),  # spheres 30 m up: above the leg
    ],
)
def test_no_detour_without_a_closed_gap_across_the_leg(centres, radii, start):
    obstacles = pack_shapes(spheres=zip(centres, radii, strict=True))
    assert detour(start, GOAL, obstacles, CLEARANCE, 0.0, TOLERANCE) is None


def test_the_narrowest_shapes_width_counts_and_cylinders_and_prisms_close_gaps_too():
    """A 30 m gap between a tree (cylinder) and a building (prism): flown through by a column (half-width 0:
    30 > 2 x 7), round by a formation whose narrowest shape is 20 m wide (30 < 2 x (7 + 10))."""
    obstacles = pack_shapes(
        cylinders=[((100.0, 20.0), 5.0, 0.0, 30.0)],
        prisms=[([(90.0, -15.0), (110.0, -15.0), (110.0, -40.0), (90.0, -40.0)], 0.0, 25.0)],
    )
    assert detour(START, GOAL, obstacles, CLEARANCE, 0.0, TOLERANCE) is None
    assert detour(START, GOAL, obstacles, CLEARANCE, 10.0, TOLERANCE) is not None


def test_footprints_are_the_cross_sections_at_the_height_grown():
    """A sphere of 10 m cut 6 m above its centre is a circle of 8 m; a cylinder or prism only between its
    bottom and top."""
    obstacles = pack_shapes(
        spheres=[((0.0, 0.0, 4.0), 10.0)],
        cylinders=[((50.0, 0.0), 3.0, 0.0, 5.0)],
        prisms=[([(0.0, 50.0), (10.0, 50.0), (10.0, 60.0)], 0.0, 20.0)],
    )
    high = footprints(obstacles, 10.0, 1.0)
    assert len(high) == 2  # the cylinder ends at 5 m
    assert high[0].bounds == pytest.approx((-9.0, -9.0, 9.0, 9.0), abs=1e-9)
    assert high[1].buffer(-1.0).area == pytest.approx(50.0, rel=1e-3)
    assert len(footprints(obstacles, 2.0, 0.0)) == 3


@pytest.mark.parametrize(("width", "stalls"), [(12.0, True), (14.0, False)])
def test_a_lone_leader_stalls_in_front_of_a_12_m_gap_and_passes_a_14_m_one(width, stalls):
    """The measurement gap_clearance_m's default (7 m: gaps under 14 m) rests on: with the field's defaults
    the leader's reference, flown forward from rest 100 m before two spheres of 8 m, is held in front of a
    12 m gap (attraction and the repulsion of both walls balance on the centre line) and gets through a 14 m
    one. Off the centre line by a fifth of the gap it stalls the same: the walls push it back onto it."""
    centres, radii = _gap(width, shift=0.2 * width)
    ctl = FleetController(1, 0, np.zeros((1, 3)), GOAL[None], z_min=1.0)
    ctl.reset(START[None], np.zeros((1, 3)), np.zeros(1))
    assert ctl.heading is not None
    zero = np.zeros(3)
    held = leader_stalls(ctl.leader_model, START, zero, zero, ctl.heading, GOAL, 10.0, centres, radii)
    assert held is stalls


def _fly(ctl: FleetController, centres: np.ndarray, radii: np.ndarray, seconds: float) -> np.ndarray:
    """Tick a lone leader with perfect tracking (the vehicle where its reference is); its track (T, 3)."""
    dt, track = ctl.control_dt, []
    for k in range(round(seconds / dt)):
        pos, vel = ctl.generator.p.copy(), ctl.generator.v.copy()
        ctl.tick(k * dt, pos, vel, np.zeros((1, 3)), centres, radii, np.ones(1, dtype=bool))
        track.append(pos[0])
        if ctl.on_last_point and np.linalg.norm(pos[0] - GOAL) < 1.0:
            break
    return np.array(track)


@pytest.mark.parametrize("round_gaps", [True, False])
def test_the_leader_goes_round_a_gap_it_would_stall_in(round_gaps):
    """A 10 m gap across the leader's leg. Planned round: an event names the via points, the mission's
    waypoint index stays 0 while the leader flies them (the runner's legs and arrival count mission
    waypoints), and it reaches its goal within 40 s, never within 5 m of a surface. Without the route it is
    still in front of the gap after 40 s."""
    centres, radii = _gap(10.0)
    still = pack_shapes(spheres=zip(centres, radii, strict=True))
    reshape = ReshapeParams(route_round_gaps=round_gaps)
    ctl = FleetController(
        1, 0, np.zeros((1, 3)), GOAL[None], z_min=1.0, reshape=reshape, still_obstacles=still
    )
    ctl.reset(START[None], np.zeros((1, 3)), np.zeros(1))
    track = _fly(ctl, centres, radii, 40.0)
    events = ctl.drain_events()
    if round_gaps:
        assert len(ctl.route_points) > 1 and ctl.waypoint_index == 0
        assert any("route: round a gap" in e for e in events)
        assert np.linalg.norm(track[-1] - GOAL) < 1.0
        surface = np.linalg.norm(track[:, None, :] - centres[None], axis=2) - radii
        assert surface.min() > 5.0
    else:
        assert len(ctl.route_points) == 1 and not events
        assert track[:, 0].max() < 100.0
