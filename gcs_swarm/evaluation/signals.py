"""Signals derived from a run's logs for the paper-style figures and report figures (spec 10).

Times `t` (T,) s, increasing; positions and velocities (T, N, 3) ENU; angles rad.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gcs_swarm.evaluation import metrics
from gcs_swarm.evaluation.metrics import rounded
from gcs_swarm.guidance.formation import leader_frame_offsets

RATE_SETTLE_ABS = 0.02  # rad/s, y_abs of the settling time of rate signals (spec 10)
CHATTER_WINDOW_S = 20.0  # s, chattering is measured over the first and the last 20 s (spec 10)
FIRST_SETTLED_HOLD_S = 20.0  # s, the end of the initial transient: the trend stays in its band this long
RATE_FIGURES = (  # the figures of one rate signal (`_rate_figures`), all None when it has too few samples
    "settling_s",
    "trend_settling_s",
    "trend_first_settled_s",
    "peak",
    "chatter_first_20s",
    "chatter_last_20s",
)


def held_at(log_t: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """values (L, ...) logged at log_t (L,), held between samples, at times t (T,) -> (T, ...)."""
    idx = np.clip(np.searchsorted(log_t, t, side="right") - 1, 0, len(log_t) - 1)
    return values[idx]


def accelerations(t: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Acceleration (T, N, 3) m/s^2 by central differences of velocity (T, N, 3) over t (T,) (Figs 14-16)."""
    t = np.asarray(t, dtype=float)
    vel = np.asarray(vel, dtype=float)
    if len(t) < 2:
        return np.zeros_like(vel)
    return np.gradient(vel, t, axis=0)


def relative_angles(p: np.ndarray, leader: int, psi_leader: np.ndarray) -> np.ndarray:
    """Angle (T, N) rad of each vehicle as seen from the leader in the leader's heading frame,
    atan2(d_y, d_x) of the measured offset (spec 6, Eq 29; the paper's "angle alpha" of Figs 5 and 19).
    The leader's own column is NaN. p (T, N, 3), psi_leader (T,)."""
    d = leader_frame_offsets(np.asarray(p, dtype=float), np.asarray(p, dtype=float)[:, leader], psi_leader)
    angles = np.arctan2(d[..., 1], d[..., 0])
    angles[:, leader] = np.nan
    return angles


def near(angles: np.ndarray, reference: np.ndarray | float) -> np.ndarray:
    """angles (..., N) rad shifted by whole turns to lie within pi of reference (N,) (so -179.9 deg is shown
    as 180.1 deg next to a 180 deg slot)."""
    ref = np.asarray(reference, dtype=float)
    return ref + (np.asarray(angles, dtype=float) - ref + math.pi) % (2.0 * math.pi) - math.pi


def desired_relative_angles(offsets: np.ndarray, leader: int) -> np.ndarray:
    """The slots' angles (N,) rad, atan2(d_y, d_x) of each leader-frame offset (N, 3); NaN for the leader."""
    offsets = np.asarray(offsets, dtype=float)
    angles = np.arctan2(offsets[:, 1], offsets[:, 0])
    angles[leader] = np.nan
    return angles


def attitude_rates(t: np.ndarray, attitude: np.ndarray) -> np.ndarray:
    """Rates (T, N, 3) rad/s of commanded roll, pitch, yaw (T, N, 3) rad (Fig 26: the "virtual control
    signals"): central differences of the unwrapped angles over t (T,). Each angle is unwrapped over its own
    finite samples; NaN (not commanded) stays NaN and so do the rates beside it."""
    t = np.asarray(t, dtype=float)
    att = np.asarray(attitude, dtype=float)
    if len(t) < 2:
        return np.zeros_like(att)
    unwrapped = att.copy()
    finite = np.isfinite(att)
    every = finite.all(axis=0)  # (N, 3) angles commanded at every tick: unwrapped together
    unwrapped[:, every] = np.unwrap(att[:, every], axis=0)
    for i, k in zip(*np.nonzero(~every), strict=True):
        ok = finite[:, i, k]
        unwrapped[ok, i, k] = np.unwrap(att[ok, i, k])
    return np.gradient(unwrapped, t, axis=0)


