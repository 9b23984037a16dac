"""Commands over a lossy link against the fake ArduCopter (lockstep: vehicle time runs faster than the wall
clock): resends timed in vehicle time, lost ACKs and echoes recovered by idempotent repeats, and a refused
repeat of a takeoff that is already climbing."""

from __future__ import annotations

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import operations
from gcs_swarm.link.connection import LinkError

INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
ARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF


def test_resends_follow_the_vehicle_clock(lead) -> None:
    fleet, link, vehicle = lead()
    vehicle.ignore_commands = 2
    before = len(vehicle.commands)  # connect already asked for the telemetry streams
    fleet.run([link.commands.op_command(INTERVAL, mavlink2.MAVLINK_MSG_ID_ATTITUDE, 20000, timeout_s=0.5)])
    sent_ms = [
        t
        for (command, _, _), t in zip(vehicle.commands[before:], vehicle.command_ms[before:], strict=True)
        if command == INTERVAL
    ]
    # each resend comes 0.5 s of vehicle time after the previous attempt, however fast the lockstep runs
    assert np.diff(sent_ms).tolist() == [500, 500]
    start = fleet.state.clock_ms
    with pytest.raises(LinkError, match="^timed out after 0.5 s waiting for nothing$"):
        fleet.wait_until(lambda: False, 0.5, "nothing")
    assert 500 <= fleet.state.clock_ms - start <= 500 + vehicle.dt_ms


def test_a_vehicle_clock_that_stands_still_falls_back_on_the_wall_clock(fake, fleet_of, monkeypatch) -> None:
    monkeypatch.setattr(operations, "CLOCK_STALL_S", 0.1)
    vehicle = fake(1)  # real time and no stamped stream: the ground station sees its clock stand still
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    vehicle.intervals_ms = {mavlink2.MAVLINK_MSG_ID_HEARTBEAT: 1000}  # drop the streams connect asked for
    fleet.pump(0.2)
    still = fleet.state.clock_ms  # from here on nothing stamped arrives: the vehicle clock stands still
    vehicle.ignore_commands = 10
    with pytest.raises(
        LinkError, match=r"^lead did not acknowledge MAV_CMD_SET_MESSAGE_INTERVAL \(2 attempts"
    ):
        fleet.run([fleet.vehicle("lead").commands.op_command(INTERVAL, 30, 20000, retries=1, timeout_s=0.2)])
    assert fleet.state.clock_ms == still


def test_lost_acks_and_echoes_are_recovered_by_repeats(lead) -> None:
    fleet, link, vehicle = lead()
    vehicle.drop_acks = 1
    fleet.run([link.commands.op_set_mode("GUIDED")])
    vehicle.drop_acks = 1
    fleet.run([link.commands.op_arm()])
    assert fleet.mode[0] == 4 and fleet.armed[0]
    # the repeat of an arm that took effect is accepted, as ArduCopter does (AP_Arming_Copter::arm)
    assert [r for c, r in vehicle.results if c == ARM] == [mavlink2.MAV_RESULT_ACCEPTED] * 2
    vehicle.drop_param_values = 1
    assert fleet.run([link.parameters.op_set("GUID_OPTIONS", 8)])[0] == 8.0
    vehicle.drop_param_values = 1
    assert fleet.run([link.parameters.op_get("MOT_THST_HOVER")])[0] == pytest.approx(0.35)
    assert vehicle.received["PARAM_SET"] == 2 and vehicle.received["PARAM_REQUEST_READ"] == 3


def test_a_refused_repeat_of_a_takeoff_already_climbing_is_done(lead) -> None:
    fleet, link, vehicle = lead()
    fleet.run([link.streams.op_request_streams({"EXTENDED_SYS_STATE": 10.0, "GLOBAL_POSITION_INT": 10.0})])
    fleet.run([link.commands.op_set_mode("GUIDED")])
    fleet.run([link.commands.op_arm()])
    vehicle.drop_acks = 1  # the first NAV_TAKEOFF starts the climb; its ACK is lost
    fleet.run([link.commands.op_takeoff(5.0)])
    failed = mavlink2.MAV_RESULT_FAILED
    assert [r for c, r in vehicle.results if c == TAKEOFF] == [mavlink2.MAV_RESULT_ACCEPTED, failed]
    assert any("repeated NAV_TAKEOFF was refused" in event.text for event in fleet.events)
    fleet.wait_until(lambda: fleet.pos[0, 2] > 4.9, 3.0, "lead at 5 m")


def test_a_refused_repeat_of_a_takeoff_that_did_not_start_is_a_refusal(lead) -> None:
    fleet, link, vehicle = lead()
    fleet.run([link.streams.op_request_streams({"EXTENDED_SYS_STATE": 10.0, "GLOBAL_POSITION_INT": 10.0})])
    fleet.run([link.commands.op_set_mode("GUIDED")])  # but not armed: every attempt is refused
    vehicle.drop_acks = 1
    with pytest.raises(LinkError, match="^lead refused MAV_CMD_NAV_TAKEOFF: FAILED$"):
        fleet.run([link.commands.op_takeoff(5.0)])
    assert [c for c, _, _ in vehicle.commands].count(TAKEOFF) == 2
    assert fleet.landed_state[0] == mavlink2.MAV_LANDED_STATE_ON_GROUND
