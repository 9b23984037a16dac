"""Commands, modes, arming and parameters against a simulated ArduCopter (sitl_sim in lockstep, one fresh
vehicle per test), through a wire tap that records both directions and loses or answers what a test says."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import LinkError

ARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
# docs/sitl.md, geofence: FENCE_ENABLE 1 with FENCE_TYPE 4 and no zones uploaded fails the pre-arm check
NO_FENCE_REASON = "PreArm: Fences enabled, but none selected"


def enable_a_fence_without_zones(fleet, link) -> None:
    """Make the vehicle refuse to arm (NO_FENCE_REASON) until forced."""
    fleet.run([link.parameters.op_set("FENCE_TYPE", 4)])
    fleet.run([link.parameters.op_set("FENCE_ENABLE", 1)])


def test_refused_arm_names_result_and_prearm_reason_then_force_arms(lead) -> None:
    fleet, link, wire = lead()
    enable_a_fence_without_zones(fleet, link)
    with pytest.raises(
        LinkError, match=rf"^lead refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED \({NO_FENCE_REASON}\)$"
    ):
        fleet.run([link.commands.op_arm()])
    assert not fleet.armed[0]
    fleet.run([link.commands.op_arm(force=True)])
    assert fleet.armed[0]  # confirmed by HEARTBEAT, not just by the ACK
    assert [m.param2 for m in wire.commands(ARM)] == [0, 2989]  # one refusal, not retried; then forced
    fleet.run([link.commands.op_disarm()])
    assert not fleet.armed[0]


def test_mode_counts_once_heartbeat_shows_it(lead) -> None:
    fleet, link, wire = lead()
    fleet.run([link.commands.op_set_mode("guided")])
    assert fleet.mode[0] == 4  # set_mode returned only after a HEARTBEAT showed GUIDED
    # the vehicle never hears the LAND command, but an ACCEPTED comes back: the HEARTBEAT must decide
    wire.answer_instead(mavlink2.MAV_CMD_DO_SET_MODE, [(mavlink2.MAV_RESULT_ACCEPTED, 0)])
    with pytest.raises(
        LinkError, match="^lead accepted mode LAND but its HEARTBEAT still shows GUIDED after 0.5 s$"
    ):
        fleet.run([link.commands.op_set_mode("LAND", timeout_s=0.5)])
    with pytest.raises(LinkError, match="lead: unknown ArduCopter mode 'HOVER'"):
        fleet.run([link.commands.op_set_mode("HOVER")])


def test_a_second_ack_that_refuses_a_mode_is_the_answer(lead) -> None:
    """PX4 (mavlink_receiver.cpp since 2025, seen on PX4 SITL) ACKs DO_SET_MODE ACCEPTED at once and its
    commander answers again with the real result: a refusal that follows is reported as the refusal, not as a
    HEARTBEAT that never showed the mode."""
    fleet, link, wire = lead()
    wire.answer_instead(
        mavlink2.MAV_CMD_DO_SET_MODE,
        [(mavlink2.MAV_RESULT_ACCEPTED, 0), (mavlink2.MAV_RESULT_TEMPORARILY_REJECTED, 2)],
    )
    with pytest.raises(LinkError, match="^lead refused MAV_CMD_DO_SET_MODE: TEMPORARILY_REJECTED"):
        fleet.run([link.commands.op_set_mode("LAND", timeout_s=5.0)])
    assert fleet.mode[0] != 9  # still not in LAND


def test_command_retries_with_confirmation_and_times_out(lead) -> None:
    fleet, link, wire = lead()
    wire.drop_uplink("COMMAND_LONG", 2, lambda m: m.command == INTERVAL)
    before = len(wire.commands(INTERVAL))  # connect already asked for the telemetry streams
    fleet.run([link.commands.op_command(INTERVAL, mavlink2.MAVLINK_MSG_ID_ATTITUDE, 20000, timeout_s=0.2)])
    assert [m.confirmation for m in wire.commands(INTERVAL)[before:]] == [0, 1, 2]
    wire.drop_uplink("COMMAND_LONG", 10, lambda m: m.command == INTERVAL)
    with pytest.raises(
        LinkError, match="^lead did not acknowledge MAV_CMD_SET_MESSAGE_INTERVAL \\(2 attempts, 0.2 s"
    ):
        fleet.run(
            [
                link.commands.op_command(
                    INTERVAL, mavlink2.MAVLINK_MSG_ID_ATTITUDE, 20000, retries=1, timeout_s=0.2
                )
            ]
        )


def test_in_progress_then_accepted_and_unsupported(lead) -> None:
    fleet, link, wire = lead()
    # a slow command (a calibration): IN_PROGRESS at once, ACCEPTED 10 telemetry datagrams later
    calibration = mavlink2.MAV_CMD_PREFLIGHT_CALIBRATION
    wire.answer_instead(
        calibration, [(mavlink2.MAV_RESULT_IN_PROGRESS, 0), (mavlink2.MAV_RESULT_ACCEPTED, 10)]
    )
    assert fleet.run([link.commands.op_command(calibration, timeout_s=0.5)]) == [mavlink2.MAV_RESULT_ACCEPTED]
    # docs/sitl.md: commands outside its list are answered UNSUPPORTED, as ArduCopter does
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
        lambda: fleet.landed_state[0] == mavlink2.MAV_LANDED_STATE_IN_AIR, 10.0, "lead in the air"
    )
    fleet.wait_until(lambda: fleet.pos[0, 2] > 4.9, 20.0, "lead at 5 m")


def test_param_set_is_verified_by_its_echo(lead) -> None:
    fleet, link, wire = lead()
    assert fleet.run([link.parameters.op_set("GUID_OPTIONS", 8)])[0] == 8.0
    assert wire.received("PARAM_VALUE")[-1].param_value == 8.0  # the vehicle's own echo
    hover = fleet.run([link.parameters.op_get("MOT_THST_HOVER")])[0]
    assert hover == wire.received("PARAM_VALUE")[-1].param_value  # what the vehicle said (a float32)
    # docs/sitl.md: ANGLE_MAX is 1000..8000 cdeg; out of range is refused and the old value (3000) echoed
    with pytest.raises(LinkError, match="^lead did not accept ANGLE_MAX = 9000: it reads back 3000$"):
        fleet.run([link.parameters.op_set("ANGLE_MAX", 9000, retries=1)])
    with pytest.raises(LinkError, match="^lead did not confirm parameter NOPE"):
        fleet.run([link.parameters.op_set("NOPE", 1, retries=1, timeout_s=0.2)])
    with pytest.raises(LinkError, match="^lead did not report parameter NOPE"):
        fleet.run([link.parameters.op_get("NOPE", retries=0, timeout_s=0.2)])
    with pytest.raises(LinkError, match="1-16 ASCII characters"):
        fleet.run([link.parameters.op_get("A_NAME_MUCH_TOO_LONG")])


def test_params_all_fills_gaps_by_index(lead) -> None:
    fleet, link, wire = lead()
    wire.drop_downlink("PARAM_VALUE", 2, lambda m: m.param_index in (1, 2))
    params = fleet.run([link.parameters.op_all(timeout_s=5.0)])[0]
    values = wire.received("PARAM_VALUE")  # every PARAM_VALUE the vehicle sent, the two lost ones included
    count = values[0].param_count
    assert len(params) == count and params == {m.param_id: pytest.approx(m.param_value) for m in values}
    asked = [m.param_index for m in wire.sent("PARAM_REQUEST_READ")]
    assert sorted(i for i in asked if i >= 0) == [1, 2]  # the gaps, asked for by index


def test_message_interval_is_acked_and_the_stream_flows(lead) -> None:
    fleet, link, wire = lead()
    fleet.run([link.streams.op_set_message_interval("GLOBAL_POSITION_INT", 25.0)])
    assert wire.commands(INTERVAL)[-1].param2 == 40000  # us, for 25 Hz
    after = len(wire.received("GLOBAL_POSITION_INT"))
    fleet.wait_until(lambda: fleet.state.position_count[0] >= 3, 3.0, "positions")
    fleet.wait_until(lambda: len(wire.received("GLOBAL_POSITION_INT")) >= after + 4, 3.0, "more positions")
    stamps = [m.time_boot_ms for m in wire.received("GLOBAL_POSITION_INT")[after:]]
    assert {b - a for a, b in zip(stamps[1:], stamps[2:], strict=False)} == {40}  # now every 40 ms
    with pytest.raises(LinkError, match="unknown MAVLink message 'NOT_A_MESSAGE'"):
        fleet.run([link.streams.op_set_message_interval("NOT_A_MESSAGE", 1.0)])


def test_fleet_wide_operations_report_only_the_failing_vehicle(simulator, fleet_of) -> None:
    vehicles = simulator(2)
    good, bad = vehicles.tap(0), vehicles.tap(1)
    fleet = fleet_of(good, bad, names=["f1", "f2"])
    fleet.connect(timeout_s=10.0)
    enable_a_fence_without_zones(fleet, fleet.vehicle("f2"))
    fleet.set_mode_all("GUIDED")
    assert fleet.mode.tolist() == [4, 4]
    with pytest.raises(
        LinkError, match=rf"^f2 refused MAV_CMD_COMPONENT_ARM_DISARM: FAILED \({NO_FENCE_REASON}\)$"
    ):
        fleet.arm_all()
    assert fleet.armed.tolist() == [True, False]
    fleet.param_set_all("GUID_OPTIONS", 8)
    assert fleet.param_get_all("GUID_OPTIONS").tolist() == [8.0, 8.0]
    assert vehicles.dropped(good) == [] and vehicles.dropped(bad) == []


def test_a_vehicle_that_refuses_message_intervals_is_asked_by_stream_group(lead) -> None:
    """SET_MESSAGE_INTERVAL answered DENIED (firmware without it): each refused message is asked for by
    REQUEST_DATA_STREAM of its ArduPilot group instead, and the request as a whole does not fail."""
    fleet, link, wire = lead()
    before = len(wire.sent("REQUEST_DATA_STREAM"))
    # one SET_MESSAGE_INTERVAL per message, each answered DENIED in the vehicle's place
    wire.answer_instead(INTERVAL, [(mavlink2.MAV_RESULT_DENIED, 0)], count=3)
    fleet.run(
        [
            link.streams.op_request_streams(
                {"GLOBAL_POSITION_INT": 10.0, "ATTITUDE": 10.0, "EXTENDED_SYS_STATE": 2.0}
            )
        ]
    )
    # two of the three have a stream group (POSITION, EXTRA1); EXTENDED_SYS_STATE is in none (ardupilot.py)
    assert len(wire.sent("REQUEST_DATA_STREAM")) - before == 2
