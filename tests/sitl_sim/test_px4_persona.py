"""`sitl-sim --autopilot px4`: a vehicle answering as PX4 v1.14+ multicopter does, flown in lockstep by the
scripted pymavlink ground station of tests/sitl_sim/sim_process.py.

Expected values come from PX4's sources (cited), not from this simulator: custom_mode = main << 16 | sub << 24
(px4_custom_mode.h), TEMPORARILY_REJECTED for refused mode changes and arming (Commander.cpp), offboard
availability = a setpoint younger than COM_OF_LOSS_T (offboardCheck.cpp), int32 parameters bytewise in the
float (checked with struct, independently of the simulator's helpers).
"""

from __future__ import annotations

import math
import struct

import pytest

from tests.sitl_sim.sim_process import M

PX4_ARGS = ("--lockstep", "--lockstep-timeout", "60", "--ready-delay", "1", "--autopilot", "px4")
AUTO, OFFBOARD = 4, 6  # px4_custom_mode.h PX4_CUSTOM_MAIN_MODE_AUTO, _OFFBOARD
TAKEOFF, LOITER, RTL, LAND = 2, 3, 5, 6  # PX4_CUSTOM_SUB_MODE_AUTO_*
HOLD_MODE = (AUTO << 16) | (LOITER << 24)  # 0x03040000 = 50593792
TAKEOFF_MODE = (AUTO << 16) | (TAKEOFF << 24)
RTL_MODE = (AUTO << 16) | (RTL << 24)
LAND_MODE = (AUTO << 16) | (LAND << 24)
OFFBOARD_MODE = OFFBOARD << 16  # 393216, as every PX4 offboard example spells it


def as_int32(value: float) -> int:
    """The int32 PX4 stores bytewise in a PARAM_VALUE float."""
    return struct.unpack("<i", struct.pack("<f", value))[0]


def as_float(value: int) -> float:
    return struct.unpack("<f", struct.pack("<i", value))[0]


def set_mode(pilot, i: int, main: int, sub: int = 0) -> int:
    return pilot.command(i, M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub)


def hover_setpoints(pilot):
    """each_frame callback: SET_ATTITUDE_TARGET level at the hover thrust MPC_THR_HOVER (PX4's thrust is the
    normalised collective, so hover thrust holds altitude)."""
    hover = pilot.param(0, "MPC_THR_HOVER")
    return lambda vehicle: vehicle.attitude(0.0, 0.0, 0.0, hover)


def take_off(pilot, altitude_m: float) -> None:
    """Arm in Hold, NAV_TAKEOFF to altitude_m above home (param7 AMSL), climb, back in Hold."""
    v = pilot[0]
    pilot.spin(lambda: v.ready and "GLOBAL_POSITION_INT" in v.latest, 10.0)
    home_amsl = (v.latest["GLOBAL_POSITION_INT"].alt - v.latest["GLOBAL_POSITION_INT"].relative_alt) / 1000.0
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert "Armed by external command" in v.texts
    result = pilot.command(
        0, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, home_amsl + altitude_m
    )
    assert result == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: v.mode == TAKEOFF_MODE, 2.0)
    pilot.spin(lambda: v.mode == HOLD_MODE and v.altitude > altitude_m - 0.5, 30.0)


def test_heartbeat_streams_arming_and_takeoff_then_hold(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: "HEARTBEAT" in v.latest and "LOCAL_POSITION_NED" in v.latest, 5.0)
    hb = v.latest["HEARTBEAT"]
    assert hb.autopilot == M.MAV_AUTOPILOT_PX4 and hb.type == M.MAV_TYPE_QUADROTOR
    assert hb.custom_mode == HOLD_MODE  # UserModeIntention.hpp: the boot mode is AUTO_LOITER
    assert hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert "EKF_STATUS_REPORT" not in v.latest  # an ArduPilot message PX4 never sends
    take_off(pilot, 10.0)
    assert v.latest["HEARTBEAT"].base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
    assert v.latest["HEARTBEAT"].system_status == M.MAV_STATE_ACTIVE


