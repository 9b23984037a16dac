"""The shapes' surface distance and normal (swarm_common.obstacle_shapes): hand-derived cases, shapely for the
horizontal distance to a footprint, and properties with hypothesis."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon

from swarm_common.obstacle_shapes import (
    NEAREST_TOLERANCE,
    course_entry,
    footprint_distance,
    pack_shapes,
    segment_nearest,
    surface,
    surface_distances,
)

# a building 10 m x 20 m (x 0..10, y 0..20), 0..15 m high, written clockwise (the packer turns it), an L
# (a notch: not convex), a tree (radius 2 m, 3..12 m) and a sphere
BOX = [(0.0, 0.0), (0.0, 20.0), (10.0, 20.0), (10.0, 0.0)]
ELL = [(30.0, 0.0), (40.0, 0.0), (40.0, 4.0), (34.0, 4.0), (34.0, 12.0), (30.0, 12.0)]
SHAPES = pack_shapes(
    spheres=[((0.0, -30.0, 10.0), 3.0)],
    cylinders=[((-20.0, 0.0), 2.0, 3.0, 12.0)],
    prisms=[(BOX, 0.0, 15.0), (ELL, 2.0, 8.0)],
)
SPHERE_K, TREE, BOX_K, ELL_K = 0, 1, 2, 3


def at(x: float, y: float, z: float, k: int) -> tuple[float, float, float, float]:
    return surface(x, y, z, k, *SHAPES)


def test_beside_a_wall_the_distance_is_horizontal_and_the_normal_the_walls() -> None:
    # 4 m east of the east wall (x = 10), halfway up: 4 m, normal +x
    assert at(14.0, 10.0, 7.0, BOX_K) == pytest.approx((4.0, 1.0, 0.0, 0.0))
    # 2.5 m south of the south wall (y = 0): -y
    assert at(5.0, -2.5, 1.0, BOX_K) == pytest.approx((2.5, 0.0, -1.0, 0.0))


def test_above_the_roof_and_below_the_floor_the_distance_is_vertical() -> None:
    assert at(5.0, 10.0, 18.0, BOX_K) == pytest.approx((3.0, 0.0, 0.0, 1.0))  # 3 m above the 15 m roof
    assert at(32.0, 8.0, 0.5, ELL_K) == pytest.approx((1.5, 0.0, 0.0, -1.0))  # 1.5 m below the 2 m floor


def test_near_a_vertical_edge_and_a_roof_edge_the_normal_points_from_the_edge() -> None:
    # 3 m east and 4 m north of the corner (10, 20): the vertical edge is 5 m away, normal (0.6, 0.8, 0)
    assert at(13.0, 24.0, 7.0, BOX_K) == pytest.approx((5.0, 0.6, 0.8, 0.0))
    # 3 m east of the east wall and 4 m above the roof: the roof's edge, 5 m, normal (0.6, 0, 0.8)
    assert at(13.0, 10.0, 19.0, BOX_K) == pytest.approx((5.0, 0.6, 0.0, 0.8))
    # the corner (10, 20, 15) from (12, 22, 16): sqrt(4 + 4 + 1) = 3
    assert at(12.0, 22.0, 16.0, BOX_K) == pytest.approx((3.0, 2 / 3, 2 / 3, 1 / 3))


def test_inside_the_distance_is_negative_with_the_nearest_faces_normal() -> None:
    # 1 m inside the west wall (x = 0), far from roof and floor: -1, normal -x
    assert at(1.0, 10.0, 7.0, BOX_K) == pytest.approx((-1.0, -1.0, 0.0, 0.0))
    # 0.5 m under the roof in the middle (5 m from the walls): -0.5, normal +z
    assert at(5.0, 10.0, 14.5, BOX_K) == pytest.approx((-0.5, 0.0, 0.0, 1.0))
    # in the L's foot near the notch's wall y = 4 (x 34..40): 1 m from it, 4 m from x = 40, 3 from y = 0
    assert at(37.0, 3.0, 5.0, ELL_K) == pytest.approx((-1.0, 0.0, 1.0, 0.0))


def test_a_point_in_the_notch_is_outside_the_polygon() -> None:
    # (36, 6) lies in the L's notch (x > 34, y > 4): 2 m from the wall x = 34 and 2 m from the foot's top
    # y = 4 (both nearer than the corner (34, 4) at sqrt(8) m)
    assert at(36.0, 6.0, 5.0, ELL_K)[0] == pytest.approx(2.0)
    assert at(36.0, 7.0, 5.0, ELL_K) == pytest.approx((2.0, 1.0, 0.0, 0.0))  # nearer the wall x = 34


def test_cylinder_walls_caps_and_axis() -> None:
    assert at(-15.0, 0.0, 5.0, TREE) == pytest.approx((3.0, 1.0, 0.0, 0.0))  # 5 m from the axis, r = 2
    assert at(-20.0, 0.0, 14.0, TREE) == pytest.approx((2.0, 0.0, 0.0, 1.0))  # 2 m above the 12 m top
    assert at(-20.0, 1.5, 7.0, TREE) == pytest.approx((-0.5, 0.0, 1.0, 0.0))  # inside, 0.5 m from the bark
    assert at(-20.0, 0.0, 7.0, TREE) == pytest.approx((-2.0, 1.0, 0.0, 0.0))  # on the axis: +x (documented)
    # 3 m out from the rim and 4 m below the bottom (3 m): the rim's edge at 5 m
    assert at(-20.0, -5.0, -1.0, TREE) == pytest.approx((5.0, 0.0, -0.6, -0.8))


def test_the_sphere_is_the_papers() -> None:
    # spec 2.1: |q - c| - r along (q - c) / |q - c|; the 3-4-5 triangle: |(3, 4, 0)| = 5, minus r = 3
    assert at(3.0, -26.0, 10.0, SPHERE_K) == pytest.approx((2.0, 0.6, 0.8, 0.0))
    assert at(0.0, -30.0, 10.0, SPHERE_K) == (-3.0, 0.0, 0.0, 1.0)  # on the centre: +z


def test_footprint_distance_agrees_with_shapely() -> None:
    rng = np.random.default_rng(7)
    for ring, k in ((BOX, BOX_K), (ELL, ELL_K)):
        polygon = Polygon(ring)
        for x, y in rng.uniform(-15.0, 55.0, size=(400, 2)):
            h, nx, ny = footprint_distance(x, y, int(SHAPES.kinds[k]), SHAPES.params[k], SHAPES.vertices)
            expected = polygon.exterior.distance(Point(x, y)) * (
                -1.0 if polygon.contains(Point(x, y)) else 1.0
            )
            assert h == pytest.approx(expected, abs=1e-9)
            assert math.hypot(nx, ny) == pytest.approx(1.0)


finite = st.floats(-60.0, 60.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(finite, finite, st.floats(-10.0, 30.0), st.sampled_from([SPHERE_K, TREE, BOX_K, ELL_K]))
def test_the_normal_is_a_unit_vector_and_a_step_along_it_moves_the_distance_by_that_step(
    x: float, y: float, z: float, k: int
) -> None:
    l, n0, n1, n2 = at(x, y, z, k)
    assert math.isfinite(l)
    assert math.sqrt(n0 * n0 + n1 * n1 + n2 * n2) == pytest.approx(1.0)
    # the normal leads to a nearest point: the point l back along it lies on the surface, and the one halfway
    # there is l/2 away (a nearest point stays the nearest along the way to it)
    if abs(l) > 1e-3:
        assert at(x - l * n0, y - l * n1, z - l * n2, k)[0] == pytest.approx(0.0, abs=1e-6)
        half = 0.5 * l
        assert at(x - half * n0, y - half * n1, z - half * n2, k)[0] == pytest.approx(half, abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(finite, finite, st.floats(-10.0, 30.0), finite, finite, st.floats(-10.0, 30.0))
def test_the_distance_is_1_lipschitz(
    x0: float, y0: float, z0: float, x1: float, y1: float, z1: float
) -> None:
    # |l(p) - l(q)| <= |p - q| for a true distance to a surface: what sphere tracing relies on
    gap = math.dist((x0, y0, z0), (x1, y1, z1))
    for k in range(SHAPES.number):
        assert abs(at(x0, y0, z0, k)[0] - at(x1, y1, z1, k)[0]) <= gap + 1e-9


def test_segment_nearest_finds_the_closest_point_of_a_segment() -> None:
    # a segment passing the box's east wall at 3 m for y in 0..20 and then 5 m north: any f with x = 13 inside
    # y 0..20 is nearest; the sampled-and-refined minimum is 3 m
    f = segment_nearest(13.0, -10.0, 7.0, 13.0, 30.0, 7.0, BOX_K, *SHAPES)
    assert at(13.0, -10.0 + 40.0 * f, 7.0, BOX_K)[0] == pytest.approx(3.0, abs=1e-6)
    # past the tree's side: the point nearest the axis x = -20 is at f = 0.5 (symmetric), 1 m from the bark
    f = segment_nearest(-30.0, 3.0, 7.0, -10.0, 3.0, 7.0, TREE, *SHAPES)
    assert f == pytest.approx(0.5, abs=1e-6)
    # the sphere: exact, the foot of the perpendicular from the centre (0, -30, 10) on x = -10..10 at y = -25
    assert segment_nearest(-10.0, -25.0, 10.0, 10.0, -25.0, 10.0, SPHERE_K, *SHAPES) == 0.5


def test_segment_nearest_past_the_ells_notch_finds_the_corner_not_the_roofs_edge() -> None:
    # hypothesis' case: the segment (0, 13, 16) -> (54, 1, 4) passes 0.434 m over the stem's roof edge above
    # the notch (f = 0.631) and then 0.108 m beside the foot's vertical edge at (40, 4) (f = 0.741), both in
    # the sampled interval 5/8..6/8, whose ends tie at 0.5 m: golden-section search took the first valley.
    # The nearest point: the foot of the perpendicular from (40, 4) on the footprint's line (0, 13) + f (54,
    # -12): f = (40 * 54 + 9 * 12) / (54^2 + 12^2) = 2268 / 3060 = 63 / 85, at |(54, -12) x (40, -9)| /
    # |(54, -12)| = 6 / sqrt(3060) m; its height 16 - 12 f = 7.1 lies between the L's 2 and 8 m
    f = segment_nearest(0.0, 13.0, 16.0, 54.0, 1.0, 4.0, ELL_K, *SHAPES)
    assert f == pytest.approx(63 / 85, abs=1e-6)
    assert at(54.0 * f, 13.0 - 12.0 * f, 16.0 - 12.0 * f, ELL_K)[0] == pytest.approx(
        6 / math.sqrt(3060), abs=1e-6
    )


def nearest_against_a_dense_sampling(
    x0: float, y0: float, z0: float, x1: float, y1: float, z1: float, shapes: range
) -> None:
    # 2001 evenly spaced points of the segment (an independent brute force): each is a point of the segment,
    # so the segment's nearest is at most as far as the best of them, and segment_nearest's within
    # NEAREST_TOLERANCE of that
    fs = np.linspace(0.0, 1.0, 2001)
    points = np.array([x0, y0, z0]) + fs[:, None] * np.array([x1 - x0, y1 - y0, z1 - z0])
    brute = surface_distances(points, *SHAPES).min(axis=0)
    for k in shapes:
        f = segment_nearest(x0, y0, z0, x1, y1, z1, k, *SHAPES)
        assert 0.0 <= f <= 1.0
        found = at(x0 + f * (x1 - x0), y0 + f * (y1 - y0), z0 + f * (z1 - z0), k)[0]
        assert found <= brute[k] + NEAREST_TOLERANCE


@settings(max_examples=100, deadline=None)
@given(finite, finite, st.floats(-10.0, 30.0), finite, finite, st.floats(-10.0, 30.0))
@example(0.0, 13.0, 16.0, 54.0, 1.0, 4.0)  # two valleys in one sampled interval (the test above)
def test_segment_nearest_is_no_farther_than_a_dense_sampling(
    x0: float, y0: float, z0: float, x1: float, y1: float, z1: float
) -> None:
    nearest_against_a_dense_sampling(x0, y0, z0, x1, y1, z1, range(SHAPES.number))


near_x, near_y, near_z = st.floats(25.0, 45.0), st.floats(-5.0, 17.0), st.floats(0.0, 10.0)


@settings(max_examples=100, deadline=None)
@given(near_x, near_y, near_z, near_x, near_y, near_z)
def test_segment_nearest_round_and_through_the_notched_prism(
    x0: float, y0: float, z0: float, x1: float, y1: float, z1: float
) -> None:
    # segments about the L (x 30..40, y 0..12, z 2..8): past its notch, over and under it, into it (there the
    # nearest is the deepest point)
    nearest_against_a_dense_sampling(x0, y0, z0, x1, y1, z1, range(ELL_K, ELL_K + 1))


def test_course_entry_against_hand_geometry() -> None:
    # toward the box's west wall (x = 0) from x = -10 at 7 m: enters the 1 m clearance at x = -1, 9 m on
    assert course_entry(-10.0, 10.0, 7.0, 1.0, 0.0, 1.0, 100.0, BOX_K, *SHAPES) == pytest.approx(
        9.0, abs=2e-4
    )
    # over the roof (15 m) at 15.5 m: within 1 m already over it, so it enters when the roof's edge is 1 m
    # away: sqrt(1 - 0.25) = 0.866 m short of x = 0
    entry = course_entry(-10.0, 10.0, 15.5, 1.0, 0.0, 1.0, 100.0, BOX_K, *SHAPES)
    assert entry == pytest.approx(10.0 - math.sqrt(0.75), abs=2e-4)
    # high above: never; inside: at once; beyond the horizon: never
    assert course_entry(-10.0, 10.0, 30.0, 1.0, 0.0, 1.0, 100.0, BOX_K, *SHAPES) == math.inf
    assert course_entry(5.0, 10.0, 7.0, 1.0, 0.0, 1.0, 100.0, BOX_K, *SHAPES) == 0.0
    assert course_entry(-10.0, 10.0, 7.0, 1.0, 0.0, 1.0, 5.0, BOX_K, *SHAPES) == math.inf
    # the tree from the east along -x at y = 0: its 2 m radius plus 1 m, 10 m out from x = -7: -7 - (-17) = 10
    assert course_entry(-7.0, 0.0, 7.0, -1.0, 0.0, 1.0, 100.0, TREE, *SHAPES) == pytest.approx(10.0, abs=2e-4)


def test_pack_refuses_degenerate_shapes() -> None:
    with pytest.raises(ValueError, match="3 vertices"):
        pack_shapes(prisms=[([(0.0, 0.0), (1.0, 0.0)], 0.0, 1.0)])
    with pytest.raises(ValueError, match="top > bottom"):
        pack_shapes(cylinders=[((0.0, 0.0), 1.0, 5.0, 5.0)])
