"""GUIDED pos-vel-accel targets fly as ArduCopter's do (docs/command-modes.md): the target moves on with its
velocity and acceleration between two setpoints (AC_PosControl::input_pos_vel_accel_xy projects it forward
every loop), stops where it got to after GUID_TIMEOUT (ModeGuided::posvelaccel_control_run zeroes the
velocity and acceleration), and the speed limit bounds only the position correction, not the velocity sent
(limit_output false). Flown in lockstep by a scripted ground station."""

from __future__ import annotations

import pytest

from tests.sitl_sim.sim_process import M

FAST = ("--lockstep", "--lockstep-timeout", "60", "--ready-delay", "1")  # generous timeout: a loaded CI
TRAJECTORY = M.POSITION_TARGET_TYPEMASK_YAW_IGNORE | M.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
GUID_TIMEOUT_S = 5.0  # s, set for the test (the longest ArduCopter allows): time to reach the speed
SPEED_NORTH = 12.0  # m/s: above WPNAV_SPEED (10 m/s), which bounded the whole velocity demand before


def test_one_pos_vel_accel_target_is_flown_on_until_the_guided_timeout(sitl, pilot_for) -> None:
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 10.0)
    assert pilot.set_param(0, "GUID_TIMEOUT", GUID_TIMEOUT_S) == GUID_TIMEOUT_S
    local = lambda: v.latest["LOCAL_POSITION_NED"]  # noqa: E731
    pilot.spin(lambda: abs(local().vx) < 0.1 and abs(local().vy) < 0.1, 10.0)
    x0, y0, z0, t0 = local().x, local().y, local().z, v.t
    # one target at the vehicle, moving north at SPEED_NORTH, never updated
    v.mav.set_position_target_local_ned_send(
        v.time_boot_ms, 1, 1, M.MAV_FRAME_LOCAL_NED, TRAJECTORY, x0, y0, z0, SPEED_NORTH, 0, 0, 0, 0, 0, 0, 0
    )
    pilot.spin(lambda: v.t > t0 + GUID_TIMEOUT_S - 0.2, 5.0)
    # a target that stood still would be held at ~ (12 m/s)^2 / (2 x 2.5 m/s^2) = 29 m of lag by the
    # position correction's sqrt shaping (WPNAV_ACCEL 2.5 m/s^2) and the 10 m/s bound: the vehicle is at
    # speed instead, faster than that bound
    assert local().vx > 11.0, local()
    # GUID_TIMEOUT: the target stopped 12 m/s x 5 s = 60 m north; the vehicle brakes and comes back to it
    pilot.spin(lambda: v.t > t0 + 20.0, 22.0)
    assert local().x - x0 == pytest.approx(SPEED_NORTH * GUID_TIMEOUT_S, abs=1.5)
    assert abs(local().vx) < 0.3 and abs(local().y - y0) < 0.5 and abs(local().z - z0) < 0.5


def test_the_acceleration_of_a_target_carries_it_on(sitl, pilot_for) -> None:
    """A target at rest that accelerates east at 1 m/s^2: 1 s later its velocity is 1 m/s and it is 0.5 m
    on; at 2 s, 2 m/s and 2 m. The vehicle follows it."""
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 10.0)
    local = lambda: v.latest["LOCAL_POSITION_NED"]  # noqa: E731
    pilot.spin(lambda: abs(local().vx) < 0.1 and abs(local().vy) < 0.1, 10.0)
    x0, y0, z0, t0 = local().x, local().y, local().z, v.t
    v.mav.set_position_target_local_ned_send(
        v.time_boot_ms, 1, 1, M.MAV_FRAME_LOCAL_NED, TRAJECTORY, x0, y0, z0, 0, 0, 0, 0, 1.0, 0, 0, 0
    )
    pilot.spin(lambda: v.t > t0 + 2.5, 4.0)
    # the target: 2.5 m/s, 3.125 m east; the vehicle within a few tenths of both
    assert local().vy == pytest.approx(2.5, abs=0.4), local()
    assert local().y - y0 == pytest.approx(3.125, abs=0.6), local()
