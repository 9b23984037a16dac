"""Position control pieces: sqrt controller, speed limits, spec 5 thrust-vector inversion with tilt limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.vehicle_model.attitude_control import euler_from_quat
from sitl_sim.vehicle_model.position_control import attitude_from_accel, velocity_demand
from swarm_common.shaping import sqrt_controller

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


@pytest.mark.parametrize("p, limit", [(1.0, 2.5), (9.0, 60.0), (4.5, 5.0), (10.0, 4.0), (0.5, 7.5)])
def test_shared_sqrt_controller_is_the_simulators_law_to_the_bit(p, limit):
    """The simulator's loops call swarm_common.shaping.sqrt_controller(e, p, limit, 0.0); for p, limit > 0 it
    is ArduPilot's law as the simulator wrote it (control.cpp): p e up to limit / p^2, beyond it
    sign(e) sqrt(2 limit (|e| - limit / (2 p^2))), continuous at the knee, to the last bit."""
    linear_dist = limit / (p * p)
    for error in np.concatenate((np.linspace(-40.0, 40.0, 801), [linear_dist, -linear_dist, 0.0, -0.0])):
        error = float(error)
        if abs(error) <= linear_dist:
            expected = p * error
        else:
            expected = math.copysign(math.sqrt(2.0 * limit * (abs(error) - 0.5 * linear_dist)), error)
        got = sqrt_controller(error, p, limit, 0.0)
        assert got == expected and math.copysign(1.0, got) == math.copysign(1.0, expected), error
    assert sqrt_controller(linear_dist * (1 + 1e-12), p, limit, 0.0) == pytest.approx(p * linear_dist)


def test_velocity_demand_is_speed_limited_and_nan_means_no_position_control():
    def demand(target, feed_forward):
        return velocity_demand(
            np.zeros(3), np.array(target), np.array(feed_forward), 1.0, 1.0, 2.5, 10.0, 2.5, 1.5
        )

    assert demand([1000.0, 0.0, 0.0], [0.0, 0.0, 0.0]) == pytest.approx((10.0, 0.0, 0.0))
    assert demand([np.nan, np.nan, 100.0], [3.0, 0.0, 0.0]) == pytest.approx((3.0, 0.0, 2.5))
    assert demand([0.5, 0.0, np.nan], [0.0, 0.0, -9.0]) == pytest.approx((0.5, 0.0, -1.5))
