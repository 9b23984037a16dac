"""What the ground station must know about PX4 (multicopter, v1.14 and later) on the wire, in one place:
flight modes and how a mode change is encoded, parameter encoding, the parameters a formation flight sets,
how it takes off and enters OFFBOARD. Each fact cites the PX4 source it comes from (PX4-Autopilot, main).

`PX4` is the dialect object the link uses (registered in gcs_swarm.link.autopilots under
MAV_AUTOPILOT_PX4).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots.ardupilot import ekf_flag_names
from gcs_swarm.link.autopilots.failsafe import FailsafeSettings
from gcs_swarm.link.autopilots.thrust import normalised_thrust
from swarm_common.jit import kernel

# src/modules/commander/px4_custom_mode.h: custom_mode = main_mode << 16 | sub_mode << 24
MAIN_MODE_SHIFT, SUB_MODE_SHIFT = 16, 24

PX4_MODES: Mapping[str, int] = MappingProxyType(
    {
        name: (main << MAIN_MODE_SHIFT) | (sub << SUB_MODE_SHIFT)
        for name, (_base, main, sub) in mavutil.px4_map.items()
    }
)
"""PX4 flight mode name (pymavlink's and MAVProxy's spelling: OFFBOARD, TAKEOFF = AUTO.TAKEOFF, LOITER =
AUTO.LOITER "Hold", LAND = AUTO.LAND, RTL = AUTO.RTL, POSCTL, ...) -> HEARTBEAT.custom_mode."""

_MODE_NAMES = {number: name for name, number in PX4_MODES.items()}

# MAV_CMD_COMPONENT_ARM_DISARM param2 (src/modules/commander/Commander.cpp handle_command: 21196 forces)
FORCE_MAGIC = 21196

# NAV_DLL_ACT (src/modules/commander/commander_params.c, GCS connection loss failsafe): 0 disabled, 1 Hold,
# 2 Return, 3 Land, 5 Terminate, 6 Disarm. COM_OBL_RC_ACT (offboard loss failsafe): 0 Position, 1 Altitude,
# 2 Stabilized, 3 Return, 4 Land, 5 Hold, 6 Terminate, 7 Disarm. The mission's safety.gcs_failsafe -> both.
GCS_LOSS_ACTION = {"off": 0, "brake": 1, "rtl": 2, "land": 3}
OFFBOARD_LOSS_ACTION = {"off": 5, "brake": 5, "rtl": 3, "land": 4}  # "off": Hold (PX4 has no "do nothing")
COM_OF_LOSS_T_RANGE = (0.0, 60.0)  # s (commander_params.c COM_OF_LOSS_T @min 0 @max 60)
COM_DL_LOSS_T_RANGE = (5.0, 300.0)  # s (commander_params.c COM_DL_LOSS_T @min 5 @max 300)

# GF_ACTION (src/modules/navigator/geofence_params.c): 0 None, 1 Warning, 2 Hold mode, 3 Return mode,
# 4 Terminate, 5 Land mode; failsafe.cpp fromGfActParam makes it the geofence_breached failsafe's action.
# The mission's safety.dead_gcs.fence.action -> GF_ACTION: "brake" is Hold (a multicopter in AUTO.LOITER
# stops and holds where it is, as ArduCopter's BRAKE), "report" is Warning (a message, no mode change).
GEOFENCE_ACTION = {"report": 1, "brake": 2, "rtl": 3, "land": 5}

# OFFBOARD is refused until offboard setpoints have streamed for a while (Commander: offboard control mode
# available once `offboard_control_signal_lost` is false; mavlink_receiver publishes offboard_control_mode
# with every SET_ATTITUDE_TARGET / SET_POSITION_TARGET_*; the PX4 offboard docs: stream at > 2 Hz for > 1 s
# before switching). The ground station streams position holds for this long at its frame rate first.
OFFBOARD_PROOF_S = 1.5  # [add] s of vehicle time, with margin over PX4's 1 s


def int32_bits_as_float(value: int) -> float:
    """An int32 parameter value as PX4 puts it in PARAM_VALUE/PARAM_SET.param_value: its 4 bytes read as a
    float32 (src/modules/mavlink/mavlink_parameters.cpp send_param: memcpy). Exact for every int32 whose bits
    are not a signalling NaN (|value| < 2**31 with bits 0x7f800001..0x7fbfffff or 0xff800001..0xffbfffff)."""
    return float(struct.unpack("<f", struct.pack("<i", int(value)))[0])


def float_bits_as_int32(value: float) -> int:
    """Inverse of `int32_bits_as_float`: the int32 whose bytes the float32 `value` carries."""
    return int(struct.unpack("<i", struct.pack("<f", value))[0])


_INT_TYPES = (
    mavlink2.MAV_PARAM_TYPE_INT32,
    mavlink2.MAV_PARAM_TYPE_UINT32,
    mavlink2.MAV_PARAM_TYPE_INT16,
    mavlink2.MAV_PARAM_TYPE_UINT16,
    mavlink2.MAV_PARAM_TYPE_INT8,
    mavlink2.MAV_PARAM_TYPE_UINT8,
)


class PX4Dialect:
    """PX4 as the link speaks to it (gcs_swarm.link.autopilots.AutopilotDialect)."""

    key = "px4"
    name = "PX4"
    modes = PX4_MODES
    force_arm_param2 = float(FORCE_MAGIC)
    force_disarm_param2 = float(FORCE_MAGIC)
    land_mode = "LAND"
    hold_mode = "LOITER"  # AUTO.LOITER, "Hold": brakes and holds position (navigator Loiter)
    formation_mode = "OFFBOARD"  # SET_ATTITUDE_TARGET is flown in OFFBOARD only (mavlink_receiver.cpp)
    launch_mode = "LOITER"  # AUTO.LOITER ("Hold") before arming: arms without RC, holds after a takeoff
    # NAV_TAKEOFF switches to AUTO.TAKEOFF, which switches to AUTO.LOITER at the takeoff altitude (Commander
    # handle_command VEHICLE_CMD_NAV_TAKEOFF; navigator Takeoff::on_active -> loiter)
    takeoff_mode = "TAKEOFF"
    setpoint_proof_s = OFFBOARD_PROOF_S
    # COM_OF_LOSS_T from 0.1 s (PX4 takes 0, a failover at the first late frame); COM_DL_LOSS_T is clamped
    failsafe_ranges: Mapping[str, tuple[float, float, str]] = MappingProxyType(
        {"offboard_loss_s": (0.1, COM_OF_LOSS_T_RANGE[1], "COM_OF_LOSS_T")}
    )
    hover_param = "MPC_THR_HOVER"  # normalised thrust that hovers (mc_pos_control_params.c)
    # offboard thrust is body-z collective, no tilt compensation (mavlink_receiver)
    angle_boost_param: str | None = None
    # how a vehicle that lost its ground station flies (gcs_swarm.guidance.lost_vehicles): the offboard-loss
    # timeout s, the horizontal cruise speed m/s of Return, the Return altitude m (rtl_params.c)
    failsafe_params: tuple[tuple[str, float], ...] = (
        ("COM_OF_LOSS_T", 1.0),
        ("MPC_XY_CRUISE", 1.0),
        ("RTL_RETURN_ALT", 1.0),
    )
    # PREARM_CHECK is set in SYS_STATUS.health alone once the checks pass (HealthAndArmingChecks; seen on PX4
    # SITL: present 0x0300402f, enabled 0x0301402f, health 0x1320c83f)
    # HealthAndArmingChecks judge the selected mode; after "Disarmed by landing" PX4 is back in the last mode
    # it can arm in, OFFBOARD after a formation flight, whose checks fail with no setpoints (seen on PX4 SITL)
    arm_checks_follow_mode = True
    prearm_bit_in_enabled = False
    needs_ekf_report = False  # PX4 sends no EKF_STATUS_REPORT: readiness is SYS_STATUS's pre-arm bit
    geofence = True  # fence items over the mission protocol (mavlink_mission.cpp), acted on by GF_ACTION
    typed_params = True  # PARAM_SET must carry the parameter's own MAV_PARAM_TYPE
    unsupported_streams: frozenset[str] = frozenset({"EKF_STATUS_REPORT"})

    def mode_number(self, mode: str | int) -> int:
        """PX4 mode name (case-insensitive; "AUTO.LOITER" style accepted) or custom_mode -> custom_mode;
        ValueError if unknown."""
        if isinstance(mode, int | np.integer):
            if int(mode) in _MODE_NAMES:
                return int(mode)
        else:
            name = mode.strip().upper().removeprefix("AUTO.")
            if name in PX4_MODES:
                return PX4_MODES[name]
        raise ValueError(f"unknown PX4 mode {mode!r} (known: {', '.join(PX4_MODES)})")

    def mode_name(self, number: int) -> str:
        """custom_mode -> PX4 mode name ("UNKNOWN" for -1, "MODE_0x..." for one PX4 does not define)."""
        if number < 0:
            return "UNKNOWN"
        return _MODE_NAMES.get(int(number), f"MODE_0x{int(number):08x}")

    def set_mode_params(self, number: int) -> tuple[float, float, float]:
        """MAV_CMD_DO_SET_MODE param1..3 for custom_mode `number`: base mode with CUSTOM_MODE_ENABLED, main
        mode, sub mode (src/modules/commander/Commander.cpp handle_command VEHICLE_CMD_DO_SET_MODE)."""
        main = (number >> MAIN_MODE_SHIFT) & 0xFF
        sub = (number >> SUB_MODE_SHIFT) & 0xFF
        return float(mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(main), float(sub)

    def decode_param(self, wire_value: float, param_type: int) -> float:
        """PARAM_VALUE.param_value -> the parameter's value: ints are their bytes (int32_bits_as_float)."""
        if param_type in _INT_TYPES:
            return float(float_bits_as_int32(wire_value))
        return float(wire_value)

    def encode_param(self, value: float, param_type: int) -> float:
        """The param_value of a PARAM_SET of `value` as `param_type`: integers bytewise. PX4 ignores a
        PARAM_SET whose type differs from the parameter's (mavlink_parameters.cpp: "invalid param"), so the
        type must be the one the vehicle reported."""
        if param_type in _INT_TYPES:
            if not float(value).is_integer() or not -(2**31) <= value < 2**31:
                raise ValueError(f"{value!r} is not an int32 value")
            return int32_bits_as_float(int(value))
        return float(value)

    def takeoff_params(self, alt_m: float, ground_amsl_m: float) -> tuple[float, ...]:
        """MAV_CMD_NAV_TAKEOFF param1..7 for a climb to `alt_m` above the ground at `ground_amsl_m` (m AMSL).
        PX4 takes param7 as an altitude AMSL (navigator_main.cpp VEHICLE_CMD_NAV_TAKEOFF: rep->current.alt =
        cmd.param7) and NaN yaw, latitude, longitude as "keep the heading, climb where it stands" (as MAVSDK's
        Action::takeoff sends them)."""
        return (0.0, 0.0, 0.0, math.nan, math.nan, math.nan, float(ground_amsl_m + alt_m))

    def flight_params(self, failsafe: FailsafeSettings) -> list[tuple[str, float]]:
        """Parameters a formation flight sets (restored after it): what a silent ground station triggers.

        PX4 flies the last OFFBOARD attitude setpoint until COM_OF_LOSS_T (`offboard_loss_s`), then takes
        COM_OBL_RC_ACT (with no RC, its default Position mode falls back to Return: failsafe.cpp), so the
        action is set explicitly; the GCS-heartbeat failsafe NAV_DLL_ACT fires after COM_DL_LOSS_T =
        `gcs_loss_s`, clamped to PX4's range."""
        return [
            ("COM_OF_LOSS_T", float(np.clip(failsafe.offboard_loss_s, *COM_OF_LOSS_T_RANGE))),
            ("COM_OBL_RC_ACT", float(OFFBOARD_LOSS_ACTION[failsafe.action])),
            ("NAV_DLL_ACT", float(GCS_LOSS_ACTION[failsafe.action])),
            # an INT32 parameter (commander_params.c): whole seconds, rounded up (the longer wait is safer)
            ("COM_DL_LOSS_T", float(math.ceil(np.clip(failsafe.gcs_loss_s, *COM_DL_LOSS_T_RANGE)))),
        ]

    def fence_params(self, action: str) -> list[tuple[str, float]]:
        """GF_ACTION (GEOFENCE_ACTION[action]). PX4 checks every uploaded inclusion/exclusion zone whenever
        it has them (navigator Geofence::checkAll, isInsidePolygonOrCircle), so no enable or type parameter
        exists; its home-distance and height fences GF_MAX_HOR_DIST / GF_MAX_VER_DIST are 0 (off) by default
        and left as the vehicle has them, as is GF_PREDICT (0 by default: a breach is the crossing itself)."""
        return [("GF_ACTION", float(GEOFENCE_ACTION[action]))]

    def rally_params(self) -> list[tuple[str, float]]:
        """RTL_TYPE = 1: Return goes to the closest rally (safe) point, home only when there is none
        (navigator rtl.cpp findRtlDestination: prioritize_safe_points_over_home; the default 0 takes home
        when it is nearer). PX4 ignores a safe point within 10 m of home (MAX_DIST_FROM_HOME_FOR_LAND_
        APPROACHES)."""
        return [("RTL_TYPE", 1.0)]

    def is_angle_boost_on(self, value: float) -> bool:
        """PX4 has no angle boost on offboard thrust."""
        return False

    def thrust(
        self,
        thrust_acc: NDArray[np.float64],
        roll: NDArray[np.float64],
        pitch: NDArray[np.float64],
        hover: NDArray[np.float64],
        boost: NDArray[np.bool_],
        g: float,
    ) -> NDArray[np.float64]:
        """SET_ATTITUDE_TARGET.thrust (K,) that makes K PX4 vehicles fly the collective accelerations
        thrust_acc (K,) m/s^2 with MPC_THR_HOVER `hover` (K,); g: gravity m/s^2. OFFBOARD flies the thrust as
        given, along body z (mavlink_receiver fill_thrust: thrust_body[2] = -thrust; mc_att_control adds no
        tilt compensation), so the attitude and `boost` do not enter: thrust.normalised_thrust."""
        return _thrust(thrust_acc, hover, float(g))  # type: ignore[no-any-return]

    def other_param_name(self, name: str) -> str | None:
        """PX4 parameters are not renamed between the releases the ground station supports."""
        return None

    def sysid_param_hint(self) -> str:
        """The name of PX4's sysid parameter."""
        return "MAV_SYS_ID"

    def stream_group(self, message: str) -> int | None:
        """PX4 streams by SET_MESSAGE_INTERVAL only (no REQUEST_DATA_STREAM groups)."""
        return None

    def ekf_missing(self, flags: int, required: int, horizontal: int, forbidden: int) -> str:
        """Not used for PX4 (no EKF_STATUS_REPORT); kept so the protocol holds: the flags named."""
        return ", ".join(ekf_flag_names(flags)) or "estimate not usable"

    def gps_fix_name(self, fix_type: int) -> str:
        """GPS_RAW_INT.fix_type as words (GPS_FIX_TYPE)."""
        entry = mavlink2.enums["GPS_FIX_TYPE"].get(fix_type)
        return (
            entry.name.removeprefix("GPS_FIX_TYPE_").replace("_", " ").lower() if entry else f"fix {fix_type}"
        )


@kernel
def _thrust(thrust_acc: np.ndarray, hover: np.ndarray, g: float) -> np.ndarray:
    """PX4Dialect.thrust, one loop over the K vehicles."""
    out = np.empty(thrust_acc.shape[0])
    for i in range(thrust_acc.shape[0]):
        out[i] = normalised_thrust(thrust_acc[i], hover[i], g)
    return out


PX4 = PX4Dialect()

__all__ = ["PX4", "PX4Dialect", "float_bits_as_int32", "int32_bits_as_float"]