def test_arming_refused_in_offboard_without_setpoints_and_in_land(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: v.ready, 5.0)
    assert set_mode(pilot, 0, OFFBOARD) == M.MAV_RESULT_ACCEPTED  # always allowed while disarmed
    pilot.spin(lambda: v.mode == OFFBOARD_MODE, 2.0)
    assert not v.ready  # SYS_STATUS pre-arm bit: no offboard signal
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_TEMPORARILY_REJECTED
    assert any(t.startswith("Arming denied: Resolve system health failures") for t in v.texts)  # 50 chars
    assert "Preflight Fail: No offboard signal" in v.texts
    # the force magic does not skip the checks of an external command (Commander.cpp: from_external)
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196) == M.MAV_RESULT_TEMPORARILY_REJECTED
    assert set_mode(pilot, 0, AUTO, LAND) == M.MAV_RESULT_ACCEPTED
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_TEMPORARILY_REJECTED
    assert "Preflight Fail: Mode not suitable for arming" in v.texts


def test_offboard_refused_before_setpoints_accepted_with_them_and_lost_to_return(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    take_off(pilot, 5.0)
    assert set_mode(pilot, 0, OFFBOARD) == M.MAV_RESULT_TEMPORARILY_REJECTED
    assert "Switching to Offboard is currently not available" in v.texts
    assert v.mode == HOLD_MODE
    level_setpoint = hover_setpoints(pilot)
    start = v.t
    pilot.spin(lambda: v.t - start > 1.2, 3.0, each_frame=level_setpoint)  # 50 Hz for more than 1 s
    v.acks.clear()
    v.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, OFFBOARD)
    pilot.spin(
        lambda: any(a.command == M.MAV_CMD_DO_SET_MODE for a in v.acks), 2.0, each_frame=level_setpoint
    )
    assert v.acks[-1].result == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: v.mode == OFFBOARD_MODE, 2.0, each_frame=level_setpoint)
    altitude = v.altitude
    pilot.spin(lambda: v.t - start > 4.0, 4.0, each_frame=level_setpoint)
    assert abs(v.altitude - altitude) < 1.0  # flying the setpoints at hover thrust: holds its height
    lost_from = v.t
    pilot.spin(lambda: v.mode == RTL_MODE, 3.0)  # COM_OF_LOSS_T 1 s, COM_OBL_RC_ACT 0: Position needs sticks
    assert v.t - lost_from >= 1.0 - 0.1  # not before COM_OF_LOSS_T (minus one telemetry period)
    assert "Failsafe activated" in v.texts


