"""The command guard's site fence (issue 37 item 5): the inclusion polygon and the exclusion polygons and
circles, with the same only-brake rule as the radius. The geometry (`ring_distance`) is checked against
shapely on random simple polygons, compiled and as plain Python; the rule on hand-made cases."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon
from shapely.ops import nearest_points

from gcs_swarm.link.command_limits import CommandLimits, GuardFence, guard_attitude_commands, ring_distance

G_TAN_35 = 9.8 * math.tan(math.radians(35.0))  # m/s^2, the braking the runner gives the guard
SQUARE = np.array([[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]])  # the inclusion polygon
HOLE = np.array([[40.0, 40.0], [40.0, 60.0], [60.0, 60.0], [60.0, 40.0]])  # an exclusion polygon, clockwise
CIRCLE = SimpleNamespace(polygon=None, center=np.array([20.0, 80.0]), radius=5.0)
FENCE = GuardFence.of(SQUARE, [SimpleNamespace(polygon=HOLE, center=None, radius=0.0), CIRCLE], G_TAN_35)
LIMITS = CommandLimits(math.radians(35.0), 2.0, 1.0, 1000.0, 500.0, FENCE)


@st.composite
def star_polygons(draw: st.DrawFn) -> np.ndarray:
    """Simple polygons (K, 2) m: K vertices at increasing angles around a centre, random radii (star-shaped,
    so simple), in either orientation."""
    k = draw(st.integers(3, 12))
    cuts = sorted(draw(st.lists(st.floats(0.0, 1.0), min_size=k, max_size=k, unique=True)))
    radii = np.array(draw(st.lists(st.floats(1.0, 80.0), min_size=k, max_size=k)))
    centre = draw(st.tuples(st.floats(-500.0, 500.0), st.floats(-500.0, 500.0)))
    angles = 2.0 * math.pi * np.array(cuts)
    ring: np.ndarray = np.column_stack(
        [centre[0] + radii * np.cos(angles), centre[1] + radii * np.sin(angles)]
    )
    return ring[::-1].copy() if draw(st.booleans()) else ring


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "plain Python"])
@settings(max_examples=300, deadline=None)
@given(ring=star_polygons(), offset=st.tuples(st.floats(-120.0, 120.0), st.floats(-120.0, 120.0)))
def test_ring_distance_is_shapelys(compiled: bool, ring: np.ndarray, offset: tuple[float, float]) -> None:
    polygon = Polygon(ring)
    assume(polygon.is_valid and polygon.area > 1.0)
    x, y = float(ring[:, 0].mean() + offset[0]), float(ring[:, 1].mean() + offset[1])
    point = Point(x, y)
    expected = polygon.exterior.distance(point)
    assume(expected > 1e-6)  # on the boundary itself inside/outside is a matter of rounding
    law = ring_distance if compiled else ring_distance.py_func  # type: ignore[attr-defined]
    inside, distance, n_e, n_n = law(x, y, ring, 0, len(ring))
    assert inside == polygon.contains(point)
    assert distance == pytest.approx(expected, abs=1e-9)
    # the normal leads from shapely's nearest boundary point to the point (outside) or away from it (inside)
    nearest = nearest_points(polygon.exterior, point)[0]
    side = -1.0 if inside else 1.0
    assert math.hypot(n_e, n_n) == pytest.approx(1.0)
    assert x - side * distance * n_e == pytest.approx(nearest.x, abs=1e-6)
    assert y - side * distance * n_n == pytest.approx(nearest.y, abs=1e-6)


def test_on_an_edge_the_normal_points_out_of_either_orientation() -> None:
    for ring, normal in ((SQUARE, (1.0, 0.0)), (SQUARE[::-1].copy(), (1.0, 0.0)), (HOLE, (-1.0, 0.0))):
        x = 100.0 if ring is not HOLE else 40.0
        _, distance, n_e, n_n = ring_distance(x, 50.0, ring, 0, len(ring))
        assert distance == 0.0 and (n_e, n_n) == pytest.approx(normal)


def _guard(pos: tuple[float, float], toward: tuple[float, float], vel: tuple[float, float] | None):
    """Guard one command at yaw 0 tilting 0.3 rad toward the horizontal direction `toward`, at pos (m ENU,
    10 m up) with horizontal velocity vel m/s (None: unknown)."""
    s = math.sin(0.3) / math.hypot(*toward)
    roll = math.asin(-toward[1] * s)  # horizontal thrust direction at yaw 0: (sin p cos r, -sin r)
    pitch = math.asin(toward[0] * s / math.cos(roll))
    v = None if vel is None else np.array([[vel[0], vel[1], 0.0]])
    out = guard_attitude_commands(
        np.array([roll]), np.array([pitch]), np.zeros(1), np.array([0.5]), np.array([[pos[0], pos[1], 10.0]]),
        np.zeros(1), np.full(1, 0.5), LIMITS, vel=v,
    )  # fmt: skip
    return bool(out[4][0]), (out[0][0], out[1][0])


# Braking margin at 5 m/s closing: 5^2 / (2 * 9.8 tan 35 deg) = 25 / 13.724 = 1.82 m.
@pytest.mark.parametrize(
    ("why", "pos", "toward", "vel"),
    [
        ("outside the polygon, tilting further out", (105.0, 50.0), (1.0, 0.0), (0.0, 0.0)),
        ("outside the polygon, velocity unknown", (105.0, 50.0), (1.0, 0.0), None),
        ("1 m inside, closing at 5 m/s (margin 1.82 m)", (99.0, 50.0), (1.0, 0.2), (5.0, 0.0)),
        ("inside the exclusion polygon, tilting deeper", (45.0, 50.0), (1.0, 0.0), (0.0, 0.0)),
        ("1 m short of the exclusion polygon, closing at 5 m/s", (39.0, 50.0), (1.0, 0.0), (5.0, 0.0)),
        ("1 m short of the exclusion circle, closing at 5 m/s", (14.0, 80.0), (1.0, 0.0), (5.0, 0.0)),
        ("inside the circle, tilting towards its centre", (18.0, 80.0), (1.0, 0.0), (0.0, 0.0)),
    ],
)
def test_a_tilt_into_the_fence_is_levelled(why, pos, toward, vel) -> None:
    changed, tilt = _guard(pos, toward, vel)
    assert changed and tilt == (0.0, 0.0), why


@pytest.mark.parametrize(
    ("why", "pos", "toward", "vel"),
    [
        ("3 m inside, closing at 5 m/s (beyond the 1.82 m margin)", (97.0, 50.0), (1.0, 0.0), (5.0, 0.0)),
        ("1 m inside, not closing in", (99.0, 50.0), (1.0, 0.0), (0.0, 5.0)),
        ("outside the polygon, tilting back in", (105.0, 50.0), (-1.0, 0.0), (0.0, 0.0)),
        ("outside the polygon, flying back in and braking", (105.0, 50.0), (1.0, 0.0), (-8.0, 0.0)),
        ("inside the exclusion polygon, tilting out of it", (45.0, 50.0), (-1.0, 0.0), (0.0, 0.0)),
        ("1 m short of the circle, tilting along it", (14.0, 80.0), (0.0, 1.0), (5.0, 0.0)),
        ("2 m short of the exclusion polygon, closing at 5 m/s", (38.0, 50.0), (1.0, 0.0), (5.0, 0.0)),
    ],
)
def test_a_tilt_that_keeps_out_of_the_fence_or_only_brakes_is_left(why, pos, toward, vel) -> None:
    changed, tilt = _guard(pos, toward, vel)
    assert not changed and math.hypot(*tilt) > 0.29, why


def test_a_row_without_position_skips_the_fence() -> None:
    out = guard_attitude_commands(
        np.array([0.0]), np.array([0.3]), np.zeros(1), np.array([0.5]), np.full((1, 3), np.nan),
        np.zeros(1), np.full(1, 0.5), LIMITS, vel=np.zeros((1, 3)),
    )  # fmt: skip
    assert not out[4][0] and out[1][0] == 0.3


@pytest.mark.parametrize("v0", [5.0, 10.0])
def test_the_braking_margin_is_what_the_simulated_quadrotor_needs_to_stop(v0: float) -> None:
    """Measured, not assumed: sitl_sim's rigid-body quadrotor flying east at v0 m/s, commanded to full tilt
    (35 deg) against its motion with its altitude held (thrust m g / cos tilt), attitude slew and drag
    included, stops within 20 % of the guard's margin v0^2 / (2 g tan 35 deg) (1.82 m at 5 m/s, 7.29 m at
    10 m/s; the model measures 2.05 m and 6.55 m: the slew adds, drag takes away)."""
    from sitl_sim.vehicle_model.airframe import QuadParams
    from sitl_sim.vehicle_model.dynamics import FleetDynamics, FleetState

    params = QuadParams()
    state = FleetState.at_rest(np.array([[0.0, 0.0, 20.0]]), np.zeros(1), vel=np.array([[v0, 0.0, 0.0]]))
    dynamics = FleetDynamics(1, params, 1000.0, state=state)
    tilt = math.radians(35.0)
    back = np.array([[math.cos(-tilt / 2), 0.0, math.sin(-tilt / 2), 0.0]])  # pitched to thrust west
    thrust = np.array([params.mass * params.g / math.cos(tilt)])
    for _ in range(500):  # at most 5 s
        dynamics.set_targets(back, np.zeros((1, 3)), thrust, np.ones(1, dtype=bool), tilt)
        dynamics.step(np.zeros((1, 3)), 10)
        if state.vel[0, 0] <= 0.0:
            break
    assert state.vel[0, 0] <= 0.0
    margin = v0**2 / (2.0 * G_TAN_35)
    assert 0.8 * margin <= state.pos[0, 0] <= 1.2 * margin


@settings(max_examples=200, deadline=None)
@given(
    ring=star_polygons(),
    hole=star_polygons(),
    circle=st.tuples(st.floats(-600.0, 600.0), st.floats(-600.0, 600.0), st.floats(0.5, 50.0)),
    rows=st.lists(
        st.tuples(
            st.floats(-700.0, 700.0), st.floats(-700.0, 700.0), st.floats(-1.5, 1.5), st.floats(-1.5, 1.5),
            st.floats(-20.0, 20.0), st.floats(-20.0, 20.0),
        ),
        min_size=1, max_size=8,
    ),
)  # fmt: skip
def test_the_fence_only_ever_levels_a_tilt(ring, hole, circle, rows) -> None:
    """Whatever the fence and the states: the guard's answer is finite, and a row it changes (thrust and tilt
    within limits, inside the radius) is the same command levelled."""
    zones = [SimpleNamespace(polygon=hole, center=None, radius=0.0)]
    zones.append(SimpleNamespace(polygon=None, center=np.array(circle[:2]), radius=circle[2]))
    limits = CommandLimits(1.0, 2.0, 0.0, 1e6, 1e6, GuardFence.of(ring, zones, G_TAN_35))
    x, y, roll, pitch, v_e, v_n = (np.array(column) for column in zip(*rows, strict=True))
    pos = np.column_stack([x, y, np.full(len(x), 10.0)])
    vel = np.column_stack([v_e, v_n, np.zeros(len(x))])
    roll, pitch = (
        roll * 0.45,
        pitch * 0.45,
    )  # tilt <= acos(cos(0.675)^2) = 0.92 rad: the tilt rule leaves them
    out = guard_attitude_commands(
        roll, pitch, np.zeros(len(x)), np.full(len(x), 0.5), pos, np.zeros(len(x)), np.full(len(x), 0.5),
        limits, vel=vel,
    )  # fmt: skip
    r, p, _, t, changed = out
    assert np.isfinite(np.stack([r, p, t])).all()
    np.testing.assert_array_equal(np.where(changed, 0.0, roll), r)
    np.testing.assert_array_equal(np.where(changed, 0.0, pitch), p)


# A building 20 m high whose west wall is x = 40 (footprint x 40..60, y 40..60) and a tree 15 m high (trunk of
# radius 3 at (20, 80)): exclusion zones between their bottom and top, free air above them.
BUILDING = SimpleNamespace(footprint=HOLE, bottom=0.0, top=20.0)
TREE = SimpleNamespace(center=np.array([20.0, 80.0]), radius=3.0, bottom=0.0, top=15.0)
SITE = CommandLimits(
    math.radians(35.0), 2.0, 1.0, 1000.0, 500.0, GuardFence.of(None, [], G_TAN_35, [BUILDING], [TREE])
)


@pytest.mark.parametrize(
    ("why", "pos", "levelled"),
    [
        (
            "1 m short of the building's wall at 10 m, closing at 5 m/s (margin 1.82 m)",
            (39.0, 50.0, 10.0),
            True,
        ),
        ("the same 5 m above its roof", (39.0, 50.0, 25.0), False),
        ("1 m short of the tree's trunk at 10 m, closing at 5 m/s", (16.0, 80.0, 10.0), True),
        ("the same 1 m above its crown", (16.0, 80.0, 16.0), False),
        ("3 m short of the wall at 10 m (beyond the margin)", (37.0, 50.0, 10.0), False),
    ],
)
def test_a_tilt_into_a_building_or_a_tree_is_levelled_below_its_top_only(why, pos, levelled) -> None:
    """Tilting 0.3 rad east at yaw 0, flying east at 5 m/s."""
    roll, pitch = 0.0, 0.3  # horizontal thrust direction at yaw 0: (sin p cos r, -sin r), east
    out = guard_attitude_commands(
        np.array([roll]), np.array([pitch]), np.zeros(1), np.array([0.5]), np.array([pos]), np.zeros(1),
        np.full(1, 0.5), SITE, vel=np.array([[5.0, 0.0, 0.0]]),
    )  # fmt: skip
    assert bool(out[4][0]) is levelled and bool(out[1][0] == 0.0) is levelled, why
