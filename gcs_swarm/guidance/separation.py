"""Inter-UAV repulsion and the emergency vertical force (spec 4, paper Eqs 13-20).

Vehicle i feels the others j != i as point sources. Positions `p_at` (N, D) are where the force on each
vehicle is evaluated (its reference point, spec 8 step 2), `p_src` (N, D) where the vehicles are; row i of
both belongs to vehicle i. D = 2 or 3; the emergency force needs D = 3 (z up).
"""

from __future__ import annotations

import math

import numpy as np

from gcs_swarm.guidance.obstacles import squared_distances
from gcs_swarm.guidance.params import SeparationParams
from gcs_swarm.guidance.vector_ops import row_norms

DENSE_PAIRS_MAX = 40_000  # above this many (i, j) candidates, use the hash grid instead of a dense product


def d_max_formula(v_max: float, t_r: float, a_max: float, s_s: float) -> float:
    """D_max = v_max t_r + v_max^2 / (2 a_max) + s_s, m (spec 4, Eq 17)."""
    return v_max * t_r + v_max * v_max / (2.0 * a_max) + s_s


def d_emg_formula(v_re: np.ndarray, a_e: float, s_s: float) -> np.ndarray:
    """D_Emg = v_re^2 / (2 a_e) + s_s per pair, m (spec 4, Eq 20)."""
    return v_re * v_re / (2.0 * a_e) + s_s


def repulsion_range(sep: SeparationParams, v_max: float, a_max: float) -> float:
    """D_max of the configured mode: Table 2 constant or Eq 17 from the motion limits."""
    return sep.d_max if sep.mode == "constant" else d_max_formula(v_max, sep.t_r, a_max, sep.s_s)


def pair_potential(l: np.ndarray, k_uav: float, n: float, d_max: float) -> np.ndarray:
    """U_ij = 0.5 k_uav (1/l - 1/D_max)^2 l^n for l < D_max, else 0 (spec 4, Eq 13 with D_max)."""
    inside = l < d_max
    l_in = np.where(inside, l, d_max)
    bracket = 1.0 / l_in - 1.0 / d_max
    return np.where(inside, 0.5 * k_uav * bracket * bracket * l_in**n, 0.0)


def pair_force_scale(l: np.ndarray, k_uav: float, n: float, d_max: float) -> np.ndarray:
    """|F_ij| = k_uav (1/l - 1/D_max) l^(n-2) (1 - n/2 (1 - l/D_max)) along e_ji, > 0 for 0 < n < 2
    (spec 4, F1 + F2)."""
    bracket = np.where(l < d_max, 1.0 / l - 1.0 / d_max, 0.0)
    return k_uav * bracket * l ** (n - 2.0) * (1.0 - 0.5 * n * (1.0 - l / d_max))


