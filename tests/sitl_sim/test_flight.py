"""ArduCopter-like behaviour over MAVLink, flown in lockstep by a scripted pymavlink ground station."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.sitl_sim.sim_process import M, read_truth

GUIDED, LAND, RTL = 4, 9, 6
FAST = ("--lockstep", "--lockstep-timeout", "60", "--ready-delay", "1")  # generous timeout: a loaded CI


def test_guided_takeoff_to_10_m_then_land_disarms(sitl, pilot_for, tmp_path):
    log = tmp_path / "truth.csv"
    sim = sitl(*FAST, "--truth-log", str(log))
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 10.0)
    pilot.spin(lambda: v.altitude > 9.9, 10.0)
    status = v.latest["EXTENDED_SYS_STATE"]
    assert v.armed and v.mode == GUIDED
    pilot.spin(lambda: v.latest["EXTENDED_SYS_STATE"].landed_state == M.MAV_LANDED_STATE_IN_AIR, 2.0)
    assert pilot.set_mode(0, LAND) == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: v.latest["EXTENDED_SYS_STATE"].landed_state == M.MAV_LANDED_STATE_LANDING, 2.0)
    pilot.spin(lambda: not v.armed, 40.0)
    assert "Disarming motors" in v.texts
    assert abs(v.altitude) < 0.05 and status is not None
    assert sim.stop()[0] == 0
    truth = read_truth(log)
    assert truth["z"].max() == pytest.approx(10.0, abs=0.3)
    assert truth["landed"][-1] == 1 and truth["armed"][-1] == 0 and truth["mode"][-1] == LAND


def test_arming_and_takeoff_refused_before_ready_with_a_reason(sitl, pilot_for):
    sim = sitl("--lockstep", "--ready-delay", "3")
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: "SYS_STATUS" in v.latest and "EKF_STATUS_REPORT" in v.latest, 2.0)
    assert not v.ready
    assert not v.latest["EKF_STATUS_REPORT"].flags & M.EKF_POS_HORIZ_ABS
    assert pilot.set_mode(0, GUIDED) == M.MAV_RESULT_ACCEPTED  # allowed while disarmed, as ArduCopter
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_FAILED
    assert any(text.startswith("PreArm: ") for text in v.texts)
    assert pilot.command(0, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 5) == M.MAV_RESULT_FAILED
    pilot.spin(lambda: v.ready, 5.0)
    assert v.latest["EKF_STATUS_REPORT"].flags & M.EKF_POS_HORIZ_ABS
    assert v.latest["HEARTBEAT"].system_status == M.MAV_STATE_STANDBY
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: v.armed, 1.0)
    assert v.latest["HEARTBEAT"].system_status == M.MAV_STATE_ACTIVE


def test_sitting_armed_on_the_ground_disarms_after_disarm_delay(sitl, pilot_for):
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: v.ready, 5.0)
    assert pilot.set_param(0, "DISARM_DELAY", 2) == 2
    assert pilot.set_mode(0, GUIDED) == M.MAV_RESULT_ACCEPTED
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    armed_at = v.t  # the STATUSTEXTs come at once; v.t follows the 10 Hz telemetry (HEARTBEAT is only 1 Hz)
    pilot.spin(lambda: "Disarming motors" in v.texts, 5.0)
    assert v.t - armed_at == pytest.approx(2.0, abs=0.2)
    pilot.spin(lambda: not v.armed, 1.5)


def hold_attitude(pilot, roll, pitch, thrust, seconds):
    """Stream one SET_ATTITUDE_TARGET per frame (NED/FRD angles in degrees, yaw north) for `seconds`."""
    v = pilot[0]
    end = v.t + seconds
    target = (math.radians(roll), math.radians(pitch), 0.0, thrust)
    pilot.spin(lambda: v.t >= end, seconds + 1.0, each_frame=lambda vehicle: vehicle.attitude(*target))


@pytest.mark.parametrize(("roll", "pitch", "axis"), [(0.0, -10.0, "vx"), (10.0, 0.0, "vy")])
def test_attitude_targets_tilt_and_accelerate_in_the_right_ned_direction(sitl, pilot_for, roll, pitch, axis):
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 5.0)
    hold_attitude(pilot, roll, pitch, 0.5, 2.0)
    attitude = v.latest["ATTITUDE"]
    assert math.degrees(attitude.roll) == pytest.approx(roll, abs=1.5)
    assert math.degrees(attitude.pitch) == pytest.approx(pitch, abs=1.5)
    velocity = v.latest["LOCAL_POSITION_NED"]
    other = "vy" if axis == "vx" else "vx"
    assert getattr(velocity, axis) > 2.0  # north for nose down, east for right side down
    assert abs(getattr(velocity, other)) < 0.5
    assert abs(velocity.vz) < 0.5  # thrust 0.5 = hold altitude


def test_thrust_is_a_climb_rate_unless_guid_options_selects_thrust(sitl, pilot_for):
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 5.0)
    hold_attitude(pilot, 0.0, 0.0, 0.75, 2.0)  # climb at (0.75 - 0.5) * 2 * WPNAV_SPEED_UP = 1.25 m/s
    assert -v.latest["LOCAL_POSITION_NED"].vz == pytest.approx(1.25, abs=0.15)
    hold_attitude(pilot, 0.0, 0.0, 0.25, 2.0)  # descend at 0.5 * 2 * ... = 0.75 m/s (WPNAV_SPEED_DN 1.5)
    assert -v.latest["LOCAL_POSITION_NED"].vz == pytest.approx(-0.75, abs=0.15)

    hover = pilot.set_param(0, "MOT_THST_HOVER", 0.4)
    assert pilot.set_param(0, "GUID_OPTIONS", 8) == 8
    hold_attitude(pilot, 0.0, 0.0, hover, 1.0)  # collective = hover thrust: no vertical acceleration
    climb_before = -v.latest["LOCAL_POSITION_NED"].vz
    hold_attitude(pilot, 0.0, 0.0, hover, 1.0)
    assert abs(-v.latest["LOCAL_POSITION_NED"].vz - climb_before) < 0.3
    hold_attitude(pilot, 0.0, 0.0, 0.6, 1.0)  # 1.5 g of thrust: about +4.9 m/s^2 less drag
    assert -v.latest["LOCAL_POSITION_NED"].vz > 3.0


def test_guided_timeout_levels_and_holds_altitude(sitl, pilot_for):
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 10.0)
    assert pilot.set_param(0, "GUID_OPTIONS", 8) == 8
    hold_attitude(pilot, 10.0, 0.0, 0.38, 0.5)  # tilted, and too little thrust to hold altitude
    stopped = v.t
    pilot.spin(lambda: v.t > stopped + 3.5, 5.0)  # GUID_TIMEOUT is 3 s
    altitude = v.altitude
    pilot.spin(lambda: v.t > stopped + 6.0, 5.0)
    attitude = v.latest["ATTITUDE"]
    assert abs(math.degrees(attitude.roll)) < 2.0 and abs(math.degrees(attitude.pitch)) < 2.0
    assert abs(v.altitude - altitude) < 0.5 and v.altitude > 4.0
    assert abs(v.latest["LOCAL_POSITION_NED"].vz) < 0.3


def test_gcs_failsafe_switches_to_rtl_when_heartbeats_stop(sitl, pilot_for):
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: v.ready, 5.0)
    assert pilot.set_param(0, "FS_GCS_ENABLE", 1) == 1
    assert pilot.set_param(0, "FS_GCS_TIMEOUT", 2) == 2
    pilot.take_off(0, 5.0)
    pilot.heartbeat = False
    silent_from = v.t
    pilot.spin(lambda: v.mode == RTL, 4.0)
    assert "GCS Failsafe" in v.texts
    assert v.t - silent_from >= 1.0
    pilot.spin(lambda: v.latest["HEARTBEAT"].system_status == M.MAV_STATE_CRITICAL, 1.0)
    pilot.heartbeat = True
    pilot.spin(lambda: "GCS Failsafe Cleared" in v.texts, 3.0)
    assert v.mode == RTL  # ArduCopter does not switch back


AIRBORNE = """\
vehicles:
  - {role: leader, start: {position: [0, 0, 20], velocity: [3, 0, 0], yaw_deg: 0}}
