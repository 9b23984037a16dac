"""The lean vector helpers compute bit for bit what the numpy spellings they replace compute."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_swarm.guidance.vector_ops import column_mean, row_norms

SPECIAL = np.array([0.0, -0.0, 1.0, -1.0, np.nan, np.inf, -np.inf, 1e-310, -1e-310, 1e300, -3.5, 7.25])


def _arrays(rows: int, dim: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        rng.normal(0.0, 1.0, (rows, dim)),
        rng.normal(0.0, 1.0, (rows, dim)) * 10.0 ** rng.integers(-150, 150, (rows, dim)),
        rng.choice(SPECIAL, (rows, dim)),
    ]


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("rows", [0, 1, 2, 3, 6, 9, 17, 100, 1000])
@pytest.mark.parametrize("dim", [2, 3])
def test_row_norms_is_numpy_norm_bit_for_bit(rows: int, dim: int) -> None:
    with np.errstate(over="ignore", invalid="ignore"):  # 1e300 squared, inf - inf: both sides alike
        for vectors in _arrays(rows, dim, rows * 10 + dim):
            assert _same(row_norms(vectors), np.linalg.norm(vectors, axis=1))


def test_row_norms_by_hand() -> None:
    vectors = np.array([[3.0, 4.0, 0.0], [1.0, 2.0, 2.0], [0.0, 0.0, 0.0]])
    assert row_norms(vectors).tolist() == [5.0, 3.0, 0.0]


@pytest.mark.parametrize("rows", [1, 2, 3, 6, 10, 100])
@pytest.mark.parametrize("dim", [2, 3])
def test_column_mean_is_numpy_mean_bit_for_bit(rows: int, dim: int) -> None:
    with np.errstate(over="ignore", invalid="ignore"):
        for points in _arrays(rows, dim, rows * 7 + dim):
            assert _same(column_mean(points), points.mean(axis=0))


def test_column_mean_by_hand() -> None:
    assert column_mean(np.array([[1.0, 2.0, 3.0], [3.0, 6.0, -3.0]])).tolist() == [2.0, 4.0, 0.0]
