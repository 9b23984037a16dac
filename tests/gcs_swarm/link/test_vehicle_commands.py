"""Commands, modes, arming and parameters against the fake ArduCopter (lockstep: vehicle time runs fast)."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import LinkError
from tests.gcs_swarm.link.fake_vehicle import DEFAULT_PARAMS


def test_refused_arm_names_result_and_prearm_reason_then_force_arms(lead) -> None:
    fleet, link, vehicle = lead(arm_refusal="PreArm: Need 3D Fix")
    with pytest.raises(
        LinkError, match=r"^lead refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED \(PreArm: Need 3D Fix\)$"
    ):
        fleet.run([link.commands.op_arm()])
    assert not fleet.armed[0]
    fleet.run([link.commands.op_arm(force=True)])
    assert fleet.armed[0]  # confirmed by HEARTBEAT, not just by the ACK
    arm_commands = [c for c in vehicle.commands if c[0] == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM]
    assert len(arm_commands) == 2
    fleet.run([link.commands.op_disarm()])
    assert not fleet.armed[0]


def test_mode_counts_once_heartbeat_shows_it(lead) -> None:
    fleet, link, vehicle = lead()
    fleet.run([link.commands.op_set_mode("guided")])
    assert fleet.mode[0] == 4  # set_mode returned only after a HEARTBEAT showed GUIDED
    vehicle.ignore_mode_changes = True
    with pytest.raises(
        LinkError, match="^lead accepted mode LAND but its HEARTBEAT still shows GUIDED after 0.5 s$"
    ):
        fleet.run([link.commands.op_set_mode("LAND", timeout_s=0.5)])
    with pytest.raises(LinkError, match="lead: unknown ArduCopter mode 'HOVER'"):
        fleet.run([link.commands.op_set_mode("HOVER")])


def test_command_retries_with_confirmation_and_times_out(lead) -> None:
    fleet, link, vehicle = lead()
    vehicle.ignore_commands = 2
    cmd = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
    before = len(vehicle.commands)  # connect already asked for the telemetry streams
    fleet.run([link.commands.op_command(cmd, mavlink2.MAVLINK_MSG_ID_ATTITUDE, 20000, timeout_s=0.2)])
    assert [conf for c, conf, _ in vehicle.commands[before:] if c == cmd] == [0, 1, 2]
    vehicle.ignore_commands = 10
    with pytest.raises(
        LinkError, match="^lead did not acknowledge MAV_CMD_SET_MESSAGE_INTERVAL \\(2 attempts, 0.2 s"
    ):
        fleet.run(
            [link.commands.op_command(cmd, mavlink2.MAVLINK_MSG_ID_ATTITUDE, 20000, retries=1, timeout_s=0.2)]
        )


def test_in_progress_then_accepted_and_unsupported(lead) -> None:
    fleet, link, _ = lead()
    assert fleet.run([link.commands.op_command(mavlink2.MAV_CMD_PREFLIGHT_CALIBRATION, timeout_s=0.5)]) == [
        mavlink2.MAV_RESULT_ACCEPTED
    ]
    with pytest.raises(LinkError, match="^lead refused MAV_CMD_DO_SET_SERVO: UNSUPPORTED$"):
        fleet.run([link.commands.op_command(mavlink2.MAV_CMD_DO_SET_SERVO, 1, 1500)])


def test_takeoff_needs_guided_and_armed(lead) -> None:
    fleet, link, _ = lead()
    with pytest.raises(LinkError, match="lead refused MAV_CMD_NAV_TAKEOFF: FAILED"):
        fleet.run([link.commands.op_takeoff(5.0)])
    fleet.run([link.streams.op_request_streams({"EXTENDED_SYS_STATE": 10.0, "GLOBAL_POSITION_INT": 10.0})])
    fleet.run([link.commands.op_set_mode("GUIDED")])
    fleet.run([link.commands.op_arm()])
    fleet.run([link.commands.op_takeoff(5.0)])
    fleet.wait_until(
        lambda: fleet.landed_state[0] == mavlink2.MAV_LANDED_STATE_IN_AIR, 3.0, "lead in the air"
    )
    fleet.wait_until(lambda: fleet.pos[0, 2] > 4.9, 3.0, "lead at 5 m")


def test_param_set_is_verified_by_its_echo(lead) -> None:
    fleet, link, vehicle = lead(readonly_params=("SYSID_THISMAV",))
    assert fleet.run([link.parameters.op_set("GUID_OPTIONS", 8)])[0] == 8.0
    assert vehicle.params["GUID_OPTIONS"] == 8.0
    assert fleet.run([link.parameters.op_get("MOT_THST_HOVER")])[0] == pytest.approx(0.35)
    with pytest.raises(LinkError, match="^lead did not accept SYSID_THISMAV = 3: it reads back 1$"):
        fleet.run([link.parameters.op_set("SYSID_THISMAV", 3, retries=1)])
    with pytest.raises(LinkError, match="^lead did not confirm parameter NOPE"):
        fleet.run([link.parameters.op_set("NOPE", 1, retries=1, timeout_s=0.2)])
    with pytest.raises(LinkError, match="^lead did not report parameter NOPE"):
        fleet.run([link.parameters.op_get("NOPE", retries=0, timeout_s=0.2)])
    with pytest.raises(LinkError, match="1-16 ASCII characters"):
        fleet.run([link.parameters.op_get("A_NAME_MUCH_TOO_LONG")])


def test_params_all_fills_gaps_by_index(lead) -> None:
    fleet, link, _ = lead(drop_param_indices=(1, 2))
    params = fleet.run([link.parameters.op_all(timeout_s=5.0)])[0]
    assert params == pytest.approx(DEFAULT_PARAMS)


def test_message_interval_is_acked_and_the_stream_flows(lead) -> None:
    fleet, link, vehicle = lead()
    fleet.run([link.streams.op_set_message_interval("GLOBAL_POSITION_INT", 25.0)])
    assert vehicle.intervals_ms[mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] == 40
    fleet.wait_until(lambda: fleet.state.position_count[0] >= 3, 3.0, "positions")
    with pytest.raises(LinkError, match="unknown MAVLink message 'NOT_A_MESSAGE'"):
        fleet.run([link.streams.op_set_message_interval("NOT_A_MESSAGE", 1.0)])


def test_fleet_wide_operations_report_only_the_failing_vehicle(fake, fleet_of) -> None:
    good, bad = fake(1, lockstep=True), fake(2, lockstep=True, arm_refusal="PreArm: Battery low")
    fleet = fleet_of(good, bad, names=["f1", "f2"])
    fleet.connect(timeout_s=3.0)
    fleet.set_mode_all("GUIDED")
    assert fleet.mode.tolist() == [4, 4]
    with pytest.raises(
        LinkError, match=r"^f2 refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED \(PreArm: Battery low\)$"
    ):
        fleet.arm_all()
    assert fleet.armed.tolist() == [True, False]
    fleet.param_set_all("GUID_OPTIONS", 8)
    assert fleet.param_get_all("GUID_OPTIONS").tolist() == [8.0, 8.0]
    assert good.lockstep_drops == 0 and bad.lockstep_drops == 0


def test_a_vehicle_that_refuses_message_intervals_is_asked_by_stream_group(lead) -> None:
    """SET_MESSAGE_INTERVAL answered DENIED (firmware without it): each refused message is asked for by
    REQUEST_DATA_STREAM of its ArduPilot group instead, and the request as a whole does not fail."""
    fleet, link, vehicle = lead()
    vehicle.refuse_message_interval = True
    before = vehicle.received["REQUEST_DATA_STREAM"]
    fleet.run(
        [
            link.streams.op_request_streams(
                {"GLOBAL_POSITION_INT": 10.0, "ATTITUDE": 10.0, "EXTENDED_SYS_STATE": 2.0}
            )
        ]
    )
    # two of the three have a stream group (POSITION, EXTRA1); EXTENDED_SYS_STATE is in none (ardupilot.py)
    assert vehicle.received["REQUEST_DATA_STREAM"] - before == 2
