"""Slew limit on the commanded tilt [add]: the roll/pitch a vehicle is told to fly move toward the
controller's demand at most `rate_max` rad/s, so no command steps (an autopilot's rate loop would saturate on
a step, and a real airframe would not fly it the way a model does).

The limit acts on the (roll, pitch) pair as a vector: a change of direction is slewed as one rotation of the
tilt, not axis by axis; one compiled step per tick (swarm_common.jit). Shapes (N,), rad, FLU body / ENU
world ZYX Euler (spec 1.1).
"""

from __future__ import annotations

import numpy as np

from swarm_common.jit import kernel


@kernel
def slew_step(
    roll_d: np.ndarray,
    pitch_d: np.ndarray,
    roll: np.ndarray,
    pitch: np.ndarray,
    limit: float,
    rows: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The next commands (roll, pitch) (N,) rad from the last ones (N,) (non-finite: start at the demand)
    toward the demand roll_d, pitch_d (N,): the (roll, pitch) change at most `limit` rad long (rate_max dt;
    <= 0: no limit), only in the (N,) bool rows."""
    n = roll_d.shape[0]
    next_roll = np.empty(n)
    next_pitch = np.empty(n)
    for i in range(n):
        r, q = roll[i], pitch[i]
        if not (np.isfinite(r) and np.isfinite(q)):
            r, q = roll_d[i], pitch_d[i]
        d_roll, d_pitch = roll_d[i] - r, pitch_d[i] - q
        if limit > 0.0:
            step = np.hypot(d_roll, d_pitch)
            scale = limit / step if step > limit else 1.0
            d_roll, d_pitch = d_roll * scale, d_pitch * scale
        if rows[i]:
            r, q = r + d_roll, q + d_pitch
        next_roll[i], next_pitch[i] = r, q
    return next_roll, next_pitch
