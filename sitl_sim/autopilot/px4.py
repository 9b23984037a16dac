"""The PX4 v1.14+/main multicopter persona: its modes, arming rules, failsafes, parameters, default telemetry
and landing descent, over the shared autopilot of sitl_sim.autopilot.copter.

A PX4 vehicle keeps PX4's own state here (its navigation state as custom_mode, the last offboard setpoint,
the GCS link, the auto-disarm timers) and drives the shared control laws through an internal ArduCopter-like
mode (OFFBOARD -> GUIDED, AUTO.TAKEOFF -> GUIDED climb, AUTO.LOITER and the stick modes -> LOITER, AUTO.LAND
-> LAND, AUTO.RTL -> RTL). Every rule cites the PX4 source it comes from (PX4/PX4-Autopilot, main, 2025); the
facts are also listed in docs/sitl.md (PX4 persona). Times are simulated seconds, positions world ENU metres.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot import modes as internal
from sitl_sim.autopilot.outer_loop import DESCENT_INTERPOLATED, jerk_limited_step
from sitl_sim.autopilot.params import INT32, REAL32, ParamSpec
from sitl_sim.autopilot.persona import Persona

M = mavlink2
ACCEPTED, REJECTED = M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_TEMPORARILY_REJECTED

# src/modules/commander/px4_custom_mode.h: main modes and AUTO sub modes
MANUAL, ALTCTL, POSCTL, AUTO, ACRO, OFFBOARD_MAIN, STABILIZED = 1, 2, 3, 4, 5, 6, 7
READY, TAKEOFF_SUB, LOITER_SUB, MISSION_SUB, RTL_SUB, LAND_SUB = 1, 2, 3, 4, 5, 6


def custom_mode(main: int, sub: int = 0) -> int:
    """HEARTBEAT.custom_mode of a PX4 mode: union px4_custom_mode {uint16 reserved; uint8 main; uint8 sub}."""
    return (main << 16) | (sub << 24)


MODE_MANUAL = custom_mode(MANUAL)
MODE_ALTCTL = custom_mode(ALTCTL)
MODE_POSCTL = custom_mode(POSCTL)
MODE_ACRO = custom_mode(ACRO)
MODE_OFFBOARD = custom_mode(OFFBOARD_MAIN)
MODE_STABILIZED = custom_mode(STABILIZED)
MODE_MISSION = custom_mode(AUTO, MISSION_SUB)
MODE_TAKEOFF = custom_mode(AUTO, TAKEOFF_SUB)
MODE_LOITER = custom_mode(AUTO, LOITER_SUB)
MODE_RTL = custom_mode(AUTO, RTL_SUB)
MODE_LAND = custom_mode(AUTO, LAND_SUB)
# commander ModeUtil nav_state_names (what "Switching to %s is currently not available" prints)
MODE_NAMES = {
    MODE_MANUAL: "Manual", MODE_ALTCTL: "Altitude", MODE_POSCTL: "Position", MODE_ACRO: "Acro",
    MODE_OFFBOARD: "Offboard", MODE_STABILIZED: "Stabilized", MODE_MISSION: "Mission",
    MODE_TAKEOFF: "Takeoff", MODE_LOITER: "Hold", MODE_RTL: "Return", MODE_LAND: "Land",
}  # fmt: skip
# ModeUtil/mode_requirements.cpp: mode_req_manual_control, mode_req_prevent_arming, mode_req_offboard_signal
NEEDS_STICKS = (MODE_MANUAL, MODE_ALTCTL, MODE_POSCTL, MODE_ACRO, MODE_STABILIZED)
PREVENTS_ARMING = (MODE_RTL, MODE_LAND)
NEEDS_POSITION = (MODE_MISSION, MODE_TAKEOFF, MODE_LOITER, MODE_RTL, MODE_LAND)
# the shared control law each PX4 mode runs on (stick modes: centred sticks hold position, see docs/sitl.md)
INTERNAL_MODE = {
    MODE_OFFBOARD: internal.GUIDED, MODE_TAKEOFF: internal.GUIDED, MODE_LAND: internal.LAND,
    MODE_RTL: internal.RTL,
}  # fmt: skip
FORCE_MAGIC = 21196  # Commander.cpp VEHICLE_CMD_COMPONENT_ARM_DISARM: param2 that forces (disarm in flight)
MISSIONPLANNER_COMPID = 190  # Commander.cpp: printRejectMode only for MAV_COMP_ID_MISSIONPLANNER commands
FALLBACK_TO_RTL = (0, 1, 2)  # failsafe.cpp fromOffboardLossActParam: Position/Altitude/Stabilized need sticks
OFFBOARD_LOSS_MODES = {3: MODE_RTL, 4: MODE_LAND, 5: MODE_LOITER}  # COM_OBL_RC_ACT; 6 Terminate, 7 Disarm
GCS_LOSS_MODES = {1: MODE_LOITER, 2: MODE_RTL, 3: MODE_LAND}  # NAV_DLL_ACT; 5 Terminate, 6 Disarm
# GF_ACTION (navigator geofence_params.c: 0 None, 1 Warning, 2 Hold, 3 Return, 4 Terminate, 5 Land) -> the
# failsafe action as NAV_DLL_ACT numbers it (_act); failsafe.cpp fromGfActParam. None and Warning: no action.
GF_HOLD = 2
GEOFENCE_FAILSAFE = {GF_HOLD: 1, 3: 2, 4: 5, 5: 3}
# default ready delay of a PX4 vehicle (`sitl-sim --ready-delay` not given): simulated s from boot to the
# position estimate and pre-arm OK. Real PX4 SITL (SIH
# quadx, flown on this project's machine) said "Ready for takeoff!" 4.4-4.6 s after boot; 5 s is not earlier.
READY_DELAY_S = 5.0
G = 9.80665  # m/s^2, CONSTANTS_ONE_G (lib/geo/geo.h)
Z_VEL_P_ACC = 4.0  # 1/s, MPC_Z_VEL_P_ACC default (multicopter_position_control_gain_params.yaml)
ACC_UP_MAX = 4.0  # m/s^2, MPC_ACC_UP_MAX default (mc_pos_control: PARAM_DEFINE_FLOAT(MPC_ACC_UP_MAX, 4.f))
# mc_pos_control Takeoff.cpp TakeoffHandling::generateInitialRampValue(MPC_Z_VEL_P_ACC): the upward velocity
# limit before and at the start of the takeoff ramp, -CONSTANTS_ONE_G / MPC_Z_VEL_P_ACC (m/s up; negative = a
# descent demand: on the ground, no thrust beyond idle)
TAKEOFF_RAMP_VZ_INIT = -G / Z_VEL_P_ACC
# FlightTaskAuto::reActivate, called by FlightModeManager::generateTrajectorySetpoint every cycle while the
# takeoff state is below rampup: the trajectory restarts at the current position with 0.7 m/s DOWN (NED +0.7)
TAKEOFF_TRAJECTORY_VZ_INIT = -0.7
# FlightTaskAuto::update: _want_takeoff = unsmoothed_velocity(2) < -0.3 (NED: more than 0.3 m/s up); the
# unsmoothed velocity is PositionSmoothing::_generateVelocitySetpoint's, capped by _getMaxZSpeed (stop_speed)
WANT_TAKEOFF_VZ = 0.3
# AUTO.LAND's descent (the shared loop's DESCENT_INTERPOLATED): FlightTaskAuto::_prepareLandSetpoints,
# math::interpolate(_dist_to_ground, MPC_LAND_ALT2, MPC_LAND_ALT1, MPC_LAND_SPEED, MPC_Z_VEL_MAX_DN)
# (FlightTaskAuto::updateParams keeps ALT1 >= ALT2), MPC_LAND_CRWL at and below MPC_LAND_ALT3 while a distance
# sensor measures the height, the PositionSmoothing capping it at MPC_Z_V_AUTO_DN (_updateTrajConstraints,
# "down") with jerk MPC_JERK_AUTO; in outer_loop.Descent's column order
DESCENT_PARAMS = (
    "MPC_LAND_ALT1", "MPC_LAND_ALT2", "MPC_LAND_ALT3", "MPC_LAND_CRWL", "MPC_LAND_SPEED", "MPC_Z_VEL_MAX_DN",
    "MPC_Z_V_AUTO_DN", "MPC_JERK_AUTO",
)  # fmt: skip
# MPC_ACC_DOWN_MAX default (mc_pos_control multicopter_position_control_limits_params: 3 m/s^2), the descent
# acceleration of FlightTaskAuto's PositionSmoothing (_updateTrajConstraints, "down"); not a parameter here
ACC_DOWN_MAX = 3.0
# SIH's downward distance sensor (simulator_sih sih.cpp send_dist_snsr, published while |SIH_DISTSNSR_OVR| <
# 10000, default -1): valid up to SIH_DISTSNSR_MAX (default 100 m), so PX4's FlightTask has _dist_to_bottom
RANGE_MAX_M = 100.0


def param_specs(hover_fraction: float) -> tuple[ParamSpec, ...]:
    """The PX4 parameters a PX4 vehicle shows, with PX4's names, types and defaults (sources in the docs)."""
    return (
        # src/modules/commander/commander_params.yaml
        ParamSpec("COM_DISARM_LAND", REAL32, 2.0, -1.0, 20.0, "s", "auto-disarm this long after landing"),
        ParamSpec("COM_DISARM_PRFLT", REAL32, 10.0, -1.0, 20.0, "s", "auto-disarm: no takeoff after arming"),
        ParamSpec("COM_DL_LOSS_T", INT32, 10, 5, 300, "s", "GCS heartbeat loss before NAV_DLL_ACT"),
        ParamSpec("COM_FAIL_ACT_T", REAL32, 5.0, 0.0, 25.0, "s", "Hold this long before a failsafe action"),
        ParamSpec("COM_OBL_RC_ACT", INT32, 0, 0, 7, "", "offboard loss: 0 Pos 1 Alt 2 Stab 3 RTL 4 Land"),
        ParamSpec("COM_OF_LOSS_T", REAL32, 1.0, 0.0, 60.0, "s", "offboard setpoint loss timeout"),
        ParamSpec("COM_SPOOLUP_TIME", REAL32, 1.0, 0.0, 30.0, "s", "motor spool-up after arming (takeoff)"),
        # src/modules/navigator/geofence_params.c: the action on a breach of the uploaded fence
        ParamSpec("GF_ACTION", INT32, 2, 0, 5, "", "geofence: 0 none 1 warn 2 Hold 3 RTL 4 Term 5 Land"),
        ParamSpec("NAV_DLL_ACT", INT32, 0, 0, 6, "", "GCS loss: 0 off 1 Hold 2 RTL 3 Land 5 Term 6 Disarm"),
        # src/modules/mavlink/mavlink_params.yaml (MAV_SYS_ID), navigator/mission_params (MIS_TAKEOFF_ALT),
        # mc_pos_control/multicopter_*_params (MPC_*), navigator/navigator_params (NAV_ACC_RAD),
        # navigator/rtl_params (RTL_*)
        ParamSpec("MAV_SYS_ID", INT32, 1, 1, 250, "", "this vehicle's sysid (takes effect on restart)"),
        ParamSpec("MIS_TAKEOFF_ALT", REAL32, 2.5, 0.0, 1000.0, "m", "takeoff altitude above home"),
        ParamSpec("MPC_ACC_HOR", REAL32, 3.0, 2.0, 15.0, "m/s^2", "horizontal acceleration (auto modes)"),
        ParamSpec("MPC_JERK_AUTO", REAL32, 4.0, 1.0, 80.0, "m/s^3", "jerk limit (auto modes)"),
        ParamSpec("MPC_LAND_ALT1", REAL32, 10.0, 0.0, 122.0, "m", "landing slows down below this height"),
        ParamSpec("MPC_LAND_ALT2", REAL32, 5.0, 0.0, 122.0, "m", "landing at MPC_LAND_SPEED below this"),
        ParamSpec("MPC_LAND_ALT3", REAL32, 1.0, 0.0, 122.0, "m", "landing at MPC_LAND_CRWL below this"),
        ParamSpec("MPC_LAND_CRWL", REAL32, 0.3, 0.1, 3.0, "m/s", "landing crawl speed near the ground"),
        ParamSpec("MPC_LAND_SPEED", REAL32, 0.7, 0.6, 3.0, "m/s", "landing descent speed"),
        ParamSpec("MPC_THR_HOVER", REAL32, hover_fraction, 0.1, 0.8, "", "hover thrust"),
        ParamSpec("MPC_TILTMAX_AIR", REAL32, 45.0, 20.0, 89.0, "deg", "tilt limit (position control)"),
        ParamSpec("MPC_TKO_RAMP_T", REAL32, 3.0, 0.0, 5.0, "s", "takeoff ramp time (0: no ramp)"),
        ParamSpec("MPC_TKO_SPEED", REAL32, 1.5, 1.0, 5.0, "m/s", "takeoff climb speed"),
        ParamSpec("MPC_XY_CRUISE", REAL32, 5.0, 3.0, 20.0, "m/s", "horizontal cruise speed (auto modes)"),
        ParamSpec("MPC_Z_VEL_MAX_DN", REAL32, 1.5, 0.5, 4.0, "m/s", "maximum descent speed"),
        ParamSpec("MPC_Z_VEL_MAX_UP", REAL32, 3.0, 0.5, 8.0, "m/s", "maximum climb speed"),
        ParamSpec("MPC_Z_V_AUTO_DN", REAL32, 1.5, 0.5, 4.0, "m/s", "descent speed in auto modes (land)"),
        ParamSpec("MPC_Z_V_AUTO_UP", REAL32, 3.0, 0.5, 8.0, "m/s", "climb speed in auto modes (RTL)"),
        ParamSpec("NAV_ACC_RAD", REAL32, 10.0, 0.05, 200.0, "m", "acceptance radius (RTL near home)"),
        ParamSpec("NAV_MC_ALT_RAD", REAL32, 0.8, 0.05, 200.0, "m", "altitude acceptance (takeoff reached)"),
        ParamSpec("RTL_CONE_ANG", INT32, 45, 0, 90, "deg", "RTL cone half angle (0: always return alt)"),
        ParamSpec("RTL_MIN_DIST", REAL32, 10.0, 0.5, 100.0, "m", "closer to home: the cone limits the climb"),
        ParamSpec("RTL_RETURN_ALT", REAL32, 60.0, 0.0, 150.0, "m", "return altitude above home"),
        ParamSpec("RTL_TYPE", INT32, 0, 0, 5, "", "RTL: 0 closest of home/rally, 1 rally before home"),
    )


