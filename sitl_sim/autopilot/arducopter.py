"""The ArduCopter 4.7 persona: its defaults (ready delay, telemetry rates), HEARTBEAT, pre-arm verdict, the
unprompted "PreArm:" reports and its answers to the shared loop's events (disarm on touchdown or after
DISARM_DELAY, the GCS failsafe). Its modes, arming, guided targets, takeoff and landing are the shared
autopilot's own (sitl_sim.autopilot.copter.Autopilot, ArduCopter-numbered modes of sitl_sim.autopilot.modes),
its parameters the shared table (sitl_sim.autopilot.params), its MAVLink surface sitl_sim.network.commands
and .setpoints.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.modes import GCS_FAILSAFE_ACTIONS, GUIDED_ENABLED_MODES, LAND, RTL
from sitl_sim.autopilot.outer_loop import EVENT_DISARM
from sitl_sim.autopilot.persona import Persona

M = mavlink2
PREARM_DISPLAY_PERIOD_S = 30.0  # AP_Arming.cpp PREARM_DISPLAY_PERIOD: unprompted pre-arm failure reports
# Default rates (Hz). A fresh ArduCopter streams nothing on a link until a ground station asks: its per-link
# rates MAVn_* (SRn_* before 4.7) default to 0 in SITL (seen on a V4.7.0-dev SITL build: HEARTBEAT and a
# TIMESYNC only, until REQUEST_DATA_STREAM or SET_MESSAGE_INTERVAL). HEARTBEAT goes out at 1 Hz regardless.
# 0 = only on request (SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM, REQUEST_MESSAGE) or on change. These are
# also every stream the simulator sends, in its order (sitl_sim.network.streams.STREAM_IDS).
DEFAULT_RATES_HZ: dict[int, float] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 0.0,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 0.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 0.0,
    M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 0.0,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 0.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 0.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 0.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 0.0,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: 0.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.0,
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: 0.0,
    M.MAVLINK_MSG_ID_FENCE_STATUS: 0.0,
}


class ArduCopter(Persona):
    """ArduCopter's rules for its vehicles `rows` of the shared autopilot `ap`."""

    name: ClassVar[str] = "ardupilot"
    # `sitl-sim --ready-delay` not given: a real ArduCopter 4.7 SITL's EKF uses GPS 42 s after boot
    ready_delay_s: ClassVar[float] = 40.0
    default_rates_hz = DEFAULT_RATES_HZ
    reports_ekf_status: ClassVar[bool] = True
    legacy_fence_total: ClassVar[bool] = True  # SITL builds keep AC_POLYFENCE_FENCE_POINT_PROTOCOL_SUPPORT
    guided_fence_check: ClassVar[bool] = True

    def heartbeat(self, i: int) -> tuple[int, int, int, int]:
        """ArduCopter's HEARTBEAT: base_mode as GCS_MAVLINK_Copter::base_mode computes it, custom_mode the
        mode number; system_status BOOT, STANDBY, ACTIVE armed, CRITICAL in failsafe, EMERGENCY crashed."""
        ap = self.ap
        bits = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        bits |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        if ap.mode[i] in GUIDED_ENABLED_MODES:
            bits |= M.MAV_MODE_FLAG_GUIDED_ENABLED
        if ap.armed[i]:
            bits |= M.MAV_MODE_FLAG_SAFETY_ARMED
        status = self.system_status(i, bool(ap.failsafe_gcs[i]))
        return M.MAV_AUTOPILOT_ARDUPILOTMEGA, bits, int(ap.mode[i]), status

    def prearm_ok(self, i: int) -> bool:
        """The pre-arm checks pass: a position estimate, not crashed, the fence's checks."""
        ap = self.ap
        return bool(ap.ready[i] and not ap.state.crashed[i] and ap.fence_prearm(i) is None)

    def before_loop(self, t: float, dt: float) -> None:
        """AP_Arming::update: a vehicle that cannot arm says why by itself, "PreArm: Need Position Estimate",
        every PREARM_DISPLAY_PERIOD_S (simulated s) while disarmed, booted and without a position estimate."""
        ap = self.ap
        if (ap.ready | ~self.rows).all():
            return
        due = self.rows & ~ap.ready & ~ap.armed & (t - ap.prearm_said >= PREARM_DISPLAY_PERIOD_S)
        for i in np.flatnonzero(due & (t >= ap.boot_end)):
            ap.say(int(i), M.MAV_SEVERITY_CRITICAL, "PreArm: Need Position Estimate")
            ap.prearm_said[i] = t

    def after_loop(self, t: float, events: np.ndarray) -> None:
        """The loop's events: disarm (touchdown in LAND/RTL, DISARM_DELAY landed) or the GCS failsafe, which
        acts as FS_GCS_ENABLE says (disarms a landed vehicle)."""
        ap = self.ap
        for i in np.flatnonzero((events != 0) & self.rows).tolist():
            if events[i] == EVENT_DISARM:
                ap.disarm_motors(i)
                continue
            ap.failsafe_gcs[i] = True  # EVENT_GCS_FAILSAFE
            if ap.land_complete[i]:
                ap.say(i, M.MAV_SEVERITY_CRITICAL, "GCS Failsafe - Disarming")
                ap.disarm_motors(i)
                continue
            ap.say(i, M.MAV_SEVERITY_CRITICAL, "GCS Failsafe")
            action = GCS_FAILSAFE_ACTIONS[int(ap.params.value(i, "FS_GCS_ENABLE"))]
            if ap.mode[i] not in (LAND, RTL) or action == LAND:
                changed = action != ap.mode[i]
                ap.enter_mode(i, action)
                if changed:
                    ap.mode_changed(i)

    def fence_breached(self, i: int, new: int, t: float) -> None:
        """ArduCopter/fence.cpp: "<fences> breached" and FENCE_ACTION (copter.Autopilot.fence_action)."""
        self.ap.fence_action(i, new, t)

    def fence_cleared(self, i: int) -> None:
        """ArduCopter/fence.cpp fence_check: "Fence breach cleared"."""
        self.ap.say(i, M.MAV_SEVERITY_NOTICE, "Fence breach cleared")

    def rtl_destination(self, i: int) -> np.ndarray:
        """AP_Rally::calc_best_rally_or_home_location: the nearest rally point within RALLY_LIMIT_KM, unless
        RALLY_INCL_HOME and home is nearer (sitl_sim.autopilot.rally)."""
        ap = self.ap
        return ap.rally.arducopter_destination(
            i,
            ap.state.pos[i],
            ap.home[i],
            ap.params.value(i, "RALLY_LIMIT_KM"),
            bool(ap.params.value(i, "RALLY_INCL_HOME")),
        )