goal: [500, 0, 20]
run: {airborne_start: true}
"""


def test_airborne_start_flies_on_then_stops_at_guid_timeout(sitl, pilot_for, tmp_path):
    mission = tmp_path / "airborne.yaml"
    mission.write_text(AIRBORNE)
    sim = sitl("--mission", str(mission), "--lockstep", "--lockstep-timeout", "60")
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: {"HEARTBEAT", "LOCAL_POSITION_NED", "SYS_STATUS"} <= set(v.latest), 1.0)
    assert v.armed and v.mode == GUIDED and v.ready  # in flight from the first moment
    assert v.latest["HEARTBEAT"].system_status == M.MAV_STATE_ACTIVE
    pilot.spin(lambda: v.t > 2.5, 3.0)
    assert v.latest["LOCAL_POSITION_NED"].vy == pytest.approx(3.0, abs=0.3)  # flying east at its start speed
    assert v.altitude == pytest.approx(20.0, abs=0.2)
    pilot.spin(lambda: v.t > 6.0, 7.0)  # GUID_TIMEOUT (3 s) stops the velocity target
    local = v.latest["LOCAL_POSITION_NED"]
    assert abs(local.vx) < 0.3 and abs(local.vy) < 0.3 and abs(local.vz) < 0.3
    assert v.altitude == pytest.approx(20.0, abs=0.5)


def test_position_and_velocity_targets_then_rtl_home(sitl, pilot_for):
    sim = sitl(*FAST, "--home", "47.0,8.0,400")
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 5.0)
    position_only = 0b110111111000  # velocity, acceleration, yaw and yaw rate ignored
    v.mav.set_position_target_local_ned_send(
        v.time_boot_ms, 1, 1, M.MAV_FRAME_LOCAL_NED, position_only, 10, 5, -8, 0, 0, 0, 0, 0, 0, 0, 0
    )
    local = lambda: v.latest["LOCAL_POSITION_NED"]  # noqa: E731
    pilot.spin(lambda: math.dist((local().x, local().y, local().z), (10, 5, -8)) < 0.3, 20.0)

    north, east = 20.0, -10.0  # a global target, 6 m above home
    lat, lon = 47.0 + math.degrees(north / 6_367_000), 8.0 + math.degrees(east / (6_389_000 * math.cos(0.82)))
    v.mav.set_position_target_global_int_send(
        v.time_boot_ms, 1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, position_only,
        round(lat * 1e7), round(lon * 1e7), 6.0, 0, 0, 0, 0, 0, 0, 0, 0,
    )  # fmt: skip
    pilot.spin(lambda: math.dist((local().x, local().y, local().z), (north, east, -6)) < 0.5, 20.0)

    velocity_only = 0b110111000111
    pilot.spin(
        lambda: abs(local().vx + 2.0) < 0.1 and abs(local().vy) < 0.1,
        5.0,
        each_frame=lambda veh: veh.mav.set_position_target_local_ned_send(
            veh.time_boot_ms, 1, 1, M.MAV_FRAME_LOCAL_NED, velocity_only, 0, 0, 0, -2.0, 0, 0, 0, 0, 0, 0, 0
        ),
    )
    assert pilot.set_mode(0, RTL) == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: v.altitude > 14.5, 10.0)  # climbs to RTL_ALT (15 m) first
    pilot.spin(lambda: not v.armed, 60.0)  # returns, lands, disarms
    assert math.hypot(local().x, local().y) < 1.0 and abs(v.altitude) < 0.05


def test_angle_boost_divides_guided_thrust_by_the_cosine_of_the_lean(sitl, pilot_for, tmp_path):
    """AC_AttitudeControl_Multi::get_throttle_boosted: with ATC_ANGLE_BOOST = 1 (the default) a guided
    collective is multiplied by 1 / cos(current lean). Held at 30 deg with the same collective, the motors'
    total thrust (truth log f1..f4) is therefore 1 / cos 30 = 1.155 times larger with the boost than
    without it."""
    log = tmp_path / "truth.csv"
    sim = sitl(*FAST, "--truth-log", str(log))
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 40.0)
    assert pilot.set_param(0, "GUID_OPTIONS", 8) == 8
    assert pilot.param(0, "ATC_ANGLE_BOOST") == 1
    hold_attitude(pilot, 0.0, -30.0, 0.4, 1.5)
    boosted = (v.t - 0.5, v.t)
    assert pilot.set_param(0, "ATC_ANGLE_BOOST", 0) == 0
    hold_attitude(pilot, 0.0, -30.0, 0.4, 1.5)
    plain = (v.t - 0.5, v.t)
    sim.stop()
    truth = read_truth(log)

    def thrust(window: tuple[float, float]) -> float:
        rows = truth[(truth["t"] >= window[0]) & (truth["t"] <= window[1])]
        assert len(rows) > 10
        return float(np.mean(rows["f1"] + rows["f2"] + rows["f3"] + rows["f4"]))

    assert thrust(boosted) / thrust(plain) == pytest.approx(1.0 / math.cos(math.radians(30.0)), rel=0.02)


def test_guided_attitude_targets_are_not_capped_at_angle_max(sitl, pilot_for):
    """ArduCopter flies a guided attitude target as given (AC_AttitudeControl::input_quaternion has no lean
    limit): 35 deg with ANGLE_MAX at 30 deg is flown at 35 deg, as seen on real vehicles."""
    sim = sitl(*FAST)
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.take_off(0, 20.0)
    assert pilot.param(0, "ANGLE_MAX") == 3000
    assert pilot.set_param(0, "GUID_OPTIONS", 8) == 8
    hold_attitude(pilot, 0.0, -35.0, 0.4, 1.5)
    assert math.degrees(v.latest["ATTITUDE"].pitch) == pytest.approx(-35.0, abs=1.0)
