"""The parameter table of N simulated vehicles: the shared columns in ArduCopter's names, types and ranges
(the release chosen by PARAM_NAME_RELEASES), which the shared autopilot reads, and the columns a persona adds
(sitl_sim.autopilot.registry.fleet_params puts them together; each vehicle lists what its persona shows).

Values live in one (N, P) float64 array so the vectorised autopilot reads a whole column per parameter.
Parameters are listed (PARAM_REQUEST_LIST, param_index) in alphabetical order. World parameters (SIM_WIND_*)
describe the one shared world: setting them on any vehicle sets them on all.
"""

from __future__ import annotations

import dataclasses
import math
import struct
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

INT_TYPES = {
    mavlink2.MAV_PARAM_TYPE_INT8: (-128, 127),
    mavlink2.MAV_PARAM_TYPE_INT16: (-32768, 32767),
    mavlink2.MAV_PARAM_TYPE_INT32: (-(2**31), 2**31 - 1),
}
REAL32 = mavlink2.MAV_PARAM_TYPE_REAL32
INT8 = mavlink2.MAV_PARAM_TYPE_INT8
INT16 = mavlink2.MAV_PARAM_TYPE_INT16
INT32 = mavlink2.MAV_PARAM_TYPE_INT32


def int32_as_float(value: int) -> float:
    """The float whose 4 bytes are the int32 `value` (MAVLink's bytewise parameter encoding)."""
    return float(struct.unpack("<f", struct.pack("<i", value))[0])


