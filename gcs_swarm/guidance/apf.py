"""Traditional artificial potential field, the baseline (spec 2, paper Eqs 1-6).

Forces are virtual, in field units (k_att * m). Shapes: `q` (N, D), `goal` (D,) or (N, D), obstacles
`centres` (K, D), `radii` (K,). Each force sits beside its potential so tests can difference one against
the other.
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.obstacles import surface_geometry


def attraction_potential(q: np.ndarray, goal: np.ndarray, k_att: float) -> np.ndarray:
    """U_att = 0.5 k_att rho^2, (N,) (spec 2, Eq 1)."""
    d = q - goal
    return 0.5 * k_att * np.einsum("nd,nd->n", d, d)


def attraction_force(q: np.ndarray, goal: np.ndarray, k_att: float) -> np.ndarray:
    """F_att = -k_att (q - q_g), (N, D) (spec 2, Eq 2)."""
    return -k_att * (q - goal)


def repulsion_scale(l: np.ndarray, k_rep: float, l0: float) -> np.ndarray:
    """k_rep (1/l - 1/l0) / l^2 where l <= l0, else 0: |F_rep| per obstacle, any shape (spec 2, Eq 4)."""
    return np.where(l <= l0, k_rep * (1.0 / l - 1.0 / l0) / (l * l), 0.0)


def repulsion_potential(
    q: np.ndarray, centres: np.ndarray, radii: np.ndarray, k_rep: float, l0: float, l_min: float
) -> np.ndarray:
    """Sum over obstacles of U_rep = 0.5 k_rep (1/l - 1/l0)^2 (l <= l0), (N,) (spec 2, Eq 3)."""
    l = surface_geometry(q, centres, radii, l_min).l
    bracket = np.where(l <= l0, 1.0 / l - 1.0 / l0, 0.0)
    return 0.5 * k_rep * (bracket * bracket).sum(axis=1)


def repulsion_force(
    q: np.ndarray, centres: np.ndarray, radii: np.ndarray, k_rep: float, l0: float, l_min: float
) -> np.ndarray:
    """Sum over obstacles of F_rep = k_rep (1/l - 1/l0) / l^2 * n_o, (N, D) (spec 2, Eq 4, spec 2.1)."""
    geo = surface_geometry(q, centres, radii, l_min)
    return np.einsum("nk,nkd->nd", repulsion_scale(geo.l, k_rep, l0), geo.n_o)
