"""Inter-UAV repulsion and the emergency vertical force (spec 4, paper Eqs 13-20), and the closing-speed
caps [add].

Vehicle i feels the others j != i as point sources. Positions `p_at` (N, 3) are where the force on each
vehicle is evaluated (its reference point, spec 8 step 2), `p_src` (N, 3) where the vehicles are; row i of
both belongs to vehicle i. ENU m, m/s; z up. The pair search, the forces and the caps are compiled kernels
(swarm_common.jit); `uav_repulsion` raises the distances to the power n - 2 with numpy between them. The
potentials (`pair_potential`, `uav_potential`) are the spec's, for tests that difference them.

Pair search: small fleets test every (i, j) pair; above DENSE_PAIRS_MAX candidate pairs a horizontal hash
grid with cells of the search radius gives the candidates (own and the 8 surrounding cells), so the cost
grows with N times the neighbours per cell instead of N^2. The forces are summed in pair order either way.
"""

from __future__ import annotations

import math

import numpy as np

from gcs_swarm.guidance.params import FieldParams, SeparationParams
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip, dot3, maximum, minimum, norm3

DENSE_PAIRS_MAX = 40_000  # above this many (i, j) candidates, use the hash grid instead of testing all
CLOSING_MARGIN_M = 1.0  # m kept beyond d_emg by the closing-speed cap
CLOSING_RANGE_MAX_M = 200.0  # m, pairs farther apart than this are not checked


def d_max_formula(v_max: float, t_r: float, a_max: float, s_s: float) -> float:
    """D_max = v_max t_r + v_max^2 / (2 a_max) + s_s, m (spec 4, Eq 17)."""
    return v_max * t_r + v_max * v_max / (2.0 * a_max) + s_s


def repulsion_range(sep: SeparationParams, v_max: float, a_max: float) -> float:
    """D_max of the configured mode: Table 2 constant or Eq 17 from the motion limits."""
    return sep.d_max if sep.mode == "constant" else d_max_formula(v_max, sep.t_r, a_max, sep.s_s)


def pair_potential(l: np.ndarray, k_uav: float, n: float, d_max: float) -> np.ndarray:
    """U_ij = 0.5 k_uav (1/l - 1/D_max)^2 l^n for l < D_max, else 0 (spec 4, Eq 13 with D_max)."""
    inside = l < d_max
    l_in = np.where(inside, l, d_max)
    bracket = 1.0 / l_in - 1.0 / d_max
    return np.where(inside, 0.5 * k_uav * bracket * bracket * l_in**n, 0.0)