def float_as_int32(value: float) -> int:
    """The int32 held bytewise in the float `value` (inverse of int32_as_float)."""
    return int(struct.unpack("<i", struct.pack("<f", value))[0])


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: name (<= 16 chars), MAV_PARAM_TYPE, default, inclusive range, units, meaning."""

    name: str
    type: int
    default: float
    low: float
    high: float
    units: str
    doc: str
    world: bool = False  # shared by all vehicles (simulator world settings)


# Parameters ArduCopter 4.7 renamed (ArduCopter/Parameters.cpp conversion table, libraries/GCS_MAVLink/GCS.cpp
# "_SYSID", "_GCS_SYSID"): the simulator answers to the 4.7 names by default, to the 4.6 ones with
# `sitl-sim --param-names 4.6`, never to both (as a real vehicle). The simulator's own code uses 4.7 names.
RENAMED_IN_4_7 = {"MAV_SYSID": "SYSID_THISMAV", "MAV_GCS_SYSID": "SYSID_MYGCS"}
PARAM_NAME_RELEASES = ("4.7", "4.6")


def param_specs(hover_fraction: float, names: str = "4.7") -> tuple[ParamSpec, ...]:
    """The parameter table, alphabetical; MOT_THST_HOVER defaults to the airframe's true hover fraction;
    `names` the ArduCopter release whose parameter names to use (PARAM_NAME_RELEASES)."""
    if names not in PARAM_NAME_RELEASES:
        raise ValueError(f"parameter names of ArduCopter {' or '.join(PARAM_NAME_RELEASES)}, not {names!r}")
    specs: tuple[ParamSpec, ...] = (
        ParamSpec(
            "ANGLE_MAX", INT16, 3000, 1000, 8000, "cdeg", "maximum lean angle (not of guided attitude)"
        ),
        ParamSpec("ATC_ANGLE_BOOST", INT8, 1, 0, 1, "", "guided/alt-hold thrust x 1/cos(lean) (1 = on)"),
        ParamSpec("DISARM_DELAY", INT8, 10, 0, 127, "s", "auto-disarm after this long landed (0 = never)"),
        # geofence (libraries/AC_Fence/AC_Fence.cpp var_info, Copter defaults; sitl_sim.autopilot.fence)
        ParamSpec("FENCE_ACTION", INT8, 1, 0, 5, "", "0 report, 1 RTL, 2 LAND, 3/5 SmartRTL, 4 BRAKE"),
        ParamSpec("FENCE_ALT_MAX", REAL32, 100.0, 10.0, 1000.0, "m", "max altitude above home (type 1)"),
        ParamSpec("FENCE_ENABLE", INT8, 0, 0, 1, "", "fence on (every configured type but the floor)"),
        ParamSpec("FENCE_MARGIN", REAL32, 2.0, 1.0, 10.0, "m", "distance kept from a fence"),
        ParamSpec("FENCE_RADIUS", REAL32, 300.0, 30.0, 10000.0, "m", "circle around home (type 2)"),
        ParamSpec("FENCE_TOTAL", INT8, 0, 0, 127, "", "legacy point count (0 after a small fence: clears)"),
        ParamSpec("FENCE_TYPE", INT8, 7, 0, 15, "", "1 max alt, 2 circle, 4 polygons, 8 min alt"),
        ParamSpec("FS_GCS_ENABLE", INT8, 0, 0, 7, "", "GCS failsafe: 0 off, 1/2/3/6 RTL, 4/5 LAND, 7 BRAKE"),
        ParamSpec("FS_GCS_TIMEOUT", REAL32, 5.0, 2.0, 120.0, "s", "GCS heartbeat loss before the failsafe"),
        ParamSpec("GUID_OPTIONS", INT32, 0, 0, 65535, "", "bit 3 (8): SET_ATTITUDE_TARGET thrust is thrust"),
        ParamSpec("GUID_TIMEOUT", REAL32, 3.0, 0.1, 5.0, "s", "guided velocity/attitude target timeout"),
        ParamSpec("LAND_SPEED", INT16, 50, 30, 200, "cm/s", "final descent speed below 10 m"),
        ParamSpec("MOT_THST_HOVER", REAL32, hover_fraction, 0.125, 0.6875, "", "hover thrust fraction"),
        ParamSpec("PSC_JERK_XY", REAL32, 5.0, 1.0, 20.0, "m/s^3", "horizontal jerk of shaped stops (BRAKE)"),
        ParamSpec("PSC_POSXY_P", REAL32, 1.0, 0.5, 2.0, "1/s", "horizontal position P"),
        ParamSpec("PSC_POSZ_P", REAL32, 1.0, 0.5, 3.0, "1/s", "vertical position P"),
        ParamSpec("PSC_VELXY_I", REAL32, 1.0, 0.0, 4.0, "1/s^2", "horizontal velocity I"),
        ParamSpec("PSC_VELXY_P", REAL32, 2.0, 0.1, 6.0, "1/s", "horizontal velocity P"),
        ParamSpec("PSC_VELZ_I", REAL32, 2.0, 0.0, 10.0, "1/s^2", "vertical velocity I"),
        ParamSpec("PSC_VELZ_P", REAL32, 5.0, 1.0, 8.0, "1/s", "vertical velocity P"),
        # rally points (libraries/AP_Rally/AP_Rally.cpp var_info, Copter defaults; sitl_sim.autopilot.rally)
        ParamSpec("RALLY_INCL_HOME", INT8, 1, 0, 1, "", "RTL goes home when nearer than any rally point"),
        ParamSpec("RALLY_LIMIT_KM", REAL32, 0.3, 0.0, 50.0, "km", "rally points further than this: home"),
        ParamSpec("RALLY_TOTAL", INT8, 0, 0, 100, "", "number of stored rally points"),
        ParamSpec("RTL_ALT", INT32, 1500, 200, 300000, "cm", "minimum return altitude above home"),
        ParamSpec("SIM_LINK_CORRUPT", REAL32, 0.0, 0.0, 1.0, "", "link: probability a packet is corrupted"),
        ParamSpec("SIM_LINK_DELAY", REAL32, 0.0, 0.0, 10000.0, "ms", "link: one-way delay (simulated ms)"),
        ParamSpec("SIM_LINK_DUP", REAL32, 0.0, 0.0, 1.0, "", "link: probability a packet is duplicated"),
        ParamSpec("SIM_LINK_JITTER", REAL32, 0.0, 0.0, 10000.0, "ms", "link: extra delay, uniform 0..this"),
        ParamSpec("SIM_LINK_LOSS", REAL32, 0.0, 0.0, 1.0, "", "link: probability a packet is lost"),
        ParamSpec("SIM_LINK_REORDER", REAL32, 0.0, 0.0, 1.0, "", "link: probability a packet is held back"),
        ParamSpec("SIM_WIND_DIR", REAL32, 0.0, 0.0, 360.0, "deg", "wind comes from (0 = north)", True),
        ParamSpec("SIM_WIND_SPD", REAL32, 0.0, 0.0, 100.0, "m/s", "steady wind speed", True),
        ParamSpec("SIM_WIND_TURB", REAL32, 0.0, 0.0, 20.0, "m/s", "turbulence standard deviation", True),
        ParamSpec("MAV_GCS_SYSID", INT16, 255, 1, 255, "", "ground station sysid whose heartbeat counts"),
        ParamSpec("MAV_SYSID", INT16, 1, 1, 255, "", "this vehicle's sysid (takes effect on restart)"),
        ParamSpec("WPNAV_ACCEL", REAL32, 250.0, 50.0, 500.0, "cm/s^2", "horizontal acceleration limit"),
        ParamSpec("LOIT_BRK_ACCEL", REAL32, 250.0, 25.0, 250.0, "cm/s^2", "LAND/LOITER braking acceleration"),
        ParamSpec("LOIT_BRK_JERK", REAL32, 500.0, 500.0, 5000.0, "cm/s^3", "LAND/LOITER braking jerk"),
        ParamSpec("WPNAV_SPEED", REAL32, 1000.0, 10.0, 2000.0, "cm/s", "horizontal speed to a target"),
        ParamSpec("WPNAV_SPEED_DN", REAL32, 150.0, 10.0, 500.0, "cm/s", "descent speed"),
        ParamSpec("WPNAV_SPEED_UP", REAL32, 250.0, 10.0, 1000.0, "cm/s", "climb speed"),
    )
    if names == "4.6":
        specs = tuple(
            dataclasses.replace(spec, name=RENAMED_IN_4_7[spec.name]) if spec.name in RENAMED_IN_4_7 else spec
            for spec in specs
        )
    return tuple(sorted(specs, key=lambda s: s.name))


class ParamTable:
    """Parameter values of N vehicles: `values` (N, P) float64, column j belongs to specs[j].

    visible (N, P) bool, default all: the parameters each vehicle shows on the wire (what its persona shows,
    Persona.shows; the hidden columns still drive the shared autopilot code).
    revision counts the `set` calls: a reader that keeps something derived from `values` compares it and reads
    again when it changed (the endpoints' SIM_LINK_* check), so the columns it derives from change only
    through `set` once it runs.
    """

    def __init__(
        self,
        n: int,
        specs: tuple[ParamSpec, ...],
        visible: np.ndarray | None = None,
    ) -> None:
        self.specs = specs
        self.index = {spec.name: j for j, spec in enumerate(specs)}  # every column by its name
        self.visible = np.ones((n, len(specs)), dtype=bool) if visible is None else np.asarray(visible, bool)
        self._listings = [tuple(np.flatnonzero(row).tolist()) for row in self.visible]
        # the simulator's own code reads renamed parameters by their 4.7 names, whatever the vehicle shows
        self._internal = dict(self.index)
        for new_name, old_name in RENAMED_IN_4_7.items():
            if old_name in self.index:
                self._internal.setdefault(new_name, self.index[old_name])
        self.values = np.array([[spec.default for spec in specs]] * n, dtype=float)
        self.revision = 0

    def listing(self, i: int) -> tuple[int, ...]:
        """Columns vehicle i shows, in its PARAM_REQUEST_LIST order (param_index = position here)."""
        return self._listings[i]

    def lookup(self, i: int, name: str) -> int | None:
        """Column of `name` if vehicle i shows it, else None (an unknown parameter on that vehicle)."""
        j = self.index.get(name)
        return j if j is not None and self.visible[i, j] else None

    def column(self, name: str) -> np.ndarray:
        """(N,) current values of parameter `name` (a view; renamed ones also by their 4.7 name)."""
        return self.values[:, self._internal[name]]

    def value(self, i: int, name: str) -> float:
        """Value of `name` on vehicle i (renamed ones also by their 4.7 name)."""
        return self.values.item(i, self._internal[name])  # float(self.values[i, j]), without a numpy scalar

    def column_index(self, name: str) -> int:
        """Column j of `name` (renamed ones also by their 4.7 name)."""
        return self._internal[name]

    def check(self, name: str, value: float) -> str | None:
        """Why `value` cannot be stored in `name` (a short sentence), or None when it can."""
        j = self.index.get(name)
        if j is None:
            return f"unknown parameter {name}"
        spec = self.specs[j]
        if not math.isfinite(value):
            return f"{name}: not finite"
        if spec.type in INT_TYPES and abs(value - round(value)) > 1e-6:
            return f"{name}: must be an integer"
        if not spec.low <= value <= spec.high:
            return f"{name}: out of range {spec.low:g}..{spec.high:g}"
        return None

    def set(self, i: int, name: str, value: float) -> list[int]:
        """Store a checked value; returns the vehicles whose value changed (all of them for world params)."""
        j = self.index[name]
        spec = self.specs[j]
        stored = float(round(value)) if spec.type in INT_TYPES else float(np.float32(value))
        rows = list(range(len(self.values))) if spec.world else [i]
        self.values[rows, j] = stored
        self.revision += 1
        return rows