# Default rates (Hz) on the link a PX4 SITL instance opens on UDP 14540+i, in mavlink mode "onboard"
# (ROMFS/px4fmu_common/init.d-posix/px4-rc.mavlink): mavlink_main.cpp configure_streams_to_default,
# MAVLINK_MODE_ONBOARD. "unlimited" streams (GPS_RAW_INT) go out when their topic updates: 10 Hz here (the
# simulated GPS rate). HEARTBEAT is 1 Hz on every link. Streams of ours PX4 does not send (EKF_STATUS_REPORT,
# FENCE_STATUS) are 0.
DEFAULT_RATES_HZ = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 5.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 100.0,
    M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 50.0,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 30.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 50.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 10.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 5.0,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: 1.0,
}

# PX4 parameter -> (the shared outer loop's column it drives, scale): the shared code reads ArduCopter units
MIRRORS = {
    "MPC_THR_HOVER": ("MOT_THST_HOVER", 1.0),
    "MPC_XY_CRUISE": ("WPNAV_SPEED", 100.0),
    "MPC_ACC_HOR": ("WPNAV_ACCEL", 100.0),
    "MPC_Z_VEL_MAX_UP": ("WPNAV_SPEED_UP", 100.0),
    "MPC_Z_VEL_MAX_DN": ("WPNAV_SPEED_DN", 100.0),
    "MPC_LAND_SPEED": ("LAND_SPEED", 100.0),
    "MPC_TILTMAX_AIR": ("ANGLE_MAX", 100.0),
    "RTL_RETURN_ALT": ("RTL_ALT", 100.0),
}
# hidden ArduCopter columns on a PX4 vehicle: PX4 handles these rules itself (here), or has none of them
HIDDEN_FIXED = {
    "FS_GCS_ENABLE": 0.0,  # GCS loss is NAV_DLL_ACT (below)
    "DISARM_DELAY": 0.0,  # auto-disarm is COM_DISARM_LAND / COM_DISARM_PRFLT (below)
    "GUID_OPTIONS": 8.0,  # SET_ATTITUDE_TARGET thrust is collective thrust (fill_thrust: thrust_body[2])
    "ATC_ANGLE_BOOST": 0.0,  # mc_att_control flies thrust_body as given: no tilt compensation
    "GUID_TIMEOUT": 1e9,  # PX4 has no guided timeout: offboard loss is COM_OF_LOSS_T (below)
    # navigator Geofence::checkAll checks every uploaded zone whenever some are stored (no enable or type
    # parameter; GF_MAX_HOR_DIST / GF_MAX_VER_DIST, off by default, are not simulated): the shared fence
    # check runs on polygons and circles only, and the breach is acted on by GF_ACTION (Px4.fence_breached)
    "FENCE_TYPE": 4.0,
    "FENCE_ENABLE": 1.0,
    "FENCE_ACTION": 0.0,
}


