"""ArduCopter-like autopilot of N vehicles: modes, arming, guided targets, land detector, failsafes.

`update` runs once per outer tick, vectorised over vehicles, and hands attitude/thrust targets to the physics
(FleetDynamics, whose attitude controller runs at the physics rate). Discrete events (a command, a mode change,
a crash) are per-vehicle methods. Every mode reduces to one of two control laws:
- position/velocity control (GUIDED position/velocity targets, LOITER, BRAKE, RTL, LAND): position_control;
- angle control (GUIDED attitude targets, GUIDED_NOGPS, ALT_HOLD, STABILIZE): an attitude target plus a climb
  rate (vertical velocity loop) or a direct collective.
State is world ENU, body FLU, SI units; MAVLink conversions happen in the endpoint.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl_sim.attitude_control import level_quat, yaw_from_quat
from sitl_sim.dynamics import FleetDynamics
from sitl_sim.params import ParamTable
from sitl_sim.position_control import PositionGains, accel_demand, attitude_from_accel, velocity_demand

M = mavlink
STABILIZE, ALT_HOLD, GUIDED, LOITER, RTL, LAND, BRAKE, GUIDED_NOGPS = 0, 2, 4, 5, 6, 9, 17, 20
MODE_NAMES = {
    STABILIZE: "STABILIZE",
    ALT_HOLD: "ALT_HOLD",
    GUIDED: "GUIDED",
    LOITER: "LOITER",
    RTL: "RTL",
    LAND: "LAND",
    BRAKE: "BRAKE",
    GUIDED_NOGPS: "GUIDED_NOGPS",
}
POSITION_MODES = (
    GUIDED,
    LOITER,
    RTL,
    BRAKE,
)  # ArduCopter requires_GPS(): refused when armed without position
NOT_ARMABLE = (RTL, LAND, BRAKE)
GUIDED_ENABLED_MODES = (GUIDED, LOITER, RTL, BRAKE)  # ArduCopter base_mode() GUIDED_ENABLED list
FORCE_ARM = 2989  # MAV_CMD_COMPONENT_ARM_DISARM param2 that skips the arming checks
FORCE_DISARM = 21196  # ... and the one that disarms in flight
GUID_OPTION_THRUST = 8  # GUID_OPTIONS bit 3: SET_ATTITUDE_TARGET thrust is collective thrust

CTRL_POS, CTRL_ANGLE = 0, 1
KIND_POS, KIND_VEL, KIND_POSVEL, KIND_ACCEL = 0, 1, 2, 3  # guided position-target kinds
RTL_CLIMB, RTL_RETURN, RTL_DESCEND = 0, 1, 2

LAND_DETECT_S = 1.0  # ArduCopter LAND_DETECTOR_TRIGGER_SEC
LAND_ALT_LOW = 10.0  # m, LAND descends at WPNAV_SPEED_DN above, LAND_SPEED below (LAND_ALT_LOW 1000 cm)
SPIN_ARMED = 0.05  # fraction of full thrust while armed on the ground (MOT_SPIN_ARM-like)
RTL_REACHED_M = 1.0  # m, horizontal distance at which RTL starts its descent
TAKEOFF_REACHED_M = 0.1  # m below the takeoff altitude at which the takeoff is complete

# SYS_STATUS sensor bits as ArduCopter sets them (MAVSDK: GPS present+healthy -> position ok,
# PREARM_CHECK healthy -> armable).
SENSORS_ALWAYS = (
    M.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | M.MAV_SYS_STATUS_SENSOR_3D_MAG
    | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | M.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | M.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | M.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | M.MAV_SYS_STATUS_SENSOR_BATTERY
)
SENSOR_XY = M.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
SENSOR_Z = M.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
SENSORS_PRESENT = (
    SENSORS_ALWAYS
    | M.MAV_SYS_STATUS_SENSOR_GPS
    | SENSOR_XY
    | SENSOR_Z
    | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | M.MAV_SYS_STATUS_AHRS
    | M.MAV_SYS_STATUS_PREARM_CHECK
)
EKF_BOOTING = M.EKF_UNINITIALIZED
EKF_NO_GPS = M.EKF_ATTITUDE | M.EKF_VELOCITY_VERT | M.EKF_POS_VERT_ABS | M.EKF_CONST_POS_MODE
EKF_GOOD = (
    M.EKF_ATTITUDE
    | M.EKF_VELOCITY_HORIZ
    | M.EKF_VELOCITY_VERT
    | M.EKF_POS_HORIZ_REL
    | M.EKF_POS_HORIZ_ABS
    | M.EKF_POS_VERT_ABS
    | M.EKF_PRED_POS_HORIZ_REL
    | M.EKF_PRED_POS_HORIZ_ABS
)
# FS_GCS_ENABLE -> action (ArduCopter 4.6 enumeration; SmartRTL and DO_LAND_START fall back to RTL/LAND).
GCS_FAILSAFE_ACTIONS = {1: RTL, 2: RTL, 3: RTL, 4: LAND, 5: LAND, 6: RTL, 7: BRAKE}


class Autopilot:
    """Flight software of N vehicles over one FleetDynamics; arrays (N,) or (N,k), world ENU, SI units.

    origin (N,3): each vehicle's EKF origin (its start point); home (N,3): its start point on the ground.
    airborne (N,) bool: vehicles that start flying (armed, GUIDED, holding start_vel (N,3) until GUID_TIMEOUT).
    ready_delay: simulated seconds until a vehicle on the ground has a position estimate.
    """

    def __init__(
        self,
        dyn: FleetDynamics,
        params: ParamTable,
        origin: np.ndarray,
        home: np.ndarray,
        airborne: np.ndarray,
        start_vel: np.ndarray,
        ready_delay: float,
    ) -> None:
        n = dyn.n
        self.n = n
        self.dyn = dyn
        self.state = dyn.state
        self.params = params
        self.origin = np.array(origin, dtype=float)
        self.home = np.array(home, dtype=float)
        self.t = 0.0
        self.ready_at = np.where(airborne, 0.0, ready_delay)
        self.boot_end = np.where(airborne, 0.0, min(1.0, 0.5 * ready_delay))
        self.ready = self.ready_at <= 0.0
        self.mode = np.where(airborne, GUIDED, STABILIZE)
        self.armed = np.array(airborne, dtype=bool)
        self.land_complete = ~self.armed
        self.land_timer = np.zeros(n)
        self.disarm_timer = np.zeros(n)
        self.takeoff_active = np.zeros(n, dtype=bool)
        self.failsafe_gcs = np.zeros(n, dtype=bool)
        self.last_gcs_heartbeat = np.full(n, -math.inf)
        self.thrust_demand = np.zeros(n)  # last collective, fraction of full thrust
        # position/velocity control targets
        self.control = np.where(airborne, CTRL_POS, CTRL_ANGLE)
        self.nav_kind = np.where(airborne, KIND_VEL, KIND_POS)
        self.nav_pos = np.full((n, 3), np.nan)
        self.nav_vel = np.where(np.asarray(airborne)[:, None], start_vel, 0.0)
        self.nav_acc = np.zeros((n, 3))
        self.nav_yaw = yaw_from_quat(self.state.quat)
        self.nav_yaw_rate = np.zeros(n)
        self.target_time = np.zeros(n)
        self.rtl_stage = np.zeros(n, dtype=int)
        # angle control targets
        self.angle_quat = level_quat(self.nav_yaw)
        self.angle_rates = np.zeros((n, 3))
        self.angle_rate_ff = np.zeros(n, dtype=bool)
        self.rates_only = np.zeros(n, dtype=bool)
        self.climb_rate = np.zeros(n)
        self.collective = np.zeros(n)
        self.use_thrust = np.zeros(n, dtype=bool)
        self.angle_timed_out = np.ones(n, dtype=bool)
        self.integrator = np.zeros((n, 3))
        self.texts: list[list[tuple[int, str]]] = [[] for _ in range(n)]
        for i in np.flatnonzero(~self.armed):
            self._enter_mode(int(i), STABILIZE)

    # --- status as MAVLink reports it -----------------------------------------------------------------------

    def position_ok(self, i: int) -> bool:
        """The EKF has a position (origin, home and GPS fix are set)."""
        return bool(self.ready[i])

    def base_mode(self, i: int) -> int:
        """HEARTBEAT base_mode as ArduCopter computes it."""
        bits = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        bits |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        if self.mode[i] in GUIDED_ENABLED_MODES:
            bits |= M.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.armed[i]:
            bits |= M.MAV_MODE_FLAG_SAFETY_ARMED
        return bits

    def system_status(self, i: int) -> int:
        """HEARTBEAT system_status: BOOT, STANDBY, ACTIVE when armed, CRITICAL in failsafe, EMERGENCY crashed."""
        if self.state.crashed[i]:
            return M.MAV_STATE_EMERGENCY
        if self.failsafe_gcs[i]:
            return M.MAV_STATE_CRITICAL
        if self.t < self.boot_end[i]:
            return M.MAV_STATE_BOOT
        return M.MAV_STATE_ACTIVE if self.armed[i] else M.MAV_STATE_STANDBY

    def prearm_ok(self, i: int) -> bool:
        """The pre-arm checks pass (position estimate, not crashed)."""
        return bool(self.ready[i] and not self.state.crashed[i])

    def sensor_bits(self, i: int) -> tuple[int, int, int]:
        """SYS_STATUS (present, enabled, health) bit masks."""
        enabled = SENSORS_PRESENT & ~M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS & ~SENSOR_XY & ~SENSOR_Z
        mode = self.mode[i]
        if mode in (*POSITION_MODES, LAND):
            enabled |= SENSOR_XY | SENSOR_Z
        elif mode in (ALT_HOLD, GUIDED_NOGPS):
            enabled |= SENSOR_Z
        if self.armed[i]:
            enabled |= M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        health = SENSORS_ALWAYS | SENSOR_XY | SENSOR_Z
        if not self.state.crashed[i]:
            health |= M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        if self.t >= self.boot_end[i]:
            health |= M.MAV_SYS_STATUS_AHRS
        if self.ready[i]:
            health |= M.MAV_SYS_STATUS_SENSOR_GPS
        if self.prearm_ok(i):
            health |= M.MAV_SYS_STATUS_PREARM_CHECK
        return SENSORS_PRESENT, enabled, health

    def ekf_flags(self, i: int) -> int:
        """EKF_STATUS_REPORT flags: uninitialised, then attitude/height only, then full position."""
        if self.ready[i]:
            return EKF_GOOD
        return EKF_BOOTING if self.t < self.boot_end[i] else EKF_NO_GPS

    def landed_state(self, i: int) -> int:
        """EXTENDED_SYS_STATE landed_state (ArduCopter's GCS_MAVLINK_Copter::landed_state)."""
        if self.land_complete[i]:
            return M.MAV_LANDED_STATE_ON_GROUND
        if self._landing()[i]:
            return M.MAV_LANDED_STATE_LANDING
        if self.takeoff_active[i]:
            return M.MAV_LANDED_STATE_TAKEOFF
        return M.MAV_LANDED_STATE_IN_AIR

    def say(self, i: int, severity: int, text: str) -> None:
        """Queue a STATUSTEXT of vehicle i."""
        self.texts[i].append((severity, text))

    # --- discrete events ------------------------------------------------------------------------------------

    def arm(self, i: int, force: bool) -> int:
        """MAV_CMD_COMPONENT_ARM_DISARM param1=1; returns the MAV_RESULT. Refusals say why (STATUSTEXT)."""
        if self.armed[i]:
            return M.MAV_RESULT_ACCEPTED
        if self.state.crashed[i]:
            self.say(i, M.MAV_SEVERITY_CRITICAL, "PreArm: Vehicle crashed")
            return M.MAV_RESULT_FAILED
        if not force:
            if not self.ready[i]:
                self.say(i, M.MAV_SEVERITY_CRITICAL, "PreArm: Need Position Estimate")
                return M.MAV_RESULT_FAILED
            if self.mode[i] in NOT_ARMABLE:
                self.say(i, M.MAV_SEVERITY_CRITICAL, "Arm: Mode not armable")
                return M.MAV_RESULT_FAILED
        self.armed[i] = True
        self.disarm_timer[i] = 0.0
        self._enter_mode(i, int(self.mode[i]))
        self.say(i, M.MAV_SEVERITY_INFO, "Arming motors")
        return M.MAV_RESULT_ACCEPTED

    def disarm(self, i: int, force: bool) -> int:
        """param1=0: refused in flight unless forced (ArduCopter disarm checks); returns the MAV_RESULT."""
        if not self.armed[i]:
            return M.MAV_RESULT_ACCEPTED
        if not force and not self.land_complete[i]:
            self.say(i, M.MAV_SEVERITY_WARNING, "Disarm: vehicle is flying")
            return M.MAV_RESULT_FAILED
        self._disarm(i)
        return M.MAV_RESULT_ACCEPTED

    def set_mode(self, i: int, mode: int) -> int:
        """Change flight mode (SET_MODE / MAV_CMD_DO_SET_MODE); returns the MAV_RESULT."""
        if mode not in MODE_NAMES:
            self.say(i, M.MAV_SEVERITY_WARNING, f"Mode change failed: mode {mode} not supported")
            return M.MAV_RESULT_FAILED
        if mode == self.mode[i]:
            return M.MAV_RESULT_ACCEPTED
        if self.armed[i] and mode in POSITION_MODES and not self.position_ok(i):
            self.say(
                i, M.MAV_SEVERITY_WARNING, f"Mode change to {MODE_NAMES[mode]} failed: requires position"
            )
            return M.MAV_RESULT_FAILED
        self._enter_mode(i, mode)
        return M.MAV_RESULT_ACCEPTED

    def takeoff(self, i: int, altitude: float) -> int:
        """MAV_CMD_NAV_TAKEOFF in GUIDED to altitude m above home; returns the MAV_RESULT."""
        if self.mode[i] != GUIDED or not self.armed[i] or not self.land_complete[i]:
            return M.MAV_RESULT_FAILED
        if not (math.isfinite(altitude) and self.state.pos[i, 2] - self.home[i, 2] < altitude <= 10000.0):
            return M.MAV_RESULT_FAILED
        pos = self.state.pos[i]
        self._set_position_control(i, KIND_POS)
        self.nav_pos[i] = (pos[0], pos[1], self.home[i, 2] + altitude)
        self.takeoff_active[i] = True
        self.land_complete[i] = False
        self.land_timer[i] = 0.0
        return M.MAV_RESULT_ACCEPTED

    def set_position_target(
        self,
        i: int,
        pos: np.ndarray | None,
        vel: np.ndarray | None,
        acc: np.ndarray | None,
        yaw: float | None,
        yaw_rate: float | None,
    ) -> bool:
        """GUIDED position/velocity/acceleration target (ENU, m, m/s, m/s^2, yaw rad ENU); False if ignored.

        Combinations as ArduCopter: pos+vel, vel(+acc), acc, pos; anything else stops the vehicle.
        """
        if self.mode[i] != GUIDED:
            return False
        if pos is not None and vel is not None:
            kind = KIND_POSVEL
        elif vel is not None:
            kind = KIND_VEL
        elif acc is not None and pos is None:
            kind = KIND_ACCEL
        elif pos is not None and acc is None:
            kind = KIND_POS
        else:
            self.guided_stop(i)
            return False
        self._set_position_control(i, kind)
        self.takeoff_active[i] = False
        self.nav_pos[i] = np.nan if pos is None else pos
        self.nav_vel[i] = 0.0 if vel is None else vel
        self.nav_acc[i] = 0.0 if acc is None else acc
        if yaw is not None:
            self.nav_yaw[i] = yaw
        self.nav_yaw_rate[i] = 0.0 if yaw_rate is None else yaw_rate
        return True

    def set_attitude_target(
        self, i: int, quat: np.ndarray | None, rates: np.ndarray | None, thrust: float
    ) -> bool:
        """GUIDED/GUIDED_NOGPS attitude target: quat (4,) FLU->ENU or None (rates only), rates (3,) FLU rad/s or
        None, thrust 0..1 (a climb-rate demand, 0.5 = hold, unless GUID_OPTIONS bit 3); False if ignored.
        """
        if self.mode[i] not in (GUIDED, GUIDED_NOGPS):
            return False
        self.control[i] = CTRL_ANGLE
        self.target_time[i] = self.t
        self.angle_timed_out[i] = False
        self.takeoff_active[i] = False
        self.rates_only[i] = quat is None
        if quat is not None:
            self.angle_quat[i] = quat
        self.angle_rate_ff[i] = rates is not None
        self.angle_rates[i] = 0.0 if rates is None else rates
        thrust = min(max(thrust, 0.0), 1.0)
        if int(self.params.value(i, "GUID_OPTIONS")) & GUID_OPTION_THRUST:
            self.use_thrust[i] = True
            self.collective[i] = thrust
        else:  # ArduCopter: (thrust - 0.5) * 2 scaled by WPNAV_SPEED_UP above 0.5, WPNAV_SPEED_DN below
            self.use_thrust[i] = False
            speed = "WPNAV_SPEED_UP" if thrust >= 0.5 else "WPNAV_SPEED_DN"
            self.climb_rate[i] = (thrust - 0.5) * 2.0 * self.params.value(i, speed) / 100.0
        return True

    def guided_stop(self, i: int) -> None:
        """Invalid guided input: stop and hold (ArduCopter mode_guided.init)."""
        self._enter_mode(i, int(self.mode[i]))

    def gcs_heartbeat(self, i: int, sysid: int) -> None:
        """A HEARTBEAT from `sysid` reached vehicle i: refreshes the GCS failsafe if it is SYSID_MYGCS."""
        if sysid != int(self.params.value(i, "SYSID_MYGCS")):
            return
        self.last_gcs_heartbeat[i] = self.t
        if self.failsafe_gcs[i]:
            self.failsafe_gcs[i] = False
            self.say(i, M.MAV_SEVERITY_WARNING, "GCS Failsafe Cleared")

    def crash(self, i: int, reason: str) -> None:
        """Mark vehicle i crashed: motors stop for good, STATUSTEXT with the reason."""
        if self.state.crashed[i]:
            return
        self.state.crashed[i] = True
        self.armed[i] = False
        self.takeoff_active[i] = False
        self.say(i, M.MAV_SEVERITY_EMERGENCY, f"Crash: {reason}"[:50])

    # --- the outer loop -------------------------------------------------------------------------------------

    def update(self, t: float, dt: float) -> None:
        """One outer tick at simulated time t (s) covering dt (s): modes, controllers, targets to the physics."""
        self.t = t
        self.ready = t >= self.ready_at
        s = self.state
        p = self.params
        g = self.dyn.params.g
        hover = p.column("MOT_THST_HOVER")
        tilt_max = np.radians(p.column("ANGLE_MAX") / 100.0)
        yaw_now = yaw_from_quat(s.quat)
        guided = self.mode == GUIDED
        angle_guided = (guided | (self.mode == GUIDED_NOGPS)) & (self.control == CTRL_ANGLE)
        stale = (t - self.target_time) > p.column("GUID_TIMEOUT")

        # GUID_TIMEOUT: velocity/acceleration targets stop; attitude targets level and hold altitude.
        vel_stale = guided & (self.control == CTRL_POS) & stale & (self.nav_kind != KIND_POS)
        self.nav_vel[vel_stale] = 0.0
        self.nav_acc[vel_stale] = 0.0
        ang_stale = angle_guided & stale & ~self.angle_timed_out
        if ang_stale.any():
            self.angle_quat[ang_stale] = level_quat(yaw_now[ang_stale])
            self.angle_rates[ang_stale] = 0.0
            self.angle_rate_ff[ang_stale] = False
            self.rates_only[ang_stale] = False
            self.climb_rate[ang_stale] = 0.0
            self.use_thrust[ang_stale] = False
            self.angle_timed_out[ang_stale] = True

        self._update_navigation(dt)
        self._update_land_detector(hover, dt)

        # A positive climb/thrust demand in guided angle control takes off (ArduCopter angle_control_run).
        positive = angle_guided & np.where(self.use_thrust, self.collective > 0.0, self.climb_rate > 0.0)
        self.land_complete &= ~positive
        self.land_timer[positive] = 0.0

        stabilize = self.mode == STABILIZE
        self.collective[stabilize] = hover[stabilize]  # no RC: the throttle stick rests at mid (hover)
        angle = angle_guided | stabilize | (self.mode == ALT_HOLD)
        direct = angle & self.use_thrust
        airborne_ctl = self.armed & ~self.land_complete
        gains = self._gains(tilt_max)
        vel_sp = velocity_demand(s.pos, self.nav_pos, self.nav_vel, gains)
        vel_sp[:, 2] = np.where(angle, self.climb_rate, vel_sp[:, 2])
        active = np.stack((~angle, ~angle, ~direct), axis=1) & airborne_ctl[:, None]
        acc_ff = np.where(angle[:, None], 0.0, self.nav_acc)
        acc = accel_demand(s.vel, vel_sp, acc_ff, self.integrator, active, gains, dt)
        quat_pos, thrust_g = attitude_from_accel(acc, self.nav_yaw, tilt_max, g)

        up = 1.0 - 2.0 * (s.quat[:, 1] ** 2 + s.quat[:, 2] ** 2)  # cos(tilt) of the actual attitude
        up = np.maximum(up, np.cos(tilt_max))
        climb_fraction = hover * np.maximum(g + acc[:, 2], 0.3 * g) / g / up
        fraction = np.where(angle, np.where(direct, self.collective, climb_fraction), hover * thrust_g)
        quat = np.where(angle[:, None], self.angle_quat, quat_pos)

        idle = self.armed & self.land_complete
        quat = np.where(idle[:, None], level_quat(yaw_now), quat)
        fraction = np.where(idle, SPIN_ARMED, fraction)
        motors_on = self.armed & ~s.crashed
        fraction = np.where(motors_on, np.clip(fraction, 0.0, 1.0), 0.0)
        self.thrust_demand = fraction
        rate_ff = np.where(
            (angle_guided & self.angle_rate_ff & ~self.rates_only)[:, None], self.angle_rates, 0.0
        )
        self.dyn.set_targets(quat, rate_ff, fraction * self.dyn.params.thrust_max, motors_on, tilt_max)
        self.dyn.set_rate_targets(angle_guided & self.rates_only & ~idle, self.angle_rates)

        self._auto_disarm(dt)
        self._check_gcs_failsafe()

    # --- internals ------------------------------------------------------------------------------------------

    def _gains(self, tilt_max: np.ndarray) -> PositionGains:
        p = self.params
        return PositionGains(
            pos_xy_p=p.column("PSC_POSXY_P"),
            pos_z_p=p.column("PSC_POSZ_P"),
            vel_xy_p=p.column("PSC_VELXY_P"),
            vel_xy_i=p.column("PSC_VELXY_I"),
            vel_z_p=p.column("PSC_VELZ_P"),
            vel_z_i=p.column("PSC_VELZ_I"),
            speed_xy=p.column("WPNAV_SPEED") / 100.0,
            speed_up=p.column("WPNAV_SPEED_UP") / 100.0,
            speed_dn=p.column("WPNAV_SPEED_DN") / 100.0,
            accel_xy=p.column("WPNAV_ACCEL") / 100.0,
            tilt_max=tilt_max,
        )

    def _landing(self) -> np.ndarray:
        """(N,) vehicles in a landing descent (LAND, or RTL's final descent)."""
        return (self.mode == LAND) | ((self.mode == RTL) & (self.rtl_stage == RTL_DESCEND))

    def _update_navigation(self, dt: float) -> None:
        """Per-mode target updates: takeoff completion, RTL stages, LAND descent speed, BRAKE, yaw rate."""
        s = self.state
        height = s.pos[:, 2] - self.home[:, 2]
        done = self.takeoff_active & (s.pos[:, 2] >= self.nav_pos[:, 2] - TAKEOFF_REACHED_M)
        self.takeoff_active &= ~done

        rtl = (self.mode == RTL) & self.armed
        climbed = rtl & (self.rtl_stage == RTL_CLIMB) & (s.pos[:, 2] >= self.nav_pos[:, 2] - 0.5)
        self.nav_pos[climbed, :2] = self.home[climbed, :2]
        self.rtl_stage[climbed] = RTL_RETURN
        distance = np.hypot(*(s.pos[:, :2] - self.home[:, :2]).T)
        arrived = rtl & (self.rtl_stage == RTL_RETURN) & (distance < RTL_REACHED_M)
        self.nav_pos[arrived, 2] = np.nan
        self.rtl_stage[arrived] = RTL_DESCEND

        landing = self._landing()
        speed = np.where(
            height > LAND_ALT_LOW,
            self.params.column("WPNAV_SPEED_DN") / 100.0,
            self.params.column("LAND_SPEED") / 100.0,
        )
        self.nav_vel[landing, 2] = -speed[landing]

        braking = (self.mode == BRAKE) & np.isnan(self.nav_pos[:, 0]) & (np.hypot(*s.vel[:, :2].T) < 0.2)
        self.nav_pos[braking, :2] = s.pos[braking, :2]

        turning = (self.mode == GUIDED) & (self.control == CTRL_POS)
        self.nav_yaw[turning] += self.nav_yaw_rate[turning] * dt

    def _update_land_detector(self, hover: np.ndarray, dt: float) -> None:
        """land_complete after LAND_DETECT_S on the ground without a climb demand (immediately if disarmed)."""
        on_ground = self.state.landed & ~self.takeoff_active
        quiet = on_ground & (~self.armed | (self.thrust_demand < hover))
        self.land_timer = np.where(quiet, self.land_timer + dt, 0.0)
        self.land_complete = (self.land_complete & self.state.landed) | (quiet & ~self.armed)
        self.land_complete |= quiet & (self.land_timer >= LAND_DETECT_S)

    def _auto_disarm(self, dt: float) -> None:
        """Disarm on touchdown in LAND/RTL, and after DISARM_DELAY landed in any other mode."""
        for i in np.flatnonzero(self.armed & self.land_complete & self._landing()):
            self._disarm(int(i))
        delay = self.params.column("DISARM_DELAY")
        waiting = self.armed & self.land_complete & (delay > 0)
        self.disarm_timer = np.where(waiting, self.disarm_timer + dt, 0.0)
        for i in np.flatnonzero(waiting & (self.disarm_timer >= delay)):
            self._disarm(int(i))

    def _check_gcs_failsafe(self) -> None:
        """FS_GCS_ENABLE: armed, heard SYSID_MYGCS once, silent FS_GCS_TIMEOUT s -> RTL/LAND/BRAKE (or disarm)."""
        enable = self.params.column("FS_GCS_ENABLE")
        silent = (self.t - self.last_gcs_heartbeat) > self.params.column("FS_GCS_TIMEOUT")
        trigger = (
            (enable > 0) & self.armed & np.isfinite(self.last_gcs_heartbeat) & silent & ~self.failsafe_gcs
        )
        for i in np.flatnonzero(trigger):
            i = int(i)
            self.failsafe_gcs[i] = True
            if self.land_complete[i]:
                self.say(i, M.MAV_SEVERITY_CRITICAL, "GCS Failsafe - Disarming")
                self._disarm(i)
                continue
            self.say(i, M.MAV_SEVERITY_CRITICAL, "GCS Failsafe")
            action = GCS_FAILSAFE_ACTIONS[int(enable[i])]
            if self.mode[i] not in (LAND, RTL) or action == LAND:
                self._enter_mode(i, action)

    def _disarm(self, i: int) -> None:
        self.armed[i] = False
        self.takeoff_active[i] = False
        self.disarm_timer[i] = 0.0
        self.say(i, M.MAV_SEVERITY_INFO, "Disarming motors")

    def _set_position_control(self, i: int, kind: int) -> None:
        self.control[i] = CTRL_POS
        self.nav_kind[i] = kind
        self.target_time[i] = self.t

    def _enter_mode(self, i: int, mode: int) -> None:
        """Switch vehicle i to `mode` and initialise its targets (hold where it is, keep its heading)."""
        s = self.state
        pos, vel = s.pos[i], s.vel[i]
        yaw = float(yaw_from_quat(s.quat[i]))
        accel = max(self.params.value(i, "WPNAV_ACCEL") / 100.0, 0.5)
        stop = pos + vel * np.abs(vel) / (2.0 * accel)  # stopping point
        self.mode[i] = mode
        self.takeoff_active[i] = False
        self.nav_vel[i] = 0.0
        self.nav_acc[i] = 0.0
        self.nav_yaw[i] = yaw
        self.nav_yaw_rate[i] = 0.0
        self.target_time[i] = self.t
        self.angle_quat[i] = level_quat(np.array(yaw))
        self.angle_rates[i] = 0.0
        self.angle_rate_ff[i] = False
        self.rates_only[i] = False
        self.climb_rate[i] = 0.0
        self.use_thrust[i] = mode == STABILIZE
        self.angle_timed_out[i] = True
        self.control[i] = CTRL_ANGLE if mode in (ALT_HOLD, STABILIZE, GUIDED_NOGPS) else CTRL_POS
        self.nav_kind[i] = KIND_POS
        self.rtl_stage[i] = RTL_CLIMB
        if mode in (GUIDED, LOITER):
            self.nav_pos[i] = (stop[0], stop[1], pos[2])
        elif mode == BRAKE:
            self.nav_pos[i] = (np.nan, np.nan, pos[2])
        elif mode == RTL:
            rtl_alt = self.home[i, 2] + self.params.value(i, "RTL_ALT") / 100.0
            self.nav_pos[i] = (pos[0], pos[1], max(pos[2], rtl_alt))
        elif mode == LAND:
            self.nav_pos[i] = (stop[0], stop[1], np.nan)
        else:
            self.nav_pos[i] = np.nan
