"""ArduPilot's command-shaping primitive, written once for both programs (libraries/AP_Math/control.cpp
`sqrt_controller`): the ground station's reference generator shapes its velocity demands with it
(gcs_swarm.guidance), the simulated autopilot its angle, position and velocity loops (sitl_sim).

Scalars in, scalar out; compiled (swarm_common.jit) and callable from other kernels and from Python.
"""

from __future__ import annotations

import math

from swarm_common.jit import kernel_with


@kernel_with("float64(float64, float64, float64, float64)")  # compiled (or loaded) at import
def sqrt_controller(error: float, p: float, second_order_limit: float, dt: float) -> float:
    """Correction rate for `error`: `p * error` near zero, `sign(e) sqrt(2 L (|e| - L / (2 p^2)))` beyond
    `L / p^2` (L = second_order_limit, e.g. m/s^2 for a position error in m giving m/s), never more than
    |error| / dt when dt > 0 (dt = 0: no such bound). L <= 0: linear; p == 0: the square-root law alone.
    NaN and signed zeros follow numpy's np.sign / np.maximum / np.clip rules (the vectorised spelling this
    replaced), so an error of -0.0 gives -0.0 and a NaN error gives NaN."""
    size = abs(error)
    linear = error * p
    limit = second_order_limit
    two_limit = 2.0 * (limit if (limit > 0.0 or limit != limit) else 0.0)
    p_sq = p * p
    linear_dist = limit / p_sq if p_sq > 0.0 else math.inf
    direction = 1.0 if error > 0.0 else (-1.0 if error < 0.0 else (0.0 if error == 0.0 else error))
    if limit <= 0.0:
        rate = linear
    elif p == 0.0:
        rate = direction * math.sqrt(two_limit * size)
    elif size > linear_dist:
        beyond = size - 0.5 * linear_dist
        rate = direction * math.sqrt(two_limit * (beyond if (beyond > 0.0 or beyond != beyond) else 0.0))
    else:
        rate = linear
    if dt > 0.0 and rate == rate:  # clip to +-|error| / dt: NaN stays NaN
        bound = size / dt
        rate = rate if rate > -bound else -bound
        rate = rate if rate < bound else bound
    return rate