def _rate_figures(t: np.ndarray, y: np.ndarray) -> dict[str, float | None]:
    """Settling time (s after t[0]) of the rate signal y (T,) rad/s and of its 1 s moving average (the trend,
    without the chattering) (spec 10), the end of the trend's initial transient (first entry into its settling
    band held FIRST_SETTLED_HOLD_S; later manoeuvres, e.g. around an obstacle, do not count), peak |y| and
    the chattering amplitudes (spec 10)."""
    keep = np.isfinite(y)
    t, y = t[keep], y[keep]
    if len(t) < 3:
        return dict.fromkeys(RATE_FIGURES)
    first = (t[0], min(t[-1], t[0] + CHATTER_WINDOW_S))
    last = (max(t[0], t[-1] - CHATTER_WINDOW_S), t[-1])
    # The trend's last half second averages fewer samples (the window narrows): leave it out.
    inner = slice(None, max(3, len(t) - int(round(0.5 / float(np.median(np.diff(t)))))))
    trend = metrics.moving_average(t, y)[inner]
    trend_ss = float(np.mean(trend[-max(1, len(trend) // 10) :]))
    band = max(0.02 * abs(trend[0] - trend_ss), RATE_SETTLE_ABS)
    settled = metrics.reach_time(t[inner], np.abs(trend - trend_ss), band, FIRST_SETTLED_HOLD_S)
    return {
        "settling_s": metrics.settling_time(t, y, RATE_SETTLE_ABS) - float(t[0]),
        "trend_settling_s": metrics.settling_time(t[inner], trend, RATE_SETTLE_ABS) - float(t[0]),
        "trend_first_settled_s": None if settled is None else settled - float(t[0]),
        "peak": float(np.abs(y).max()),
        "chatter_first_20s": metrics.chattering_amplitude(t, y, first),
        "chatter_last_20s": metrics.chattering_amplitude(t, y, last),
    }


def command_rate_figures(
    t: np.ndarray, attitude_d: np.ndarray, names: list[str], t_end: float | None = None
) -> dict[str, Any]:
    """Fig 26 figures of the commanded attitude rates (spec 10 settling time and chattering amplitude), over
    the formation flight up to t_end (the leader's final approach, a new transient; None: all of it): per
    vehicle and axis (pitch, yaw), plus the worst over the fleet. t (T,) s from the formation start;
    attitude_d (T, N, 3) commanded roll, pitch, yaw rad."""
    if t_end is not None and np.count_nonzero(t <= t_end) >= 3:
        keep = t <= t_end
        t, attitude_d = t[keep], attitude_d[keep]
    rates = attitude_rates(t, attitude_d)
    per_vehicle = []
    for i, name in enumerate(names):
        entry: dict[str, Any] = {"name": name}
        for axis, k in (("pitch_rate", 1), ("yaw_rate", 2)):
            entry[axis] = {key: rounded(v) for key, v in _rate_figures(t, rates[:, i, k]).items()}
        per_vehicle.append(entry)

    def worst(key: str) -> float | None:
        values = [v[a][key] for v in per_vehicle for a in ("pitch_rate", "yaw_rate") if v[a][key] is not None]
        return max(values) if values else None

    return {
        "settling_s": worst("settling_s"),
        "trend_settling_s": worst("trend_settling_s"),
        "trend_first_settled_s": worst("trend_first_settled_s"),
        "peak_rad_s": worst("peak"),
        "chatter_first_20s_rad_s": worst("chatter_first_20s"),
        "chatter_last_20s_rad_s": worst("chatter_last_20s"),
        "vehicles": per_vehicle,
    }


def neighbour_pairs(offsets: np.ndarray) -> list[tuple[int, int]]:
    """For each follower i (offset != 0), the pair (i, j) with j its nearest slot (offsets (N, 3) m): in a V
    that is the slot one row ahead on the same arm, or the leader for the first row."""
    offsets = np.asarray(offsets, dtype=float)
    pairs = []
    for i in range(len(offsets)):
        if not np.any(offsets[i]):
            continue
        d = np.linalg.norm(offsets - offsets[i], axis=1)
        d[i] = np.inf
        pairs.append((i, int(np.argmin(d))))
    return pairs


CRUISE_FORMATION_M = 5.0  # m, the cruise window opens once every formation error is this small
SPACING_BAND_M = 1.0  # m, "holding the spacing": within this of the slots' spacing


def cruise_figures(
    t: np.ndarray,
    p: np.ndarray,
    vel: np.ndarray,
    leader: int,
    goal: np.ndarray,
    offsets: np.ndarray,
    formation_error: np.ndarray,
    approach_m: float,
) -> dict[str, Any] | None:
    """Steady formation flight (the paper's "each UAV holds 10 m/s with 20 m spacing", Fig 24). The cruise
    window runs from the first sample with every formation error <= CRUISE_FORMATION_M until the leader comes
    within approach_m of its goal. Over it: the median speed of each vehicle, the median distance between
    each follower and the vehicle of its nearest slot (`neighbour_pairs`), the worst deviation from the
    slots' spacing, and the fraction of samples with every spacing within SPACING_BAND_M. None when there is
    no such window. t (T,) s; formation_error (T, N) m; goal (3,) m."""
    formed = np.flatnonzero(np.nanmax(formation_error, axis=1) <= CRUISE_FORMATION_M)
    far = np.linalg.norm(p[:, leader] - np.asarray(goal, dtype=float), axis=1) > approach_m
    if len(formed) == 0:
        return None
    window = far & (np.arange(len(t)) >= formed[0])
    if window.sum() < 2:
        return None
    speed = np.linalg.norm(vel[window], axis=-1)
    pairs = neighbour_pairs(offsets)
    desired = np.array([np.linalg.norm(offsets[i] - offsets[j]) for i, j in pairs])
    measured = np.array([np.linalg.norm(p[window, i] - p[window, j], axis=-1) for i, j in pairs]).T
    error = np.abs(measured - desired) if pairs else np.zeros((1, 1))
    return {
        "window_s": [rounded(float(t[window][0])), rounded(float(t[window][-1]))],
        "speed_median_m_s": [rounded(float(s)) for s in np.median(speed, axis=0)],
        "spacing_desired_m": [rounded(float(d)) for d in desired],
        "spacing_median_m": [rounded(float(m)) for m in np.median(measured, axis=0)] if pairs else [],
        "spacing_max_abs_error_m": rounded(float(error.max())),
        "spacing_within_1m_fraction": rounded(float(np.mean(error.max(axis=1) <= SPACING_BAND_M))),
        "formation_max_m": rounded(float(np.nanmax(formation_error[window]))),
    }
