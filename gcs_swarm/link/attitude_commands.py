"""The send step of a formation tick: from the guidance's command to what each SET_ATTITUDE_TARGET carries.

1. Thrust: each vehicle's autopilot dialect turns the collective acceleration into its normalised thrust
   (AutopilotDialect.thrust: ArduCopter takes its own angle boost out again, PX4 flies it as given), for
   the vehicles of each dialect at once.
2. The final command guard (command_limits.guard_attitude_commands).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.link.autopilots import ARDUPILOT, PX4, AutopilotDialect
from gcs_swarm.link.command_limits import CommandLimits, guard_attitude_commands, guard_position_targets

FloatArray = NDArray[np.float64]


class AttitudeCommands(NamedTuple):
    """What goes out, per vehicle (N,): roll, pitch, yaw rad (body FLU in world ENU), normalised thrust, and
    whether the guard changed the row."""

    roll: FloatArray
    pitch: FloatArray
    yaw: FloatArray
    thrust: FloatArray
    changed: NDArray[np.bool_]


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
    dialects: Sequence[AutopilotDialect],
) -> AttitudeCommands:
    """The guidance's (N,) roll, pitch, yaw rad and collective thrust acceleration m/s^2 made into the
    commands to send, for vehicles at the measured att (N, 3) rad (roll, pitch, yaw), pos (N, 3) ENU m and
    vel (N, 3) ENU m/s, with hover thrust (N,), the autopilot's angle boost on (N,) bool, gravity g m/s^2,
    the guard's limits and each vehicle's autopilot dialect (N,) (see the module doc)."""
    acc, hov, a = (np.ascontiguousarray(x, dtype=np.float64) for x in (thrust_acc, hover, att))
    boosted = np.ascontiguousarray(boost, dtype=np.bool_)
    groups: dict[int, tuple[AutopilotDialect, list[int]]] = {}
    for i, dialect in enumerate(dialects):
        groups.setdefault(id(dialect), (dialect, []))[1].append(i)
    if len(groups) == 1:
        thrust = dialects[0].thrust(acc, a[:, 0], a[:, 1], hov, boosted, g)
    else:
        thrust = np.empty(len(acc))
        for dialect, rows in groups.values():
            thrust[rows] = dialect.thrust(acc[rows], a[rows, 0], a[rows, 1], hov[rows], boosted[rows], g)
    return AttitudeCommands(
        *guard_attitude_commands(roll, pitch, yaw, thrust, pos, a[:, 2], hov, limits, vel=vel)
    )


def warm_up() -> None:
    """Compile the send step (both dialects' thrust and the guard) or load it from numba's cache, before a
    tick needs it."""
    row, rows = np.zeros(1), np.zeros((1, 3))
    limits = CommandLimits(1.0, 1.0, 0.0, 1.0, 1.0)
    for dialect in (ARDUPILOT, PX4):
        attitude_commands(
            row, row, row, row, rows, rows, rows, row, np.ones(1, dtype=bool), 9.8, limits, [dialect]
        )
    guard_position_targets(rows, rows, rows, rows, limits, 9.8)  # the position command mode's
