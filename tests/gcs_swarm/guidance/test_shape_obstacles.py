"""Cylinders and prisms in every consumer of the obstacles (spec 2.2): the field's repulsion, the slot push,
the failsafe speed caps, the simulator's swept collision check and the report's clearance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from gcs_swarm.evaluation.metrics import min_obstacle_clearance
from gcs_swarm.guidance.failsafe_speed import distance_along_course
from gcs_swarm.guidance.field import obstacle_repulsion
from gcs_swarm.guidance.obstacles import push_out_of_shapes
from gcs_swarm.guidance.params import FieldParams
from sitl_sim.world import FUSELAGE_RADIUS, Obstacles, find_collisions
from swarm_common.obstacle_shapes import pack_shapes, surface

# a building x 0..10, y 0..20, 0..15 m high, and a tree at (-20, 0), radius 2 m, 0..12 m
BUILDING = ([(0.0, 0.0), (10.0, 0.0), (10.0, 20.0), (0.0, 20.0)], 0.0, 15.0)
TREE = ((-20.0, 0.0), 2.0, 0.0, 12.0)
SHAPES = pack_shapes(cylinders=[TREE], prisms=[BUILDING])
NONE3 = np.zeros((0, 3))


@pytest.mark.parametrize("law", ["iaapf", "apf"])
def test_a_wall_repels_as_the_sphere_tangent_to_it_at_the_nearest_point(law: str) -> None:
    # 5 m east of the east wall (x = 10) at mid height: the field sees l = 5 m and n_o = +x. The existing
    # sphere law with a sphere of radius 1000 m centred 1005 m west of the vehicle sees the same l and n_o at
    # the same point, so the two forces must agree (the sphere path is the paper's, unchanged)
    fp = FieldParams(method=law)
    q = np.array([[15.0, 10.0, 7.0]])
    dest = np.array([[60.0, 40.0, 7.0]])
    shape_force = obstacle_repulsion(q, q, dest, NONE3, np.zeros(0), fp, shapes=SHAPES)
    sphere_force = obstacle_repulsion(
        q, q, dest, np.array([[15.0 - 1005.0, 10.0, 7.0]]), np.array([1000.0]), fp
    )
    np.testing.assert_allclose(shape_force, sphere_force, rtol=1e-12)
    assert shape_force[0, 0] > 0.0  # pushed away from the wall


def test_a_roof_repels_upward_and_nothing_beyond_l0() -> None:
    fp = FieldParams(method="apf", circulation=0.0)
    q = np.array([[5.0, 10.0, 18.0], [5.0, 10.0, 15.0 + fp.l0 + 1.0]])  # 3 m above the roof; beyond l0
    force = obstacle_repulsion(q, q, q + np.array([50.0, 0.0, 0.0]), NONE3, np.zeros(0), fp, shapes=SHAPES)
    assert force[0, 2] > 0.0
    assert force[0, 0] == pytest.approx(0.0, abs=1e-9 * abs(force[0, 2]))  # n_o = +z; n_g along +x
    np.testing.assert_array_equal(force[1], 0.0)


def test_the_braking_path_meets_the_wall_before_the_vehicle_does() -> None:
    # 30 m west of the building's west wall (x = 0), heading east: at q it is beyond l0 (20 m), but its
    # braking path reaches x = -5: the wall is felt from the path's nearest point, 5 m away (spec 2.2: the
    # segment's point nearest the surface)
    fp = FieldParams(method="apf")
    only_building = pack_shapes(prisms=[BUILDING])
    q = np.array([[-30.0, 10.0, 7.0]])
    ahead = np.array([[-5.0, 10.0, 7.0]])
    dest = np.array([[-60.0, 10.0, 7.0]])
    assert not obstacle_repulsion(q, q, dest, NONE3, np.zeros(0), fp, shapes=only_building).any()
    felt = obstacle_repulsion(q, ahead, dest, NONE3, np.zeros(0), fp, shapes=only_building)
    at_path_end = obstacle_repulsion(ahead, ahead, dest, NONE3, np.zeros(0), fp, shapes=only_building)
    np.testing.assert_allclose(felt, at_path_end, rtol=1e-6)
    assert felt[0, 0] < 0.0


def test_a_slot_inside_a_building_goes_out_past_the_nearest_wall() -> None:
    # (8, 10) at 7 m is 2 m inside the east wall: out to x = 10 + margin 3 = 13, y kept
    assert push_out_of_shapes(8.0, 10.0, 7.0, *SHAPES, 3.0) == pytest.approx((13.0, 10.0))
    # 2 m above the 15 m roof with margin 3: the grown roof edge reaches sqrt(9 - 4) m out: x = 10 + 2.236
    assert push_out_of_shapes(9.0, 10.0, 17.0, *SHAPES, 3.0) == pytest.approx((10.0 + math.sqrt(5.0), 10.0))
    # 4 m above the roof: outside the grown building, not moved
    assert push_out_of_shapes(9.0, 10.0, 19.0, *SHAPES, 3.0) == (9.0, 10.0)
    # beside the tree, 1 m from its bark: out to 2 + 3 = 5 m from its axis
    assert push_out_of_shapes(-17.0, 0.0, 5.0, *SHAPES, 3.0) == pytest.approx((-15.0, 0.0))


def test_the_failsafe_course_distance_stops_the_clearance_short_of_a_wall() -> None:
    # heading east at 7 m from x = -15, y = 10 (8 m north of the tree's bark: clear) toward the west wall
    # x = 0: 15 m minus the 3 m clearance
    pos, vel = np.array([[-15.0, 10.0, 7.0]]), np.array([[4.0, 0.0, 0.0]])
    d = distance_along_course(pos, vel, NONE3, np.zeros(0), 3.0, *SHAPES, 500.0)
    assert d[0] == pytest.approx(12.0, abs=1e-3)
    # heading north at y = 30 past everything: inf
    north = np.array([[5.0, 30.0, 7.0]]), np.array([[0.0, 4.0, 0.0]])
    d = distance_along_course(*north, NONE3, np.zeros(0), 3.0, *SHAPES, 500.0)
    assert d[0] == math.inf


def test_the_simulator_sees_a_step_through_a_thin_wall() -> None:
    # a wall 0.1 m thick (x 0..0.1) crossed in one 1 m step from x = -0.5 to 0.5: neither end is within the
    # fuselage radius (0.5 - 0.1 = 0.4 > 0.175) but the segment crosses it: a hit, numbered after the spheres
    wall = pack_shapes(prisms=[([(0.0, -5.0), (0.1, -5.0), (0.1, 5.0), (0.0, 5.0)], 0.0, 10.0)])
    obstacles = Obstacles(np.array([[50.0, 50.0, 5.0]]), np.array([1.0]), np.zeros((1, 3)), wall)
    pos0, pos1 = np.array([[-0.5, 0.0, 5.0], [-0.5, 8.0, 5.0]]), np.array([[0.5, 0.0, 5.0], [0.5, 8.0, 5.0]])
    hits = find_collisions(pos0, pos1, obstacles, 0.0, 0.01, np.zeros(2, dtype=bool))
    assert hits == [(0, "collision with obstacle 1")]  # the second passes 3 m north of its end
    # passing the tree's bark at 0.2 m (> the fuselage radius): no hit; at 0.1 m: a hit
    tree = Obstacles(NONE3, np.zeros(0), NONE3, SHAPES)
    for gap, hit in ((0.2, False), (0.1, True)):
        y = 2.0 + gap
        found = find_collisions(np.array([[-25.0, y, 5.0]]), np.array([[-15.0, y, 5.0]]), tree, 0.0, 0.01,
                                np.zeros(1, dtype=bool))  # fmt: skip
        assert bool(found) is hit
    assert 0.1 < FUSELAGE_RADIUS < 0.2


def test_the_reports_clearance_includes_the_shapes() -> None:
    # two samples of one vehicle: 4 m east of the building's east wall, then 1.5 m from the tree's bark; a
    # sphere 10 m away; a NaN sample (no position) is left out
    pos = np.array([[[14.0, 10.0, 7.0]], [[-16.5, 0.0, 5.0]], [[np.nan, np.nan, np.nan]]])
    clearance, collided = min_obstacle_clearance(
        pos, np.array([[14.0, 30.0, 7.0]]), np.array([10.0]), shapes=SHAPES
    )
    assert clearance == pytest.approx(1.5)
    assert not collided


@settings(max_examples=200, deadline=None)
@given(st.floats(-30.0, 20.0), st.floats(-10.0, 30.0), st.floats(-5.0, 20.0), st.floats(0.5, 5.0))
@example(0.0, 1.0255655139018618, 0.0, 1.0)  # on the west wall: its nearest point differs from it by rounding
def test_a_pushed_slot_is_outside_the_grown_shapes(x: float, y: float, z: float, margin: float) -> None:
    # the building and the tree are convex and 10 m apart, so one pass leaves the point outside both grown
    # shapes: its 3-D distance to each is at least the margin (within rounding)
    px, py = push_out_of_shapes(x, y, z, *SHAPES, margin)
    for k in range(SHAPES.number):
        assert surface(px, py, z, k, *SHAPES)[0] >= margin - 1e-9
    # and a point already outside both is not moved
    if all(surface(x, y, z, k, *SHAPES)[0] >= margin for k in range(SHAPES.number)):
        assert (px, py) == (x, y)