def _grid_candidates(p_at: np.ndarray, p_src: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Candidate pairs from a horizontal hash grid of cell size `cell`: each point against the sources of
    its own and the 8 surrounding cells. Rows of p_at must be finite."""
    src_cell = np.floor(p_src[:, :2] / cell).astype(np.int64)
    at_cell = np.floor(p_at[:, :2] / cell).astype(np.int64)
    low = np.minimum(src_cell.min(axis=0), at_cell.min(axis=0)) - 1
    width = int(max(src_cell[:, 1].max(), at_cell[:, 1].max()) - low[1]) + 2
    src_key = (src_cell[:, 0] - low[0]) * width + (src_cell[:, 1] - low[1])
    order = np.argsort(src_key, kind="stable")
    keys = src_key[order]
    at_key = (at_cell[:, 0] - low[0]) * width + (at_cell[:, 1] - low[1])
    shifts = np.array([dx * width + dy for dx in (-1, 0, 1) for dy in (-1, 0, 1)])
    query = (at_key[:, None] + shifts[None, :]).ravel()
    lo = np.searchsorted(keys, query, side="left")
    counts = np.searchsorted(keys, query, side="right") - lo
    i = np.repeat(np.arange(len(p_at)).repeat(len(shifts)), counts)
    first = np.repeat(lo - (np.cumsum(counts) - counts), counts)
    return i, order[np.arange(len(i)) + first]


def neighbour_pairs(
    p_at: np.ndarray, p_src: np.ndarray, radius: float, same_rows: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) with |p_at[i] - p_src[j]| < radius; `same_rows`: row i of p_at and row i of p_src
    are the same vehicle, so pairs i == j are left out (when p_src is a subset of the vehicles, the caller
    drops self-pairs by vehicle). Rows of p_src must be finite; NaN rows of p_at match nothing.

    Small fleets: one dense matrix product. Large ones: a horizontal hash grid with cells of `radius`, so
    the cost grows with N times the neighbours per cell instead of N^2.
    """
    n_at, n_src = len(p_at), len(p_src)
    if n_at == 0 or n_src == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    if n_at * n_src <= DENSE_PAIRS_MAX:
        i, j = np.nonzero(squared_distances(p_at, p_src) < (radius + 1e-6) ** 2)
    else:
        finite = np.flatnonzero(np.isfinite(p_at).all(axis=1))
        i, j = _grid_candidates(p_at[finite], p_src, radius)
        i = finite[i]
    if same_rows:
        keep = i != j
        i, j = i[keep], j[keep]
    d = p_at[i] - p_src[j]
    near = np.einsum("pd,pd->p", d, d) < radius * radius
    return i[near], j[near]


CLOSING_MARGIN_M = 1.0  # m kept beyond d_emg by the closing-speed cap
CLOSING_RANGE_MAX_M = 200.0  # m, pairs farther apart than this are not checked


def closing_deceleration(sep: SeparationParams, tilt_max: float, g: float) -> float:
    """m/s^2: the deceleration the closing-speed cap assumes, sep.closing_brake_accel bounded by
    sep.closing_brake_tilt_share x g tan(tilt_max) (tilt_max rad, g m/s^2), the horizontal acceleration the
    tilt limit allows; 0 when the cap is off."""
    accel = sep.closing_brake_accel
    if sep.closing_brake_tilt_share > 0.0:
        accel = min(accel, sep.closing_brake_tilt_share * g * math.tan(tilt_max))
    return accel


def closing_speed_caps(
    pos: np.ndarray, vel: np.ndarray, valid: np.ndarray, d_emg: float, accel: float, speed_max: float
) -> np.ndarray:
    """(N,) m/s horizontal speed caps [add]: vehicle i closing on vehicle j at c = (v_i - v_j) . u_ij
    (u_ij the unit vector from i to j) faster than it could stop at `accel` m/s^2 before `d_emg` + 1 m,
    c > sqrt(2 accel (d - d_emg - 1)), is capped at |v_i,xy| - (c - that), but only while its own velocity
    points at j (v_i . u_ij > 0): the vehicle behind slows down, the one ahead is left alone. inf where
    nothing closes in; pairs with an invalid row (`valid` (N,) bool False) are skipped. pos, vel (N, 3) ENU.
    `speed_max` m/s bounds the relative speeds that set the range checked."""
    n = len(pos)
    caps = np.full(n, np.inf)
    if n < 2 or accel <= 0:
        return caps
    reach = d_emg + CLOSING_MARGIN_M + (2.0 * speed_max) ** 2 / (2.0 * accel)
    rows = np.flatnonzero(valid & np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1))
    i, j = neighbour_pairs(pos[rows], pos[rows], min(reach, CLOSING_RANGE_MAX_M), same_rows=True)
    if not len(i):
        return caps
    i, j = rows[i], rows[j]
    rel = pos[j] - pos[i]
    dist = np.sqrt(np.einsum("pd,pd->p", rel, rel))
    unit = rel / np.maximum(dist, 1e-9)[:, None]
    own = np.einsum("pd,pd->p", vel[i], unit)
    closing = own - np.einsum("pd,pd->p", vel[j], unit)
    allowed = np.sqrt(2.0 * accel * np.maximum(dist - d_emg - CLOSING_MARGIN_M, 0.0))
    excess = closing - allowed
    hit = (own > 0.0) & (excess > 0.0)
    speed = np.hypot(vel[i, 0], vel[i, 1])
    np.minimum.at(caps, i[hit], np.maximum(speed[hit] - excess[hit], 0.0))
    return caps


