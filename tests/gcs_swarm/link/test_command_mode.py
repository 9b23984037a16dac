"""Command modes that fit the link (issue 38 item 3): the budget, the bytes each mode needs, the choice, and
the position targets the fleet sends (one per position report, pos + vel + acc on the wire).

Wire sizes by hand from the MAVLink XML field lists (MAVLink 2: 10 header + 2 checksum bytes around the
payload; the payload at its full length): ATTITUDE 4 + 6 x 4 = 28 -> 40; GLOBAL_POSITION_INT 4 + 5 x 4 +
3 x 2 + 2 = 28 -> 40; SET_ATTITUDE_TARGET 4 + 16 + 12 + 4 + 3 = 39 -> 51; SET_POSITION_TARGET_GLOBAL_INT
4 + 2 x 4 + 4 + 8 x 4 + 2 + 3 = 53 -> 65; HEARTBEAT 9 -> 21; SYS_STATUS 31 + 12 (extensions) = 43 -> 55;
EKF_STATUS_REPORT 5 x 4 + 2 + 4 = 26 -> 38; EXTENDED_SYS_STATE 2 -> 14; GPS_RAW_INT 30 + 22 = 52 -> 64.
The four health messages: 55 + 38 + 14 + 64 = 171 bytes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.command_mode import (
    ATTITUDE,
    POSITION,
    CommandModeError,
    LinkBudget,
    command_plan,
    link_budget,
    wire_bytes,
)
from gcs_swarm.link.setpoints import HOLD_RESEND_S, HOLD_YAW_RAD
from gcs_swarm.mission.model import LinkSpec
from tests.gcs_swarm.link.simulated_vehicles import ORIGIN

HEALTH = 171  # bytes of one of each health message (module doc)


@pytest.mark.parametrize(
    ("message", "size"),
    [
        ("ATTITUDE", 40),
        ("GLOBAL_POSITION_INT", 40),
        ("SET_ATTITUDE_TARGET", 51),
        ("SET_POSITION_TARGET_GLOBAL_INT", 65),
        ("HEARTBEAT", 21),
    ],
)
def test_wire_bytes_are_the_framed_full_payload(message: str, size: int) -> None:
    assert wire_bytes(message) == size
    assert wire_bytes(message, signed=True) == size + 13  # link id 1 + timestamp 6 + signature 6


def test_without_a_budget_the_paper_s_attitude_targets_fly_as_today() -> None:
    plan = command_plan(None, 50.0)
    assert (plan.mode, plan.setpoint_hz, plan.state_hz, plan.status_hz) == (ATTITUDE, 50.0, 50.0, 2.0)
    # up: 50 x 51 + 21; down: 50 x (40 + 40) + 2 x 171 + 21
    assert (plan.up_B_s, plan.down_B_s) == (2571.0, 4363.0)
    assert plan.telemetry == {
        "ATTITUDE": 50.0,
        "GLOBAL_POSITION_INT": 50.0,
        "SYS_STATUS": 2.0,
        "EKF_STATUS_REPORT": 2.0,
        "EXTENDED_SYS_STATE": 2.0,
        "GPS_RAW_INT": 2.0,
    }
    assert "attitude targets at 50 Hz" in plan.text()


def test_a_sik64_radio_gets_position_targets_at_10_hz() -> None:
    budget = link_budget(LinkSpec(radio="sik64"), 3)
    assert budget is not None
    assert budget.bytes_per_s == pytest.approx(64000 / 10.2)  # docs/radio.md: 10.2 bit times a byte
    assert budget.packet_bytes == 0.0
    plan = command_plan(budget, 50.0)
    # attitude needs 2571 + 4363 = 6934 B/s, more than half of 6275; position at 10 Hz: up 10 x 65 + 21,
    # down 10 x 80 + 1 x 171 + 21 = 992, together 1663 <= 3137
    assert (plan.mode, plan.setpoint_hz, plan.state_hz, plan.status_hz) == (POSITION, 10.0, 10.0, 1.0)
    assert (plan.up_B_s, plan.down_B_s, plan.attitude_B_s) == (671.0, 992.0, 6934.0)
    assert plan.text() == (
        "command mode: position targets at 10 Hz (1663 B/s), attitude targets need 6934 B/s of a 6275 B/s "
        "budget (sik64 64000 bit/s / 10.2 bit times a byte)"
    )
    assert plan.as_json()["mode"] == "position" and plan.as_json()["forced"] is False
    # PX4's unasked default streams, whose data ATTITUDE and GLOBAL_POSITION_INT carry, are stopped
    assert plan.telemetry["ATTITUDE_QUATERNION"] == plan.telemetry["LOCAL_POSITION_NED"] == 0.0


def test_the_mission_s_budget_comes_before_its_radio() -> None:
    budget = link_budget(LinkSpec(radio="sik64", budget_bps=80000.0), 3)
    assert budget == LinkBudget(10000.0, 0.0, "world.link.budget_bps 80000 bit/s")
    assert link_budget(LinkSpec(), 3) is None  # no radio, no budget: unlimited


def test_a_shared_radio_is_divided_and_its_packet_overhead_counted() -> None:
    """wifi: 24 Mbit/s at 8 bit times a byte = 3e6 B/s for 3 vehicles, 1e6 each; a packet costs 64 bytes
    plus 165.5 us of air, 165.5e-6 x 3e6 = 496.5 bytes more."""
    budget = link_budget(LinkSpec(radio="wifi"), 3)
    assert budget is not None
    assert budget.bytes_per_s == pytest.approx(1e6)
    assert budget.packet_bytes == pytest.approx(560.5)
    plan = command_plan(budget, 50.0)
    # 51 packets a second up (50 targets and a HEARTBEAT): 2571 + 51 x 560.5; fits within half of 1e6
    assert plan.mode == ATTITUDE and plan.up_B_s == pytest.approx(2571 + 51 * 560.5)


def test_a_narrow_budget_takes_the_slowest_position_rate_or_refuses_with_one_sentence() -> None:
    # 1000 B/s: 10 Hz (1663) and 5 Hz (up 5 x 65 + 21 = 346, down 5 x 80 + 171 + 21 = 592: 938) are over half
    # of it; 4 Hz (281 + 512 = 793) is too, but fits the whole budget
    plan = command_plan(LinkBudget(1000.0, 0.0, "test"), 50.0)
    assert (plan.mode, plan.setpoint_hz, plan.up_B_s + plan.down_B_s) == (POSITION, 4.0, 793.0)
    assert "beyond the 50% margin" in plan.text()
    with pytest.raises(CommandModeError, match=r"^the link budget of 500 B/s .* cannot carry position"):
        command_plan(LinkBudget(500.0, 0.0, "test"), 50.0)


def test_the_mission_may_force_either_mode() -> None:
    budget = LinkBudget(500.0, 0.0, "test")
    forced = command_plan(budget, 50.0, mode="attitude")  # flown as today, whatever it needs
    assert (forced.mode, forced.setpoint_hz, forced.forced) == (ATTITUDE, 50.0, True)
    unlimited = command_plan(None, 50.0, mode="position")
    assert (unlimited.mode, unlimited.setpoint_hz, unlimited.status_hz) == (POSITION, 10.0, 1.0)
    assert "world.link.command_mode" in unlimited.text()


def test_position_targets_go_once_per_position_report_with_position_velocity_acceleration(
    simulator, fleet_of
) -> None:
    """Against the simulator in lockstep (20 ms frames): a fleet whose plan is position targets at 10 Hz asks
    for its state telemetry every 100 ms and its health every second; told twice a tick to send a trajectory
    target, it sends one per GLOBAL_POSITION_INT, each with every field but the yaw rate, in NED."""
    vehicles = simulator(1)
    tap = vehicles.tap(0)
    plan = command_plan(None, 50.0, mode="position")
    fleet = fleet_of(tap, command_plan=plan)
    fleet.connect(timeout_s=10.0)
    intervals = {
        int(m.param1): m.param2 for m in tap.commands(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL)
    }  # message id -> us
    assert intervals[mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == 100_000.0
    assert intervals[mavlink2.MAVLINK_MSG_ID_ATTITUDE] == 100_000.0
    assert intervals[mavlink2.MAVLINK_MSG_ID_SYS_STATUS] == 1_000_000.0
    fleet.set_mode_all("GUIDED")
    fleet.arm_all()
    fleet.takeoff_all(3.0)
    fleet.wait_until(lambda: bool(fleet.pos[0, 2] > 2.5), 20.0, "in the air")
    reports: list[int] = []
    sent_before = len(tap.sent("SET_POSITION_TARGET_GLOBAL_INT"))
    target = np.array([[5.0, -3.0, 4.0]])
    vel, acc, yaw = np.array([[1.0, 2.0, -0.5]]), np.array([[0.2, -0.1, 0.3]]), np.array([0.5])
    ticks: list[int] = []
    for _ in range(50):
        assert fleet.wait_tick(timeout_s=2.0)
        for _ in range(2):  # the second finds no new position report: nothing goes
            fleet.send_trajectory_targets(target, vel, acc, yaw, np.array([True]))
        reports.append(int(fleet.state.position_ms[0]))
        ticks.append(int(fleet.state.time_ms[0]))
        fleet.answer_frame()
    # the ticks come every 20 ms frame (the simulator's SYSTEM_TIME stamps the frames without a position),
    # the position reports every 100 ms: one target per report
    assert set(np.diff(ticks)) == {20}
    distinct = sorted(set(reports))
    assert set(np.diff(distinct)) == {100} and len(distinct) >= 9
    fleet.pump(0.2)  # the tap passes the last targets on
    sent = tap.sent("SET_POSITION_TARGET_GLOBAL_INT")[sent_before:]
    assert [m.time_boot_ms for m in sent] == distinct
    last = sent[-1]
    assert last.type_mask == mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE  # pos, vel, acc, yaw used
    assert last.coordinate_frame == mavlink2.MAV_FRAME_GLOBAL_INT
    # ENU (1, 2, -0.5) -> NED (2, 1, 0.5); ENU (0.2, -0.1, 0.3) -> NED (-0.1, 0.2, -0.3); ENU yaw 0.5 rad
    # counter-clockwise from East -> NED pi/2 - 0.5 clockwise from North
    np.testing.assert_allclose([last.vx, last.vy, last.vz], [2.0, 1.0, 0.5], atol=1e-6)
    np.testing.assert_allclose([last.afx, last.afy, last.afz], [-0.1, 0.2, -0.3], atol=1e-6)
    assert last.yaw == pytest.approx(math.pi / 2 - 0.5, abs=1e-6)
    # 5 m east, 3 m south of the origin at 4 m above it: 1 deg of latitude is ~111.2 km
    assert (last.lat_int / 1e7 - ORIGIN[0]) * 111_200 == pytest.approx(-3.0, abs=0.05)
    assert last.alt == pytest.approx(ORIGIN[2] + 4.0, abs=0.01)


def test_an_unchanged_hold_is_repeated_only_as_a_keep_alive(simulator, fleet_of) -> None:
    """Holds (setpoints module doc) told every 20 ms frame: the first goes, then an unchanged one only once
    HOLD_RESEND_S = 0.25 s of vehicle time has passed, i.e. at the 13th frame after (12 x 20 = 240 ms is
    too soon, 260 ms is not): over 60 frames (0..1180 ms) at 0, 260, 520, 780, 1040 ms, five. A yaw jitter
    below HOLD_YAW_RAD is no change; a new velocity, a new yaw or any other target in between sends the
    next hold at once. The frames no hold answered are answered by SYSTEM_TIME: the clock goes on."""
    assert HOLD_RESEND_S == 0.25 and HOLD_YAW_RAD == 0.02
    vehicles = simulator(1)
    tap = vehicles.tap(0)
    fleet = fleet_of(tap)
    fleet.connect(timeout_s=10.0)
    setpoints = fleet.vehicle(0).setpoints

    def frames(n: int, action) -> list[int]:
        before = len(tap.sent("SET_POSITION_TARGET_LOCAL_NED"))
        start = None
        for k in range(n):
            assert fleet.wait_tick(timeout_s=2.0)
            start = int(fleet.state.time_ms[0]) if start is None else start
            action(k)
            fleet.answer_frame()
        fleet.pump(0.2)
        return [m.time_boot_ms - start for m in tap.sent("SET_POSITION_TARGET_LOCAL_NED")[before:]]

    # the yaw jitters by 0.01 rad every other frame: the same hold
    hold = lambda k: setpoints.send_velocity_target(np.zeros(3), yaw=0.3 + 0.01 * (k % 2))  # noqa: E731
    assert frames(60, hold) == [0, 260, 520, 780, 1040]
    assert frames(3, lambda k: setpoints.send_velocity_target(np.zeros(3), yaw=0.35 + 0.05 * k)) == [
        0,
        20,
        40,
    ]
    moving = lambda k: setpoints.send_velocity_target(np.array([0.0, 0.1 * (k > 1), 0.0]), yaw=0.4)  # noqa: E731
    assert frames(4, moving) == [0, 40]  # (0, 0, 0) at once (the yaw changed), then (0, 0.1, 0) when it came

    def after_attitude(k: int) -> None:
        if k == 1:
            setpoints.send_attitude_quaternion([1.0, 0.0, 0.0, 0.0], 0.5)
        else:
            setpoints.send_velocity_target(np.zeros(3), yaw=0.4)

    assert frames(3, after_attitude) == [0, 40]