def uav_potential(p_at: np.ndarray, p_src: np.ndarray, k_uav: float, n: float, d_max: float) -> np.ndarray:
    """Sum over j != i of U_ij(|p_at[i] - p_src[j]|), (N,) (dense; for tests and small N)."""
    d = np.linalg.norm(p_at[:, None, :] - p_src[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    return pair_potential(d, k_uav, n, d_max).sum(axis=1)


def closing_deceleration(sep: SeparationParams, tilt_max: float, g: float) -> float:
    """m/s^2: the deceleration the closing-speed cap assumes, sep.closing_brake_accel bounded by
    sep.closing_brake_tilt_share x g tan(tilt_max) (tilt_max rad, g m/s^2), the horizontal acceleration the
    tilt limit allows; 0 when the cap is off."""
    accel = sep.closing_brake_accel
    if sep.closing_brake_tilt_share > 0.0:
        accel = min(accel, sep.closing_brake_tilt_share * g * math.tan(tilt_max))
    return accel


def closing_range(d_emg: float, accel: float, speed_max: float) -> float:
    """m: how far apart `closing_speed_caps` checks pairs: d_emg + 1 m plus the distance two vehicles
    closing at 2 speed_max m/s need to stop at accel m/s^2, at most CLOSING_RANGE_MAX_M."""
    reach = d_emg + CLOSING_MARGIN_M + (2.0 * speed_max) ** 2 / (2.0 * accel)
    return min(reach, CLOSING_RANGE_MAX_M)


@kernel
def _largest_norm(v: np.ndarray) -> float:
    """The largest |v| of the rows of (N, 3) that are not NaN (np.nanmax's rule: NaN when all are)."""
    largest = np.nan
    for r in range(v.shape[0]):
        x = norm3(v[r, 0], v[r, 1], v[r, 2])
        if x > largest or (largest != largest and x == x):
            largest = x
    return largest


@kernel
def _stable_order(keys: np.ndarray) -> np.ndarray:
    """The indices (M,) that sort the integer `keys` (M,), equal keys in index order (bottom-up merge)."""
    n = keys.shape[0]
    order = np.empty(n, dtype=np.intp)
    for i in range(n):
        order[i] = i
    merged = np.empty(n, dtype=np.intp)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid, hi = min(lo + width, n), min(lo + 2 * width, n)
            i, j = lo, mid
            for k in range(lo, hi):
                if j >= hi or (i < mid and keys[order[i]] <= keys[order[j]]):
                    merged[k] = order[i]
                    i += 1
                else:
                    merged[k] = order[j]
                    j += 1
        order, merged = merged, order
        width *= 2
    return order


@kernel
def _first_at_least(keys: np.ndarray, value: int) -> int:
    """The first index of the increasing `keys` whose key is >= value (keys.shape[0] if none)."""
    lo, hi = 0, keys.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if keys[mid] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@kernel
def _grid_order(p_at: np.ndarray, rows: np.ndarray, p_src: np.ndarray, cell: float) -> np.ndarray:
    """The hash grid's candidates: for each at-row of `rows`, in order, the source indices of its own and
    the 8 surrounding horizontal cells of size `cell` m, cell by cell (dx, then dy, from -1), each cell's
    sources in index order. Returns (candidates, 2) index pairs (at row, source)."""
    n_src, n_rows = p_src.shape[0], rows.shape[0]
    src_cell = np.empty((n_src, 2), dtype=np.int64)
    at_cell = np.empty((n_rows, 2), dtype=np.int64)
    for j in range(n_src):
        for d in range(2):
            src_cell[j, d] = np.int64(np.floor(p_src[j, d] / cell))
    for r in range(n_rows):
        for d in range(2):
            at_cell[r, d] = np.int64(np.floor(p_at[rows[r], d] / cell))
    low0, low1, high1 = src_cell[0, 0], src_cell[0, 1], src_cell[0, 1]
    for cells in (src_cell, at_cell):
        for m in range(cells.shape[0]):
            low0, low1, high1 = min(low0, cells[m, 0]), min(low1, cells[m, 1]), max(high1, cells[m, 1])
    low0, low1 = low0 - 1, low1 - 1
    width = high1 - low1 + 2  # keys of neighbouring columns never meet
    src_key = np.empty(n_src, dtype=np.int64)
    for j in range(n_src):
        src_key[j] = (src_cell[j, 0] - low0) * width + (src_cell[j, 1] - low1)
    order = _stable_order(src_key)
    keys = np.empty(n_src, dtype=np.int64)
    for m in range(n_src):
        keys[m] = src_key[order[m]]
    out = np.empty((0, 2), dtype=np.intp)
    for fill in (False, True):  # count the candidates, then write them
        p = 0
        for r in range(n_rows):
            at_key = (at_cell[r, 0] - low0) * width + (at_cell[r, 1] - low1)
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    query = at_key + dx * width + dy
                    for m in range(_first_at_least(keys, query), _first_at_least(keys, query + 1)):
                        if fill:
                            out[p, 0], out[p, 1] = rows[r], order[m]
                        p += 1
        if not fill:
            out = np.empty((p, 2), dtype=np.intp)
    return out


@kernel
def neighbour_pairs(p_at: np.ndarray, p_src: np.ndarray, radius: float) -> np.ndarray:
    """Index pairs (P, 2) (i, j) (j indexes p_src (M, 3)) with |p_at[i] - p_src[j]| < radius m, in (i, j)
    order (the hash grid's visiting order above DENSE_PAIRS_MAX candidates). Rows of p_src must be finite;
    NaN rows of p_at match nothing."""
    n_at, n_src = p_at.shape[0], p_src.shape[0]
    if n_at * n_src <= DENSE_PAIRS_MAX:
        candidates = np.empty((n_at * n_src, 2), dtype=np.intp)
        m = 0
        for i in range(n_at):
            for j in range(n_src):
                candidates[m, 0], candidates[m, 1] = i, j
                m += 1
    else:
        finite = np.empty(n_at, dtype=np.intp)
        f = 0
        for i in range(n_at):
            if np.isfinite(p_at[i, 0]) and np.isfinite(p_at[i, 1]) and np.isfinite(p_at[i, 2]):
                finite[f] = i
                f += 1
        if f == 0:
            return np.empty((0, 2), dtype=np.intp)
        candidates = _grid_order(p_at, finite[:f], p_src, radius)
    out = np.empty_like(candidates)
    r_sq = radius * radius
    p = 0
    for m in range(candidates.shape[0]):
        i, j = candidates[m, 0], candidates[m, 1]
        d0, d1, d2 = p_at[i, 0] - p_src[j, 0], p_at[i, 1] - p_src[j, 1], p_at[i, 2] - p_src[j, 2]
        if dot3(d0, d1, d2, d0, d1, d2) < r_sq:
            out[p, 0], out[p, 1] = i, j
            p += 1
    return out[:p]


@kernel
def uav_pairs(
    p_at: np.ndarray, p_src: np.ndarray, vel: np.ndarray, at_vel: np.ndarray, src_valid: np.ndarray,
    d_max: float, l_min: float, brake_accel: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The pairs (P, 2) (i, j), j != i a valid source (src_valid (N,)), closer than d_max m, with the unit
    vectors e_ji (P, 3) from j to i and l = max(distance, l_min) (P,). Two vehicles at one point
    (distance < l_min) get the direction sgn(i - j) z.

    [add] With brake_accel a_b > 0, a closing pair is felt at its closest approach along the relative
    braking path: the separation d = p_at[i] - p_src[j] moving at w = at_vel[i] - vel[j] for
    |w| / (4 a_b) s (both braking at a_b), so two vehicles heading for each other start to give way while
    they can still stop, and sideways (at the separation they would pass at) rather than head-on. Pairs
    moving apart are felt where they are."""
    n = p_at.shape[0]
    src_index = np.flatnonzero(src_valid)
    sweep = brake_accel > 0.0
    if sweep:
        rel_speed_max = _largest_norm(at_vel) + _largest_norm(vel)
        reach = d_max + rel_speed_max * rel_speed_max / (4.0 * brake_accel)
    else:
        reach = d_max
    src = np.empty((src_index.shape[0], 3))
    for m in range(src_index.shape[0]):
        for d in range(3):
            src[m, d] = p_src[src_index[m], d]
    candidates = (
        neighbour_pairs(p_at, src, reach) if n > 0 and src.shape[0] > 0 else np.empty((0, 2), np.intp)
    )
    pairs = np.empty_like(candidates)
    e_ji = np.empty((candidates.shape[0], 3))
    l_out = np.empty(candidates.shape[0])
    p = 0
    for m in range(candidates.shape[0]):
        i, j = candidates[m, 0], src_index[candidates[m, 1]]
        if i == j:
            continue
        d0, d1, d2 = p_at[i, 0] - p_src[j, 0], p_at[i, 1] - p_src[j, 1], p_at[i, 2] - p_src[j, 2]
        if sweep:
            w0, w1, w2 = at_vel[i, 0] - vel[j, 0], at_vel[i, 1] - vel[j, 1], at_vel[i, 2] - vel[j, 2]
            w_sq = dot3(w0, w1, w2, w0, w1, w2)
            length = math.sqrt(w_sq) / (4.0 * brake_accel)
            closing = -dot3(d0, d1, d2, w0, w1, w2)
            t_cpa = clip(closing / w_sq if w_sq > 0.0 else 0.0, 0.0, length)
            d0, d1, d2 = d0 + w0 * t_cpa, d1 + w1 * t_cpa, d2 + w2 * t_cpa
        dist = math.sqrt(dot3(d0, d1, d2, d0, d1, d2))
        if not dist < d_max:
            continue
        pairs[p, 0], pairs[p, 1] = i, j
        if dist < l_min:
            e_ji[p, 0], e_ji[p, 1], e_ji[p, 2] = 0.0, 0.0, 1.0 if i > j else -1.0
        else:
            e_ji[p, 0], e_ji[p, 1], e_ji[p, 2] = d0 / dist, d1 / dist, d2 / dist
        l_out[p] = maximum(dist, l_min)
        p += 1
    return pairs[:p], e_ji[:p], l_out[:p]


@kernel
def uav_forces(
    n: int, pairs: np.ndarray, e_ji: np.ndarray, l: np.ndarray, l_pow: np.ndarray, vel: np.ndarray,
    k_uav: float, n_exp: float, d_max: float, formula: bool, d_emg: float, a_e: float, s_s: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The force (n, 3) and emergency flags (n,) of the pairs of `uav_pairs` (l_pow = l^(n-2) (P,)):
    |F_ij| = k_uav (1/l - 1/D_max) l^(n-2) (1 - n/2 (1 - l/D_max)) along e_ji (spec 4, F1 + F2), plus
    |F_ij| sgn(i - j) z inside D_Emg (Eq 18: the larger index pushed up), which also flags vehicle i.
    D_Emg: `formula` Eq 20 from the velocities (N, 3), at most d_max, else the constant `d_emg`."""
    force = np.zeros((n, 3))
    emergency = np.zeros(n, dtype=np.bool_)
    half_n = 0.5 * n_exp
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        lp = l[p]
        bracket = 1.0 / lp - 1.0 / d_max if lp < d_max else 0.0
        scale = k_uav * bracket * l_pow[p] * (1.0 - half_n * (1.0 - lp / d_max))
        sign = 1.0 if i > j else -1.0
        if formula:
            v_re = norm3(vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1], vel[i, 2] - vel[j, 2])
            limit = minimum(v_re * v_re / (2.0 * a_e) + s_s, d_max)
        else:
            limit = d_emg
        in_emg = lp <= limit
        force[i, 0] += scale * e_ji[p, 0]
        force[i, 1] += scale * e_ji[p, 1]
        force[i, 2] += scale * e_ji[p, 2] + (scale * sign if in_emg else 0.0)
        if in_emg:
            emergency[i] = True
    return force, emergency


@kernel
def closing_speed_caps(
    pos: np.ndarray, vel: np.ndarray, valid: np.ndarray, d_emg: float, accel: float, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """(N,) m/s horizontal speed caps [add]: vehicle i closing on vehicle j at c = (v_i - v_j) . u_ij
    (u_ij the unit vector from i to j) faster than it could stop at `accel` m/s^2 before d_emg + 1 m,
    c > sqrt(2 accel (d - d_emg - 1)), is capped at |v_i,xy| - (c - that), but only while its own velocity
    points at j (v_i . u_ij > 0): the vehicle behind slows down, the one ahead is left alone. inf where
    nothing closes in; rows not `valid` (N,) or not finite are skipped; pairs farther apart than `radius`
    m (closing_range) are not checked. pos, vel (N, 3) ENU.

    Also the (N,) bool rows `on_course` whose cap comes from a pair that, flying on at their velocities,
    would pass closer than d_emg + 1 m (their closest approach in 3D): a cap on two vehicles that close
    in but would pass wide of each other only keeps their closing speed within what they could stop from."""
    n = pos.shape[0]
    caps = np.full(n, np.inf)
    on_course = np.zeros(n, dtype=np.bool_)
    if n < 2 or accel <= 0:
        return caps, on_course
    rows = np.empty(n, dtype=np.intp)
    m = 0
    for r in range(n):
        ok = valid[r]
        for d in range(3):
            ok = ok and np.isfinite(pos[r, d]) and np.isfinite(vel[r, d])
        if ok:
            rows[m] = r
            m += 1
    rows = rows[:m]
    sub = np.empty((m, 3))
    for r in range(m):
        for d in range(3):
            sub[r, d] = pos[rows[r], d]
    pairs = neighbour_pairs(sub, sub, radius)
    for p in range(pairs.shape[0]):
        i, j = rows[pairs[p, 0]], rows[pairs[p, 1]]
        if i == j:
            continue
        r0, r1, r2 = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
        dist = math.sqrt(dot3(r0, r1, r2, r0, r1, r2))
        floor = maximum(dist, 1e-9)
        u0, u1, u2 = r0 / floor, r1 / floor, r2 / floor
        own = dot3(vel[i, 0], vel[i, 1], vel[i, 2], u0, u1, u2)
        closing = own - dot3(vel[j, 0], vel[j, 1], vel[j, 2], u0, u1, u2)
        allowed = math.sqrt(2.0 * accel * maximum(dist - d_emg - CLOSING_MARGIN_M, 0.0))
        excess = closing - allowed
        if own > 0.0 and excess > 0.0:
            speed = np.hypot(vel[i, 0], vel[i, 1])
            caps[i] = minimum(caps[i], maximum(speed - excess, 0.0))
            w0, w1, w2 = vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1], vel[i, 2] - vel[j, 2]
            t_cpa = dot3(r0, r1, r2, w0, w1, w2) / dot3(w0, w1, w2, w0, w1, w2)  # > 0: they close in
            m0, m1, m2 = r0 - w0 * t_cpa, r1 - w1 * t_cpa, r2 - w2 * t_cpa
            if dot3(m0, m1, m2, m0, m1, m2) < (d_emg + CLOSING_MARGIN_M) ** 2:
                on_course[i] = True
    return caps, on_course


def uav_repulsion(
    p_at: np.ndarray,
    p_src: np.ndarray,
    vel: np.ndarray,
    src_valid: np.ndarray,
    at_vel: np.ndarray,
    brake_accel: float,
    fp: FieldParams,
    d_max: float,
    formula: bool,
    d_emg: float,
    a_e: float,
    s_s: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Total inter-UAV force F_uav,i = sum_j F_uav,ij (N, 3) and the emergency flags (N,) (spec 4, Eq 19),
    gains fp.k_uav, exponent fp.n_uav, range d_max m, floor fp.l_min; sources with src_valid (N,) False are
    ignored. Emergency range D_Emg: `formula` Eq 20 v_re^2 / (2 a_e) + s_s from the velocities vel (N, 3)
    (at most d_max), else the constant d_emg (already at most d_max). [add] The braking sweep with at_vel,
    brake_accel (uav_pairs)."""
    pairs, e_ji, l = uav_pairs(
        p_at, p_src, vel, at_vel, src_valid, float(d_max), float(fp.l_min), brake_accel
    )
    if not len(l):
        return np.zeros((len(p_at), 3)), np.zeros(len(p_at), dtype=bool)
    l_pow = l ** (fp.n_uav - 2.0)
    return uav_forces(
        len(p_at), pairs, e_ji, l, l_pow, vel, float(fp.k_uav), float(fp.n_uav), float(d_max), formula,
        float(d_emg), float(a_e), float(s_s),
    )  # fmt: skip
