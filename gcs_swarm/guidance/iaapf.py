"""Improved adaptive APF: segmented attraction and adaptive repulsion (spec 3, paper Eqs 7-12).

Shapes: `q` (N, D); `goal` / `dest` (D,) or (N, D); obstacles `centres` (K, D), `radii` (K,). `dest` is the
vehicle's final destination g_i of the adaptive factor rho^n (spec 8 step 1), not necessarily the
attraction target.
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.obstacles import surface_geometry
from gcs_swarm.guidance.vector_ops import row_norms


def segmented_attraction_potential(q: np.ndarray, goal: np.ndarray, k_att: float, d_g: float) -> np.ndarray:
    """U*_att (N,): quadratic within d_g of the goal, linear (C1) beyond (spec 3.1, corrected Eq 7)."""
    rho = np.linalg.norm(q - goal, axis=-1)
    return np.where(rho <= d_g, 0.5 * k_att * rho * rho, k_att * d_g * rho - 0.5 * k_att * d_g * d_g)


def segmented_attraction_force(q: np.ndarray, goal: np.ndarray, k_att: float, d_g: float) -> np.ndarray:
    """F*_att (N, D) = -k_att (q - q_g) * min(1, d_g / rho); |F*_att| <= k_att d_g (spec 3.1, Eq 8)."""
    d = q - goal
    rho = np.linalg.norm(d, axis=-1)
    scale = np.where(rho <= d_g, 1.0, d_g / np.maximum(rho, d_g))
    return -k_att * scale[:, None] * d


def goal_distance(q: np.ndarray, dest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """rho (N,) = |q - g| and n_g (N, D) unit vector toward g (zero at the goal)."""
    d = dest - q
    rho = row_norms(d)
    n_g = d / np.where(rho > 0.0, rho, 1.0)[:, None]
    return rho, n_g


def adaptive_repulsion_scales(
    l: np.ndarray, rho: np.ndarray, k_rep: float, l0: float, n: float, rho_eps: float
) -> tuple[np.ndarray, np.ndarray]:
    """Magnitudes of F*_rep1 (along n_o) and F*_rep2 (along n_g) per obstacle, broadcast shapes (spec 3.2).

    F*_rep1 = k_rep (1/l - 1/l0) rho^n / l^2, F*_rep2 = 0.5 n k_rep (1/l - 1/l0)^2 rho^(n-1); both 0 for
    l > l0, F*_rep2 = 0 for rho < rho_eps.
    """
    bracket = np.where(l <= l0, 1.0 / l - 1.0 / l0, 0.0)
    near_goal = rho < rho_eps
    rho_n = rho**n
    f1 = k_rep * bracket * rho_n / (l * l)
    f2 = np.where(near_goal, 0.0, 0.5 * n * k_rep * bracket * bracket * rho_n / np.where(near_goal, 1.0, rho))
    return f1, f2


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
    """Sum over obstacles of U*_rep = 0.5 k_rep (1/l - 1/l0)^2 rho^n (l <= l0), (N,) (spec 3.2, Eq 9)."""
    l = surface_geometry(q, centres, radii, l_min).l
    rho = np.linalg.norm(q - dest, axis=-1)
    bracket = np.where(l <= l0, 1.0 / l - 1.0 / l0, 0.0)
    return 0.5 * k_rep * (bracket * bracket).sum(axis=1) * rho**n


def adaptive_repulsion_terms(
    q: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    dest: np.ndarray,
    k_rep: float,
    l0: float,
    n: float,
    l_min: float,
    rho_eps: float,
) -> tuple[np.ndarray, np.ndarray]:
    """F*_rep1 (away from the obstacles) and F*_rep2 (toward dest), each (N, D) summed over obstacles
    (spec 3.2, Eqs 10-12)."""
    geo = surface_geometry(q, centres, radii, l_min)
    rho, n_g = goal_distance(q, dest)
    f1, f2 = adaptive_repulsion_scales(geo.l, rho[:, None], k_rep, l0, n, rho_eps)
    return np.einsum("nk,nkd->nd", f1, geo.n_o), f2.sum(axis=1)[:, None] * n_g


def adaptive_repulsion_force(
    q: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    dest: np.ndarray,
    k_rep: float,
    l0: float,
    n: float,
    l_min: float,
    rho_eps: float,
) -> np.ndarray:
    """F*_rep = F*_rep1 + F*_rep2, (N, D) (spec 3.2)."""
    f1, f2 = adaptive_repulsion_terms(q, centres, radii, dest, k_rep, l0, n, l_min, rho_eps)
    return f1 + f2
