"""Compiled twins of the tick's field and separation stages (gcs_swarm.guidance.field, separation,
failsafe_speed), one scalar loop per stage instead of dozens of small numpy calls.

Same bits as the numpy functions, by construction and by test (tests/gcs_swarm/guidance/test_field_kernels.py,
and the closed-loop replay test_tick_replay.py): every operation is the numpy code's IEEE operation in the
same order, reductions sum in numpy's order (`_dot3`: np.einsum("pd,pd->p") over three components adds (x0 y0
+ x2 y2) + x1 y1 to a zero; `_norm3`: np.add.reduce adds left to right, from the first term; np.bincount adds
the pairs in their order to a zero), and max/min/clip/sign follow numpy's NaN and signed-zero rules
(shaping_kernels). Transcendental functions (the powers rho^n and l^(n-2) of the IAAPF and inter-UAV terms)
are not evaluated here: numpy's SIMD versions differ from libm in the last bit, so each stage stops where a
power is needed and the caller evaluates it with numpy on the very array the numpy code would (the split
stages below: pairs first, forces after).

Candidate pairs: the numpy code prefilters pairs by squared distances from a matrix product (rounding up to
about 1e-16 of the scene's squared extent) with 1e-6 m of slack, then keeps those that pass an exact test;
these kernels apply the exact test to every pair, which keeps the same pairs (the slack exceeds the rounding
by orders of magnitude for any scene smaller than hundreds of kilometres). Above DENSE_PAIRS_MAX candidate
pairs the inter-UAV pairs come from the same horizontal hash grid as separation.neighbour_pairs, visited in
its order (so the forces sum in the same order).

No fastmath (it would reorder and contract); error_model "numpy" (x / 0 gives inf or NaN). Compiled at import
with cache=True (numba's cache makes later imports cheap); importing requires numba (extra "fast").
Shapes: N vehicles, K obstacles, P pairs; ENU m, m/s, m/s^2.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_swarm.guidance.field import HEAD_ON_BIAS
from gcs_swarm.guidance.separation import CLOSING_MARGIN_M, DENSE_PAIRS_MAX
from gcs_swarm.guidance.shaping_kernels import _clip, _clip_to_scalars, _maximum

_scalar = njit(cache=True, error_model="numpy", inline="always")
_kernel = njit(cache=True, error_model="numpy")


@_scalar
def _minimum(a: float, b: float) -> float:
    """np.minimum of two floats: NaN if either is, else the smaller; b when they compare equal (+-0)."""
    return a if (a < b or a != a) else b


@_scalar
def _dot3(x0: float, x1: float, x2: float, y0: float, y1: float, y2: float) -> float:
    """np.einsum("pd,pd->p") of one row of three: (x0 y0 + x2 y2) + x1 y1, added to a zero (-0 -> +0)."""
    return (x0 * y0 + x2 * y2) + x1 * y1 + 0.0


@_scalar
def _norm3(x0: float, x1: float, x2: float) -> float:
    """vector_ops.row_norms of one row of three: sqrt((x0^2 + x1^2) + x2^2)."""
    return math.sqrt((x0 * x0 + x1 * x1) + x2 * x2)


@_kernel
def row_norms(v: np.ndarray) -> np.ndarray:
    """vector_ops.row_norms of (N, 3) rows, (N,)."""
    n = v.shape[0]
    out = np.empty(n)
    for r in range(n):
        out[r] = _norm3(v[r, 0], v[r, 1], v[r, 2])
    return out


@_kernel
def obstacle_pairs(
    q: np.ndarray, ahead: np.ndarray, dest: np.ndarray, centres: np.ndarray, radii: np.ndarray, l0: float,
    l_min: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """First half of field.obstacle_repulsion with `ahead` (3-D): the (vehicle, obstacle) pairs whose
    evaluation point (the point of the segment q[i] -> ahead[i] (N, 3) nearest the obstacle's centre) is
    within l0 m of the surface, in (i, k) order. Returns the vehicle index i (P,), l = max(surface distance,
    l_min) (P,), the unit vectors n_o centre -> point (P, 3) and n_g point -> dest[i] (P, 3) ((N, 3)
    destinations), and rho (P,) the point's distance to dest[i] (raise it to the power n with numpy:
    field.obstacle_repulsion's rho**n)."""
    n, k_obs = q.shape[0], radii.shape[0]
    size = n * k_obs
    vehicle = np.empty(size, dtype=np.intp)
    l_out = np.empty(size)
    rho_out = np.empty(size)
    n_o = np.empty((size, 3))
    n_g = np.empty((size, 3))
    p = 0
    for i in range(n):
        s0, s1, s2 = q[i, 0], q[i, 1], q[i, 2]
        g0, g1, g2 = ahead[i, 0] - s0, ahead[i, 1] - s1, ahead[i, 2] - s2  # field.nearest_on_segments
        length_sq = _dot3(g0, g1, g2, g0, g1, g2)
        for k in range(k_obs):
            c0, c1, c2 = centres[k, 0], centres[k, 1], centres[k, 2]
            along = _dot3(c0 - s0, c1 - s1, c2 - s2, g0, g1, g2)
            frac = _clip_to_scalars(along / length_sq if length_sq > 0.0 else 0.0, 0.0, 1.0)
            a0, a1, a2 = s0 + g0 * frac, s1 + g1 * frac, s2 + g2 * frac
            d0, d1, d2 = a0 - c0, a1 - c1, a2 - c2
            d = math.sqrt(_dot3(d0, d1, d2, d0, d1, d2))
            raw = d - radii[k]
            if not raw <= l0:
                continue
            vehicle[p] = i
            l_out[p] = _maximum(raw, l_min)
            safe = 1.0 if d == 0.0 else d
            n_o[p, 0], n_o[p, 1], n_o[p, 2] = d0 / safe, d1 / safe, d2 / safe
            if d == 0.0:
                n_o[p, 2] = 1.0
            e0, e1, e2 = dest[i, 0] - a0, dest[i, 1] - a1, dest[i, 2] - a2  # iaapf.goal_distance
            rho = _norm3(e0, e1, e2)
            div = rho if rho > 0.0 else 1.0
            n_g[p, 0], n_g[p, 1], n_g[p, 2] = e0 / div, e1 / div, e2 / div
            rho_out[p] = rho
            p += 1
    return vehicle[:p], l_out[:p], n_o[:p], n_g[:p], rho_out[:p]


@_kernel
def obstacle_forces(
    n: int, vehicle: np.ndarray, l: np.ndarray, n_o: np.ndarray, n_g: np.ndarray, rho: np.ndarray,
    rho_n: np.ndarray, iaapf: bool, k_rep: float, l0: float, n_exp: float, rho_eps: float, circulation: float,
    obstacle_vertical: float,
) -> np.ndarray:  # fmt: skip
    """Second half of field.obstacle_repulsion (3-D): the summed repulsion (n, 3) of the pairs from
    obstacle_pairs, with rho_n = rho**n (P,) from numpy (IAAPF) and `iaapf` False for the APF baseline."""
    force = np.zeros((n, 3))
    bracket_scale = 0.5 * n_exp * k_rep
    for p in range(vehicle.shape[0]):
        lp = l[p]
        o0, o1, o2 = n_o[p, 0], n_o[p, 1], n_o[p, 2]
        g0, g1, g2 = n_g[p, 0], n_g[p, 1], n_g[p, 2]
        if iaapf:  # iaapf.adaptive_repulsion_scales
            bracket = 1.0 / lp - 1.0 / l0 if lp <= l0 else 0.0
            f1 = k_rep * bracket * rho_n[p] / (lp * lp)
            if rho[p] < rho_eps:
                f2 = 0.0
            else:
                f2 = bracket_scale * bracket * bracket * rho_n[p] / rho[p]
            x0, x1, x2 = f1 * o0 + f2 * g0, f1 * o1 + f2 * g1, f1 * o2 + f2 * g2
        else:  # apf.repulsion_scale
            f1 = k_rep * (1.0 / lp - 1.0 / l0) / (lp * lp) if lp <= l0 else 0.0
            x0, x1, x2 = f1 * o0, f1 * o1, f1 * o2
        if circulation > 0.0:  # field.circulation
            r0, r1, r2 = -o1, o0, 0.0
            dot = _dot3(g0, g1, g2, o0, o1, o2)
            t0, t1, t2 = g0 - dot * o0, g1 - dot * o1, 0.0
            bias = HEAD_ON_BIAS * _dot3(r0, r1, r2, r0, r1, r2)
            w0, w1, w2 = t0 + bias * r0, t1 + bias * r1, t2 + bias * r2
            length = _norm3(w0, w1, w2)
            if length > 0.0:
                w0, w1, w2 = w0 / length, w1 / length, w2 / length
            else:
                w0, w1, w2 = 0.0, 0.0, 0.0
            blocking = _maximum(-_dot3(o0, o1, o2, g0, g1, g2), 0.0)
            c = circulation * f1 * blocking
            x0, x1, x2 = x0 + c * w0, x1 + c * w1, x2 + c * w2
        x2 = x2 * obstacle_vertical
        i = vehicle[p]
        force[i, 0] += x0
        force[i, 1] += x1
        force[i, 2] += x2
    return force


@_kernel
def attraction(q: np.ndarray, target: np.ndarray, k_att: float, d_g: float, segmented: bool) -> np.ndarray:
    """field.attraction (N, 3): iaapf.segmented_attraction_force, or apf.attraction_force."""
    n = q.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        d0, d1, d2 = q[i, 0] - target[i, 0], q[i, 1] - target[i, 1], q[i, 2] - target[i, 2]
        if segmented:
            rho = _norm3(d0, d1, d2)
            scale = -k_att * (1.0 if rho <= d_g else d_g / _maximum(rho, d_g))
            out[i, 0], out[i, 1], out[i, 2] = scale * d0, scale * d1, scale * d2
        else:
            out[i, 0], out[i, 1], out[i, 2] = -k_att * d0, -k_att * d1, -k_att * d2
    return out


@_kernel
def _grid_order(p_at: np.ndarray, rows: np.ndarray, p_src: np.ndarray, cell: float) -> np.ndarray:
    """separation._grid_candidates: for each at-row of `rows`, in order, the source indices of its own and the
    8 surrounding horizontal cells of size `cell`, cell by cell (dx, then dy, from -1), each cell's sources in
    index order. Returns (candidates, 2) index pairs (at row, source)."""
    n_src = p_src.shape[0]
    src_cell = np.empty((n_src, 2), dtype=np.int64)
    for j in range(n_src):
        src_cell[j, 0] = np.int64(np.floor(p_src[j, 0] / cell))
        src_cell[j, 1] = np.int64(np.floor(p_src[j, 1] / cell))
    at_cell = np.empty((rows.shape[0], 2), dtype=np.int64)
    for r in range(rows.shape[0]):
        at_cell[r, 0] = np.int64(np.floor(p_at[rows[r], 0] / cell))
        at_cell[r, 1] = np.int64(np.floor(p_at[rows[r], 1] / cell))
    low0 = min(src_cell[:, 0].min(), at_cell[:, 0].min()) - 1
    low1 = min(src_cell[:, 1].min(), at_cell[:, 1].min()) - 1
    width = max(src_cell[:, 1].max(), at_cell[:, 1].max()) - low1 + 2
    src_key = (src_cell[:, 0] - low0) * width + (src_cell[:, 1] - low1)
    order = np.argsort(src_key, kind="mergesort")
    keys = src_key[order]
    pairs = []
    for r in range(rows.shape[0]):
        at_key = (at_cell[r, 0] - low0) * width + (at_cell[r, 1] - low1)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                query = at_key + dx * width + dy
                lo = np.searchsorted(keys, query, side="left")
                hi = np.searchsorted(keys, query, side="right")
                for m in range(lo, hi):
                    pairs.append((rows[r], order[m]))
    out = np.empty((len(pairs), 2), dtype=np.intp)
    for m in range(len(pairs)):
        out[m, 0], out[m, 1] = pairs[m]
    return out


@_kernel
def neighbour_pairs(p_at: np.ndarray, p_src: np.ndarray, radius: float, same_rows: bool) -> np.ndarray:
    """separation.neighbour_pairs: index pairs (P, 2) (i, j) (j indexes p_src), with |p_at[i] - p_src[j]| <
    radius, in the numpy function's order; `same_rows`: i == j is one vehicle, left out. Rows of p_src must
    be finite."""
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
        if same_rows and i == j:
            continue
        d0, d1, d2 = p_at[i, 0] - p_src[j, 0], p_at[i, 1] - p_src[j, 1], p_at[i, 2] - p_src[j, 2]
        if _dot3(d0, d1, d2, d0, d1, d2) < r_sq:
            out[p, 0], out[p, 1] = i, j
            p += 1
    return out[:p]


@_kernel
def uav_pairs(
    p_at: np.ndarray, p_src: np.ndarray, vel: np.ndarray, at_vel: np.ndarray, src_valid: np.ndarray,
    d_max: float, l_min: float, brake_accel: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """First half of separation.uav_repulsion (3-D, with at_vel): the pairs (P, 2) (i, j) within d_max after
    the braking sweep (brake_accel > 0), with the unit vectors e_ji (P, 3) and l = max(distance, l_min) (P,)
    (raise l to the power n - 2 with numpy: pair_force_scale's l ** (n - 2.0))."""
    n = p_at.shape[0]
    src_index = np.flatnonzero(src_valid)
    sweep = brake_accel > 0.0
    if sweep:
        at_speed = row_norms(at_vel)
        speed = row_norms(vel)
        rel_speed_max = np.nanmax(at_speed) + np.nanmax(speed)
        reach = d_max + rel_speed_max * rel_speed_max / (4.0 * brake_accel)
    else:
        reach = d_max
    src = np.empty((src_index.shape[0], 3))
    for m in range(src_index.shape[0]):
        src[m] = p_src[src_index[m]]
    candidates = (
        neighbour_pairs(p_at, src, reach, False) if n > 0 and src.shape[0] > 0 else np.empty((0, 2), np.intp)
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
            w_sq = _dot3(w0, w1, w2, w0, w1, w2)
            length = math.sqrt(w_sq) / (4.0 * brake_accel)
            closing = -_dot3(d0, d1, d2, w0, w1, w2)
            t_cpa = _clip(closing / w_sq if w_sq > 0.0 else 0.0, 0.0, length)
            d0, d1, d2 = d0 + w0 * t_cpa, d1 + w1 * t_cpa, d2 + w2 * t_cpa
        dist = math.sqrt(_dot3(d0, d1, d2, d0, d1, d2))
        if not dist < d_max:
            continue
        pairs[p, 0], pairs[p, 1] = i, j
        if dist < l_min:
            e_ji[p, 0], e_ji[p, 1], e_ji[p, 2] = 0.0, 0.0, 1.0 if i > j else -1.0
        else:
            e_ji[p, 0], e_ji[p, 1], e_ji[p, 2] = d0 / dist, d1 / dist, d2 / dist
        l_out[p] = _maximum(dist, l_min)
        p += 1
    return pairs[:p], e_ji[:p], l_out[:p]


@_kernel
def uav_forces(
    n: int, pairs: np.ndarray, e_ji: np.ndarray, l: np.ndarray, l_pow: np.ndarray, vel: np.ndarray,
    k_uav: float, n_exp: float, d_max: float, formula: bool, d_emg: float, a_e: float, s_s: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Second half of separation.uav_repulsion: the force (n, 3) and emergency flags (n,) of the pairs from
    uav_pairs, with l_pow = l ** (n - 2) (P,) from numpy; `formula` the Eq 20 D_Emg from the velocities
    (N, 3), else the constant `d_emg` (already min(d_emg, d_max))."""
    force = np.zeros((n, 3))
    emergency = np.zeros(n, dtype=np.bool_)
    half_n = 0.5 * n_exp
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        lp = l[p]
        bracket = 1.0 / lp - 1.0 / d_max if lp < d_max else 0.0  # separation.pair_force_scale
        scale = k_uav * bracket * l_pow[p] * (1.0 - half_n * (1.0 - lp / d_max))
        sign = 1.0 if i > j else -1.0
        if formula:
            v_re = _norm3(vel[i, 0] - vel[j, 0], vel[i, 1] - vel[j, 1], vel[i, 2] - vel[j, 2])
            limit = _minimum(v_re * v_re / (2.0 * a_e) + s_s, d_max)
        else:
            limit = d_emg
        in_emg = lp <= limit
        force[i, 0] += scale * e_ji[p, 0]
        force[i, 1] += scale * e_ji[p, 1]
        force[i, 2] += scale * e_ji[p, 2] + (scale * sign if in_emg else 0.0)
        if in_emg:
            emergency[i] = True
    return force, emergency


@_kernel
def closing_speed_caps(
    pos: np.ndarray, vel: np.ndarray, valid: np.ndarray, d_emg: float, accel: float, radius: float
) -> np.ndarray:
    """separation.closing_speed_caps (N,) with its range `radius` = min(reach, CLOSING_RANGE_MAX_M) computed
    by the caller (the numpy function's Python arithmetic)."""
    n = pos.shape[0]
    caps = np.full(n, np.inf)
    if n < 2 or accel <= 0:
        return caps
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
        sub[r] = pos[rows[r]]
    pairs = neighbour_pairs(sub, sub, radius, True)
    for p in range(pairs.shape[0]):
        i, j = rows[pairs[p, 0]], rows[pairs[p, 1]]
        r0, r1, r2 = pos[j, 0] - pos[i, 0], pos[j, 1] - pos[i, 1], pos[j, 2] - pos[i, 2]
        dist = math.sqrt(_dot3(r0, r1, r2, r0, r1, r2))
        floor = _maximum(dist, 1e-9)
        u0, u1, u2 = r0 / floor, r1 / floor, r2 / floor
        own = _dot3(vel[i, 0], vel[i, 1], vel[i, 2], u0, u1, u2)
        closing = own - _dot3(vel[j, 0], vel[j, 1], vel[j, 2], u0, u1, u2)
        allowed = math.sqrt(2.0 * accel * _maximum(dist - d_emg - CLOSING_MARGIN_M, 0.0))
        excess = closing - allowed
        if own > 0.0 and excess > 0.0:
            speed = math.hypot(vel[i, 0], vel[i, 1])
            caps[i] = _minimum(caps[i], _maximum(speed - excess, 0.0))
    return caps


@_scalar
def _interp(x: float, xp: np.ndarray, fp: np.ndarray) -> float:
    """np.interp of one x on an increasing table xp, fp (numpy's compiled_base.c arr_interp): fp[0] left of
    the table, fp[-1] right of it and at its last point, fp[j] at a table point, else the slope
    (fp[j+1] - fp[j]) / (xp[j+1] - xp[j]) times (x - xp[j]) plus fp[j]."""
    last = xp.shape[0] - 1
    if x != x:
        return x
    if x < xp[0]:
        return fp[0]
    if x > xp[last]:
        return fp[last]
    j = np.searchsorted(xp, x, side="right") - 1
    if j == last or xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + fp[j]
    if out != out:
        out = slope * (x - xp[j + 1]) + fp[j + 1]
        if out != out and fp[j] == fp[j + 1]:
            out = fp[j]
    return out


@_kernel
def failsafe_speed_caps(
    pos: np.ndarray, vel: np.ndarray, centres: np.ndarray, radii: np.ndarray, clearance: float,
    total: np.ndarray, speeds: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """failsafe_speed.failsafe_speed_caps (N,) from the stopping table: `total` (S,) m covered from each of
    `speeds` (S,) m/s (speeds * reaction_s + brake distances, increasing)."""
    n, k_obs = pos.shape[0], radii.shape[0]
    caps = np.full(n, np.inf)
    if k_obs == 0:
        return caps
    for i in range(n):
        speed = math.hypot(vel[i, 0], vel[i, 1])  # failsafe_speed.distance_along_course
        if not speed > 1e-6:
            continue
        u0, u1 = vel[i, 0] / speed, vel[i, 1] / speed
        entry_min = np.inf
        for k in range(k_obs):
            r0, r1 = centres[k, 0] - pos[i, 0], centres[k, 1] - pos[i, 1]
            dz = pos[i, 2] - centres[k, 2]
            grown = radii[k] + clearance
            grown_sq = grown * grown - dz * dz
            along = 0.0 + r0 * u0 + r1 * u1
            rel_sq = 0.0 + r0 * r0 + r1 * r1
            half_chord_sq = grown_sq - (rel_sq - along * along)
            if rel_sq < grown_sq and grown_sq > 0.0:
                entry = 0.0
            elif grown_sq > 0.0 and half_chord_sq >= 0.0 and along > 0.0:
                entry = along - math.sqrt(_maximum(half_chord_sq, 0.0))
            else:
                entry = np.inf
            entry_min = _minimum(entry_min, entry)
        if np.isfinite(entry_min):
            caps[i] = _interp(entry_min, total, speeds)
    return caps
