"""Position controller pieces: spec 5 thrust-vector inversion with the tilt limit, speed limits."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sitl_sim.attitude_control import euler_from_quat
from sitl_sim.position_control import PositionGains, attitude_from_accel, velocity_demand

G = 9.8


def gains(n: int) -> PositionGains:
    def full(value):
        return np.full(n, value)

    return PositionGains(
        pos_xy_p=full(1.0), pos_z_p=full(1.0), vel_xy_p=full(2.0), vel_xy_i=full(1.0), vel_z_p=full(5.0),
        vel_z_i=full(2.0), speed_xy=full(10.0), speed_up=full(2.5), speed_dn=full(1.5), accel_xy=full(2.5),
        tilt_max=full(math.radians(30.0)),
    )  # fmt: skip


def test_inversion_levels_hovers_and_limits_tilt():
    accel = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 0.0, -50.0]])
    yaw = np.array([0.3, 0.0, math.pi / 2, 0.0])
    quat, thrust_g = attitude_from_accel(accel, yaw, np.full(4, math.radians(30.0)), G)
    euler = euler_from_quat(quat)
    assert np.allclose(euler[0], [0.0, 0.0, 0.3]) and thrust_g[0] == pytest.approx(1.0)
    assert euler[1][1] == pytest.approx(math.atan2(2.0, G))  # east acceleration facing east: pitch forward
    tilt = np.arccos(np.cos(euler[2][0]) * np.cos(euler[2][1]))
    assert tilt == pytest.approx(math.radians(30.0))  # shortened to the limit, altitude kept
    assert euler[2][0] > 0  # east acceleration facing north: right side down (spec 1.1)
    assert thrust_g[2] == pytest.approx(1.0 / math.cos(math.radians(30.0)))
    assert thrust_g[3] == pytest.approx(0.3)  # no free-fall commands


def test_velocity_demand_is_speed_limited_and_nan_means_no_position_control():
    pos = np.zeros((3, 3))
    target = np.array([[1000.0, 0.0, 0.0], [np.nan, np.nan, 100.0], [0.5, 0.0, np.nan]])
    vel = velocity_demand(pos, target, np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 0.0, -1.0]]), gains(3))
    assert vel[0] == pytest.approx([10.0, 0.0, 0.0])
    assert vel[1] == pytest.approx([3.0, 0.0, 2.5])
    assert vel[2] == pytest.approx([0.5, 0.0, -1.0])
