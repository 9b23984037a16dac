"""What SET_ATTITUDE_TARGET.thrust means to a multicopter autopilot flying a collective thrust, compiled, and
numpy.nan_to_num for one float64, which the send step keeps (NaN, infinities).

Both dialects fly `normalised_thrust`: ArduCopter with GUID_OPTIONS bit 3 (thrust is collective thrust, not
a climb rate) and PX4 in OFFBOARD (mavlink_receiver fill_thrust: thrust_body[2] = -thrust, flown as given by
mc_att_control) take thrust / hover thrust as thrust / weight.
"""

from __future__ import annotations

import math

import numpy as np

from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip_to_scalars

_FLOAT_MAX = float(np.finfo(np.float64).max)  # numpy.nan_to_num's value for +inf


@kernel
def nan_to_num(x: float) -> float:
    """numpy.nan_to_num of one float64: NaN -> 0, +-inf -> the largest finite float of its sign."""
    if x != x:
        return 0.0
    if x == math.inf:
        return _FLOAT_MAX
    if x == -math.inf:
        return -_FLOAT_MAX
    return x


@kernel
def normalised_thrust(acc: float, hover: float, g: float) -> float:
    """Collective thrust acceleration `acc` m/s^2 -> normalised thrust hover * acc / g in [0, 1], `hover`
    being the normalised thrust that holds 1 g (MOT_THST_HOVER, MPC_THR_HOVER) and `g` gravity m/s^2 (spec
    5). A NaN acceleration gives no thrust, +inf full thrust, -inf none."""
    return clip_to_scalars(hover * nan_to_num(acc) / g, 0.0, 1.0)
