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
from gcs_swarm.guidance.vector_ops import row_norms

HEAD_ON_BIAS = 0.05  # share of the right-hand side mixed into the way round, so a dead-ahead obstacle has one


def attraction(q: np.ndarray, target: np.ndarray, fp: FieldParams, d_g: float) -> np.ndarray:
    """F_att (APF, spec 2) or F*_att (IAAPF, spec 3.1) toward `target`, (N, D)."""
    if fp.method == "apf":
        return apf.attraction_force(q, target, fp.k_att)
    return iaapf.segmented_attraction_force(q, target, fp.k_att, d_g)


def nearest_on_segments(start: np.ndarray, end: np.ndarray, i: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """For pairs (i, k): the point (P, D) of segment i, from start[i] to end[i] (N, D), nearest to centres
    (P, D) (the pair's obstacle centre)."""
    seg = end[i] - start[i]
    length_sq = np.einsum("pd,pd->p", seg, seg)
    along = np.einsum("pd,pd->p", centres - start[i], seg)
    frac = np.clip(np.divide(along, length_sq, out=np.zeros_like(along), where=length_sq > 0.0), 0.0, 1.0)
    return start[i] + seg * frac[:, None]


def obstacle_repulsion(
    q: np.ndarray,
    dest: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    fp: FieldParams,
    ahead: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Summed obstacle repulsion (N, D) and the collision flag (N,): an evaluation point (q, or with `ahead`
    a point of the braking path) at or inside an obstacle (spec 2.1).

    APF: F_rep (spec 2); IAAPF: F*_rep1 + F*_rep2 with the adaptive factor rho^n of the distance to
    `dest` (spec 3.2). With `ahead` (N, D) [add], each obstacle's force on vehicle i is evaluated at the
    point of the segment q[i] -> ahead[i] nearest to that obstacle's centre (the braking path,
    gcs_swarm.guidance.reference.ReferenceGenerator.lookahead_points): an obstacle ahead is felt as soon
    as the vehicle could no longer stop short of it, one alongside or behind exactly as at q.
    """
    n_pts, dim = q.shape
    force = np.zeros((n_pts, dim))
    if len(radii) == 0 or n_pts == 0:
        return force, np.zeros(n_pts, dtype=bool)
    reach = radii + fp.l0 + 1e-6  # slack for the rounding of the matrix-product distances
    if ahead is None:
        i, k = np.nonzero(squared_distances(q, centres) <= (reach * reach)[None, :])
        at = q[i]
    else:
        # candidates: obstacles within reach of the segment's bounding sphere, then the exact nearest point
        middle, half = 0.5 * (q + ahead), 0.5 * row_norms(ahead - q)
        bound = reach[None, :] + half[:, None]
        i, k = np.nonzero(squared_distances(middle, centres) <= bound * bound)
        at = nearest_on_segments(q, ahead, i, centres[k])
    diff = at - centres[k]
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
    rho, n_g = iaapf.goal_distance(at[near], dest[i] if dest.ndim == 2 else dest)
    if fp.method == "apf":
        f1 = apf.repulsion_scale(l, fp.k_rep, fp.l0)
        pair = f1[:, None] * n_o
    else:
        f1, f2 = iaapf.adaptive_repulsion_scales(l, rho, fp.k_rep, fp.l0, fp.n, fp.rho_eps)
        pair = f1[:, None] * n_o + f2[:, None] * n_g
    if fp.circulation > 0.0 and dim == 3:
        pair += circulation(f1, n_o, n_g, fp.circulation)
    if dim == 3:
        pair[:, 2] *= fp.obstacle_vertical  # [add] 1 = the paper's 3-D repulsion
    for axis in range(dim):
        force[:, axis] = np.bincount(i, weights=pair[:, axis], minlength=n_pts)
    return force, inside


def circulation(f1: np.ndarray, n_o: np.ndarray, n_g: np.ndarray, gain: float) -> np.ndarray:
    """[add] Tangential companion of the obstacle repulsion, (P, 3) for P (vehicle, obstacle) pairs: the
    horizontal unit vector across n_o (P, 3) on the side where the goal direction n_g (P, 3) leads,
    scaled by gain * |F_rep1| (f1 (P,)) * max(0, -n_o . n_g), i.e. only while the obstacle stands between the
    vehicle and its goal. The paper's repulsion pushes straight back from an obstacle ahead, so a goal behind
    it is a saddle where the vehicle stalls (exactly head-on, for ever); this turns the push into a way
    round, as a vortex field does. An obstacle dead ahead is passed on the right (a small fixed bias keeps
    the side continuous)."""
    across = np.stack([-n_o[:, 1], n_o[:, 0], np.zeros(len(n_o))], axis=1)  # right of the travel, -n_o
    toward_goal = n_g - np.einsum("pd,pd->p", n_g, n_o)[:, None] * n_o
    toward_goal[:, 2] = 0.0
    side = toward_goal + HEAD_ON_BIAS * np.einsum("pd,pd->p", across, across)[:, None] * across
    length = row_norms(side)
    unit = np.divide(side, length[:, None], out=np.zeros_like(side), where=length[:, None] > 0.0)
    blocking = np.maximum(-np.einsum("pd,pd->p", n_o, n_g), 0.0)
    return (gain * f1 * blocking)[:, None] * unit
