"""`sitl-sim --autopilot px4`: a vehicle answering as PX4 v1.14+ multicopter does, flown in lockstep by the
scripted pymavlink ground station of tests/sitl_sim/sim_process.py.

Expected values come from PX4's sources (cited), not from this simulator: custom_mode = main << 16 | sub << 24
(px4_custom_mode.h), TEMPORARILY_REJECTED for refused mode changes and arming (Commander.cpp), offboard
availability = a setpoint younger than COM_OF_LOSS_T (offboardCheck.cpp), int32 parameters bytewise in the
float (checked with struct, independently of the simulator's helpers). The takeoff, landing and return rules
are checked against bounds worked out by hand from PX4's parameters and the code that uses them
(mc_pos_control Takeoff.cpp, FlightTaskAuto.cpp, navigator rtl.cpp), in simulated time from the truth log.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from tests.sitl_sim.sim_process import M, read_truth

PX4_ARGS = ("--lockstep", "--lockstep-timeout", "60", "--ready-delay", "1", "--autopilot", "px4")
AUTO, OFFBOARD = 4, 6  # px4_custom_mode.h PX4_CUSTOM_MAIN_MODE_AUTO, _OFFBOARD
TAKEOFF, LOITER, RTL, LAND = 2, 3, 5, 6  # PX4_CUSTOM_SUB_MODE_AUTO_*
HOLD_MODE = (AUTO << 16) | (LOITER << 24)  # 0x03040000 = 50593792
TAKEOFF_MODE = (AUTO << 16) | (TAKEOFF << 24)
RTL_MODE = (AUTO << 16) | (RTL << 24)
LAND_MODE = (AUTO << 16) | (LAND << 24)
OFFBOARD_MODE = OFFBOARD << 16  # 393216, as every PX4 offboard example spells it
INTERNAL_GUIDED, INTERNAL_LAND = 4, 9  # truth log mode column: the shared law (docs/sitl.md, PX4 persona)
# PX4 defaults (mc_pos_control multicopter_takeoff_land_params.yaml, multicopter_autonomous_params.yaml,
# commander COM_SPOOLUP_TIME, navigator navigator_params.yaml / rtl_params.yaml)
SPOOLUP_S, TKO_SPEED, TKO_RAMP_S = 1.0, 1.5, 3.0
LAND_ALT1, LAND_ALT2, LAND_ALT3, LAND_SPEED, LAND_CRAWL, AUTO_DN = 10.0, 5.0, 1.0, 0.7, 0.3, 1.5
NAV_ACC_RAD = 10.0
POSITION_ONLY = 0b110111111000  # SET_POSITION_TARGET type_mask: position only (velocity/accel/yaw ignored)


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


def fly_truth(sitl, pilot_for, tmp_path, script, *args: str):
    """Run `script(pilot)` against a PX4 vehicle whose truth log is kept; returns the log (one vehicle)."""
    log = tmp_path / "truth.csv"
    sim = sitl(*PX4_ARGS, "--truth-log", str(log), *args)
    pilot = pilot_for(sim)
    script(pilot)
    code, _ = sim.stop()
    assert code == 0
    return read_truth(log)


def first_time(truth, mask) -> float:
    """Simulated s of the first truth sample where `mask` holds."""
    assert mask.any()
    return float(truth["t"][np.flatnonzero(mask)[0]])


def test_default_ready_delay_is_px4s_for_px4_vehicles_only(sitl, pilot_for):
    # no --ready-delay: a real PX4 SITL (SIH) was ready for takeoff 4.4-4.6 s after boot, a real ArduCopter's
    # EKF used GPS after 42 s: neither vehicle may be ready earlier than its real counterpart
    sim = sitl("--lockstep", "--lockstep-timeout", "60", "--autopilot", "ardupilot,px4", vehicles=2)
    pilot = pilot_for(sim)
    ardupilot, px4 = pilot[0], pilot[1]
    ready_seen = []
    pilot.spin(lambda: px4.ready or ready_seen.append(px4.t), 10.0)
    assert ready_seen and max(ready_seen) >= 4.6 - 0.05  # not ready before real PX4 was
    assert px4.t <= 5.0 + 0.3  # READY_DELAY_S 5 s, seen in the next 5 Hz SYS_STATUS
    assert not ardupilot.ready and "LOCAL_POSITION_NED" not in ardupilot.latest  # its 40 s are not over
    # an explicit --ready-delay applies to every vehicle
    sim = sitl("--lockstep", "--lockstep-timeout", "60", "--ready-delay", "2", "--autopilot", "ardupilot,px4",
               vehicles=2)  # fmt: skip
    pilot = pilot_for(sim)
    pilot.spin(lambda: all(v.ready for v in pilot.vehicles), 4.0)
    assert all(1.9 <= v.t <= 2.0 + 0.3 for v in pilot.vehicles)


def test_takeoff_spools_up_ramps_and_climbs_at_takeoff_speed(sitl, pilot_for, tmp_path):
    truth = fly_truth(sitl, pilot_for, tmp_path, lambda pilot: take_off(pilot, 10.0))
    armed_at = first_time(truth, truth["armed"] == 1)
    lifted = first_time(truth, truth["z"] > 0.01) - armed_at
    # Takeoff.cpp: no thrust while spooling up (COM_SPOOLUP_TIME); then FlightTaskAuto's trajectory starts at
    # 0.7 m/s down (reActivate) and accelerates up at most MPC_TKO_SPEED / MPC_TKO_RAMP_T = 0.5 m/s^2
    accel = TKO_SPEED / TKO_RAMP_S
    assert lifted >= SPOOLUP_S + 0.7 / accel
    # below MPC_LAND_ALT1 the climb is at most MPC_TKO_SPEED (the shared law alone would climb at 3 m/s)
    climbing = (truth["mode"] == INTERNAL_GUIDED) & (truth["t"] > armed_at) & (truth["z"] < LAND_ALT1)
    assert truth["vz"][climbing].max() <= TKO_SPEED + 0.05
    assert truth["vz"][climbing].max() >= TKO_SPEED - 0.1  # and it does reach it
    # so 9.5 m take at least: spool-up, the 0.7 m/s down to 0, 0 to MPC_TKO_SPEED at 0.5 m/s^2 (2.25 m), the
    # rest at MPC_TKO_SPEED; jerk (MPC_JERK_AUTO), braking and tracking make the real one somewhat slower
    at_9_5 = first_time(truth, truth["z"] >= 9.5) - armed_at
    least = SPOOLUP_S + 0.7 / accel + TKO_SPEED / accel + (9.5 - TKO_SPEED**2 / (2 * accel)) / TKO_SPEED
    assert least <= at_9_5 <= least + 1.5


def test_takeoff_follows_changed_spoolup_ramp_and_speed(sitl, pilot_for, tmp_path):
    def script(pilot):
        v = pilot[0]
        pilot.spin(lambda: v.ready, 5.0)
        for name, value in (("COM_SPOOLUP_TIME", 2.5), ("MPC_TKO_SPEED", 1.0), ("MPC_TKO_RAMP_T", 2.0)):
            assert pilot.set_param(0, name, value) == pytest.approx(value)
        take_off(pilot, 4.0)

    truth = fly_truth(sitl, pilot_for, tmp_path, script)
    armed_at = first_time(truth, truth["armed"] == 1)
    accel = 1.0 / 2.0  # MPC_TKO_SPEED / MPC_TKO_RAMP_T
    assert first_time(truth, truth["z"] > 0.01) - armed_at >= 2.5 + 0.7 / accel
    climbing = (truth["mode"] == INTERNAL_GUIDED) & (truth["t"] > armed_at)
    assert truth["vz"][climbing].max() <= 1.0 + 0.05
    least = 2.5 + 0.7 / accel + 1.0 / accel + (3.5 - 1.0 / (2 * accel)) / 1.0
    assert first_time(truth, truth["z"] >= 3.5) - armed_at >= least


def px4_land_speed(height: float) -> float:
    """FlightTaskAuto::_prepareLandSetpoints at the defaults: MPC_LAND_SPEED at and below MPC_LAND_ALT2,
    MPC_Z_VEL_MAX_DN (1.5) above MPC_LAND_ALT1, linear between (math::interpolate), MPC_LAND_CRWL below
    MPC_LAND_ALT3 (SIH's downward distance sensor measures the height); MPC_Z_V_AUTO_DN caps the lot."""
    if height <= LAND_ALT3:
        return LAND_CRAWL
    if height <= LAND_ALT2:
        return LAND_SPEED
    if height > LAND_ALT1:
        return min(1.5, AUTO_DN)
    return LAND_SPEED + (1.5 - LAND_SPEED) * (height - LAND_ALT2) / (LAND_ALT1 - LAND_ALT2)


def test_land_slows_down_below_land_alt1_and_crawls_below_alt3(sitl, pilot_for, tmp_path):
    def script(pilot):
        v = pilot[0]
        take_off(pilot, 16.0)
        assert pilot.command(0, M.MAV_CMD_NAV_LAND) == M.MAV_RESULT_ACCEPTED
        pilot.spin(lambda: not v.armed, 60.0)

    truth = fly_truth(sitl, pilot_for, tmp_path, script)
    landing = (truth["mode"] == INTERNAL_LAND) & (truth["armed"] == 1)
    height, speed = truth["z"][landing], -truth["vz"][landing]
    for low, high, tolerance in ((11.0, 13.0, 0.1), (5.5, 9.5, 0.1), (1.2, 4.5, 0.05)):
        band = (height > low) & (height < high)
        expected = np.array([px4_land_speed(h) for h in height[band]])
        assert np.all(np.abs(speed[band] - expected) <= tolerance), (low, high)
    # below MPC_LAND_ALT3: slowing from 0.7 to 0.3 m/s with jerk <= MPC_JERK_AUTO (4 m/s^3) takes >= 0.63 s,
    # <= 0.44 m; then MPC_LAND_CRWL
    crawl = (height > 0.05) & (height < 1.0 - 0.44)
    assert speed[crawl].max() <= LAND_CRAWL + 0.05
    # from 5 m: 4 m at <= MPC_LAND_SPEED, then >= 0.63 s slowing down and >= 0.56 m at MPC_LAND_CRWL
    below_5 = first_time(truth, landing & (truth["z"] < 5.0))
    touchdown = first_time(truth, landing & (truth["z"] <= 0.0))
    assert touchdown - below_5 >= 4.0 / LAND_SPEED + 0.63 + (1.0 - 0.44) / LAND_CRAWL


def fly_offboard_to(pilot, north_m: float, height_m: float) -> None:
    """Stream a position setpoint (LOCAL_NED) for > 1 s, switch to OFFBOARD, fly there and settle."""
    v = pilot[0]

    def setpoint(vehicle):
        vehicle.mav.set_position_target_local_ned_send(
            vehicle.time_boot_ms, vehicle.sysid, 1, M.MAV_FRAME_LOCAL_NED, POSITION_ONLY,
            north_m, 0.0, -height_m, 0, 0, 0, 0, 0, 0, 0, 0,
        )  # fmt: skip

    start = v.t
    pilot.spin(lambda: v.t - start > 1.2, 3.0, each_frame=setpoint)
    v.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, OFFBOARD)
    pilot.spin(lambda: v.mode == OFFBOARD_MODE, 3.0, each_frame=setpoint)

    def settled() -> bool:
        local = v.latest["LOCAL_POSITION_NED"]
        return abs(local.x - north_m) < 0.3 and abs(local.vx) < 0.1 and abs(v.altitude - height_m) < 0.3

    pilot.spin(settled, 30.0, each_frame=setpoint)


