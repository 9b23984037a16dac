"""The shared autopilot of N vehicles: ArduCopter-numbered modes and their control laws, arming, guided
targets, takeoff, land detector, geofences; what differs per autopilot is asked of each vehicle's persona
(sitl_sim.autopilot.persona: HEARTBEAT, pre-arm verdict, rules around each tick, descent profile).

`update` runs once per outer tick: the personas' rules, then one compiled loop over all vehicles
(sitl_sim.autopilot.outer_loop) that hands attitude/thrust targets to the physics (FleetDynamics, whose
attitude controller runs at the physics rate) and flags the rare events (disarm, failsafe) the personas then
handle.
Discrete inputs (a command, a mode change, a crash) are per-vehicle methods. Every mode reduces to one of two
control laws:
- position/velocity control (GUIDED position/velocity targets, LOITER, BRAKE, RTL, LAND): position_control;
- angle control (GUIDED attitude targets, GUIDED_NOGPS, ALT_HOLD, STABILIZE): an attitude target plus a climb
  rate (vertical velocity loop) or a direct collective.
State is world ENU, body FLU, SI units; MAVLink conversions happen in the endpoint.
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot import fence as fences
from sitl_sim.autopilot.health import (
    EKF_BOOTING,
    EKF_GOOD,
    EKF_NO_GPS,
    SENSOR_XY,
    SENSOR_Z,
    SENSORS_ALWAYS,
    SENSORS_PRESENT,
)
from sitl_sim.autopilot.modes import (
    ALT_HOLD,
    BRAKE,
    GUID_OPTION_THRUST,
    GUIDED,
    GUIDED_NOGPS,
    LAND,
    LOITER,
    MODE_NAMES,
    NOT_ARMABLE,
    POSITION_MODES,
    RTL,
    STABILIZE,
)
from sitl_sim.autopilot.outer_loop import (
    CTRL_ANGLE,
    CTRL_POS,
    DESCENT_INTERPOLATED,
    KIND_ACCEL,
    KIND_BRAKE,
    KIND_POS,
    KIND_POSVEL,
    KIND_VEL,
    LOOP_PARAMS,
    RTL_CLIMB,
    RTL_DESCEND,
    AngleTargets,
    Descent,
    Modes,
    Navigation,
    Outputs,
    Vehicles,
    outer_loop,
)
from sitl_sim.autopilot.params import ParamTable
from sitl_sim.autopilot.persona import Persona
from sitl_sim.autopilot.rally import RallyItem, RallyPoints
from sitl_sim.autopilot.registry import fleet_personas
from sitl_sim.vehicle_model.attitude_control import level_quat, yaw_from_quat
from sitl_sim.vehicle_model.dynamics import FleetDynamics

GPS_FIX_S = 10.0  # simulated s from boot to the GPS 3D fix (real SITL: 10 s), at most half the ready delay


class Autopilot:
    """Flight software of N vehicles over one FleetDynamics; arrays (N,) or (N,k), world ENU, SI units.

    origin (N,3): each vehicle's EKF origin (its start point); home (N,3): its start point on the ground.
    airborne (N,) bool: vehicles that start flying (armed, GUIDED, holding start_vel (N,3) until
    GUID_TIMEOUT).
    ready_delay: simulated seconds until a vehicle on the ground has a position estimate, one for all or (N,)
    one per vehicle. personas: each vehicle's persona class (default ArduCopter for all).
    """

    def __init__(
        self,
        dyn: FleetDynamics,
        params: ParamTable,
        origin: np.ndarray,
        home: np.ndarray,
        airborne: np.ndarray,
        start_vel: np.ndarray,
        ready_delay: float | np.ndarray,
        personas: tuple[type[Persona], ...] = (),
    ) -> None:
        n = dyn.n
        self.n = n
        self.dyn = dyn
        self.state = dyn.state
        self.params = params
        self.origin = np.array(origin, dtype=float)
        self.home = np.array(home, dtype=float)
        self.t = 0.0
        delay = np.asarray(ready_delay, dtype=float)
        self.ready_at = np.where(airborne, 0.0, delay)
        self.boot_end = np.where(airborne, 0.0, np.minimum(1.0, 0.5 * delay))
        # the GPS has its 3D fix well before the EKF uses it (real ArduCopter SITL: a few seconds vs 20-40 s)
        self.gps_fix_at = np.where(airborne, 0.0, np.minimum(GPS_FIX_S, 0.5 * delay))
        self.ready = self.ready_at <= 0.0
        self.prearm_said = np.zeros(n)  # simulated s of the last periodic "PreArm:" report (first at 30 s)
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
        # upward velocity limit (m/s) on top of the position controller's own, +inf = none: a persona's own
        # climb rules (Persona.before_loop)
        self.climb_cap = np.full(n, np.inf)
        self.texts: list[list[tuple[int, str]]] = [[] for _ in range(n)]
        self.fence = fences.Fences(n)  # geofences and their breach state (sitl_sim.autopilot.fence)
        self.rally = RallyPoints(n)  # rally points (sitl_sim.autopilot.rally)
        self.rtl_dest = self.home.copy()  # (N,3) ENU m where RTL returns: set as RTL starts (enter_mode)
        self.fence_log: list[str] = []  # breaches and their actions, for the simulator's log (stderr)
        self._rate_control = False  # some vehicle was under rate-only control at the last tick
        self._columns = np.array([params.column_index(name) for name in LOOP_PARAMS], dtype=np.int64)
        kinds = personas or fleet_personas((), n)
        descent_columns = np.zeros((n, 8), dtype=np.int64)
        for row, kind in enumerate(kinds):
            if kind.descent_profile == DESCENT_INTERPOLATED:
                descent_columns[row] = [params.column_index(name) for name in kind.descent_params]
        s = self.state
        self._vehicles = Vehicles(s.pos, s.vel, s.quat, s.landed, s.crashed, self.home, self.rtl_dest)
        self._modes = Modes(
            self.mode, self.armed, self.control, self.rtl_stage, self.takeoff_active, self.land_complete,
            self.land_timer, self.disarm_timer, self.target_time, self.last_gcs_heartbeat, self.failsafe_gcs,
        )  # fmt: skip
        self._navigation = Navigation(
            self.nav_kind, self.nav_pos, self.nav_vel, self.nav_acc, self.nav_yaw, self.nav_yaw_rate,
            self.climb_cap, self.integrator,
        )  # fmt: skip
        self._angle = AngleTargets(
            self.angle_quat, self.angle_rates, self.angle_rate_ff, self.rates_only, self.climb_rate,
            self.collective, self.use_thrust, self.angle_timed_out,
        )  # fmt: skip
        self._descent = Descent(
            np.array([kind.descent_profile for kind in kinds], dtype=np.int64),
            descent_columns,
            np.array([kind.descent_accel_down for kind in kinds], dtype=float),
            np.array([kind.descent_range_max for kind in kinds], dtype=float),
        )
        self._outputs = Outputs(
            np.zeros((n, 4)), np.zeros((n, 3)), self.thrust_demand, np.zeros(n, dtype=bool), np.zeros(n),
            np.zeros(n, dtype=bool), np.zeros(n, dtype=np.int64),
        )  # fmt: skip
        for i in np.flatnonzero(~self.armed):
            self.enter_mode(int(i), STABILIZE)
        # one instance of each persona over its vehicles (after the state above: a persona may set modes)
        rows = {kind: np.array([k is kind for k in kinds], dtype=bool) for kind in dict.fromkeys(kinds)}
        self.personas = [kind(self, mask) for kind, mask in rows.items()]
        self._persona_of = [next(p for p in self.personas if isinstance(p, kind)) for kind in kinds]

    def persona(self, i: int) -> Persona:
        """Vehicle i's persona (the instance holding its persona's rules and state)."""
        return self._persona_of[i]

    def climb_to(self, i: int, z: float) -> None:
        """Take off vertically to world height z (m) under position control (the shared takeoff law)."""
        pos = self.state.pos[i]
        self._set_position_control(i, KIND_POS)
        self.nav_pos[i] = (pos[0], pos[1], z)
        self.takeoff_active[i] = True
        self.land_complete[i] = False
        self.land_timer[i] = 0.0

    # --- status as MAVLink reports it -----------------------------------------------------------------------

    def gps_fix(self, i: int) -> bool:
        """The GPS reports a 3D fix (GPS_RAW_INT), which comes before the EKF's position."""
        return bool(self.t >= self.gps_fix_at[i])

    def position_ok(self, i: int) -> bool:
        """The EKF has a position (origin, home and GPS fix are set)."""
        return bool(self.ready[i])

    def fence_prearm(self, i: int) -> str | None:
        """Why the fence forbids arming vehicle i (AC_Fence::pre_arm_check, which AP_Arming::fence_checks
        reports as "PreArm: ..."), or None."""
        p = self.params
        enable = p.value(i, "FENCE_ENABLE")
        if not enable and not self.fence.enabled_mask[i]:
            return None
        return self.fence.pre_arm_failure(
            i,
            enable,
            int(p.value(i, "FENCE_TYPE")),
            bool(self.ready[i]),
            p.value(i, "FENCE_MARGIN"),
            p.value(i, "FENCE_ALT_MAX"),
            p.value(i, "FENCE_RADIUS"),
        )

    def sensor_bits(self, i: int) -> tuple[int, int, int]:
        """SYS_STATUS (present, enabled, health) bit masks."""
        enabled = SENSORS_PRESENT & ~mavlink2.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS & ~SENSOR_XY & ~SENSOR_Z
        mode = self.mode[i]
        if mode in (*POSITION_MODES, LAND):
            enabled |= SENSOR_XY | SENSOR_Z
        elif mode in (ALT_HOLD, GUIDED_NOGPS):
            enabled |= SENSOR_Z
        if self.armed[i]:
            enabled |= mavlink2.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        health = SENSORS_ALWAYS | SENSOR_XY | SENSOR_Z
        if not self.state.crashed[i]:
            health |= mavlink2.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        if self.t >= self.boot_end[i]:
            health |= mavlink2.MAV_SYS_STATUS_AHRS
        if self.ready[i]:
            health |= mavlink2.MAV_SYS_STATUS_SENSOR_GPS
        if self.persona(i).prearm_ok(i):
            health |= mavlink2.MAV_SYS_STATUS_PREARM_CHECK
        present = SENSORS_PRESENT
        # AC_Fence::sys_status_present/_enabled/_failed: the geofence bit
        configured = int(self.params.value(i, "FENCE_TYPE"))
        if self.fence.present_one(i, configured):
            present |= mavlink2.MAV_SYS_STATUS_GEOFENCE
            if self.fence.enabled_mask[i] and self.params.value(i, "FENCE_ACTION") != fences.REPORT_ONLY:
                enabled |= mavlink2.MAV_SYS_STATUS_GEOFENCE
            if not self.fence.breaches[i]:
                health |= mavlink2.MAV_SYS_STATUS_GEOFENCE
        return present, enabled, health

    def ekf_flags(self, i: int) -> int:
        """EKF_STATUS_REPORT flags: uninitialised, then attitude/height only, then full position."""
        if self.ready[i]:
            return EKF_GOOD
        return EKF_BOOTING if self.t < self.boot_end[i] else EKF_NO_GPS

    def landed_state(self, i: int) -> int:
        """EXTENDED_SYS_STATE landed_state (ArduCopter's GCS_MAVLINK_Copter::landed_state)."""
        if self.land_complete[i]:
            return mavlink2.MAV_LANDED_STATE_ON_GROUND
        if self.mode[i] == LAND or (self.mode[i] == RTL and self.rtl_stage[i] == RTL_DESCEND):  # descending
            return mavlink2.MAV_LANDED_STATE_LANDING
        if self.takeoff_active[i]:
            return mavlink2.MAV_LANDED_STATE_TAKEOFF
        return mavlink2.MAV_LANDED_STATE_IN_AIR

    def say(self, i: int, severity: int, text: str) -> None:
        """Queue a STATUSTEXT of vehicle i."""
        self.texts[i].append((severity, text))

    # --- discrete events ------------------------------------------------------------------------------------

    def arm(self, i: int, force: bool) -> int:
        """MAV_CMD_COMPONENT_ARM_DISARM param1=1; returns the MAV_RESULT. Refusals say why (STATUSTEXT)."""
        if self.armed[i]:
            return mavlink2.MAV_RESULT_ACCEPTED
        if self.state.crashed[i]:
            self.say(i, mavlink2.MAV_SEVERITY_CRITICAL, "PreArm: Vehicle crashed")
            return mavlink2.MAV_RESULT_FAILED
        if not force:
            if not self.ready[i]:
                self.say(i, mavlink2.MAV_SEVERITY_CRITICAL, "PreArm: Need Position Estimate")
                # AP_Arming_Copter::gps_checks: a circle or polygon fence needs a position in any mode
                configured = int(self.params.value(i, "FENCE_TYPE"))
                enabled = self.fence.enabled_mask[i] & self.fence.present_one(i, configured)
                if enabled & (fences.CIRCLE | fences.POLYGON):
                    self.say(
                        i, mavlink2.MAV_SEVERITY_CRITICAL, "PreArm: Fence enabled, need position estimate"
                    )
                return mavlink2.MAV_RESULT_FAILED
            if self.mode[i] in NOT_ARMABLE:
                self.say(i, mavlink2.MAV_SEVERITY_CRITICAL, "Arm: Mode not armable")
                return mavlink2.MAV_RESULT_FAILED
            fence_problem = self.fence_prearm(i)
            if fence_problem is not None:
                self.say(i, mavlink2.MAV_SEVERITY_CRITICAL, f"PreArm: {fence_problem}")
                return mavlink2.MAV_RESULT_FAILED
        self.armed[i] = True
        self.disarm_timer[i] = 0.0
        self.enter_mode(i, int(self.mode[i]))
        self.say(i, mavlink2.MAV_SEVERITY_INFO, "Arming motors")
        return mavlink2.MAV_RESULT_ACCEPTED

    def disarm(self, i: int, force: bool) -> int:
        """param1=0: refused in flight unless forced (ArduCopter disarm checks); returns the MAV_RESULT."""
        if not self.armed[i]:
            return mavlink2.MAV_RESULT_ACCEPTED
        if not force and not self.land_complete[i]:
            self.say(i, mavlink2.MAV_SEVERITY_WARNING, "Disarm: vehicle is flying")
            return mavlink2.MAV_RESULT_FAILED
        self.disarm_motors(i)
        return mavlink2.MAV_RESULT_ACCEPTED

    def set_mode(self, i: int, mode: int) -> int:
        """Change flight mode (SET_MODE / MAV_CMD_DO_SET_MODE); returns the MAV_RESULT."""
        if mode not in MODE_NAMES:
            self.say(i, mavlink2.MAV_SEVERITY_WARNING, f"Mode change failed: mode {mode} not supported")
            return mavlink2.MAV_RESULT_FAILED
        if mode == self.mode[i]:
            return mavlink2.MAV_RESULT_ACCEPTED
        if self.armed[i] and mode in POSITION_MODES and not self.position_ok(i):
            self.say(
                i,
                mavlink2.MAV_SEVERITY_WARNING,
                f"Mode change to {MODE_NAMES[mode]} failed: requires position",
            )
            return mavlink2.MAV_RESULT_FAILED
        self.enter_mode(i, mode)
        self.mode_changed(i)
        return mavlink2.MAV_RESULT_ACCEPTED

    def mode_changed(self, i: int) -> None:
        """ArduCopter mode.cpp set_mode: any mode change while breached (the fence's own action too) starts
        the fence's manual recovery, 10 s in which new breaches are not acted on."""
        if self.params.value(i, "FENCE_ACTION") != fences.REPORT_ONLY and self.fence.manual_recovery_start(
            i, self.t
        ):
            self.say(i, mavlink2.MAV_SEVERITY_INFO, "Manual recovery started")

    def takeoff(self, i: int, altitude: float) -> int:
        """MAV_CMD_NAV_TAKEOFF in GUIDED to altitude m above home; returns the MAV_RESULT."""
        if self.mode[i] != GUIDED or not self.armed[i] or not self.land_complete[i]:
            return mavlink2.MAV_RESULT_FAILED
        if not (math.isfinite(altitude) and self.state.pos[i, 2] - self.home[i, 2] < altitude <= 10000.0):
            return mavlink2.MAV_RESULT_FAILED
        self.climb_to(i, self.home[i, 2] + altitude)
        return mavlink2.MAV_RESULT_ACCEPTED

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
        if (
            pos is not None
            and self.persona(i).guided_fence_check
            and not self.fence.destination_ok(
                i,
                pos[:2],
                self.home[i, :2],
                float(pos[2] - self.home[i, 2]),
                self.params.value(i, "FENCE_ALT_MAX"),
                self.params.value(i, "FENCE_RADIUS"),
            )
        ):
            return False  # ModeGuided::set_destination: a destination outside the fence is refused
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
        self,
        i: int,
        quat: tuple[float, float, float, float] | None,
        rates: tuple[float, float, float] | None,
        thrust: float,
    ) -> bool:
        """GUIDED/GUIDED_NOGPS attitude target: quat (4,) FLU->ENU or None (rates only), rates (3,) FLU
        rad/s or None, thrust 0..1 (a climb-rate demand, 0.5 = hold, unless GUID_OPTIONS bit 3); False if
        ignored.
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
        self.enter_mode(i, int(self.mode[i]))

    def gcs_heartbeat(self, i: int, sysid: int) -> None:
        """A HEARTBEAT from `sysid` reached vehicle i: refreshes the GCS failsafe if it is MAV_GCS_SYSID."""
        if sysid != int(self.params.value(i, "MAV_GCS_SYSID")):
            return
        self.last_gcs_heartbeat[i] = self.t
        if self.failsafe_gcs[i]:
            self.failsafe_gcs[i] = False
            self.say(i, mavlink2.MAV_SEVERITY_WARNING, "GCS Failsafe Cleared")

    def crash(self, i: int, reason: str) -> None:
        """Mark vehicle i crashed: motors stop for good, STATUSTEXT with the reason."""
        if self.state.crashed[i]:
            return
        self.state.crashed[i] = True
        self.armed[i] = False
        self.takeoff_active[i] = False
        self.say(i, mavlink2.MAV_SEVERITY_EMERGENCY, f"Crash: {reason}"[:50])

    # --- the outer loop -------------------------------------------------------------------------------------

    def update(self, t: float, dt: float) -> None:
        """One outer tick at simulated time t (s) covering dt (s): modes, control, targets to the physics."""
        self.t = t
        self.ready = t >= self.ready_at
        for persona in self.personas:
            persona.before_loop(t, dt)
        outer_loop(
            t, dt, self.dyn.params.g, self.params.values, self._columns,
            self._vehicles, self._modes, self._navigation, self._angle, self._descent, self._outputs,
        )  # fmt: skip
        out = self._outputs
        thrust = self.thrust_demand * self.dyn.params.thrust_max
        self.dyn.set_targets(out.quat_sp, out.rate_ff, thrust, out.motors_on, out.tilt_max)
        if out.rate_mask.any() or self._rate_control:  # rate-only control started, continues or ends
            self.dyn.set_rate_targets(out.rate_mask, self.angle_rates)
            self._rate_control = bool(out.rate_mask.any())
        for persona in self.personas:
            persona.after_loop(t, out.events)
        if t - self.fence.last_check >= fences.CHECK_PERIOD_S - 1e-9:
            self._fence_check(t)

    def _fence_check(self, t: float) -> None:
        """ArduCopter/fence.cpp at 25 Hz: AC_Fence::check for every vehicle (sitl_sim.autopilot.fence), then
        each armed vehicle with a new breach says "<fences> breached" and acts as FENCE_ACTION says: 0 report
        only, 1 RTL (else LAND), 2 LAND, 3 SmartRTL (not simulated: RTL) else LAND, 4 BRAKE else LAND,
        5 SmartRTL (RTL here) else LAND; landed it disarms, more than 100 m outside it lands."""
        p, fence, s = self.params, self.fence, self.state
        for k in fence.legacy_clears(p.column("FENCE_TOTAL")):
            if self.persona(k).legacy_fence_total:
                fence.store(k, [], np.zeros((0, 2)))
        if not fence.active(p.column("FENCE_ENABLE")):  # AC_Fence::check returns at once when disabled
            fence.last_check = t
            return
        before = fence.breaches.copy()
        fence.update_enable(p.column("FENCE_ENABLE"), p.column("FENCE_TYPE"))
        new = fence.check(
            t,
            s.pos,
            self.home,
            self.ready,
            p.column("FENCE_TYPE"),
            p.column("FENCE_ALT_MAX"),
            p.column("FENCE_RADIUS"),
        )
        cleared = (new == 0) & (before != 0) & (fence.breaches == 0) & ~self.land_complete
        for i in np.flatnonzero(cleared):
            self.persona(int(i)).fence_cleared(int(i))
            self.fence_log.append(f"vehicle {i}: fence breach cleared at t={t:.2f} s")
        for i in np.flatnonzero((new != 0) & self.armed):
            self.persona(int(i)).fence_breached(int(i), int(new[i]), t)

    def store_rally(self, i: int, items: list[RallyItem], xy: np.ndarray) -> None:
        """Vehicle i's uploaded rally points, xy (K,2) their ENU horizontal positions m (each alt_m above
        home); RALLY_TOTAL follows (AP_Rally::append: _rally_point_total_count.set_and_save)."""
        z = self.home[i, 2] + np.array([item.alt_m for item in items], dtype=float)
        self.rally.store(i, items, np.column_stack([np.asarray(xy, dtype=float).reshape(-1, 2), z]))
        self.params.set(i, "RALLY_TOTAL", len(items))

    def fence_action(self, i: int, new: int, t: float) -> None:
        """ArduCopter/fence.cpp: vehicle i has newly breached the fences `new` (FENCE_TYPE bits) at simulated
        time t: "<fences> breached", then FENCE_ACTION (see _fence_check); logged for the simulator."""
        names = fences.fence_names(new)
        if not self.land_complete[i]:
            self.say(i, mavlink2.MAV_SEVERITY_NOTICE, f"{names} breached")
        action = int(self.params.value(i, "FENCE_ACTION"))
        if action != fences.REPORT_ONLY:
            if self.land_complete[i]:
                self.disarm_motors(i)
            elif self.fence.breach_distance(i, new) > fences.GIVE_UP_DISTANCE_M:
                self.set_mode(i, LAND)
            else:
                first = {fences.ALWAYS_LAND: LAND, fences.BRAKE_OR_LAND: BRAKE}.get(action, RTL)
                if self.set_mode(i, first) != mavlink2.MAV_RESULT_ACCEPTED:
                    self.set_mode(i, LAND)
        x, y, z = self.state.pos[i]
        self.fence_log.append(
            f"vehicle {i}: {names} breached at t={t:.2f} s at ({x:.1f}, {y:.1f}, {z:.1f}) m: "
            f"FENCE_ACTION {action}, mode {MODE_NAMES.get(int(self.mode[i]), self.mode[i])}"
            + (", disarmed" if not self.armed[i] else "")
        )

    # --- internals ------------------------------------------------------------------------------------------

    def disarm_motors(self, i: int) -> None:
        """Vehicle i disarms now (motors stop), saying so."""
        self.armed[i] = False
        self.takeoff_active[i] = False
        self.disarm_timer[i] = 0.0
        self.say(i, mavlink2.MAV_SEVERITY_INFO, "Disarming motors")

    def _set_position_control(self, i: int, kind: int) -> None:
        self.control[i] = CTRL_POS
        self.nav_kind[i] = kind
        self.target_time[i] = self.t

    def enter_mode(self, i: int, mode: int) -> None:
        """Switch vehicle i to internal (ArduCopter-numbered) `mode` and initialise its shared control law's
        targets from its state (hold where it is, keep its heading)."""
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
        elif mode == BRAKE:  # ModeBrake::init: the shaped stop starts from the vehicle's own velocity
            self.nav_pos[i] = pos
            self.nav_vel[i] = (vel[0], vel[1], 0.0)
            self.nav_kind[i] = KIND_BRAKE
        elif mode == RTL:
            self.rtl_dest[i] = self.persona(i).rtl_destination(i)
            rtl_alt = self.home[i, 2] + self.params.value(i, "RTL_ALT") / 100.0
            self.nav_pos[i] = (pos[0], pos[1], max(pos[2], rtl_alt))
        elif mode == LAND:  # ModeLand::init: loiter_nav's stop (shaped like BRAKE's, LOIT_BRK_*), descending
            self.nav_pos[i] = (pos[0], pos[1], np.nan)
            self.nav_vel[i] = (vel[0], vel[1], 0.0)
            self.nav_kind[i] = KIND_BRAKE
        else:
            self.nav_pos[i] = np.nan