def test_land_disarms_after_com_disarm_land(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    take_off(pilot, 5.0)
    assert pilot.command(0, M.MAV_CMD_NAV_LAND) == M.MAV_RESULT_ACCEPTED
    assert "Landing at current position" in v.texts
    pilot.spin(lambda: v.mode == LAND_MODE, 2.0)
    pilot.spin(lambda: v.latest["EXTENDED_SYS_STATE"].landed_state == M.MAV_LANDED_STATE_ON_GROUND, 30.0)
    landed_at = v.t
    pilot.spin(lambda: "Disarmed by landing" in v.texts, 5.0)
    # COM_DISARM_LAND 2 s after the land detector, whose landed_state reaches us up to one 5 Hz period late
    assert 2.0 - 0.25 <= v.t - landed_at <= 2.0 + 0.05
    pilot.spin(lambda: not v.armed, 1.5)
    pilot.spin(lambda: v.mode == HOLD_MODE, 2.0)  # UserModeIntention::onDisarm: the last armable mode


def test_gcs_loss_holds_then_returns_per_nav_dll_act(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: v.ready, 5.0)
    for name, value in (("NAV_DLL_ACT", 2), ("COM_DL_LOSS_T", 5)):
        v.params.pop(name, None)
        v.mav.param_set_send(v.sysid, 1, name.encode(), as_float(value), M.MAV_PARAM_TYPE_INT32)
        pilot.spin(lambda name=name: name in v.params, 2.0)
        assert as_int32(v.params[name].param_value) == value
    take_off(pilot, 5.0)
    pilot.heartbeat = False
    silent_from = v.t
    pilot.spin(lambda: "Connection to ground station lost" in v.texts, 10.0)
    assert v.t - silent_from >= 5.0 - 1.0  # COM_DL_LOSS_T after the last heartbeat (sent once a second)
    assert "Failsafe activated: entering Hold for 5 seconds" in v.texts  # COM_FAIL_ACT_T
    assert v.mode == HOLD_MODE
    held_from = v.t
    pilot.spin(lambda: v.mode == RTL_MODE, 7.0)
    assert 5.0 - 0.1 <= v.t - held_from <= 5.0 + 1.1  # COM_FAIL_ACT_T; the mode shows in the 1 Hz HEARTBEAT
    assert v.latest["HEARTBEAT"].system_status == M.MAV_STATE_CRITICAL


def test_parameters_are_px4_names_with_int32_bytewise(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: "HEARTBEAT" in v.latest, 2.0)
    pilot.param(0, "COM_OBL_RC_ACT")
    value = v.params["COM_OBL_RC_ACT"]
    assert value.param_type == M.MAV_PARAM_TYPE_INT32 and as_int32(value.param_value) == 0
    pilot.param(0, "MAV_SYS_ID")
    assert as_int32(v.params["MAV_SYS_ID"].param_value) == 1
    assert pilot.param(0, "COM_OF_LOSS_T") == pytest.approx(1.0)  # floats as floats (commander_params.yaml)
    assert v.params["COM_OF_LOSS_T"].param_type == M.MAV_PARAM_TYPE_REAL32
    assert pilot.set_param(0, "MPC_XY_CRUISE", 7.5) == pytest.approx(7.5)
    # an int32 parameter set with the REAL32 type: refused, the unchanged value echoed
    v.params.pop("COM_OBL_RC_ACT", None)
    v.mav.param_set_send(v.sysid, 1, b"COM_OBL_RC_ACT", 4.0, M.MAV_PARAM_TYPE_REAL32)
    pilot.spin(lambda: "COM_OBL_RC_ACT" in v.params, 2.0)
    assert as_int32(v.params["COM_OBL_RC_ACT"].param_value) == 0
    # ArduPilot-only parameters do not exist on a PX4 vehicle: no PARAM_VALUE, a STATUSTEXT
    v.mav.param_set_send(v.sysid, 1, b"GUID_OPTIONS", 8.0, M.MAV_PARAM_TYPE_INT32)
    pilot.spin(lambda: any("unknown param: GUID_OPTIONS" in t for t in v.texts), 2.0)
    assert "GUID_OPTIONS" not in v.params


def test_mixed_fleet_answers_as_two_autopilots(sitl, pilot_for):
    sim = sitl("--lockstep", "--lockstep-timeout", "60", "--ready-delay", "1", "--autopilot", "ardupilot,px4",
               vehicles=2)  # fmt: skip
    pilot = pilot_for(sim)
    pilot.spin(lambda: all("HEARTBEAT" in v.latest for v in pilot.vehicles), 3.0)
    assert pilot[0].latest["HEARTBEAT"].autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert pilot[1].latest["HEARTBEAT"].autopilot == M.MAV_AUTOPILOT_PX4
    assert pilot.param(0, "GUID_OPTIONS") == 0  # ArduCopter name on the ArduPilot vehicle
    pilot.param(1, "NAV_DLL_ACT")
    assert as_int32(pilot[1].params["NAV_DLL_ACT"].param_value) == 0
    # the same DO_SET_MODE means GUIDED to ArduCopter (custom mode 4) and AUTO (main mode 4) to PX4
    assert pilot.set_mode(0, 4) == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: pilot[0].mode == 4, 2.0)


def test_garbage_never_crashes_a_px4_handler(sitl, pilot_for):
    sim = sitl(*PX4_ARGS)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: "HEARTBEAT" in v.latest, 2.0)
    nan = math.nan
    v.command(M.MAV_CMD_COMPONENT_ARM_DISARM, nan, nan)
    v.command(M.MAV_CMD_DO_SET_MODE, nan, nan, nan)
    v.command(M.MAV_CMD_DO_SET_MODE, 1, 4, 99)
    v.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, nan)
    v.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_HEARTBEAT, 1e5)
    v.mav.set_mode_send(v.sysid, 255, 0xFFFFFFFF)
    v.mav.set_attitude_target_send(v.time_boot_ms, v.sysid, 1, 0, [nan, 0, 0, 0], 0, 0, 0, 0.5)
    v.mav.set_position_target_local_ned_send(
        v.time_boot_ms, v.sysid, 1, 99, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    v.mav.set_position_target_local_ned_send(
        v.time_boot_ms, v.sysid, 1, 1, 0xFFFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
    )
    v.mav.param_set_send(v.sysid, 1, b"\xff\xfe", nan, 77)
    v.mav.param_request_read_send(v.sysid, 1, b"", 9999)
    v.mav.request_data_stream_send(v.sysid, 1, 255, 1000, 1)
    v.conn.write(b"\xfd\xff\x00garbage" * 20)
    pilot.spin(lambda: len(v.acks) >= 5, 3.0)
    assert "Unsupported auto mode" in v.texts
    code, err = sim.stop()
    assert code == 0
    assert "handler_errors=0" in err
