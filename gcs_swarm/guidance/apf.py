"""Traditional artificial potential field, the baseline (spec 2, paper Eqs 1-3): its potentials.

The forces, their negative gradients, are gcs_swarm.guidance.field's kernels (method "apf"); these
potentials are what tests difference to check them. Shapes: `q` (N, D), `goal` (D,) or (N, D), obstacles
`centres` (K, D), `radii` (K,); potentials in field units (k_att m^2).
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.obstacles import surface_distance


def attraction_potential(q: np.ndarray, goal: np.ndarray, k_att: float) -> np.ndarray:
    """U_att = 0.5 k_att rho^2, (N,) (spec 2, Eq 1)."""
    d = q - goal
    return 0.5 * k_att * np.einsum("nd,nd->n", d, d)


def repulsion_potential(
    q: np.ndarray, centres: np.ndarray, radii: np.ndarray, k_rep: float, l0: float, l_min: float
) -> np.ndarray:
    """Sum over obstacles of U_rep = 0.5 k_rep (1/l - 1/l0)^2 (l <= l0), (N,) (spec 2, Eq 3)."""
    l = surface_distance(q, centres, radii, l_min)
    bracket = np.where(l <= l0, 1.0 / l - 1.0 / l0, 0.0)
    return 0.5 * k_rep * (bracket * bracket).sum(axis=1)
