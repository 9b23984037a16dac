"""Autopilot dialects: what differs between autopilots on the wire, behind one interface and a registry.

The link picks a vehicle's dialect from its first HEARTBEAT (`HEARTBEAT.autopilot`, MAV_AUTOPILOT) with
`dialect_for`; until then, and for an autopilot with no dialect of its own, it speaks ArduPilot (the only
dialect today; PX4 joins the registry in a later issue). Nothing else in gcs_swarm.link names an autopilot's
modes or parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots.ardupilot import ARDUPILOT


class AutopilotDialect(Protocol):
    """The autopilot-specific facts the link needs (modes, parameter spellings, stream groups, health)."""

    name: str
    modes: Mapping[str, int]  # flight mode name -> HEARTBEAT.custom_mode number
    force_arm_param2: float  # MAV_CMD_COMPONENT_ARM_DISARM param2 that arms skipping the pre-arm checks
    force_disarm_param2: float  # ... that disarms even in flight
    land_mode: str  # the mode that lands the vehicle where it is

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

_REGISTRY: dict[int, AutopilotDialect] = {mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA: ARDUPILOT}


def dialect_for(autopilot: int) -> AutopilotDialect:
    """The dialect of HEARTBEAT.autopilot `autopilot` (MAV_AUTOPILOT); DEFAULT_DIALECT if none registered."""
    return _REGISTRY.get(autopilot, DEFAULT_DIALECT)