@pytest.mark.parametrize(
    ("north_m", "params"),
    [
        (0.0, {}),  # above home: 2 x 0 m -> no climb, lands from where it is
        (6.0, {}),  # within NAV_ACC_RAD (10 m): twice the distance, 12 m (not RTL_RETURN_ALT 60 m)
        (8.0, {"NAV_ACC_RAD": 2.0, "RTL_MIN_DIST": 20.0, "RTL_RETURN_ALT": 30.0}),  # the 45 deg cone: 8 m
    ],
)
def test_return_altitude_follows_px4s_cone(sitl, pilot_for, tmp_path, north_m, params):
    height_m = 4.0
    seen: dict[str, float] = {}

    def script(pilot):
        v = pilot[0]
        pilot.spin(lambda: v.ready, 5.0)
        for name, value in params.items():
            assert pilot.set_param(0, name, value) == pytest.approx(value)
        take_off(pilot, height_m)
        if north_m:
            fly_offboard_to(pilot, north_m, height_m)
        local = v.latest["LOCAL_POSITION_NED"]
        seen["distance"] = math.hypot(local.x, local.y)  # home is the start point, the local origin
        seen["height"] = v.altitude
        assert pilot.command(0, M.MAV_CMD_NAV_RETURN_TO_LAUNCH) == M.MAV_RESULT_ACCEPTED
        pilot.spin(lambda: not v.armed, 90.0)

    truth = fly_truth(sitl, pilot_for, tmp_path, script)
    # rtl.cpp RTL::calculate_return_alt_from_cone_half_angle, worked out for home at the ground
    d = seen["distance"]
    acceptance = params.get("NAV_ACC_RAD", NAV_ACC_RAD)
    if d <= acceptance:
        expected = 2.0 * d
    else:
        expected = params.get("RTL_RETURN_ALT", 60.0)
        if d <= params.get("RTL_MIN_DIST", 10.0):
            expected = min(d / math.tan(math.radians(45.0)), expected)
        expected = max(expected, 2.0 * acceptance)
    expected = max(expected, seen["height"])
    returning = (truth["mode"] == 6) & (truth["armed"] == 1)  # the shared RTL law (internal mode 6)
    assert returning.any()
    assert expected - 0.6 <= truth["z"][returning].max() <= expected + 0.3
    final = np.flatnonzero(truth["armed"] == 1)[-1]
    assert math.hypot(truth["x"][final], truth["y"][final]) < 1.0  # and it landed at home