class Px4(Persona):
    """The PX4 rules of the vehicles `rows` (N,) bool of the shared Autopilot `ap`; arrays (N,)."""

    name: ClassVar[str] = "px4"
    ready_delay_s: ClassVar[float] = READY_DELAY_S
    default_rates_hz = DEFAULT_RATES_HZ
    bytewise_params: ClassVar[bool] = True  # MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    shows_shared_params: ClassVar[bool] = False  # a PX4 vehicle lists PX4's names (and SIM_*)
    descent_profile: ClassVar[int] = DESCENT_INTERPOLATED
    descent_params = DESCENT_PARAMS
    descent_accel_down: ClassVar[float] = ACC_DOWN_MAX
    descent_range_max: ClassVar[float] = RANGE_MAX_M
    mirrors = MIRRORS
    hidden_fixed = HIDDEN_FIXED
    mission_protocol: ClassVar[str] = "px4"  # src/modules/mavlink/mavlink_mission.cpp

    param_specs = staticmethod(param_specs)  # PX4's own parameters

    def __init__(self, ap: Any, rows: np.ndarray) -> None:  # ap: the shared copter.Autopilot
        super().__init__(ap, rows)
        n = ap.n
        # UserModeIntention.hpp: the user intended nav state starts as AUTO_LOITER (Hold)
        self.nav = np.full(n, MODE_LOITER, dtype=np.int64)
        self.nav_after_disarm = np.full(n, MODE_LOITER, dtype=np.int64)
        self.last_setpoint = np.full(n, -math.inf)  # simulated s of the last offboard setpoint
        self.last_gcs = np.full(n, -math.inf)  # simulated s of the last HEARTBEAT of type GCS
        self.gcs_lost = np.zeros(n, dtype=bool)
        self.failsafe = np.zeros(n, dtype=bool)
        self.failsafe_action_at = np.full(n, math.inf)  # Hold until then (COM_FAIL_ACT_T), then act
        self.pending_action = np.zeros(n, dtype=np.int64)
        self.takeoff_z = np.full(n, np.nan)
        self.taken_off = np.zeros(n, dtype=bool)
        self.landed_since = np.full(n, math.inf)
        self.armed_at = np.zeros(n)
        self.last_reject_text = np.full(n, -math.inf)
        # mc_pos_control's takeoff (Takeoff.cpp) and FlightTaskAuto's vertical trajectory of AUTO.TAKEOFF:
        # simulated s the ramp started (+inf: spool-up or ready_for_takeoff; -inf: already flying), and the
        # trajectory's upward velocity (m/s) and acceleration (m/s^2)
        self.ramp_start = np.full(n, math.inf)
        self.takeoff_vz = np.zeros(n)
        self.takeoff_az = np.zeros(n)
        self.takeoff_hold = np.zeros(n, dtype=bool)  # in the Hold a takeoff ended in, still climbing to it
        for i in np.flatnonzero(self.rows & ap.armed):  # airborne starts fly OFFBOARD with a fresh setpoint
            self.nav[i] = MODE_OFFBOARD
            self.last_setpoint[i] = 0.0
            self.taken_off[i] = True
        for i in np.flatnonzero(self.rows & ~ap.armed):
            ap.enter_mode(int(i), internal.LOITER)

    # --- what HEARTBEAT and SYS_STATUS say ------------------------------------------------------------------

    def heartbeat(self, i: int) -> tuple[int, int, int, int]:
        """(autopilot, base_mode, custom_mode, system_status) of vehicle i's HEARTBEAT."""
        base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if self.ap.armed[i]:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
        return M.MAV_AUTOPILOT_PX4, base, int(self.nav[i]), self.system_status(i, bool(self.failsafe[i]))

    def prearm_ok(self, i: int) -> bool:
        """Commander::run's pre_flight_checks_pass: vehicle i could arm in its current mode."""
        return self.arming_problem(i, int(self.nav[i])) is None

    def arming_problem(self, i: int, mode: int) -> str | None:
        """Why vehicle i cannot arm in `mode` (HealthAndArmingChecks modeCheck.cpp messages), or None."""
        if mode in PREVENTS_ARMING:
            return "Mode not suitable for arming"
        return self.run_problem(i, mode)

    def run_problem(self, i: int, mode: int) -> str | None:
        """Why `mode` cannot run on vehicle i (modeCheck.cpp clearCanRunBits), or None."""
        if self.ap.state.crashed[i]:
            return "Vehicle crashed"
        if mode in NEEDS_STICKS:  # no RC or MANUAL_CONTROL is simulated: manual_control_signal_lost
            return "No manual control input"
        if not self.ap.position_ok(i) and (mode in NEEDS_POSITION or mode == MODE_OFFBOARD):
            return "No valid global position estimate"
        if mode == MODE_OFFBOARD and not self.offboard_signal(i):
            return "No offboard signal"
        if mode == MODE_MISSION:
            return "No valid mission available"  # this simulator stores no PX4 mission
        return None

    def offboard_signal(self, i: int) -> bool:
        """offboardCheck.cpp: a setpoint (any offboard_control_mode) younger than COM_OF_LOSS_T."""
        return bool(self.ap.t < self.last_setpoint[i] + self.ap.params.value(i, "COM_OF_LOSS_T"))

    # --- commands -------------------------------------------------------------------------------------------

    def set_mode(self, i: int, base_mode: int, main: int, sub: int, source_compid: int) -> int:
        """Commander.cpp VEHICLE_CMD_DO_SET_MODE: the MAV_RESULT."""
        if not base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return ACCEPTED  # base-mode-only requests: not simulated, acknowledged as PX4 without a change
        if main == AUTO:
            if sub == 0:
                wanted = MODE_MISSION  # "custom_sub_mode > 0" else AUTO_MISSION
            elif sub in (LOITER_SUB, MISSION_SUB, RTL_SUB, TAKEOFF_SUB, LAND_SUB):
                wanted = custom_mode(AUTO, sub)
            else:
                self.ap.say(i, M.MAV_SEVERITY_CRITICAL, "Unsupported auto mode")
                return REJECTED
        elif main == POSCTL:
            wanted = MODE_POSCTL  # sub mode POSCTL_SLOW is simulated as Position
        elif main in (MANUAL, ALTCTL, ACRO, OFFBOARD_MAIN, STABILIZED):
            wanted = custom_mode(main)
        else:
            return ACCEPTED  # desired_nav_state stays NAVIGATION_STATE_MAX: NOT_CHANGED -> ACCEPTED
        return self.change_mode(i, wanted, source_compid)

    def change_mode(self, i: int, wanted: int, source_compid: int = MISSIONPLANNER_COMPID) -> int:
        """UserModeIntention::change: always allowed disarmed, else only if the mode can run."""
        if self.ap.armed[i]:
            problem = self.run_problem(i, wanted)
            if problem is not None:
                if source_compid == MISSIONPLANNER_COMPID and self.ap.t - self.last_reject_text[i] > 1.0:
                    text = f"Switching to {MODE_NAMES[wanted]} is currently not available"
                    self.ap.say(i, M.MAV_SEVERITY_CRITICAL, text)
                    self.last_reject_text[i] = self.ap.t
                return REJECTED
        self.failsafe[i] = False  # failsafe.cpp: RTL/Land failsafes clear OnModeChangeOrDisarm
        self.failsafe_action_at[i] = math.inf
        if wanted != MODE_TAKEOFF:
            self.takeoff_z[i] = np.nan
        self._enter(i, wanted)
        if wanted not in PREVENTS_ARMING:
            self.nav_after_disarm[i] = wanted
        return ACCEPTED

    def arm(self, i: int, arm: float, force: float) -> int:
        """Commander::handle_command COMPONENT_ARM_DISARM: external commands always run the checks."""
        action = round(arm) if math.isfinite(arm) else -1
        if action not in (0, 1):
            self.ap.say(i, M.MAV_SEVERITY_CRITICAL, f"Unsupported ARM_DISARM param: {arm:.3f}")
            return M.MAV_RESULT_UNSUPPORTED
        if action == 0:
            if not self.ap.armed[i]:
                return ACCEPTED
            forced = math.isfinite(force) and round(force) == FORCE_MAGIC
            if not forced and not self.ap.land_complete[i]:
                self.ap.say(i, M.MAV_SEVERITY_CRITICAL, "Disarming denied: not landed")
                return REJECTED
            self.disarm(i, "external command")
            return ACCEPTED
        if self.ap.armed[i]:
            return ACCEPTED
        problem = self.arming_problem(i, int(self.nav[i]))
        if problem is not None:
            self.ap.say(i, M.MAV_SEVERITY_CRITICAL, f"Preflight Fail: {problem}")
            self.ap.say(i, M.MAV_SEVERITY_CRITICAL, "Arming denied: Resolve system health failures first")
            return REJECTED
        ap = self.ap
        ap.armed[i] = True
        ap.disarm_timer[i] = 0.0
        self.armed_at[i] = ap.t
        self.taken_off[i] = False
        self.landed_since[i] = math.inf
        ap.say(i, M.MAV_SEVERITY_INFO, "Armed by external command")
        self._enter(i, int(self.nav[i]))
        return ACCEPTED

    def disarm(self, i: int, reason: str) -> None:
        """Commander::disarm: "Disarmed by <reason>", the user intention returns to the last armable mode."""
        ap = self.ap
        ap.armed[i] = False
        ap.takeoff_active[i] = False
        ap.say(i, M.MAV_SEVERITY_INFO, f"Disarmed by {reason}")
        self._clear_failsafe(i)

    def takeoff(self, i: int, altitude_amsl: float, home_amsl: float) -> int:
        """VEHICLE_CMD_NAV_TAKEOFF: switch to AUTO.TAKEOFF (navigator takeoff: param7 altitude AMSL, NaN ->
        MIS_TAKEOFF_ALT above home); the climb starts once armed."""
        home_z = self.ap.home[i, 2]
        if math.isfinite(altitude_amsl):
            target = home_z + (altitude_amsl - home_amsl)
        else:
            target = home_z + self.ap.params.value(i, "MIS_TAKEOFF_ALT")
        previous = self.takeoff_z[i]
        self.takeoff_z[i] = max(target, self.ap.state.pos[i, 2])
        result = self.change_mode(i, MODE_TAKEOFF)
        if result != ACCEPTED:
            self.takeoff_z[i] = previous
        return result

    def setpoint(self, i: int) -> bool:
        """An offboard setpoint arrived (mavlink_receiver publishes offboard_control_mode): proof of life;
        True when vehicle i flies it (only in OFFBOARD)."""
        self.last_setpoint[i] = self.ap.t
        return bool(self.nav[i] == MODE_OFFBOARD)

    def gcs_heartbeat(self, i: int, mav_type: int) -> None:
        """mavlink_receiver handle_message_heartbeat: any sysid's HEARTBEAT of type MAV_TYPE_GCS counts."""
        if mav_type != M.MAV_TYPE_GCS:
            return
        if self.gcs_lost[i]:
            self.gcs_lost[i] = False
            self.ap.say(i, M.MAV_SEVERITY_INFO, "GCS connection regained")
            if self.failsafe[i] and self.pending_action[i] == 1:  # Hold clears with its condition
                self._clear_failsafe(i)
        self.last_gcs[i] = self.ap.t

    # --- every tick -----------------------------------------------------------------------------------------

    def before_loop(self, t: float, dt: float) -> None:
        """The upward velocity limits PX4 puts on the shared control law this tick (Autopilot.climb_cap):
        AUTO.TAKEOFF's spool-up, ramp and takeoff trajectory (_takeoff_limit), AUTO.RTL's MPC_Z_V_AUTO_UP."""
        ap = self.ap
        ap.climb_cap[self.rows] = math.inf
        for i in np.flatnonzero(self.rows & ap.armed).tolist():
            nav = int(self.nav[i])
            if nav == MODE_TAKEOFF and ap.takeoff_active[i]:
                ap.climb_cap[i] = self._takeoff_limit(i, t, dt)
            elif nav == MODE_LOITER and self.takeoff_hold[i]:
                ap.climb_cap[i] = self._hold_climb_limit(i, dt)
            elif nav == MODE_RTL:
                # FlightTaskAuto::_updateTrajConstraints: auto modes climb at MPC_Z_V_AUTO_UP (mc_pos_control
                # parameters_update keeps it <= MPC_Z_VEL_MAX_UP, which the shared law already applies)
                ap.climb_cap[i] = ap.params.value(i, "MPC_Z_V_AUTO_UP")

    def _trajectory_step(self, i: int, wanted: float, accel: float, jerk: float, dt: float) -> float:
        """Vehicle i's vertical trajectory one tick towards the upward velocity `wanted`; its new velocity."""
        self.takeoff_vz[i], self.takeoff_az[i] = jerk_limited_step(
            float(self.takeoff_vz[i]), float(self.takeoff_az[i]), wanted, accel, jerk, dt
        )
        return float(self.takeoff_vz[i])

    def _hold_climb_limit(self, i: int, dt: float) -> float:
        """Vehicle i's upward velocity limit (m/s) in the Hold its takeoff ended in (navigator
        Takeoff::on_active loiters at the takeoff setpoint, setLoiterItemFromCurrentPositionSetpoint):
        FlightTaskAuto's trajectory goes on, now of a loiter item, to the takeoff altitude at MPC_Z_V_AUTO_UP,
        MPC_ACC_UP_MAX, MPC_JERK_AUTO (_updateTrajConstraints, "up"); +inf once there."""
        ap, p = self.ap, self.ap.params
        remaining = float(ap.nav_pos[i, 2] - ap.state.pos[i, 2])
        if remaining <= 0.05 and self.takeoff_vz[i] <= 0.05:
            self.takeoff_hold[i] = False
            return math.inf
        speed = min(p.value(i, "MPC_Z_V_AUTO_UP"), p.value(i, "MPC_Z_VEL_MAX_UP"))
        jerk = p.value(i, "MPC_JERK_AUTO")
        wanted = min(speed, stop_speed(remaining, ACC_UP_MAX, jerk)) if remaining > 0.0 else 0.0
        return self._trajectory_step(i, wanted, ACC_UP_MAX, jerk, dt)

    def takeoff_reached(self, i: int) -> bool:
        """navigator MissionBlock::is_mission_item_reached_or_completed, NAV_CMD_TAKEOFF of a rotary wing:
        only the altitude counts, above the takeoff altitude minus Navigator::get_altitude_acceptance_radius
        (NAV_MC_ALT_RAD), or minus half the takeoff altitude above home when that is smaller."""
        acceptance = self.ap.params.value(i, "NAV_MC_ALT_RAD")
        takeoff_alt = float(self.takeoff_z[i] - self.ap.home[i, 2])
        if 0.0 < takeoff_alt < acceptance:
            acceptance = takeoff_alt / 2.0
        return bool(self.ap.state.pos[i, 2] > self.takeoff_z[i] - acceptance)

    def _takeoff_limit(self, i: int, t: float, dt: float) -> float:
        """Vehicle i's upward velocity limit (m/s) in AUTO.TAKEOFF at simulated time t, one tick dt later.

        mc_pos_control (MulticopterPositionControl::Run, Takeoff.cpp TakeoffHandling): after arming the
        motors spool up for COM_SPOOLUP_TIME (state spoolup, no thrust: the limit is TAKEOFF_RAMP_VZ_INIT and
        the integrators are reset); once spooled and wanting to take off (ready_for_takeoff -> rampup),
        updateRamp raises the limit linearly from TAKEOFF_RAMP_VZ_INIT to the vehicle constraint speed_up over
        MPC_TKO_RAMP_T (in AUTO max(MPC_Z_VEL_MAX_UP, 1.2 MPC_Z_V_AUTO_UP), capped at MPC_Z_VEL_MAX_UP by
        Run: MPC_Z_VEL_MAX_UP). The climb itself is FlightTaskAuto's PositionSmoothing
        (_updateTrajConstraints): below MPC_LAND_ALT1 above the ground at most MPC_TKO_SPEED, accelerating at
        min(MPC_ACC_UP_MAX, MPC_TKO_SPEED / MPC_TKO_RAMP_T), its position held at the vehicle's
        (forceSetPosition), so the trajectory's velocity is the demand; higher up MPC_Z_V_AUTO_UP at
        MPC_ACC_UP_MAX; jerk MPC_JERK_AUTO. Until the ramp starts the trajectory restarts every cycle at
        TAKEOFF_TRAJECTORY_VZ_INIT (FlightTaskAuto::reActivate).
        """
        ap, p = self.ap, self.ap.params
        pos_z, home_z = float(ap.state.pos[i, 2]), float(ap.home[i, 2])
        remaining = float(ap.nav_pos[i, 2]) - pos_z
        max_up = p.value(i, "MPC_Z_VEL_MAX_UP")
        jerk = p.value(i, "MPC_JERK_AUTO")
        ramp_time = p.value(i, "MPC_TKO_RAMP_T")
        # mc_pos_control parameters_update: MPC_TKO_SPEED <= MPC_Z_VEL_MAX_UP, MPC_Z_V_AUTO_UP likewise
        if pos_z - home_z < max(p.value(i, "MPC_LAND_ALT1"), p.value(i, "MPC_LAND_ALT2")):
            speed = min(p.value(i, "MPC_TKO_SPEED"), max_up)
            accel = min(ACC_UP_MAX, speed / ramp_time) if ramp_time > 0.0 else ACC_UP_MAX
        else:
            speed, accel = min(p.value(i, "MPC_Z_V_AUTO_UP"), max_up), ACC_UP_MAX
        wanted = min(speed, stop_speed(remaining, accel, jerk)) if remaining > 0.0 else 0.0
        if self.ramp_start[i] == math.inf:  # spoolup / ready_for_takeoff
            spooled = t >= self.armed_at[i] + p.value(i, "COM_SPOOLUP_TIME")
            if not (spooled and wanted > WANT_TAKEOFF_VZ):
                ap.integrator[i, 2] = 0.0  # MulticopterPositionControl::Run: not taken off -> resetIntegral
                return TAKEOFF_RAMP_VZ_INIT
            self.ramp_start[i] = t
            self.takeoff_vz[i], self.takeoff_az[i] = TAKEOFF_TRAJECTORY_VZ_INIT, 0.0
        if ap.state.landed[i]:
            # PositionControl::_velocityControl anti-windup: on the ground the thrust is at its minimum, a
            # descent demand integrates nothing
            ap.integrator[i, 2] = max(ap.integrator[i, 2], 0.0)
        limit = self._trajectory_step(i, wanted, accel, jerk, dt)
        progress = (t - self.ramp_start[i]) / ramp_time if ramp_time > dt else 1.0
        if progress < 1.0:  # Takeoff.cpp updateRamp
            limit = min(limit, TAKEOFF_RAMP_VZ_INIT + progress * (max_up - TAKEOFF_RAMP_VZ_INIT))
        return limit

    def after_loop(self, t: float, events: np.ndarray) -> None:
        """Takeoff completion, offboard loss, GCS loss, auto-disarm of the PX4 vehicles (the shared loop's
        events are ArduCopter's rules: a PX4 vehicle disarms and fails safe by its own)."""
        ap = self.ap
        for i in np.flatnonzero(self.rows & ap.armed).tolist():
            if not ap.land_complete[i]:
                self.taken_off[i] = True
            nav = int(self.nav[i])
            # navigator Takeoff::on_active: reached (takeoff_reached), the takeoff is completed and the loiter
            # item is the current position setpoint, the takeoff altitude; Commander: takeoff finished ->
            # AUTO.LOITER (COM_TAKEOFF_ACT 0)
            if (
                nav == MODE_TAKEOFF
                and self.taken_off[i]
                and (self.takeoff_reached(i) or not ap.takeoff_active[i])
            ):
                altitude = float(self.takeoff_z[i])
                if self.change_mode(i, MODE_LOITER) == ACCEPTED:
                    ap.nav_pos[i, 2] = altitude
                    self.takeoff_hold[i] = True
            if nav == MODE_OFFBOARD and not self.offboard_signal(i) and not self.failsafe[i]:
                self._offboard_lost(i)
            self._gcs_check(i, t)
            if self.failsafe[i] and t >= self.failsafe_action_at[i]:
                self.failsafe_action_at[i] = math.inf
                self._act(i, int(self.pending_action[i]))
            self._auto_disarm(i, t)

    def fence_breached(self, i: int, new: int, t: float) -> None:
        """Navigator geofence_breach_check: "Geofence violation" (once until back inside); Commander's
        geofence_breached failsafe then acts as GF_ACTION says (failsafe.cpp fromGfActParam): Hold at once
        (AlwaysModeSwitchOnly), Return and Land after COM_FAIL_ACT_T in Hold (user takeover Auto), Terminate
        at once. A vehicle already in a failsafe keeps that one's action (PX4 would take the more severe)."""
        ap = self.ap
        ap.say(i, M.MAV_SEVERITY_CRITICAL, "Geofence violation")
        action = int(ap.params.value(i, "GF_ACTION"))
        failsafe = GEOFENCE_FAILSAFE.get(action)
        if failsafe is not None and not self.failsafe[i]:
            if action == GF_HOLD:
                self.failsafe[i] = True
                ap.say(i, M.MAV_SEVERITY_CRITICAL, "Failsafe activated")
                self._enter(i, MODE_LOITER)
            else:
                self._start_failsafe(i, failsafe, t)
        x, y, z = ap.state.pos[i]
        ap.fence_log.append(
            f"vehicle {i}: geofence violation at t={t:.2f} s at ({x:.1f}, {y:.1f}, {z:.1f}) m: GF_ACTION "
            f"{action}, mode {MODE_NAMES.get(int(self.nav[i]), self.nav[i])}"
            + (", disarmed" if not ap.armed[i] else "")
        )

    def _offboard_lost(self, i: int) -> None:
        """failsafe.cpp checkModeFallback + getSelectedAction: COM_OBL_RC_ACT; the stick modes it names
        cannot run without manual control, so they fall through to RTL; no COM_FAIL_ACT_T delay (mode
        fallbacks allow user takeover Always, not Auto)."""
        act = int(self.ap.params.value(i, "COM_OBL_RC_ACT"))
        self.failsafe[i] = True
        self.ap.say(i, M.MAV_SEVERITY_CRITICAL, "Failsafe activated")
        self._enter_or_disarm(i, MODE_RTL if act in FALLBACK_TO_RTL else OFFBOARD_LOSS_MODES.get(act))

    def _gcs_check(self, i: int, t: float) -> None:
        """Commander::dataLinkCheck (COM_DL_LOSS_T after a GCS heartbeat was seen) and failsafe.cpp
        (NAV_DLL_ACT, ignored in AUTO.LAND; the action follows a COM_FAIL_ACT_T Hold)."""
        p = self.ap.params
        if not self.gcs_lost[i] and math.isfinite(self.last_gcs[i]):
            if t - self.last_gcs[i] > p.value(i, "COM_DL_LOSS_T"):
                self.gcs_lost[i] = True
                self.ap.say(i, M.MAV_SEVERITY_INFO, "Connection to ground station lost")
                action = int(p.value(i, "NAV_DLL_ACT"))
                if action in (1, 2, 3, 5, 6) and self.nav[i] != MODE_LAND and not self.failsafe[i]:
                    self._start_failsafe(i, action, t)

    def _start_failsafe(self, i: int, action: int, t: float) -> None:
        self.failsafe[i] = True
        self.pending_action[i] = action
        delay = self.ap.params.value(i, "COM_FAIL_ACT_T")
        if action in (5, 6) or delay <= 0.1:  # Terminate, Disarm: UserTakeoverAllowed::Never, no delay
            self.ap.say(i, M.MAV_SEVERITY_CRITICAL, "Failsafe activated")
            self._act(i, action)
            return
        text = f"Failsafe activated: entering Hold for {round(delay)} seconds"
        self.ap.say(i, M.MAV_SEVERITY_CRITICAL, text)
        self._enter(i, MODE_LOITER)
        self.failsafe_action_at[i] = t + delay

    def _act(self, i: int, action: int) -> None:
        """failsafe.cpp fromNavDllOrRclActParam: 1 Hold, 2 RTL, 3 Land, 5 Terminate, 6 Disarm."""
        self._enter_or_disarm(i, GCS_LOSS_MODES.get(action))

    def _enter_or_disarm(self, i: int, mode: int | None) -> None:
        """A failsafe's action: enter PX4 mode `mode`, or (None: Terminate, Disarm) stop the motors."""
        if mode is None:
            self.disarm(i, "failsafe")
        else:
            self._enter(i, mode)

    def _clear_failsafe(self, i: int) -> None:
        """No failsafe any more: vehicle i returns to the last mode the user chose that it may arm in."""
        self.failsafe[i] = False
        self.failsafe_action_at[i] = math.inf
        self._enter(i, int(self.nav_after_disarm[i]))

    def _auto_disarm(self, i: int, t: float) -> None:
        """Commander::handleAutoDisarm: landed COM_DISARM_LAND s after a takeoff, or COM_DISARM_PRFLT s after
        arming without one (values <= 0 disable)."""
        ap, p = self.ap, self.ap.params
        landed = bool(ap.land_complete[i])
        if not landed:
            self.landed_since[i] = math.inf
            return
        self.landed_since[i] = min(self.landed_since[i], t)
        if self.taken_off[i]:
            delay = p.value(i, "COM_DISARM_LAND")
            if delay > 0 and t - self.landed_since[i] >= delay:
                self.disarm(i, "landing")
        else:
            delay = p.value(i, "COM_DISARM_PRFLT")
            if delay > 0 and t - self.armed_at[i] >= delay and self.nav[i] != MODE_TAKEOFF:
                self.disarm(i, "auto preflight disarming")

    # --- internals ------------------------------------------------------------------------------------------

    def _enter(self, i: int, mode: int) -> None:
        """Vehicle i is in PX4 mode `mode`: run its shared control law from the current state."""
        self.nav[i] = mode
        self.takeoff_hold[i] = False
        self.ap.enter_mode(i, INTERNAL_MODE.get(mode, internal.LOITER))
        if mode == MODE_TAKEOFF:
            if not math.isfinite(self.takeoff_z[i]):
                self.takeoff_z[i] = self.ap.home[i, 2] + self.ap.params.value(i, "MIS_TAKEOFF_ALT")
            self._start_takeoff(i)
        elif mode == MODE_RTL:  # the shared RTL climbs to nav_pos z, returns at it and lands
            self.ap.nav_pos[i, 2] = self.return_altitude(i)

    def _start_takeoff(self, i: int) -> None:
        ap = self.ap
        if ap.armed[i] and self.nav[i] == MODE_TAKEOFF:
            # Takeoff.cpp updateTakeoffState: landed, the takeoff starts over (spoolup if just armed, else
            # ready_for_takeoff); in the air it is in flight (no spool-up, no ramp); a takeoff still on the
            # ground keeps its state. FlightTaskAuto::activate starts the trajectory at the current velocity.
            if ap.land_complete[i]:
                self.ramp_start[i] = math.inf
                self.takeoff_vz[i], self.takeoff_az[i] = 0.0, 0.0
            elif not ap.state.landed[i]:
                if self.ramp_start[i] == math.inf:
                    self.ramp_start[i] = -math.inf
                self.takeoff_vz[i], self.takeoff_az[i] = float(ap.state.vel[i, 2]), 0.0
            ap.climb_to(i, float(self.takeoff_z[i]))

    def rtl_destination(self, i: int) -> np.ndarray:
        """navigator rtl.cpp findRtlDestination by RTL_TYPE over home and the safe points
        (sitl_sim.autopilot.rally)."""
        ap = self.ap
        return ap.rally.px4_destination(i, ap.state.pos[i], ap.home[i], int(ap.params.value(i, "RTL_TYPE")))

    def return_altitude(self, i: int) -> float:
        """World height (m) vehicle i returns at in AUTO.RTL: navigator rtl.cpp
        RTL::calculate_return_alt_from_cone_half_angle for its destination (home or a safe point, the
        Autopilot's rtl_dest, chosen first), used for rotary wings when RTL_CONE_ANG > 0
        (RTL::findRtlDestination; else max(current, destination + RTL_RETURN_ALT)): within NAV_ACC_RAD of the
        destination 2x the horizontal distance d; beyond it RTL_RETURN_ALT, lowered within RTL_MIN_DIST to the
        cone's d / tan(RTL_CONE_ANG clamped to 1..89 deg), and at least 2 x NAV_ACC_RAD; never below the
        current altitude (RtlDirect climbs only if lower)."""
        p = self.ap.params
        pos, home = self.ap.state.pos[i], self.ap.rtl_dest[i]
        cone_deg = p.value(i, "RTL_CONE_ANG")
        return_alt = home[2] + p.value(i, "RTL_RETURN_ALT")
        if cone_deg > 0:
            dist = math.hypot(pos[0] - home[0], pos[1] - home[1])
            acceptance = p.value(i, "NAV_ACC_RAD")
            if dist <= acceptance:
                return_alt = home[2] + 2.0 * dist
            else:
                if dist <= p.value(i, "RTL_MIN_DIST"):
                    cone = math.radians(min(max(cone_deg, 1.0), 89.0))
                    return_alt = min(home[2] + dist / math.tan(cone), return_alt)
                return_alt = max(return_alt, home[2] + 2.0 * acceptance)
        return float(max(return_alt, pos[2]))


def stop_speed(distance: float, accel: float, jerk: float) -> float:
    """The highest speed (m/s) from which a jerk-limited stop (acceleration <= accel, jerk <= jerk) fits in
    `distance` m: PX4 lib/mathlib/math/TrajMath.hpp computeMaxSpeedFromDistance(jerk, accel, distance, 0),
    which PositionSmoothing::_getMaxZSpeed uses to slow the vertical trajectory down towards its target."""
    b = 4.0 * accel * accel / jerk
    return 0.5 * (-b + math.sqrt(b * b + 8.0 * accel * max(distance, 0.0)))
