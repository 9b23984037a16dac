"""Autopilot dialects: what differs between autopilots on the wire, behind one interface and a registry.

The link picks a vehicle's dialect from its first HEARTBEAT (`HEARTBEAT.autopilot`, MAV_AUTOPILOT) with
`dialect_for` (ArduPilot or PX4), unless the mission names the vehicle's autopilot (`vehicles[i].autopilot`,
`dialect_named`); until then, and for an autopilot with no dialect of its own, it speaks ArduPilot. Nothing
outside gcs_swarm.link.autopilots names an autopilot's modes or parameters: the flight layer asks the
vehicle's dialect (its formation mode, the parameters a flight sets, how it takes off).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from operator import attrgetter
from typing import Protocol

import numpy as np
from numpy.typing import NDArray
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots.ardupilot import ARDUPILOT
from gcs_swarm.link.autopilots.failsafe import FailsafeSettings
from gcs_swarm.link.autopilots.px4 import PX4


class AutopilotDialect(Protocol):
    """The autopilot-specific facts the link needs (modes, parameter spellings, stream groups, health)."""

    key: str  # "ardupilot" | "px4": the mission's `vehicles[i].autopilot` spelling
    name: str  # for people: "ArduCopter", "PX4"
    modes: Mapping[str, int]  # flight mode name -> HEARTBEAT.custom_mode number
    force_arm_param2: float  # MAV_CMD_COMPONENT_ARM_DISARM param2 that arms skipping the pre-arm checks
    force_disarm_param2: float  # ... that disarms even in flight
    land_mode: str  # the mode that lands the vehicle where it is
    hold_mode: str  # the mode that stops the vehicle and holds where it is, with no ground station
    formation_mode: str  # the mode in which it flies SET_ATTITUDE_TARGET (and position targets)
    launch_mode: str  # the mode to arm and take off in
    takeoff_mode: str  # the mode NAV_TAKEOFF puts the vehicle in by itself (launch_mode if none)
    # s of vehicle time a setpoint stream must already flow before formation_mode is accepted (0: none)
    setpoint_proof_s: float
    # FailsafeSettings field -> (lowest, highest, parameter): the values of the failsafe timings it sets that
    # the autopilot accepts; a mission outside them is refused where it is loaded (gcs_swarm.mission.checks)
    failsafe_ranges: Mapping[str, tuple[float, float, str]]
    hover_param: str  # the parameter holding the normalised thrust that hovers
    angle_boost_param: str | None  # the parameter that makes the autopilot add 1/cos(tilt) to thrust, if any
    failsafe_params: tuple[tuple[str, float], ...]  # (name, factor to SI) of: failsafe timeout s, Return
    # speed m/s, Return altitude m (how a vehicle that lost its ground station flies)
    arm_checks_follow_mode: bool  # its pre-arm checks judge the current mode (PX4: none pass in OFFBOARD
    # without setpoints, where it is left after landing), so it is put in launch_mode before they are awaited
    prearm_bit_in_enabled: bool  # SYS_STATUS's PREARM_CHECK counts only when also in `enabled`
    needs_ekf_report: bool  # readiness needs EKF_STATUS_REPORT (else SYS_STATUS's pre-arm bit alone)
    geofence: bool  # the ground station can install its fence (gcs_swarm.flight.geofence) on it
    typed_params: bool  # PARAM_SET must carry the parameter's own MAV_PARAM_TYPE (read it first)
    unsupported_streams: frozenset[str]  # telemetry messages this autopilot does not have

    def set_mode_params(self, number: int) -> tuple[float, float, float]:
        """MAV_CMD_DO_SET_MODE param1..3 that select custom_mode `number`."""
        ...

    def decode_param(self, wire_value: float, param_type: int) -> float:
        """PARAM_VALUE.param_value of MAV_PARAM_TYPE `param_type` -> the parameter's value."""
        ...

    def encode_param(self, value: float, param_type: int) -> float:
        """A value -> PARAM_SET.param_value for a parameter of MAV_PARAM_TYPE `param_type`."""
        ...

    def takeoff_params(self, alt_m: float, ground_amsl_m: float) -> tuple[float, ...]:
        """MAV_CMD_NAV_TAKEOFF param1..7 for a climb to `alt_m` above the ground at `ground_amsl_m` m AMSL."""
        ...

    def flight_params(self, failsafe: FailsafeSettings) -> list[tuple[str, float]]:
        """(name, value) the flight sets: what the vehicle does when the ground station goes silent, and
        whatever else flying its attitude targets needs."""
        ...

    def fence_params(self, action: str) -> list[tuple[str, float]]:
        """(name, value) that make the uploaded fence items act (restored after the flight): a breach does
        `action` ("report", "rtl", "land", "brake": safety.dead_gcs.fence.action)."""
        ...

    def rally_params(self) -> list[tuple[str, float]]:
        """(name, value) that make its RTL return to the nearest uploaded rally point (restored after)."""
        ...

    def is_angle_boost_on(self, value: float) -> bool:
        """`angle_boost_param`'s value as read -> whether the boost is on."""
        ...

    def thrust(
        self,
        thrust_acc: NDArray[np.float64],
        roll: NDArray[np.float64],
        pitch: NDArray[np.float64],
        hover: NDArray[np.float64],
        boost: NDArray[np.bool_],
        g: float,
    ) -> NDArray[np.float64]:
        """SET_ATTITUDE_TARGET.thrust (K,) normalised, that makes K vehicles of this autopilot fly the
        collective thrust accelerations thrust_acc (K,) m/s^2, at measured roll, pitch (K,) rad, with hover
        thrust `hover` (K,) (hover_param) and the angle boost on (`boost` (K,) bool); g: gravity m/s^2."""
        ...

    def mode_number(self, mode: str | int) -> int:
        """Mode name (case-insensitive) or number -> custom_mode number; ValueError if unknown."""
        ...

    def mode_name(self, number: int) -> str:
        """custom_mode number -> mode name ("UNKNOWN" for -1)."""
        ...

    def other_param_name(self, name: str) -> str | None:
        """The other spelling of a parameter renamed between releases, or None."""
        ...

    def sysid_param_hint(self) -> str:
        """The name of the parameter that sets the vehicle's sysid, for an error sentence."""
        ...

    def stream_group(self, message: str) -> int | None:
        """The REQUEST_DATA_STREAM group carrying `message` (a MAVLink message name), or None."""
        ...

    def ekf_missing(self, flags: int, required: int, horizontal: int, forbidden: int) -> str:
        """Why EKF_STATUS_REPORT.flags `flags` is not a usable position estimate, as a clause."""
        ...

    def gps_fix_name(self, fix_type: int) -> str:
        """GPS_RAW_INT.fix_type as words."""
        ...


