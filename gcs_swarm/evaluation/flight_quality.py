"""Whole-flight quality figures: what a pilot sees in a flight, measured over all of it, not only after the
formation has settled (docs/metrics.md defines each one).

Motion figures take the simulator's ground truth (or the ground station's record when there is none);
command figures take the commands of record.csv. Shapes: t (T,) s; positions/velocities (T, N, 3) ENU m,
m/s; commanded attitude (T, N, 3) roll, pitch, yaw rad.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.signal import savgol_filter

from gcs_swarm.evaluation import metrics
from gcs_swarm.evaluation.metrics import rounded
from gcs_swarm.guidance.formation import ASSEMBLED_M

CUSP_TURN_DEG = 90.0  # a cusp: the horizontal course turns by more than this ...
CUSP_WINDOW_S = 1.0  # ... within this long ...
CUSP_MIN_SPEED = 2.0  # m/s ... while the speed is above this at both ends
JERK_WINDOW_S = 0.25  # s, Savitzky-Golay window of the jerk estimate (cubic fit of the true velocity)
JERK_MIN_SAMPLES = 7  # samples: a shorter stretch of velocity gives no jerk estimate
SHAPE_AT_REST_S = 0.5  # s: the formation's shape is at rest where no change of it is recorded this soon after


def cusp_times(t: np.ndarray, vel_xy: np.ndarray) -> list[float]:
    """Times (s) of the cusps of one vehicle: a sample t_j starts a cusp when the course
    atan2(v_y, v_x) at t_j and at the first sample at least CUSP_WINDOW_S later differ by more than
    CUSP_TURN_DEG (the wrapped difference, so at most 180 deg) and the horizontal speed is above
    CUSP_MIN_SPEED at both. Counted once per second: after a cusp at t_j the next can start no earlier than
    t_j + CUSP_WINDOW_S. vel_xy (T, 2)."""
    t = np.asarray(t, dtype=float)
    v = np.asarray(vel_xy, dtype=float)
    if len(t) < 2:
        return []
    later = np.searchsorted(t, t + CUSP_WINDOW_S - 1e-9)
    valid = later < len(t)
    j = np.flatnonzero(valid)
    k = later[valid]
    speed = np.hypot(v[:, 0], v[:, 1])
    course = np.arctan2(v[:, 1], v[:, 0])
    turn = np.abs((course[k] - course[j] + math.pi) % (2.0 * math.pi) - math.pi)
    starts = j[
        (turn > math.radians(CUSP_TURN_DEG)) & (speed[j] > CUSP_MIN_SPEED) & (speed[k] > CUSP_MIN_SPEED)
    ]
    out: list[float] = []
    for s in starts:
        if not out or t[s] >= out[-1] + CUSP_WINDOW_S:
            out.append(float(t[s]))
    return out


def command_rates(t: np.ndarray, attitude_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rates between consecutive command ticks: t_mid (T-1,) s and (T-1, N, 3) rad/s of roll, pitch and the
    unwrapped yaw; a pair with a non-finite command (vehicle not commanded) gives NaN."""
    t = np.asarray(t, dtype=float)
    att = np.asarray(attitude_d, dtype=float)
    if len(t) < 2:
        return np.zeros(0), np.zeros((0,) + att.shape[1:])
    unwrapped = att.copy()
    for i in range(att.shape[1]):
        yaw = att[:, i, 2]
        ok = np.isfinite(yaw)
        if ok.any():
            unwrapped[ok, i, 2] = np.unwrap(yaw[ok])
    dt = np.diff(t)
    rates = np.diff(unwrapped, axis=0) / np.where(dt > 0, dt, np.nan)[:, None, None]
    return 0.5 * (t[1:] + t[:-1]), rates


