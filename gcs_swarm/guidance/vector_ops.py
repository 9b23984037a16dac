"""Small vector operations of the per-tick guidance, without the Python-level overhead of their numpy
spellings, and bit for bit what those spellings compute (tests/gcs_swarm/guidance/test_vector_ops.py).

At 50 Hz for a few vehicles the guidance is dozens of numpy calls on (N, 3) arrays, where each call's Python
wrapper costs more than its arithmetic. These helpers call the ufuncs that the wrappers end in, in the same
order, so the results (rounding, NaN, signed zeros) are unchanged.
"""

from __future__ import annotations

import numpy as np


def row_norms(vectors: np.ndarray) -> np.ndarray:
    """Euclidean length of each row of a real (N, D) array, (N,): `np.linalg.norm(vectors, axis=1)`, which
    for real input is sqrt(add.reduce(v * v, axis=1)) (numpy.linalg.norm)."""
    return np.sqrt(np.add.reduce(vectors * vectors, axis=1))


def column_mean(points: np.ndarray) -> np.ndarray:
    """Mean of the rows of a non-empty real (K, D) array, (D,): `points.mean(axis=0)`, which is
    add.reduce(points, axis=0) / K (numpy _methods._mean)."""
    return np.add.reduce(points, axis=0) / len(points)
