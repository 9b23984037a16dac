"""Commands over a lossy link against a simulated ArduCopter (sitl_sim in lockstep: vehicle time runs faster
than the wall clock), the losses scripted in a wire tap: resends timed in vehicle time, lost ACKs and echoes
recovered by idempotent repeats, and a refused repeat of a takeoff that is already climbing."""

from __future__ import annotations

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import operations
from gcs_swarm.link.connection import LinkError

INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
ARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF
FRAME_MS = 20  # the simulator's lockstep frame (--lockstep-hz 50)


def test_resends_follow_the_vehicle_clock(lead) -> None:
    fleet, link, wire = lead()
    wire.drop_uplink("COMMAND_LONG", 2, lambda m: m.command == INTERVAL)
    before = len(wire.uplink)
    fleet.run([link.commands.op_command(INTERVAL, mavlink2.MAVLINK_MSG_ID_ATTITUDE, 20000, timeout_s=0.5)])
    # the vehicle time of each attempt: the frame it was decided on, which the ground station answers right
    # after its commands (the next lockstep answer on the wire)
    sent_ms, waiting = [], 0
    for msg in wire.uplink[before:]:
        if msg.get_type() == "COMMAND_LONG" and msg.command == INTERVAL:
            waiting += 1
        elif msg.get_type() == "SYSTEM_TIME" and waiting:
            sent_ms += [msg.time_boot_ms] * waiting
            waiting = 0
    # each resend comes 0.5 s of vehicle time after the previous attempt, however fast the lockstep runs
    assert np.diff(sent_ms).tolist() == [500, 500]
    start = fleet.state.clock_ms
    with pytest.raises(LinkError, match="^timed out after 0.5 s waiting for nothing$"):
        fleet.wait_until(lambda: False, 0.5, "nothing")
    assert 500 <= fleet.state.clock_ms - start <= 500 + FRAME_MS


def test_a_vehicle_clock_that_stands_still_falls_back_on_the_wall_clock(lead, monkeypatch) -> None:
    monkeypatch.setattr(operations, "CLOCK_STALL_S", 0.1)
    fleet, link, wire = lead()
    stamped = ("SYSTEM_TIME", "GLOBAL_POSITION_INT", "ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED")
    for kind in stamped:  # from here on nothing stamped arrives: the vehicle clock stands still
        wire.drop_downlink(kind, 10**9)
    fleet.pump(0.2)
    still = fleet.state.clock_ms
    wire.drop_uplink("COMMAND_LONG", 10, lambda m: m.command == INTERVAL)
    with pytest.raises(
        LinkError, match=r"^lead did not acknowledge MAV_CMD_SET_MESSAGE_INTERVAL \(2 attempts"
    ):
        fleet.run([link.commands.op_command(INTERVAL, 30, 20000, retries=1, timeout_s=0.2)])
    assert fleet.state.clock_ms == still
    assert len(wire.commands(INTERVAL)) >= 2  # both attempts went out


def test_lost_acks_and_echoes_are_recovered_by_repeats(lead) -> None:
    fleet, link, wire = lead()
    wire.drop_downlink("COMMAND_ACK", 1)
    fleet.run([link.commands.op_set_mode("GUIDED")])
    wire.drop_downlink("COMMAND_ACK", 1)
    fleet.run([link.commands.op_arm()])
    assert fleet.mode[0] == 4 and fleet.armed[0]
    # the repeat of an arm that took effect is accepted, as ArduCopter does (AP_Arming_Copter::arm)
    assert wire.results(ARM) == [mavlink2.MAV_RESULT_ACCEPTED] * 2
    sets, reads = len(wire.sent("PARAM_SET")), len(wire.sent("PARAM_REQUEST_READ"))
    wire.drop_downlink("PARAM_VALUE", 1)
    assert fleet.run([link.parameters.op_set("GUID_OPTIONS", 8)])[0] == 8.0
    wire.drop_downlink("PARAM_VALUE", 1)
    hover = fleet.run([link.parameters.op_get("MOT_THST_HOVER")])[0]
    assert hover == wire.received("PARAM_VALUE")[-1].param_value
    # one repeat each: PARAM_SET twice, PARAM_REQUEST_READ twice
    assert len(wire.sent("PARAM_SET")) - sets == 2 and len(wire.sent("PARAM_REQUEST_READ")) - reads == 2


def test_a_refused_repeat_of_a_takeoff_already_climbing_is_done(lead) -> None:
    fleet, link, wire = lead()
    fleet.run([link.streams.op_request_streams({"EXTENDED_SYS_STATE": 10.0, "GLOBAL_POSITION_INT": 10.0})])
    fleet.run([link.commands.op_set_mode("GUIDED")])
    fleet.run([link.commands.op_arm()])
    wire.drop_downlink("COMMAND_ACK", 1, lambda m: m.command == TAKEOFF)  # the climb starts; its ACK is lost
    fleet.run([link.commands.op_takeoff(5.0)])
    # ArduCopter refuses a NAV_TAKEOFF when not landed: the repeat is FAILED (docs/sitl.md, Take-off)
    assert wire.results(TAKEOFF) == [mavlink2.MAV_RESULT_ACCEPTED, mavlink2.MAV_RESULT_FAILED]
    assert any("repeated NAV_TAKEOFF was refused" in event.text for event in fleet.events)
    fleet.wait_until(lambda: fleet.pos[0, 2] > 4.9, 20.0, "lead at 5 m")


def test_a_refused_repeat_of_a_takeoff_that_did_not_start_is_a_refusal(lead) -> None:
    fleet, link, wire = lead()
    fleet.run([link.streams.op_request_streams({"EXTENDED_SYS_STATE": 10.0, "GLOBAL_POSITION_INT": 10.0})])
    fleet.run([link.commands.op_set_mode("GUIDED")])  # but not armed: every attempt is refused
    wire.drop_downlink("COMMAND_ACK", 1, lambda m: m.command == TAKEOFF)
    with pytest.raises(LinkError, match="^lead refused MAV_CMD_NAV_TAKEOFF: FAILED$"):
        fleet.run([link.commands.op_takeoff(5.0)])
    assert len(wire.commands(TAKEOFF)) == 2
    assert fleet.landed_state[0] == mavlink2.MAV_LANDED_STATE_ON_GROUND