def true_jerk(t: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """|jerk| (T, N) m/s^3 of the true motion: the second derivative of the true velocity (T, N, 3) by a
    Savitzky-Golay cubic fit over JERK_WINDOW_S (scipy.signal.savgol_filter), which differentiates a smooth
    signal exactly up to its cubic terms and does not amplify the sample-to-sample rounding of the log.
    Uniform sampling is assumed (the truth log is). A vehicle with gaps (no truth row: NaN velocity) is fitted
    over each unbroken stretch; NaN in the gaps and in stretches shorter than JERK_MIN_SAMPLES."""
    t = np.asarray(t, dtype=float)
    vel = np.asarray(vel, dtype=float)
    out = np.full(vel.shape[:2], np.nan)
    if len(t) < JERK_MIN_SAMPLES:
        return out
    dt = float(np.median(np.diff(t)))
    finite = np.isfinite(vel).all(axis=-1)  # (T, N)
    whole = finite.all(axis=0)  # (N,) vehicles with every sample
    if whole.any():
        out[:, whole] = _savgol_jerk(vel[:, whole], dt)
    for i in np.flatnonzero(~whole):
        edges = np.diff(np.concatenate([[0], finite[:, i].astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
            if b - a >= JERK_MIN_SAMPLES:
                out[a:b, i] = _savgol_jerk(vel[a:b, i], dt)
    return out


def _savgol_jerk(vel: np.ndarray, dt: float) -> np.ndarray:
    """|d^2 v / dt^2| (T, ...) of velocities (T, ..., 3) sampled every dt s, T >= JERK_MIN_SAMPLES, all
    finite (`true_jerk`)."""
    window = max(5, int(round(JERK_WINDOW_S / dt)) | 1)
    window = min(window, len(vel) - (1 - len(vel) % 2))
    jerk = savgol_filter(vel, window, 3, deriv=2, delta=dt, axis=0, mode="interp")
    return np.linalg.norm(jerk, axis=-1)


def path_ratio(pos: np.ndarray, route: np.ndarray) -> float:
    """Length of the path pos (T, 3) over the length of the straight route through its points (W, 3)
    (start, waypoints, goal); samples without a position (NaN: silent) are left out; nan for a route of zero
    length or fewer than two positions."""
    straight = metrics.path_length(np.asarray(route, dtype=float))
    pos = np.asarray(pos, dtype=float)
    pos = pos[np.isfinite(pos).all(axis=1)]
    return metrics.path_length(pos) / straight if straight > 0 and len(pos) > 1 else math.nan


def time_below(
    t: np.ndarray, pos: np.ndarray, distance: float, closest: np.ndarray | None = None
) -> tuple[float, float]:
    """(s spent with any pair of vehicles closer than `distance` m, the smallest pair distance m), over
    pos (T, N, 3); each sample counts for the interval to the next. `closest`: (T,) m, the caller's
    metrics.closest_pair_distance(pos), computed here when not given."""
    t = np.asarray(t, dtype=float)
    p = np.asarray(pos, dtype=float)
    if p.shape[1] < 2 or len(t) == 0:
        return 0.0, math.inf
    if closest is None:
        closest = metrics.closest_pair_distance(p)
    dt = np.diff(t, append=t[-1])
    return float(dt[closest < distance].sum()), float(np.nanmin(closest))


def formation_schedule(
    flight: dict[str, Any], t: np.ndarray, leader: int, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Leader (T,), slot offsets (T, N, 3) and whether a column's slots followed the leader's path (T,) bool
    in force at each time t (T,) s, from flight.json's formation_timeline (re-forms after a loss, a new
    leader, live reshapes, degraded widening; NaN rows for vehicles out of the formation; a column following
    the path, spec 6a.9); the final `leader`/`offsets` throughout, not following, for a flight.json without
    it."""
    timeline = flight.get("formation_timeline") or []
    if not timeline:
        fixed = np.broadcast_to(offsets, (len(t),) + offsets.shape)
        return np.full(len(t), leader), fixed, np.zeros(len(t), dtype=bool)
    starts = np.array([entry["t"] for entry in timeline], dtype=float)
    leaders = np.array([entry["leader"] for entry in timeline], dtype=int)
    table = np.array(
        [[[np.nan] * 3 if row is None else row for row in entry["offsets"]] for entry in timeline],
        dtype=float,
    )
    follows = np.array([entry.get("follows_path") is True for entry in timeline], dtype=bool)
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(timeline) - 1)
    return leaders[k], table[k], follows[k]


def scheduled_formation_error(
    t: np.ndarray, pos: np.ndarray, psi: np.ndarray, flight: dict[str, Any], leader: int, offsets: np.ndarray
) -> tuple[metrics.FormationError, np.ndarray]:
    """Spec 10 formation error over t (T,), pos (T, N, 3), with psi_L (T,) rad as flown and the formation in
    force at each time (`formation_schedule`; a column that followed the leader's path measured against the
    path the leader truly flew), and the follower-to-slot error (T, N) m: the same e_F,i before any settling
    window, NaN for the leader of the moment and for vehicles out of the formation."""
    leaders, flown, follows = formation_schedule(flight, t, leader, offsets)
    fe = metrics.formation_error(t, pos, leaders, psi, flown, follows_path=follows)
    err = fe.error.copy()
    err[np.arange(len(t)), leaders] = np.nan  # the leader's own slot is where it is
    return fe, err


def assembled_figures(t: np.ndarray, slot_error: np.ndarray) -> dict[str, Any]:
    """Figures once the formation has assembled, from the follower-to-slot error (T, N) m (NaN: the leader,
    vehicles out of the formation) at times t (T,) s: `assembly_s` from t[0] until every follower is within
    ASSEMBLED_M of its slot for the first time (None if never), and the slot error's RMS and maximum m from
    then on (docs/metrics.md)."""
    with np.errstate(invalid="ignore"):
        worst = np.fmax.reduce(slot_error, axis=1) if slot_error.shape[1] else np.zeros(len(t))
    inside = np.flatnonzero(worst <= ASSEMBLED_M)
    if not len(t) or not len(inside):
        return {"assembly_s": None}
    k = int(inside[0])
    err = slot_error[k:]
    err = err[np.isfinite(err)]
    return {
        "assembly_s": rounded(float(t[k] - t[0]), 2),
        "slot_error_assembled_rms_m": rounded(float(np.sqrt(np.mean(err * err)))) if err.size else None,
        "slot_error_assembled_max_m": rounded(float(err.max())) if err.size else None,
    }


def shape_at_rest(flight: dict[str, Any], t: np.ndarray) -> np.ndarray:
    """(T,) bool at the times t (T,) s: flight.json's formation_timeline records no change of the formation
    in (t, t + SHAPE_AT_REST_S] (a change of shape under way records one every control tick, the last where
    the slots reach their new places, so the shape is at rest from that entry on; its first entry, the
    formation's start, is not a change); all true for a flight.json without it."""
    t = np.asarray(t, dtype=float)
    timeline = flight.get("formation_timeline") or []
    changes = np.array([entry["t"] for entry in timeline[1:]], dtype=float)
    before = np.searchsorted(changes, t, side="right")
    after = np.searchsorted(changes, t + SHAPE_AT_REST_S, side="right")
    return np.asarray(after == before)


def shape_formed(t: np.ndarray, slot_error: np.ndarray, at_rest: np.ndarray) -> dict[str, Any]:
    """`shape_formed_s`: from t[0] until every follower is within ASSEMBLED_M of its slot at a moment when the
    formation's shape is at rest (`at_rest` (T,) bool, `shape_at_rest`) for the first time, None if never;
    from the follower-to-slot error (T, N) m (NaN: the leader, vehicles out of the formation) at times t (T,)
    s. Where the formation changes shape before it has assembled (a change may start where the followers
    stand, spec 6a.4), `assembly_s` is when every follower is first on the slots of that moment, and this is
    when the shape they were moving to was formed (docs/metrics.md)."""
    with np.errstate(invalid="ignore"):
        worst = np.fmax.reduce(slot_error, axis=1) if slot_error.shape[1] else np.zeros(len(t))
    formed = np.flatnonzero((worst <= ASSEMBLED_M) & at_rest)
    return {"shape_formed_s": rounded(float(t[formed[0]] - t[0]), 2) if len(formed) else None}


def whole_flight_figures(
    t: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    slot_error: np.ndarray | None,
    leader_route: np.ndarray,
    leader: int,
    window: tuple[float, float],
    formation_altitude: np.ndarray,
    below: tuple[float, float],
    commands: tuple[np.ndarray, np.ndarray] | None,
    names: list[str],
) -> dict[str, Any]:
    """The whole-flight figures of report.json (docs/metrics.md). Motion over t (T,), pos, vel (T, N, 3),
    the follower-to-slot error slot_error (T, N) m (NaN for the leader; None without a record), inside
    window = (formation start, arrival or end of formation flight) s; the leader's route (W, 3) from its
    start; formation_altitude (N,) m (slot height); below = `time_below` over the whole flight at D_Emg (s
    below, smallest pair distance m); commands = (t (C,), attitude_d (C, N, 3)) of the formation phase, or
    None."""
    t = np.asarray(t, dtype=float)
    sel = (t >= window[0]) & (t <= window[1])
    ts, ps, vs = t[sel], pos[sel], vel[sel]
    out: dict[str, Any] = {"window_s": [rounded(window[0], 2), rounded(window[1], 2)]}
    if slot_error is not None and sel.any():
        err = slot_error[sel]
        err = err[np.isfinite(err)]
        if err.size:
            out["slot_error_rms_m"] = rounded(float(np.sqrt(np.mean(err * err))))
            out["slot_error_p95_m"] = rounded(float(np.percentile(err, 95)))
            out["slot_error_max_m"] = rounded(float(err.max()))
        out |= assembled_figures(ts, slot_error[sel])
    cusps = [cusp_times(ts, vs[:, i, :2]) for i in range(pos.shape[1])]
    out["cusps"] = [len(c) for c in cusps]
    out["cusps_total"] = int(sum(out["cusps"]))
    # when they happened, s since the formation's start, per vehicle: where to look in the figures
    out["cusp_times_s"] = [[rounded(c - window[0], 2) for c in times] for times in cusps]
    jerk = true_jerk(ts, vs)
    if np.isfinite(jerk).any():
        per = [
            float(np.percentile(j[np.isfinite(j)], 99)) if np.isfinite(j).any() else math.nan for j in jerk.T
        ]
        out["jerk_p99_m_s3"] = [rounded(x, 3) for x in per]
        out["jerk_p99_max_m_s3"] = rounded(float(np.nanmax(per)), 3)
    out["leader_path_ratio"] = rounded(path_ratio(ps[:, leader], leader_route))
    out["min_separation_whole_flight_m"] = rounded(below[1])
    out["time_below_d_emg_s"] = rounded(below[0])
    if sel.any():
        z = ps[:, :, 2]
        out["min_altitude_in_formation_m"] = rounded(float(np.nanmin(z)))
        out["max_drop_below_formation_altitude_m"] = rounded(
            float(np.nanmax(formation_altitude[None, :] - z))
        )
    if commands is not None and len(commands[0]) > 2:
        ct, att = commands
        mid, rates = command_rates(ct, att)
        with np.errstate(invalid="ignore"):
            tilt = np.fmax(np.abs(rates[..., 0]), np.abs(rates[..., 1]))
            yaw_rate = rates[..., 2]
            yaw_step = np.abs(np.diff(yaw_rate, axis=0))
        out["max_tilt_command_rate_rad_s"] = rounded(float(np.nanmax(tilt)), 3)
        out["max_yaw_command_rate_rad_s"] = rounded(float(np.nanmax(np.abs(yaw_rate))), 3)
        out["max_yaw_rate_step_rad_s"] = rounded(float(np.nanmax(yaw_step)) if yaw_step.size else 0.0, 3)
        chatter, rate_chatter = [], []
        for i in range(att.shape[1]):
            pitch = att[:, i, 1]
            ok = np.isfinite(pitch)
            if np.count_nonzero(ok) > 3:
                chatter.append(metrics.chattering_amplitude(ct[ok], pitch[ok], (ct[ok][0], ct[ok][-1])))
            q = rates[:, i, 1]
            okq = np.isfinite(q)
            if np.count_nonzero(okq) > 3:
                rate_chatter.append(
                    metrics.chattering_amplitude(mid[okq], q[okq], (mid[okq][0], mid[okq][-1]))
                )
        out["pitch_command_chatter_rad"] = [rounded(c, 4) for c in chatter]
        out["pitch_command_chatter_max_rad"] = rounded(max(chatter), 4) if chatter else None
        out["pitch_rate_chatter_whole_flight_rad_s"] = rounded(max(rate_chatter), 4) if rate_chatter else None
    out["vehicles"] = names
    return out