def uav_potential(p_at: np.ndarray, p_src: np.ndarray, k_uav: float, n: float, d_max: float) -> np.ndarray:
    """Sum over j != i of U_ij(|p_at[i] - p_src[j]|), (N,) (dense; for tests and small N)."""
    d = np.linalg.norm(p_at[:, None, :] - p_src[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    return pair_potential(d, k_uav, n, d_max).sum(axis=1)


def uav_repulsion(
    p_at: np.ndarray,
    p_src: np.ndarray,
    vel: np.ndarray,
    k_uav: float,
    n: float,
    d_max: float,
    sep: SeparationParams,
    l_min: float,
    src_valid: np.ndarray | None = None,
    at_vel: np.ndarray | None = None,
    brake_accel: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Total inter-UAV force F_uav,i = sum_j F_uav,ij (N, D) and the emergency flag (N,) (spec 4, Eq 19).

    `vel` (N, D) measured velocities give v_re = |v_i - v_j| in formula mode (Eq 20, D_Emg clamped to
    D_max). Inside D_Emg the pair adds |F_ij| sgn(i - j) z_hat (Eq 18: larger index pushed up). Two vehicles
    at one point (l < l_min) use l_min and direction sgn(i - j) along the last axis. Sources with
    `src_valid` False are ignored.

    [add] With `at_vel` (N, D), the velocities of the evaluation points, and `brake_accel` a_b > 0, a closing
    pair is felt at its closest approach along the relative braking path: the separation
    d = p_at[i] - p_src[j] moving at w = at_vel[i] - vel[j] for |w|^2 / (4 a_b) (both braking at a_b), so two
    vehicles heading for each other start to give way while they can still stop, and sideways (at the
    separation they would pass at) rather than head-on. Pairs moving apart are felt where they are.
    """
    n_veh, dim = p_at.shape
    force = np.zeros((n_veh, dim))
    emergency = np.zeros(n_veh, dtype=bool)
    if src_valid is None:
        src_index = np.arange(n_veh)
    else:
        src_index = np.flatnonzero(src_valid)
    sweep = at_vel is not None and brake_accel > 0.0
    if sweep:
        assert at_vel is not None
        rel_speed_max = np.nanmax(row_norms(at_vel)) + np.nanmax(row_norms(vel))
        reach = d_max + rel_speed_max * rel_speed_max / (4.0 * brake_accel)
    else:
        reach = d_max
    # src_index maps the valid sources back to vehicles; a self-pair is one whose vehicles are equal
    i, jj = neighbour_pairs(p_at, p_src[src_index], reach, same_rows=False)
    j = src_index[jj]
    keep = i != j
    i, j = i[keep], j[keep]
    if len(i) == 0:
        return force, emergency
    diff = p_at[i] - p_src[j]
    if sweep:
        assert at_vel is not None
        w = at_vel[i] - vel[j]
        w_sq = np.einsum("pd,pd->p", w, w)
        length = np.sqrt(w_sq) / (4.0 * brake_accel)  # s of relative motion until both have stopped
        closing = -np.einsum("pd,pd->p", diff, w)
        t_cpa = np.clip(np.divide(closing, w_sq, out=np.zeros_like(closing), where=w_sq > 0.0), 0.0, length)
        diff = diff + w * t_cpa[:, None]
    l = np.sqrt(np.einsum("pd,pd->p", diff, diff))
    near = l < d_max
    i, j, diff, l = i[near], j[near], diff[near], l[near]
    if len(i) == 0:
        return force, emergency
    sign = np.sign(i - j).astype(float)
    coincident = l < l_min
    e_ji = diff / np.where(coincident, 1.0, l)[:, None]
    e_ji[coincident] = 0.0
    e_ji[coincident, -1] = sign[coincident]
    l = np.maximum(l, l_min)
    scale = pair_force_scale(l, k_uav, n, d_max)
    pair_force = scale[:, None] * e_ji
    if sep.mode == "constant":
        d_emg = np.full(len(i), min(sep.d_emg, d_max))
    else:
        v_re = row_norms(vel[i] - vel[j])
        d_emg = np.minimum(d_emg_formula(v_re, sep.a_e, sep.s_s), d_max)
    in_emg = l <= d_emg
    if dim == 3:
        pair_force[:, 2] += np.where(in_emg, scale * sign, 0.0)
    for axis in range(dim):
        force[:, axis] = np.bincount(i, weights=pair_force[:, axis], minlength=n_veh)
    emergency[i[in_emg]] = True
    return force, emergency
