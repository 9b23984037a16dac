"""Scalar helpers of the compiled laws (the guidance, the link's command guard and thrust mapping) that keep
numpy's rules, so that the laws give the results their vectorised spellings gave (flights are reproducible
across versions of this code):

- `maximum`, `minimum`: NaN if either argument is, else the larger / smaller; the second argument when
  they compare equal (+0 and -0), as np.maximum / np.minimum;
- `clip`: np.clip with bounds given per row (NaN x, else NaN lo, wins; hi when equal), `clip_to_scalars`:
  np.clip with scalar bounds (NaN lo, else hi, else x, wins; x itself when it equals a bound);
- `sign`: np.sign (NaN for NaN);
- `dot3`: the sum order of np.einsum("pd,pd->p") over three components, (x0 y0 + x2 y2) + x1 y1, added to
  +0 (so -0 becomes +0); `norm3`: sqrt((x0^2 + x1^2) + x2^2), numpy's row norm.

All scalar, compiled (swarm_common.jit) and callable from other kernels.

The kernels of the guidance write the length of a 2-vector as np.hypot, not math.hypot: compiled, both are
the platform's libm hypot; run as plain Python (NUMBA_DISABLE_JIT=1), np.hypot is libm's as well while
CPython's math.hypot is an algorithm of its own that can differ in the last bit.
"""

from __future__ import annotations

import math

from swarm_common.jit import kernel


@kernel
def maximum(a: float, b: float) -> float:
    """np.maximum of two floats."""
    return a if (a > b or a != a) else b


@kernel
def minimum(a: float, b: float) -> float:
    """np.minimum of two floats."""
    return a if (a < b or a != a) else b


@kernel
def clip(x: float, lo: float, hi: float) -> float:
    """np.clip of x between per-row bounds."""
    if x != x:
        return x
    if lo != lo:
        return lo
    bounded_below = x if x > lo else lo
    return bounded_below if bounded_below < hi else hi


@kernel
def clip_to_scalars(x: float, lo: float, hi: float) -> float:
    """np.clip of x between scalar bounds."""
    if lo != lo:
        return lo
    if hi != hi:
        return hi
    if x != x:
        return x
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


@kernel
def sign(x: float) -> float:
    """np.sign of a float: -1, 0 or 1, NaN for NaN."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    if x == 0.0:
        return 0.0
    return x


@kernel
def dot3(x0: float, x1: float, x2: float, y0: float, y1: float, y2: float) -> float:
    """x . y of two 3-vectors in np.einsum's order."""
    return (x0 * y0 + x2 * y2) + x1 * y1 + 0.0


@kernel
def norm3(x0: float, x1: float, x2: float) -> float:
    """|x| of a 3-vector in numpy's row-norm order."""
    return math.sqrt((x0 * x0 + x1 * x1) + x2 * x2)
