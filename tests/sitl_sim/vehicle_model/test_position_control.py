"""Position control pieces: sqrt controller, speed limits, spec 5 thrust-vector inversion with tilt limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.vehicle_model.attitude_control import euler_from_quat
from sitl_sim.vehicle_model.position_control import attitude_from_accel, sqrt_controller, velocity_demand

G = 9.8
TILT = math.radians(30.0)


def euler_of(ax: float, ay: float, az: float, yaw: float) -> tuple[np.ndarray, float]:
    *quat, thrust_g = attitude_from_accel(ax, ay, az, yaw, TILT, G)
    return euler_from_quat(np.array(quat)), thrust_g


def test_inversion_levels_hovers_and_limits_tilt():
    euler, thrust_g = euler_of(0.0, 0.0, 0.0, 0.3)
    assert np.allclose(euler, [0.0, 0.0, 0.3]) and thrust_g == pytest.approx(1.0)
    euler, _ = euler_of(2.0, 0.0, 0.0, 0.0)  # east acceleration facing east: nose down (pitch > 0, spec 1.1)
    assert euler[1] == pytest.approx(math.atan2(2.0, G)) and euler[0] == pytest.approx(0.0)
    euler, thrust_g = euler_of(100.0, 0.0, 0.0, math.pi / 2)  # east, facing north: right side down
    assert euler[0] > 0 and math.acos(math.cos(euler[0]) * math.cos(euler[1])) == pytest.approx(TILT)
    assert thrust_g == pytest.approx(1.0 / math.cos(TILT))  # shortened to the limit, altitude kept
    assert euler_of(0.0, 0.0, -50.0, 0.0)[1] == pytest.approx(0.3)  # no free-fall commands


def test_sqrt_controller_is_linear_then_square_root():
    assert sqrt_controller(0.5, 1.0, 2.5) == pytest.approx(0.5)
    assert sqrt_controller(-10.0, 1.0, 2.5) == pytest.approx(-math.sqrt(2 * 2.5 * (10.0 - 1.25)))


def test_velocity_demand_is_speed_limited_and_nan_means_no_position_control():
    def demand(target, feed_forward):
        return velocity_demand(
            np.zeros(3), np.array(target), np.array(feed_forward), 1.0, 1.0, 2.5, 10.0, 2.5, 1.5
        )

    assert demand([1000.0, 0.0, 0.0], [0.0, 0.0, 0.0]) == pytest.approx((10.0, 0.0, 0.0))
    assert demand([np.nan, np.nan, 100.0], [3.0, 0.0, 0.0]) == pytest.approx((3.0, 0.0, 2.5))
    assert demand([0.5, 0.0, np.nan], [0.0, 0.0, -9.0]) == pytest.approx((0.5, 0.0, -1.5))
