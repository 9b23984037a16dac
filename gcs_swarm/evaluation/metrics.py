"""Run metrics with the spec's definitions (spec 10), as pure functions of logged arrays.

Times `t` (T,) s, increasing; positions (T, N, D) m; velocities (T, D) or (T, N, D) m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import pdist, squareform

from gcs_swarm.guidance.column_path import slots_along_path
from gcs_swarm.guidance.formation import slot_positions
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays, surface_distances


def reach_time(t: np.ndarray, distance: np.ndarray, r_goal: float, hold_s: float = 2.0) -> float | None:
    """Start of the first interval with distance (T,) <= r_goal held continuously for hold_s s, else None
    (spec 10 "reached destination"; r_goal 0.5 m for the 2-D planner, 1.0 m for formation runs)."""
    inside = np.asarray(distance) <= r_goal
    if not inside.any():
        return None
    # Runs of consecutive inside samples: starts where inside begins, ends where it stops.
    edges = np.diff(np.concatenate([[False], inside, [False]]).astype(np.int8))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1) - 1
    held = t[ends] - t[starts] >= hold_s - 1e-9
    return float(t[starts[np.argmax(held)]]) if held.any() else None


def heading_extrema(
    t: np.ndarray, vel: np.ndarray, min_speed: float = 0.5, swing_deg: float = 5.0
) -> np.ndarray:
    """Times (E,) of the interior extrema of the unwrapped heading chi = atan2(v_y, v_x), on samples with
    |v_xy| >= min_speed, with hysteresis: an extremum counts once the heading has swung back by swing_deg
    (spec 10 "oscillation time")."""
    vel = np.asarray(vel, dtype=float)
    moving = np.hypot(vel[:, 0], vel[:, 1]) >= min_speed
    if moving.sum() < 3:
        return np.zeros(0)
    times = np.asarray(t)[moving]
    chi = np.unwrap(np.arctan2(vel[moving, 1], vel[moving, 0]))
    swing = math.radians(swing_deg)
    found: list[int] = []
    hi_idx = lo_idx = 0
    direction = 0  # +1 tracking a maximum, -1 a minimum, 0 not yet known
    for k in range(1, len(chi)):
        if chi[k] > chi[hi_idx]:
            hi_idx = k
        if chi[k] < chi[lo_idx]:
            lo_idx = k
        if direction >= 0 and chi[hi_idx] - chi[k] >= swing:
            if hi_idx > 0:
                found.append(hi_idx)
            direction, lo_idx = -1, k
        elif direction <= 0 and chi[k] - chi[lo_idx] >= swing:
            if lo_idx > 0:
                found.append(lo_idx)
            direction, hi_idx = 1, k
    return times[np.array(found, dtype=int)]


def oscillation(
    t: np.ndarray, vel: np.ndarray, min_speed: float = 0.5, swing_deg: float = 5.0
) -> tuple[float, int]:
    """Oscillation time T_osc (s, last minus first interior heading extremum, 0 if fewer than two) and the
    heading reversal count (spec 10)."""
    ext = heading_extrema(t, vel, min_speed, swing_deg)
    return (float(ext[-1] - ext[0]) if len(ext) >= 2 else 0.0), len(ext)


def path_length(p: np.ndarray) -> float:
    """Length of a polyline (T, D), m."""
    return float(np.linalg.norm(np.diff(np.asarray(p, dtype=float), axis=0), axis=1).sum())


def closest_pair_distance(p: np.ndarray) -> np.ndarray:
    """(T,) m: the smallest distance between two vehicles at each sample of p (T, N, D) m. A pair with a NaN
    coordinate is left out; NaN at a sample without any finite pair; inf everywhere for fewer than 2
    vehicles. scipy's pdist, one sample at a time (memory stays O(N^2) however long the flight)."""
    p = np.asarray(p, dtype=float)
    n = p.shape[1]
    if n < 2:
        return np.full(len(p), math.inf)
    return np.array([np.fmin.reduce(pdist(sample)) for sample in p]).reshape(len(p))


def nearest_neighbour_distance(p: np.ndarray) -> np.ndarray:
    """(T, N) m: each vehicle's distance to its nearest other vehicle at each sample of p (T, N, D) m; NaN
    where the vehicle or any other has a NaN coordinate; inf for a single vehicle."""
    p = np.asarray(p, dtype=float)
    n = p.shape[1]
    out = np.full(p.shape[:2], math.inf)
    if n < 2:
        return out
    for k, sample in enumerate(p):
        d = squareform(pdist(sample))
        np.fill_diagonal(d, math.inf)
        out[k] = d.min(axis=1)
    return out


def min_separation(p: np.ndarray, closest: np.ndarray | None = None) -> float:
    """d_min = min over t and i < j of |p_i - p_j| from (T, N, D), pairs with a NaN coordinate left out; inf
    for fewer than 2 vehicles or no finite pair (spec 10). `closest`: closest_pair_distance(p), when the
    caller has it."""
    if closest is None:
        closest = closest_pair_distance(p)
    finite = closest[~np.isnan(closest)]
    return float(finite.min()) if finite.size else math.inf


