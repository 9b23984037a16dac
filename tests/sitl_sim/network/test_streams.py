"""Telemetry: NED/FRD conversion, stream scheduling, SET_MESSAGE_INTERVAL / REQUEST_MESSAGE and the other
requests a ground station makes on connecting."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sitl_sim.network.streams import StreamSchedule, ned_telemetry, swap_quat_enu_ned
from swarm_common.rotations import euler_to_quaternion
from tests.sitl_sim.sim_process import M

ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FRD_TO_FLU = np.diag([1.0, -1.0, -1.0])


def rotation(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


angles = st.floats(-3.0, 3.0)


@given(roll=angles, pitch=st.floats(-1.5, 1.5), yaw=angles)
def test_quaternion_conversion_matches_the_frame_rotations(roll, pitch, yaw):
    q_enu = euler_to_quaternion(np.stack((roll, pitch, yaw), axis=-1))
    q_ned = swap_quat_enu_ned(q_enu)
    assert np.allclose(rotation(q_ned), ENU_TO_NED @ rotation(q_enu) @ FRD_TO_FLU, atol=1e-9)
    assert np.allclose(swap_quat_enu_ned(q_ned), q_enu, atol=1e-12)
    pos, vel, omega = np.array([[1.0, 2.0, 3.0]]), np.array([[4.0, 5.0, 6.0]]), np.array([[0.1, 0.2, 0.3]])
    row = ned_telemetry(pos, vel, q_enu[None, :], omega, np.array([[0.5, 0.5, 0.5]]))[0]
    assert np.allclose(row[0:4], q_ned) and np.allclose(row[7:], [0.1, -0.2, -0.3, 1.5, 0.5, -2.5, 5, 4, -6])
    ned_roll, ned_pitch, ned_yaw = row[4:7]  # spec 1.1 relations
    assert ned_roll == pytest.approx(roll, abs=1e-6)
    assert ned_pitch == pytest.approx(-pitch, abs=1e-6)
    assert math.remainder(ned_yaw - (math.pi / 2 - yaw), 2 * math.pi) == pytest.approx(0.0, abs=1e-6)


def test_schedule_at_multiples_of_the_interval_from_boot():
    schedule = StreamSchedule(2, tick_us=10_000)
    attitude = M.MAVLINK_MSG_ID_ATTITUDE
    assert schedule.set_interval(1, attitude, 20_000, now_us=30_000)
    assert schedule.set_interval(0, attitude, -1, now_us=30_000)
    due = [t for t in range(40_000, 120_000, 10_000) if (1, attitude) in schedule.due(t)]
    assert due == [40_000, 60_000, 80_000, 100_000]
    assert schedule.interval(0, attitude) == -1
    assert schedule.set_interval(0, attitude, 100, now_us=0) and schedule.interval(0, attitude) == 10_000
    # 0 = back to the default rate, which for ArduCopter's streams is "not sent" until asked (streams.py)
    assert schedule.set_interval(0, attitude, 0, now_us=0) and schedule.interval(0, attitude) == -1
    assert not schedule.set_interval(0, M.MAVLINK_MSG_ID_VFR_HUD, 1e5, now_us=0)
    assert schedule.interval(0, M.MAVLINK_MSG_ID_VFR_HUD) is None


def test_slow_streams_are_spread_over_the_ticks_by_vehicle():
    # 200 vehicles, 10 ms ticks: each 1 Hz HEARTBEAT is due at i x 10 ms mod 1 s, so no tick of the second
    # carries more than 2 of them (vehicles i and i + 100), while a 50 Hz stream of every vehicle is due on
    # the same ticks (multiples of 20 ms from boot)
    n, tick = 200, 10_000
    schedule = StreamSchedule(n, tick_us=tick)
    heartbeat, position = M.MAVLINK_MSG_ID_HEARTBEAT, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    for i in range(n):
        schedule.set_interval(i, position, 20_000, now_us=0)
    per_tick: dict[int, int] = {}
    beats: dict[int, list[int]] = {i: [] for i in range(n)}
    for t in range(0, 2_000_000, tick):
        due = schedule.due(t)
        for i, m in due:
            if m == heartbeat:
                beats[i].append(t)
        per_tick[t] = sum(1 for _, m in due if m == heartbeat)
        fast = [i for i, m in due if m == position]
        assert fast == (list(range(n)) if t % 20_000 == 0 else [])
    assert max(per_tick.values()) == 2
    assert beats[0] == [0, 1_000_000]
    assert beats[37] == beats[137] == [370_000, 1_370_000]  # 1370 ms mod 1 s = 370 ms
    assert beats[199] == [990_000, 1_990_000]
    # a new interval keeps the vehicle's phase: set at 1.5 s, vehicle 37's next heartbeat is at 2.37 s
    schedule.set_interval(37, heartbeat, 1e6, now_us=1_500_000)
    assert (37, heartbeat) not in schedule.due(2_360_000)
    assert (37, heartbeat) in schedule.due(2_370_000)


def test_requests_of_a_connecting_ground_station(sitl, pilot_for):
    sim = sitl("--lockstep", "--ready-delay", "0.5", "--home", "47.0,8.0,400", vehicles=2)
    pilot = pilot_for(sim)
    v = pilot[1]
    pilot.spin(lambda: v.ready, 3.0)

    assert pilot.command(1, M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, 20_000) == 0
    stamps: list[int] = []

    def record(vehicle):
        if vehicle is v:
            stamps.append(vehicle.latest["ATTITUDE"].time_boot_ms)

    pilot.spin(lambda: len(stamps) >= 5, 1.0, each_frame=record)
    assert list(np.diff(stamps[-4:])) == [20, 20, 20]  # 50 Hz: one per 20 ms lockstep frame
    assert pilot.command(1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 12345678, 20_000) == M.MAV_RESULT_DENIED

    assert pilot.command(1, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == 0
    pilot.spin(lambda: "AUTOPILOT_VERSION" in v.latest, 1.0)
    capabilities = v.latest["AUTOPILOT_VERSION"].capabilities
    assert capabilities & M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert capabilities & M.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET

    assert pilot.command(1, M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_HOME_POSITION) == 0
    pilot.spin(lambda: "HOME_POSITION" in v.latest and "GLOBAL_POSITION_INT" in v.latest, 1.0)
    home = v.latest["HOME_POSITION"]
    east, north, up = pymap3d.geodetic2enu(
        home.latitude / 1e7, home.longitude / 1e7, home.altitude / 1e3, 47, 8, 400
    )
    assert (east, north, up) == pytest.approx((5.0, 0.0, 0.0), abs=0.02)  # vehicle 1 starts 5 m east
    position = v.latest["GLOBAL_POSITION_INT"]
    assert (position.lat, position.lon, position.alt) == (home.latitude, home.longitude, home.altitude)
    local = v.latest["LOCAL_POSITION_NED"]
    assert (local.x, local.y, local.z) == (0.0, 0.0, 0.0)  # relative to its own EKF origin

    v.mav.timesync_send(0, 123456789)
    pilot.spin(lambda: "TIMESYNC" in v.latest, 1.0)
    assert v.latest["TIMESYNC"].ts1 == 123456789 and v.latest["TIMESYNC"].tc1 > 0

    v.acks.clear()
    v.mav.set_mode_send(v.sysid, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 5)
    pilot.spin(lambda: any(a.command == M.MAVLINK_MSG_ID_SET_MODE for a in v.acks), 1.0)
    pilot.spin(lambda: v.mode == 5, 1.0)
    assert pilot.command(1, M.MAV_CMD_DO_SET_MODE, 1, 3) == M.MAV_RESULT_FAILED  # AUTO is not simulated
    assert pilot.command(1, M.MAV_CMD_DO_FLIGHTTERMINATION, 1) == M.MAV_RESULT_UNSUPPORTED
