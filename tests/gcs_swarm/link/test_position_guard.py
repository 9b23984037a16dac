"""The final guard on the position command mode's trajectory targets (command_limits.guard_position_targets):
targets outside the site fence, the geofence radius or the altitude band moved back onto the boundary, the
velocity and acceleration that lead further out removed, the acceleration feed-forward within the attitude
limits, broken rows held where the vehicle is. Expected values are worked by hand in each test; the polygon
projection is checked against shapely's nearest point."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon
from shapely.ops import nearest_points

from gcs_swarm.link.command_limits import CommandLimits, GuardFence, guard_position_targets

G = 9.81
SQUARE = np.array([[0.0, 0.0], [60.0, 0.0], [60.0, 60.0], [0.0, 60.0]])  # the site, ENU m
TILT = math.radians(30.0)


def _circle(e: float, n: float, radius: float) -> SimpleNamespace:
    return SimpleNamespace(polygon=None, center=np.array([e, n]), radius=radius)


def _polygon(vertices: list[list[float]]) -> SimpleNamespace:
    return SimpleNamespace(polygon=np.array(vertices), center=None, radius=0.0)


def _limits(fence: GuardFence | None = None, radius: float = 100.0) -> CommandLimits:
    """Tilt 30 deg, thrust 2 g, altitude 1..50 m, geofence radius `radius` m."""
    return CommandLimits(TILT, 2.0, 1.0, radius, 50.0, fence=fence or GuardFence())


def _one(limits: CommandLimits, p, v=(0.0, 0.0, 0.0), a=(0.0, 0.0, 0.0), at=(30.0, 30.0, 10.0)):
    out = guard_position_targets(
        np.array([p], dtype=float), np.array([v], dtype=float), np.array([a], dtype=float),
        np.array([at], dtype=float), limits, G,
    )  # fmt: skip
    return out.pos[0], out.vel[0], out.acc[0], bool(out.changed[0])


def test_a_target_outside_the_site_fence_is_moved_onto_its_edge_and_stops_heading_out() -> None:
    """(70, 30) is 10 m east of the square's east edge x = 60: moved to (60, 30). Its velocity (2, 1) keeps
    only the part along the edge (0, 1); its acceleration (3, 0, 2) loses the outward 3 (the vertical 2 is
    within the thrust limit)."""
    fence = GuardFence.of(SQUARE, [], brake=1.0)
    p, v, a, changed = _one(_limits(fence), (70.0, 30.0, 10.0), (2.0, 1.0, 0.0), (3.0, 0.0, 2.0))
    np.testing.assert_allclose(p, [60.0, 30.0, 10.0])
    np.testing.assert_allclose(v, [0.0, 1.0, 0.0])
    np.testing.assert_allclose(a, [0.0, 0.0, 2.0])
    assert changed


def test_a_target_inside_everything_is_left_exactly() -> None:
    fence = GuardFence.of(SQUARE, [_circle(45.0, 45.0, 5.0)], brake=1.0)
    target = ((30.0, 20.0, 10.0), (3.0, -1.0, 0.5), (1.0, 2.0, -1.0))
    p, v, a, changed = _one(_limits(fence), *target)
    assert (p.tolist(), v.tolist(), a.tolist(), changed) == (
        [30.0, 20.0, 10.0],
        [3.0, -1.0, 0.5],
        [1.0, 2.0, -1.0],
        False,
    )


def test_a_target_in_an_exclusion_zone_is_moved_out_of_it() -> None:
    """Circle at (30, 30) of radius 5: (32, 30) is 3 m inside, moved out along the radius to (35, 30); its
    velocity (-1, 0.5) heads into the circle (towards its centre) by 1: removed. A square hole 20..30 x
    40..50: (21, 45) is 1 m inside its west edge: moved to (20, 45)."""
    circle = _circle(30.0, 30.0, 5.0)
    hole = _polygon([[20.0, 40.0], [30.0, 40.0], [30.0, 50.0], [20.0, 50.0]])
    limits = _limits(GuardFence.of(None, [circle, hole], brake=1.0))
    p, v, _, changed = _one(limits, (32.0, 30.0, 10.0), (-1.0, 0.5, 0.0))
    np.testing.assert_allclose(p, [35.0, 30.0, 10.0])
    np.testing.assert_allclose(v, [0.0, 0.5, 0.0])
    assert changed
    p, _, _, changed = _one(limits, (21.0, 45.0, 10.0))
    np.testing.assert_allclose(p, [20.0, 45.0, 10.0])
    assert changed


def test_the_geofence_radius_and_the_altitude_band() -> None:
    """Radius 100: (80, 80) at 113.1 m is moved in to (70.71, 70.71); its outward velocity (1, 1) goes, a
    tangential (-1, 1) stays. Altitude 1..50 m: 0.5 m goes up to 1 and loses its -2 m/s down; 60 m comes
    down to 50 and loses its +1 m/s and +2 m/s^2 up."""
    limits = _limits()
    r = 100.0 / math.sqrt(2.0)
    p, v, _, _ = _one(limits, (80.0, 80.0, 10.0), (1.0, 1.0, 0.0))
    np.testing.assert_allclose(p, [r, r, 10.0])
    np.testing.assert_allclose(v, [0.0, 0.0, 0.0], atol=1e-12)
    _, v, _, _ = _one(limits, (80.0, 80.0, 10.0), (-1.0, 1.0, 0.0))
    np.testing.assert_allclose(v, [-1.0, 1.0, 0.0])
    p, v, _, _ = _one(limits, (10.0, 10.0, 0.5), (0.0, 0.0, -2.0))
    assert (p[2], v[2]) == (1.0, 0.0)
    p, v, a, _ = _one(limits, (10.0, 10.0, 60.0), (0.0, 0.0, 1.0), (0.0, 0.0, 2.0))
    assert (p[2], v[2], a[2]) == (50.0, 0.0, 0.0)


def test_the_acceleration_feed_forward_stays_within_the_attitude_limits() -> None:
    """Tilt 30 deg: horizontally at most g tan 30 = 5.664 m/s^2, so (20, 0) -> (5.664, 0) and (6, 8) (10)
    -> (3.398, 4.531); thrust 2 g: up at most g (2 - 1) = 9.81, down at most g."""
    limits = _limits()
    a_max = G * math.tan(TILT)
    _, _, a, changed = _one(limits, (10.0, 10.0, 10.0), a=(20.0, 0.0, 15.0))
    np.testing.assert_allclose(a, [a_max, 0.0, G])
    assert changed
    _, _, a, _ = _one(limits, (10.0, 10.0, 10.0), a=(6.0, 8.0, -20.0))
    np.testing.assert_allclose(a, [0.6 * a_max, 0.8 * a_max, -G])


def test_a_broken_target_becomes_a_hold_where_the_vehicle_is() -> None:
    limits = _limits()
    p, v, a, changed = _one(
        limits, (math.nan, 1.0, 2.0), (1.0, 1.0, 1.0), (1.0, 1.0, 1.0), at=(5.0, 6.0, 7.0)
    )
    assert (p.tolist(), v.tolist(), a.tolist(), changed) == ([5.0, 6.0, 7.0], [0.0] * 3, [0.0] * 3, True)
    p, _, _, changed = _one(limits, (math.inf, 1.0, 2.0), at=(math.nan, 6.0, 7.0))
    assert math.isinf(p[0]) and not changed  # nothing to hold at: the fleet sends this row nothing


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-40.0, 100.0),
    y=st.floats(-40.0, 100.0),
    skew=st.floats(-15.0, 15.0),
)
def test_a_target_outside_a_convex_site_lands_on_shapely_s_nearest_point(
    x: float, y: float, skew: float
) -> None:
    """For a convex inclusion polygon (a sheared square), the guarded target is the point itself inside and
    shapely's nearest point of the boundary outside (the nearest edge's foot or a vertex)."""
    ring = np.array([[0.0, 0.0], [60.0, skew], [60.0, 60.0 + skew], [0.0, 60.0]])
    limits = _limits(GuardFence.of(ring, [], brake=1.0), radius=1000.0)  # the radius never acts here
    p, _, _, changed = _one(limits, (x, y, 10.0))
    polygon = Polygon(ring)
    if polygon.contains(Point(x, y)):
        assert (p[0], p[1]) == (x, y) and not changed
    else:
        expected = nearest_points(polygon.exterior, Point(x, y))[0]
        assert p[0] == pytest.approx(expected.x, abs=1e-9) and p[1] == pytest.approx(expected.y, abs=1e-9)


def test_a_target_inside_a_building_is_moved_onto_its_wall_but_not_one_above_its_roof() -> None:
    """A building 20 m high, footprint x 20..40, y 20..40: the target (22, 30) at 10 m is 2 m inside its west
    wall (the nearest), so it goes to (20, 30) and its eastward velocity (3, 0, 0) is dropped; the same target
    at 25 m, above the roof, is free air and left as it is."""
    building = SimpleNamespace(
        footprint=np.array([[20.0, 20.0], [40.0, 20.0], [40.0, 40.0], [20.0, 40.0]]), bottom=0.0, top=20.0
    )
    limits = _limits(GuardFence.of(None, [], brake=1.0, prisms=[building]))
    p, v, _, changed = _one(limits, (22.0, 30.0, 10.0), v=(3.0, 0.0, 0.0))
    assert changed and p == pytest.approx([20.0, 30.0, 10.0]) and v == pytest.approx([0.0, 0.0, 0.0])
    p, v, _, changed = _one(limits, (22.0, 30.0, 25.0), v=(3.0, 0.0, 0.0))
    assert not changed and p == pytest.approx([22.0, 30.0, 25.0]) and v == pytest.approx([3.0, 0.0, 0.0])