def min_obstacle_clearance(
    p: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    l_arm: float = 0.175,
    shapes: ShapeArrays = NO_SHAPES,
) -> tuple[float, bool]:
    """c_min = min over t, i, k of |p_i - c_k(t)| - r_k and the collision flag c_min <= l_arm (spec 10); with
    `shapes` (cylinders and prisms, 3-D p only) also of their surface distances (spec 2.2).

    p (T, N, D); centres (K, D) static or (T, K, D) moving; radii (K,). Without obstacles or without a finite
    position: (inf, False).
    """
    p = np.asarray(p, dtype=float)
    radii = np.asarray(radii, dtype=float)
    c_min = math.inf
    if radii.size:
        c = np.asarray(centres, dtype=float)
        c = np.broadcast_to(c, (p.shape[0],) + c.shape) if c.ndim == 2 else c
        d = np.linalg.norm(p[:, :, None, :] - c[:, None, :, :], axis=-1) - radii
        d = d[np.isfinite(d)]  # a vehicle with no position (no sample, silent) has no clearance
        if d.size:
            c_min = float(d.min())
    if shapes.number:
        points = p.reshape(-1, 3)
        points = np.ascontiguousarray(points[np.isfinite(points).all(axis=1)])
        if len(points):
            c_min = min(c_min, float(surface_distances(points, *shapes).min()))
    return c_min, c_min <= l_arm


@dataclass(frozen=True)
class FormationError:
    """e_F (T, N) m per sample and vehicle; t_settle s (None if never settled); max and RMS over the window
    [t_settle, end] (the whole run if never settled)."""

    error: np.ndarray
    t_settle: float | None
    max: float
    rms: float


def formation_error(
    t: np.ndarray,
    p: np.ndarray,
    leader: int | np.ndarray,
    psi_leader: np.ndarray,
    offsets: np.ndarray,
    settle_threshold: float = 1.0,
    follows_path: np.ndarray | None = None,
) -> FormationError:
    """e_F,i(t) = |p_i(t) - s_i(t)| with slots from the leader's actual position and psi_L (spec 10).

    p (T, N, 3); psi_leader (T,) rad; leader: index, or (T,) indices when the lead passed on; offsets (N, 3)
    leader frame, or (T, N, 3) when the formation changed (NaN rows: a vehicle out of the formation, e.g.
    lost; its error is NaN and left out). Settled when max_i e_F,i <= threshold for the rest of the run.
    follows_path (T,) bool: where a column's slots followed the leader's actual path instead (spec 6a.9,
    guidance.column_path.slots_along_path).
    """
    p = np.asarray(p, dtype=float)
    lead = np.broadcast_to(np.asarray(leader, dtype=int), (len(p),))
    p_leader = p[np.arange(len(p)), lead]
    slots = slot_positions(p_leader, psi_leader, offsets)
    if follows_path is not None and follows_path.any():
        table = np.broadcast_to(offsets, p.shape)
        along = slots_along_path(p_leader, np.asarray(psi_leader, dtype=float), lead, table, follows_path)
        slots = np.where(np.isnan(along), slots, along)
    err = np.linalg.norm(p - slots, axis=-1)
    with np.errstate(invalid="ignore"):
        worst = np.fmax.reduce(err, axis=1)  # NaN only where no vehicle is in the formation
    above = np.flatnonzero(~(worst <= settle_threshold))
    if len(above) == 0:
        first = 0
    elif above[-1] + 1 < len(t):
        first = int(above[-1] + 1)
    else:
        first = -1
    window = err if first < 0 else err[first:]
    return FormationError(
        error=err,
        t_settle=None if first < 0 else float(t[first]),
        max=float(np.nanmax(window)),
        rms=float(np.sqrt(np.nanmean(window * window))),
    )


def settling_time(t: np.ndarray, y: np.ndarray, y_abs: float) -> float:
    """Smallest t_s with |y - y_ss| <= max(0.02 |y(0) - y_ss|, y_abs) from t_s on; y_ss = mean of the last
    10 % of the run (spec 10). y (T,)."""
    y = np.asarray(y, dtype=float)
    y_ss = float(np.mean(y[-max(1, len(y) // 10) :]))
    band = max(0.02 * abs(y[0] - y_ss), y_abs)
    outside = np.flatnonzero(np.abs(y - y_ss) > band)
    if len(outside) == 0:
        return float(t[0])
    return float(t[min(outside[-1] + 1, len(t) - 1)])


def chattering_amplitude(
    t: np.ndarray, y: np.ndarray, window: tuple[float, float], ma_s: float = 1.0
) -> float:
    """Peak-to-peak of y - MA(y) inside window (t0, t1) s; MA is a centred moving average over ma_s s,
    narrowed symmetrically near the ends of the log so trends leave no residual (spec 10). Uniform sampling,
    y (T,)."""
    y = np.asarray(y, dtype=float)
    t = np.asarray(t, dtype=float)
    sel = (t >= window[0]) & (t <= window[1])
    if not sel.any():
        raise ValueError(f"no samples inside the window {window}")
    resid = (y - moving_average(t, y, ma_s))[sel]
    return float(resid.max() - resid.min())


def moving_average(t: np.ndarray, y: np.ndarray, span_s: float = 1.0) -> np.ndarray:
    """Centred moving average (T,) of y (T,) over span_s s (uniform sampling, t (T,) s), narrowed
    symmetrically near the ends of the log: the trend of a chattering signal."""
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    k = np.arange(len(y))
    half = np.minimum(max(1, int(round(span_s / dt / 2.0))), np.minimum(k, len(y) - 1 - k))
    sums = np.concatenate([[0.0], np.cumsum(y)])
    return (sums[k + half + 1] - sums[k - half]) / (2 * half + 1)


def rounded(x: float | None, digits: int = 4) -> float | None:
    """x rounded to `digits` decimals for a report, None when it is None or not finite."""
    return None if x is None or not math.isfinite(x) else round(float(x), digits)
