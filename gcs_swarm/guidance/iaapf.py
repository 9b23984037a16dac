"""Improved adaptive APF (spec 3, paper Eqs 7 and 9): its potentials, segmented attraction and adaptive
repulsion.

The forces, their negative gradients, are gcs_swarm.guidance.field's kernels (method "iaapf"); these
potentials are what tests difference to check them. Shapes: `q` (N, D); `goal` / `dest` (D,) or (N, D);
obstacles `centres` (K, D), `radii` (K,). `dest` is the vehicle's final destination g_i of the adaptive
factor rho^n (spec 8 step 1), not necessarily the attraction target.
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.apf import repulsion_potential


def segmented_attraction_potential(q: np.ndarray, goal: np.ndarray, k_att: float, d_g: float) -> np.ndarray:
    """U*_att (N,): quadratic within d_g of the goal, linear (C1) beyond (spec 3.1, corrected Eq 7)."""
    rho = np.linalg.norm(q - goal, axis=-1)
    return np.where(rho <= d_g, 0.5 * k_att * rho * rho, k_att * d_g * rho - 0.5 * k_att * d_g * d_g)


def adaptive_repulsion_potential(
    q: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    dest: np.ndarray,
    k_rep: float,
    l0: float,
    n: float,
    l_min: float,
) -> np.ndarray:
    """Sum over obstacles of U*_rep = 0.5 k_rep (1/l - 1/l0)^2 rho^n (l <= l0), (N,) (spec 3.2, Eq 9): the APF
    repulsion potential times the adaptive factor rho^n, rho = |q - dest|."""
    return repulsion_potential(q, centres, radii, k_rep, l0, l_min) * np.linalg.norm(q - dest, axis=-1) ** n
