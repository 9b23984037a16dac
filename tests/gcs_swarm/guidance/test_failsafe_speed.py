"""Speed caps that keep a stop possible: ArduCopter's BRAKE and LAND stopping distances (checked against their
closed form and the real vehicle) for a dead ground station, and the closing-speed cap between vehicles."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_swarm.guidance.failsafe_speed import (
    distance_along_course,
    failsafe_speed_caps,
    interp,
    stopping_table,
)
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.params import Limits, SeparationParams
from gcs_swarm.guidance.separation import (
    CLOSING_RANGE_MAX_M,
    closing_deceleration,
    closing_range,
    closing_speed_caps,
)
from swarm_common.obstacle_shapes import NO_SHAPES

A, J = 7.5, 5.0  # BRAKE_MODE_DECEL_RATE m/s^2, PSC_JERK_XY m/s^3


def brake_distance(speed: np.ndarray | float, accel: float, jerk: float) -> np.ndarray:
    """m: the BRAKE distance from each speed (up to the table's 60 m/s): the stopping table with no reaction
    time, read as the speed caps read it."""
    distances, speeds = stopping_table(0.0, accel, jerk)
    return np.vectorize(lambda v: interp(float(v), speeds, distances), otypes=[float])(speed)


def closed_form(v: float, a: float = A, j: float = J) -> float:
    """The shaping's stopping distance by hand. k = j / a; below a^2 / j the correction acceleration is
    k v: the acceleration ramps up at j until j t = k (v - j t^2 / 2), then follows k v (an exponential
    decay, whose distance is v / k). Above a^2 / j: ramp to a in a / j, constant a down to a^2 / j, then
    the exponential."""
    k, linear = j / a, a * a / j
    if v <= linear:
        t1 = (-j + math.sqrt(j * j + 2.0 * k * k * j * v)) / (k * j)
        return v * t1 - j * t1**3 / 6.0 + (v - j * t1 * t1 / 2.0) / k
    t1 = a / j
    ramp = v * t1 - j * t1**3 / 6.0
    v1 = v - a * a / (2.0 * j)
    return ramp + (v1 * v1 - linear * linear) / (2.0 * a) + linear / k


@pytest.mark.parametrize("v", [0.5, 2.0, 3.76, 6.0, 10.0, 10.14, 11.0, 14.0, 20.0, 30.0])
def test_brake_distance_matches_the_closed_form(v: float) -> None:
    assert float(brake_distance(v, A, J)) == pytest.approx(closed_form(v), rel=0.01)


def test_brake_distance_against_a_real_arducopter() -> None:
    """Real ArduCopter SITL, 10.14 m/s to a stop in BRAKE: 20.4 m (its tracking lag included); 3.76 m/s in
    about 6.5 m (the same vehicle after a ground-station kill, docs/reliability.md)."""
    assert float(brake_distance(10.14, A, J)) == pytest.approx(20.4, rel=0.05)
    assert float(brake_distance(10.0, A, J)) > 2.5 * 10.0**2 / (2 * A)  # not a constant 7.5 m/s^2 stop
    # LAND's loiter braking (LOIT_BRK_ACCEL 2.5 m/s^2, LOIT_BRK_JERK 5 m/s^3): 23.7 m on the real vehicle
    assert float(brake_distance(10.14, 2.5, 5.0)) == pytest.approx(23.7, rel=0.05)


@given(st.floats(0.0, 40.0), st.floats(0.0, 40.0))
def test_brake_distance_grows_with_speed(v1: float, v2: float) -> None:
    lo, hi = sorted((v1, v2))
    assert float(brake_distance(lo, A, J)) <= float(brake_distance(hi, A, J)) + 1e-9


def test_speed_cap_stops_exactly_short_of_the_obstacle() -> None:
    pos = np.array([[0.0, 0.0, 10.0]])
    centres, radii = np.array([[80.0, 0.0, 10.0]]), np.array([5.0])
    t, clearance = 3.0, 3.0
    cap = float(failsafe_speed_caps(pos, np.array([[1.0, 0.0, 0.0]]), centres, radii, t, A, clearance, J)[0])
    available = 80.0 - 5.0 - clearance
    assert cap * t + float(brake_distance(cap, A, J)) == pytest.approx(available, abs=0.05)
    assert 0.0 < cap < available / t


def test_no_cap_when_the_course_misses_every_obstacle() -> None:
    pos = np.array([[0.0, 0.0, 10.0], [0.0, 0.0, 10.0], [0.0, 0.0, 10.0]])
    vel = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # beside, away, hovering
    centres, radii = np.array([[80.0, 0.0, 10.0]]), np.array([5.0])
    caps = failsafe_speed_caps(pos, vel, centres, radii, 3.0, A, 3.0, J)
    assert np.isinf(caps).all()
    assert np.isinf(distance_along_course(pos, vel, centres, radii, 3.0, *NO_SHAPES, np.inf)).all()


def test_inside_the_grown_sphere_the_cap_is_zero() -> None:
    pos = np.array([[73.0, 0.0, 10.0]])  # 2 m from the surface, clearance 3 m
    centres, radii = np.array([[80.0, 0.0, 10.0]]), np.array([5.0])
    cap = failsafe_speed_caps(pos, np.array([[1.0, 0.0, 0.0]]), centres, radii, 3.0, A, 3.0, J)
    assert float(cap[0]) == pytest.approx(0.0, abs=1e-9)


def test_closing_speed_cap_slows_the_vehicle_behind_only() -> None:
    """Two vehicles on the x axis, 20 m apart: the one behind at 20 m/s, the one ahead at 10 m/s. Closing
    at 10 m/s, while stopping at 2 m/s^2 one metre outside d_emg = 3 m allows sqrt(2 * 2 * (20 - 3 - 1)) = 8
    m/s: the one behind is capped at 20 - (10 - 8) = 18 m/s, the one ahead (moving away) not at all."""
    pos = np.array([[0.0, 0.0, 10.0], [20.0, 0.0, 10.0], [0.0, 500.0, 10.0]])
    vel = np.array([[20.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0, -5.0, 0.0]])  # the third: far, not in range
    radius = closing_range(3.0, 2.0, 20.0)  # 3 + 1 + 40^2 / 4 = 404 m, at most 200 m
    assert radius == CLOSING_RANGE_MAX_M
    caps, on_course = closing_speed_caps(pos, vel, np.ones(3, dtype=bool), 3.0, 2.0, radius)
    assert caps[0] == pytest.approx(18.0)
    assert np.isinf(caps[1]) and np.isinf(caps[2])
    assert on_course.tolist() == [True, False, False]  # straight at it: they would meet
    # slow enough, or unknown, or out of range: no cap
    assert np.isinf(closing_speed_caps(pos, vel * 0.3, np.ones(3, dtype=bool), 3.0, 2.0, radius)[0]).all()
    assert np.isinf(closing_speed_caps(pos, vel, np.array([True, False, True]), 3.0, 2.0, radius)[0]).all()
    assert np.isinf(closing_speed_caps(pos, vel, np.ones(3, dtype=bool), 3.0, 2.0, 19.9)[0]).all()
    assert closing_range(3.0, 2.0, 2.0) == pytest.approx(3.0 + 1.0 + 16.0 / 4.0)


@pytest.mark.parametrize(("accel", "jerk"), [(A, J), (2.5, 5.0), (1.0, 20.0)])
def test_the_stopping_table_is_bounded_by_the_physics_of_the_shaping(accel, jerk):
    """The BRAKE shaping (acceleration at most A, ramping at most J, then the linear k v law, k = J / A) can
    stop no shorter than at a constant A from the start, v^2 / (2 A); for a small v (error within the linear
    region A^2 / J) it decays like exp(-k t), covering v / k = v A / J, plus at most v times the ramp time
    k v / J to reach that law. Distances grow with the speed, from 0."""
    speeds = np.array([0.0, 0.05, 0.2, 1.0, 5.0, 10.0, 20.0, 40.0, 60.0])
    d = brake_distance(speeds, accel, jerk)
    assert d[0] == 0.0 and np.all(np.diff(d) > 0.0)
    assert np.all(d >= speeds**2 / (2.0 * accel) * (1.0 - 1e-9))
    k = jerk / accel
    small = speeds[1:4][speeds[1:4] < accel * accel / jerk]
    lo, hi = small / k, small / k + small * (k * small / jerk)
    got = brake_distance(small, accel, jerk)
    assert np.all(got >= lo * 0.99) and np.all(got <= hi * 1.01 + 0.01)


def test_the_arducopter_brake_distance_from_10_m_s():
    """Module docstring: from 10 m/s with A = 7.5 m/s^2, J = 5 m/s^3 about 20 m, not the 6.7 m of a
    constant deceleration (a real ArduCopter SITL quad stopped from 10.1 m/s in 20.4 m)."""
    assert float(brake_distance(10.0, A, J)) == pytest.approx(20.0, abs=1.0)


def test_a_capped_pair_passing_wide_is_not_on_a_collision_course() -> None:
    """The one ahead 5 m to the side: closing at 10 x 20 / sqrt(20^2 + 5^2) = 9.70 m/s, more than the
    sqrt(2 * 2 * (20.62 - 4)) = 8.15 m/s the cap allows, so the one behind is capped at 20 - 1.55 = 18.45
    m/s; flying on they would pass 5 m apart, outside d_emg + 1 m = 4 m, so not on a collision course. At
    3.5 m to the side they would pass within it."""
    vel = np.array([[20.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    for side, expected in ((5.0, False), (3.5, True)):
        pos = np.array([[0.0, 0.0, 10.0], [20.0, side, 10.0]])
        caps, on_course = closing_speed_caps(pos, vel, np.ones(2, dtype=bool), 3.0, 2.0, 100.0)
        d = math.hypot(20.0, side)
        assert caps[0] == pytest.approx(20.0 - (10.0 * 20.0 / d - math.sqrt(4.0 * (d - 4.0))))
        assert on_course.tolist() == [expected, False]


def test_the_closing_deceleration_is_what_the_tilt_limit_allows() -> None:
    """closing_brake_accel, bounded by closing_brake_tilt_share x g tan(tilt_max), by hand."""
    sep = SeparationParams()  # 2 m/s^2, share 0.3
    assert closing_deceleration(sep, math.radians(35.0), 9.8) == 2.0  # 0.3 x 9.8 x 0.7002 = 2.06: not bound
    assert closing_deceleration(sep, math.radians(11.0), 9.8) == pytest.approx(0.3 * 9.8 * 0.19438, rel=1e-4)
    assert closing_deceleration(replace(sep, closing_brake_tilt_share=0.0), math.radians(11.0), 9.8) == 2.0
    assert closing_deceleration(replace(sep, closing_brake_accel=0.0), math.radians(11.0), 9.8) == 0.0  # off
    with pytest.raises(ValueError, match="closing_brake_tilt_share"):
        SeparationParams(closing_brake_tilt_share=1.5)


def test_a_low_tilt_limit_lowers_the_controllers_closing_cap() -> None:
    offsets = np.array([[0.0, 0.0, 0.0], [-10.0, 0.0, 0.0]])
    goal = np.array([[100.0, 0.0, 10.0]])
    steep = FleetController(2, 0, offsets, goal)
    flat = FleetController(2, 0, offsets, goal, limits=Limits(tilt_max_deg=11.0))
    assert steep.closing_accel == 2.0
    assert flat.closing_accel == pytest.approx(0.5715, abs=1e-4)
