"""The potential field of the configured method (APF baseline or IAAPF) at many points at once.

Obstacle terms are evaluated only for the (vehicle, obstacle) pairs inside the influence distance l0,
so N vehicles x K obstacles costs one N x K matrix product plus work proportional to the close pairs.
Shapes: `q` (N, D), `target`/`dest` (N, D) or (D,), `centres` (K, D), `radii` (K,).
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance import apf, iaapf
from gcs_swarm.guidance.obstacles import squared_distances
from gcs_swarm.guidance.params import FieldParams


def attraction(q: np.ndarray, target: np.ndarray, fp: FieldParams, d_g: float) -> np.ndarray:
    """F_att (APF, spec 2) or F*_att (IAAPF, spec 3.1) toward `target`, (N, D)."""
    if fp.method == "apf":
        return apf.attraction_force(q, target, fp.k_att)
    return iaapf.segmented_attraction_force(q, target, fp.k_att, d_g)


def obstacle_repulsion(
    q: np.ndarray, dest: np.ndarray, centres: np.ndarray, radii: np.ndarray, fp: FieldParams
) -> tuple[np.ndarray, np.ndarray]:
    """Summed obstacle repulsion (N, D) and the collision flag (N,): at or inside an obstacle (spec 2.1).

    APF: F_rep (spec 2); IAAPF: F*_rep1 + F*_rep2 with the adaptive factor rho^n of the distance to
    `dest` (spec 3.2).
    """
    n_pts, dim = q.shape
    force = np.zeros((n_pts, dim))
    if len(radii) == 0 or n_pts == 0:
        return force, np.zeros(n_pts, dtype=bool)
    reach = radii + fp.l0 + 1e-6  # slack for the rounding of the matrix-product distances
    i, k = np.nonzero(squared_distances(q, centres) <= (reach * reach)[None, :])
    diff = q[i] - centres[k]
    d = np.sqrt(np.einsum("pd,pd->p", diff, diff))
    raw = d - radii[k]
    inside = np.zeros(n_pts, dtype=bool)
    inside[i[raw <= 0.0]] = True
    near = raw <= fp.l0
    i, k, diff, d, raw = i[near], k[near], diff[near], d[near], raw[near]
    if len(i) == 0:
        return force, inside
    l = np.maximum(raw, fp.l_min)
    on_centre = d == 0.0
    n_o = diff / np.where(on_centre, 1.0, d)[:, None]
    n_o[on_centre, -1] = 1.0
    if fp.method == "apf":
        pair = apf.repulsion_scale(l, fp.k_rep, fp.l0)[:, None] * n_o
    else:
        rho, n_g = iaapf.goal_distance(q, np.broadcast_to(dest, q.shape))
        f1, f2 = iaapf.adaptive_repulsion_scales(l, rho[i], fp.k_rep, fp.l0, fp.n, fp.rho_eps)
        pair = f1[:, None] * n_o + f2[:, None] * n_g[i]
    for axis in range(dim):
        force[:, axis] = np.bincount(i, weights=pair[:, axis], minlength=n_pts)
    return force, inside