DEFAULT_DIALECT: AutopilotDialect = ARDUPILOT
"""The dialect of a vehicle not heard yet, or of an autopilot the registry does not know."""

_REGISTRY: dict[int, AutopilotDialect] = {
    mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA: ARDUPILOT,
    mavlink2.MAV_AUTOPILOT_PX4: PX4,
}
DIALECTS: tuple[AutopilotDialect, ...] = tuple(_REGISTRY.values())
_BY_KEY: dict[str, AutopilotDialect] = {dialect.key: dialect for dialect in _REGISTRY.values()}

MODE_NAMES: tuple[str, ...] = tuple(dict.fromkeys(name for d in _REGISTRY.values() for name in d.modes))
"""Every flight mode name some dialect knows (ArduCopter's, then PX4's not already listed), for the console;
a vehicle whose own dialect lacks the name refuses it."""


def dialect_for(autopilot: int) -> AutopilotDialect:
    """The dialect of HEARTBEAT.autopilot `autopilot` (MAV_AUTOPILOT); DEFAULT_DIALECT if none registered."""
    return _REGISTRY.get(autopilot, DEFAULT_DIALECT)


def dialect_named(key: str) -> AutopilotDialect:
    """The dialect a mission names: "ardupilot" or "px4"; ValueError for anything else."""
    try:
        return _BY_KEY[key]
    except KeyError:
        raise ValueError(f"unknown autopilot {key!r} (known: {', '.join(_BY_KEY)})") from None


ModeChoice = str | int | Callable[[AutopilotDialect], str]
"""A flight mode for a vehicle: its name or custom_mode in the vehicle's dialect, or a function of the dialect
that names it (formation_mode, ...), for fleets of several autopilots."""


# ModeChoice functions: each vehicle's mode of that role in its own dialect (AutopilotDialect's attributes)
formation_mode: Callable[[AutopilotDialect], str] = attrgetter("formation_mode")  # GUIDED, OFFBOARD
launch_mode: Callable[[AutopilotDialect], str] = attrgetter("launch_mode")  # GUIDED, LOITER
takeoff_mode: Callable[[AutopilotDialect], str] = attrgetter("takeoff_mode")  # GUIDED (stays), TAKEOFF
hold_mode: Callable[[AutopilotDialect], str] = attrgetter("hold_mode")  # BRAKE, LOITER


def mode_name_in(dialect: AutopilotDialect, mode: ModeChoice) -> str | int:
    """`mode` as a name or number in `dialect` (a ModeChoice function is applied)."""
    return mode(dialect) if callable(mode) else mode
