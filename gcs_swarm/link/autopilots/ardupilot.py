"""What the ground station must know about ArduCopter on the wire, in one place (PX4's is px4.py beside it):
flight modes, telemetry stream groups, parameter names that changed between releases, how to read its
health, and what its guided-attitude thrust means. Each fact cites the ArduPilot source it comes from.

`ARDUPILOT` is the dialect object the link uses (registered in gcs_swarm.link.autopilots under
MAV_AUTOPILOT_ARDUPILOTMEGA, and the fallback for an autopilot with no dialect of its own).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots.failsafe import FailsafeSettings
from gcs_swarm.link.autopilots.thrust import normalised_thrust
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip_to_scalars

ARDUCOPTER_MODES: Mapping[str, int] = MappingProxyType(
    {name: number for number, name in mavutil.mode_mapping_acm.items()}
)
"""ArduCopter flight mode name -> custom_mode number (pymavlink's table)."""

# REQUEST_DATA_STREAM groups of the messages the ground station uses (libraries/GCS_MAVLink/
# GCS_MAVLink_Parameters.cpp STREAM_*_msgs): the fallback for firmware that refuses SET_MESSAGE_INTERVAL.
# EXTENDED_SYS_STATE is in no group: without SET_MESSAGE_INTERVAL it is not streamed.
STREAM_GROUP = {
    "GLOBAL_POSITION_INT": mavlink2.MAV_DATA_STREAM_POSITION,  # STREAM_POSITION: MSG_LOCATION
    "LOCAL_POSITION_NED": mavlink2.MAV_DATA_STREAM_POSITION,
    "ATTITUDE": mavlink2.MAV_DATA_STREAM_EXTRA1,  # STREAM_EXTRA1: MSG_ATTITUDE
    "SYS_STATUS": mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS,  # STREAM_EXTENDED_STATUS
    "GPS_RAW_INT": mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS,
    "EKF_STATUS_REPORT": mavlink2.MAV_DATA_STREAM_EXTRA3,  # STREAM_EXTRA3
    "SYSTEM_TIME": mavlink2.MAV_DATA_STREAM_EXTRA3,
}

# Parameters renamed in ArduCopter 4.7 (ArduCopter/Parameters.cpp conversion table; libraries/GCS_MAVLink/
# GCS.cpp "_SYSID", "_GCS_SYSID", and the per-link stream rates SRn_* that became MAV(n+1)_*). A vehicle
# answers to one spelling only: read whichever it has.
_RENAMED = {"SYSID_THISMAV": "MAV_SYSID", "SYSID_MYGCS": "MAV_GCS_SYSID"}
_STREAM_RATE_OLD = re.compile(r"^SR(\d)_(\w+)$")
_STREAM_RATE_NEW = re.compile(r"^MAV(\d)_(\w+)$")


# EKF_STATUS_REPORT.flags bit names, for a preflight that says what the estimator still lacks.
_EKF_FLAG_NAMES = {
    mavlink2.EKF_ATTITUDE: "attitude",
    mavlink2.EKF_VELOCITY_HORIZ: "horizontal velocity",
    mavlink2.EKF_VELOCITY_VERT: "vertical velocity",
    mavlink2.EKF_POS_HORIZ_REL: "relative horizontal position",
    mavlink2.EKF_POS_HORIZ_ABS: "absolute horizontal position",
    mavlink2.EKF_POS_VERT_ABS: "absolute vertical position",
    mavlink2.EKF_POS_VERT_AGL: "height above ground",
    mavlink2.EKF_CONST_POS_MODE: "constant-position mode (no GPS)",
    mavlink2.EKF_PRED_POS_HORIZ_REL: "predicted relative horizontal position",
    mavlink2.EKF_PRED_POS_HORIZ_ABS: "predicted absolute horizontal position",
    mavlink2.EKF_UNINITIALIZED: "uninitialised",
}


def ekf_flag_names(flags: int) -> list[str]:
    """Names of the EKF_STATUS_REPORT flags set in `flags`, in bit order."""
    return [name for bit, name in sorted(_EKF_FLAG_NAMES.items()) if flags & bit]


FORCE_ARM_MAGIC = 2989  # MAV_CMD_COMPONENT_ARM_DISARM param2 (ArduPilot): arm skipping the pre-arm checks
FORCE_DISARM_MAGIC = 21196  # ... and disarm even in flight

_GPS_FIX_NAMES = {
    0: "no GPS",
    1: "no fix",
    2: "2D fix",
    3: "3D fix",
    4: "DGPS fix",
    5: "RTK float",
    6: "RTK fixed",
}


# FS_GCS_ENABLE values (ArduCopter/events.cpp failsafe_gcs_on_event): 1 RTL, 5 Land, 7 Brake or Land
FS_GCS_ENABLE = {"off": 0, "rtl": 1, "land": 5, "brake": 7}
FENCE_TYPE_POLYGON = 4  # FENCE_TYPE bit 2: inclusion/exclusion circles and polygons (AC_Fence.h)
FENCE_ACTION = {"report": 0, "rtl": 1, "land": 2, "brake": 4}  # Copter FENCE_ACTION values (AC_Fence.cpp)
GUID_OPTIONS_THRUST = 8  # bit 3: SET_ATTITUDE_TARGET thrust is normalised collective thrust (not climb rate)


class ArduPilotDialect:
    """ArduCopter as the link speaks to it (gcs_swarm.link.autopilots.AutopilotDialect)."""

    key = "ardupilot"
    name = "ArduCopter"
    modes = ARDUCOPTER_MODES
    force_arm_param2 = float(FORCE_ARM_MAGIC)
    force_disarm_param2 = float(FORCE_DISARM_MAGIC)
    land_mode = "LAND"
    hold_mode = "BRAKE"
    formation_mode = "GUIDED"  # SET_ATTITUDE_TARGET is flown in GUIDED (mode_guided.cpp angle_control_run)
    launch_mode = "GUIDED"  # NAV_TAKEOFF is accepted in GUIDED (Mode::do_user_takeoff)
    takeoff_mode = "GUIDED"  # and the climb stays in GUIDED
    setpoint_proof_s = 0.0  # GUIDED is accepted without setpoints
    # the failsafe timings a flight sets, and the ranges ArduCopter accepts (their parameters' @Range)
    failsafe_ranges: Mapping[str, tuple[float, float, str]] = MappingProxyType(
        {"gcs_loss_s": (2.0, 120.0, "FS_GCS_TIMEOUT"), "guided_timeout_s": (0.1, 5.0, "GUID_TIMEOUT")}
    )
    hover_param = "MOT_THST_HOVER"
    angle_boost_param: str | None = "ATC_ANGLE_BOOST"
    # how a vehicle that lost its ground station flies (gcs_swarm.guidance.lost_vehicles): parameter and the
    # factor to SI: FS_GCS_TIMEOUT s, WPNAV_SPEED cm/s -> m/s, RTL_ALT cm -> m
    failsafe_params: tuple[tuple[str, float], ...] = (
        ("FS_GCS_TIMEOUT", 1.0),
        ("WPNAV_SPEED", 0.01),
        ("RTL_ALT", 0.01),
    )
    arm_checks_follow_mode = False
    prearm_bit_in_enabled = True  # enabled when arming checks are on (GCS_Common.cpp send_sys_status)
    needs_ekf_report = True
    geofence = True
    typed_params = False  # PARAM_SET must carry the parameter's own MAV_PARAM_TYPE
    unsupported_streams: frozenset[str] = frozenset()

    def set_mode_params(self, number: int) -> tuple[float, float, float]:
        """MAV_CMD_DO_SET_MODE param1..3: CUSTOM_MODE_ENABLED and the custom mode (GCS_Common.cpp
        handle_command_do_set_mode)."""
        return float(mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(number), 0.0

    def decode_param(self, wire_value: float, param_type: int) -> float:
        """ArduPilot sends every parameter as its value in a float (AP_Param: cast, not bytes)."""
        return float(wire_value)

    def encode_param(self, value: float, param_type: int) -> float:
        """ArduPilot takes every PARAM_SET value as a float, whatever its type."""
        return float(value)

    def takeoff_params(self, alt_m: float, ground_amsl_m: float) -> tuple[float, ...]:
        """MAV_CMD_NAV_TAKEOFF param1..7: ArduCopter reads param7 only, metres above home
        (GCS_MAVLink_Copter.cpp handle_MAV_CMD_NAV_TAKEOFF); the vehicle takes off from its home."""
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, float(alt_m))

    def flight_params(self, failsafe: FailsafeSettings) -> list[tuple[str, float]]:
        """Parameters a formation flight sets (restored after it): attitude-target thrust as normalised
        collective, the GCS failsafe and its timeout, and GUID_TIMEOUT (the last attitude target is flown
        this long, then the vehicle levels and holds its altitude)."""
        return [
            ("GUID_OPTIONS", float(GUID_OPTIONS_THRUST)),
            ("FS_GCS_ENABLE", float(FS_GCS_ENABLE[failsafe.action])),
            ("FS_GCS_TIMEOUT", float(failsafe.gcs_loss_s)),
            ("GUID_TIMEOUT", float(failsafe.guided_timeout_s)),
        ]

    def fence_params(self, action: str) -> list[tuple[str, float]]:
        """FENCE_TYPE = 4 exactly (inclusion/exclusion circles and polygons, AC_Fence.h; the max-altitude and
        home-circle fences of the default 7 would stop missions flying far or high), FENCE_ACTION (`action`
        as Copter numbers it, AC_Fence.cpp), FENCE_ENABLE = 1 (AC_Fence::update)."""
        return [
            ("FENCE_TYPE", float(FENCE_TYPE_POLYGON)),
            ("FENCE_ACTION", float(FENCE_ACTION[action])),
            ("FENCE_ENABLE", 1.0),
        ]

    def rally_params(self) -> list[tuple[str, float]]:
        """RALLY_INCL_HOME = 0 and RALLY_LIMIT_KM = 0: RTL returns to the nearest rally point even when home
        is nearer or the point lies beyond the default 0.3 km (libraries/AP_Rally/AP_Rally.cpp
        find_nearest_rally_point, calc_best_rally_or_home_location; Copter's defaults 1 and 0.3). RALLY_TOTAL
        is the rally upload's own (AP_Rally::append)."""
        return [("RALLY_INCL_HOME", 0.0), ("RALLY_LIMIT_KM", 0.0)]

    def is_angle_boost_on(self, value: float) -> bool:
        """ATC_ANGLE_BOOST as read from a vehicle: 0 off, else on (ArduCopter's default is on)."""
        return not (math.isfinite(value) and value == 0.0)

    def thrust(
        self,
        thrust_acc: NDArray[np.float64],
        roll: NDArray[np.float64],
        pitch: NDArray[np.float64],
        hover: NDArray[np.float64],
        boost: NDArray[np.bool_],
        g: float,
    ) -> NDArray[np.float64]:
        """SET_ATTITUDE_TARGET.thrust (K,) that makes K ArduCopters fly the collective accelerations
        thrust_acc (K,) m/s^2, measured at roll, pitch (K,) rad, with MOT_THST_HOVER `hover` (K,) and
        ATC_ANGLE_BOOST on (`boost` (K,) bool); g: gravity m/s^2.

        The guidance's thrust already counts the tilt (spec 5, Eq 36: U_z / (cos phi cos theta) at the
        measured attitude). ArduCopter's guided-attitude thrust goes through set_throttle_out(thrust,
        apply_angle_boost = true) (ArduCopter/mode_guided.cpp angle_control_run), and with ATC_ANGLE_BOOST = 1
        AC_AttitudeControl_Multi::get_throttle_boosted multiplies it by 1 / cos(its own current lean angle)
        (floored at 0.1; an inverted factor only above 84 deg). So for those vehicles the tilt is taken out
        again here, at the measured attitude, and ArduCopter puts it back with its own, fresher attitude: the
        thrust is not counted twice. Then thrust.normalised_thrust (GUID_OPTIONS bit 3)."""
        return _thrust(thrust_acc, roll, pitch, hover, boost, float(g))  # type: ignore[no-any-return]

    def mode_number(self, mode: str | int) -> int:
        """ArduCopter mode name (case-insensitive) or number -> custom_mode number; ValueError if unknown."""
        if isinstance(mode, int | np.integer):
            if int(mode) in mavutil.mode_mapping_acm:
                return int(mode)
        elif mode.strip().upper() in ARDUCOPTER_MODES:
            return ARDUCOPTER_MODES[mode.strip().upper()]
        raise ValueError(f"unknown ArduCopter mode {mode!r} (known: {', '.join(ARDUCOPTER_MODES)})")

    def mode_name(self, number: int) -> str:
        """custom_mode number -> ArduCopter mode name ("MODE_<n>" when unknown, "UNKNOWN" for -1)."""
        return "UNKNOWN" if number < 0 else mavutil.mode_mapping_acm.get(int(number), f"MODE_{number}")

    def other_param_name(self, name: str) -> str | None:
        """The other release's spelling of a renamed parameter (e.g. SYSID_THISMAV <-> MAV_SYSID,
        SR0_EXTRA1 <-> MAV1_EXTRA1), or None."""
        for old, new in _RENAMED.items():
            if name == old:
                return new
            if name == new:
                return old
        if m := _STREAM_RATE_OLD.match(name):
            return f"MAV{int(m.group(1)) + 1}_{m.group(2)}"
        if (m := _STREAM_RATE_NEW.match(name)) and int(m.group(1)) >= 1:
            return f"SR{int(m.group(1)) - 1}_{m.group(2)}"
        return None

    def sysid_param_hint(self) -> str:
        """How to name the sysid parameter to a user who may fly either release."""
        return "MAV_SYSID (SYSID_THISMAV before ArduCopter 4.7)"

    def stream_group(self, message: str) -> int | None:
        """The REQUEST_DATA_STREAM group (MAV_DATA_STREAM) that carries `message`, or None (STREAM_GROUP)."""
        return STREAM_GROUP.get(message)

    def ekf_missing(self, flags: int, required: int, horizontal: int, forbidden: int) -> str:
        """A clause saying why `flags` is not a usable position estimate: what is missing, what is wrong."""
        missing = ekf_flag_names(required & ~flags)
        if not flags & horizontal:
            missing.append("absolute horizontal position")
        wrong = ekf_flag_names(flags & forbidden)
        parts = []
        if missing:
            parts.append("no " + ", ".join(missing))
        if wrong:
            parts.append(", ".join(wrong))
        return "; ".join(parts) or "estimate not usable"

    def gps_fix_name(self, fix_type: int) -> str:
        """GPS_RAW_INT.fix_type as words, e.g. "no fix", "3D fix"."""
        return _GPS_FIX_NAMES.get(fix_type, f"fix type {fix_type}")


ARDUPILOT = ArduPilotDialect()


@kernel
def _thrust(
    thrust_acc: np.ndarray,
    roll: np.ndarray,
    pitch: np.ndarray,
    hover: np.ndarray,
    boost: np.ndarray,
    g: float,
) -> np.ndarray:
    """ArduPilotDialect.thrust, one loop over the K vehicles."""
    out = np.empty(thrust_acc.shape[0])
    for i in range(thrust_acc.shape[0]):
        acc = thrust_acc[i]
        if boost[i]:
            cos_tilt = clip_to_scalars(math.cos(roll[i]) * math.cos(pitch[i]), 0.1, 1.0)
            if not math.isfinite(cos_tilt):
                cos_tilt = 1.0
            acc = acc * cos_tilt
        out[i] = normalised_thrust(acc, hover[i], g)
    return out
