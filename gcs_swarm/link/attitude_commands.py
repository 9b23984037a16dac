"""The send step of a formation tick: from the guidance's command to what each SET_ATTITUDE_TARGET carries.

1. Thrust for ArduCopter: the collective acceleration with ArduCopter's own angle boost taken out again
   (autopilots.ardupilot.unboosted_thrust), made finite (numpy.nan_to_num: NaN 0, +-inf the largest float,
   so no thrust or full thrust once normalised), normalised (autopilots.ardupilot.thrust_from_acc).
2. The final command guard (command_limits.guard_attitude_commands).

`attitude_commands_numpy` is that sequence of numpy functions, the reference. `attitude_commands` gives the
same bits from one compiled loop over the vehicles (link_kernels.attitude_commands) when numba is installed:
for 6 vehicles 45 us of numpy calls become 10 us (timeit), a twentieth of the formation tick's work
(BENCHMARKS.md). tests/gcs_swarm/link/test_attitude_commands.py compares the two bit for bit.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.link.autopilots import ardupilot
from gcs_swarm.link.command_limits import TILT_SLACK, CommandLimits, guard_attitude_commands

try:  # the compiled loop (the same bits) when numba is there (extra "fast")
    from gcs_swarm.link import link_kernels
except ImportError:  # pragma: no cover - numba is optional
    link_kernels = None  # type: ignore[assignment]

FloatArray = NDArray[np.float64]


class AttitudeCommands(NamedTuple):
    """What goes out, per vehicle (N,): roll, pitch, yaw rad (body FLU in world ENU), normalised thrust, and
    whether the guard changed the row."""

    roll: FloatArray
    pitch: FloatArray
    yaw: FloatArray
    thrust: FloatArray
    changed: NDArray[np.bool_]


def attitude_commands_numpy(
    roll: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    thrust_acc: FloatArray,
    att: FloatArray,
    pos: FloatArray,
    vel: FloatArray,
    hover: FloatArray,
    boost: NDArray[np.bool_],
    g: float,
    limits: CommandLimits,
) -> AttitudeCommands:
    """The guidance's (N,) roll, pitch, yaw rad and collective thrust acceleration m/s^2 made into the
    commands to send, for vehicles at the measured att (N, 3) rad (roll, pitch, yaw), pos (N, 3) ENU m and
    vel (N, 3) ENU m/s, with hover thrust (N,) (MOT_THST_HOVER), ATC_ANGLE_BOOST on (N,) bool, gravity g
    m/s^2 and the guard's limits (see the module doc)."""
    acc = ardupilot.unboosted_thrust(thrust_acc, att[:, 0], att[:, 1], boost)
    thrust = ardupilot.thrust_from_acc(np.nan_to_num(acc), hover, g)
    return AttitudeCommands(
        *guard_attitude_commands(roll, pitch, yaw, thrust, pos, att[:, 2], hover, limits, vel=vel)
    )


def attitude_commands(
    roll: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    thrust_acc: FloatArray,
    att: FloatArray,
    pos: FloatArray,
    vel: FloatArray,
    hover: FloatArray,
    boost: NDArray[np.bool_],
    g: float,
    limits: CommandLimits,
) -> AttitudeCommands:
    """attitude_commands_numpy (same arguments, same bits), by the compiled loop when numba is there."""
    if link_kernels is None:
        return attitude_commands_numpy(roll, pitch, yaw, thrust_acc, att, pos, vel, hover, boost, g, limits)
    r, p, y, acc, a, x, v, h = (
        np.ascontiguousarray(values, dtype=np.float64)
        for values in (roll, pitch, yaw, thrust_acc, att, pos, vel, hover)
    )
    # numpy's own arccos (the compiled loop's acos is the C library's; module doc of link_kernels)
    commanded_tilt = np.arccos(np.clip(np.cos(r) * np.cos(p), -1.0, 1.0))
    bounds = (
        float(limits.tilt_max),
        float(limits.thrust_max_g),
        float(limits.min_altitude),
        float(limits.geofence_radius),
        float(limits.geofence_max_alt),
    )
    boosted = np.ascontiguousarray(boost, dtype=np.bool_)
    out = link_kernels.attitude_commands(
        r, p, y, acc, commanded_tilt, a, x, v, h, boosted, float(g), bounds, TILT_SLACK
    )  # fmt: skip
    return AttitudeCommands(*out)
