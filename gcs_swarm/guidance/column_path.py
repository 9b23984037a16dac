"""A column that follows the leader's path [add] (docs/iaapf-smc-spec.md section 6a.9).

A column held in the leader's heading frame is a rigid stick: when the leader turns at a corner, the stick
swings round the leader and its tail cuts across the inside of the corner (a 56 m column turned by 90 deg
sweeps its last slot along an arc of 88 m), and when the leader swerves round an obstacle the stick does
not. While the formation is a column (`column_rows`: every follower slot on the line astern of the leader),
each follower's slot is instead the point d metres behind the leader along the path the leader has flown
since the column formed, d its distance astern in the column; beyond the start of that path, the line
astern at the heading psi_L had when the column formed. The slots therefore turn where the leader turned
and pass obstacles where the leader passed them, and when the column forms they are where the rigid
column's slots are.

`LeaderTrail` keeps that path (ENU m) and the leader's horizontal speed along it, so that the leader can
be held to a pace its followers can fly each bend at (FleetController): a follower reaching a bend at the
leader's present speed, when the leader itself went round it slower, would overshoot it.
"""

from __future__ import annotations

import math

import numpy as np

TRAIL_STEP_M = 0.5  # m of leader travel between two kept points of its path
ON_LINE_M = 1e-6  # m a slot may lie off the line astern and still be in the column
CURVATURE_MIN_SPEED = 1.0  # m/s: where the leader flew slower, its motion gives no course nor curvature


def column_rows(offsets: np.ndarray) -> np.ndarray | None:
    """The follower rows (F,) int of offsets (N, 3) leader-frame m (x forward, y left, z up) when the
    formation is a column: every row neither zero (the leader) nor NaN (out of the formation) lies astern of
    the leader on its line (x < 0, |y| and |z| within ON_LINE_M), and there is at least one; else None."""
    offsets = np.asarray(offsets, dtype=float)
    rows = np.flatnonzero(np.isfinite(offsets).all(axis=1) & np.any(offsets != 0.0, axis=1))
    if not len(rows):
        return None
    slots = offsets[rows]
    on_line = (slots[:, 0] < 0.0) & (np.abs(slots[:, 1]) <= ON_LINE_M) & (np.abs(slots[:, 2]) <= ON_LINE_M)
    return rows if bool(on_line.all()) else None


class LeaderTrail:
    """The leader's path since the column formed: points (M, 3) ENU m, oldest first, TRAIL_STEP_M apart, with
    the leader's horizontal velocity (M, 2) m/s and reference acceleration (M, 2) m/s^2 at each, kept for
    the last `keep_m` m of travel; beyond the oldest point the path goes on straight back, at first along
    the heading psi_L had when the column formed."""

    def __init__(
        self, p_leader: np.ndarray, v_leader: np.ndarray, a_leader: np.ndarray, psi_leader: float,
        keep_m: float,
    ) -> None:  # fmt: skip
        """The column formed with the leader at p_leader (3,) ENU m flying v_leader (2,) m/s, accelerating
        a_leader (2,) m/s^2, heading psi_leader rad; `keep_m` m of path kept (at least the column's
        length)."""
        self.keep_m = float(keep_m)
        self.points = np.array(p_leader, dtype=float).reshape(1, 3)
        self.velocities = np.array(v_leader, dtype=float).reshape(1, 2)
        self.accelerations = np.array(a_leader, dtype=float).reshape(1, 2)
        self.astern = np.array([-math.cos(psi_leader), -math.sin(psi_leader), 0.0])

    def record(self, p_leader: np.ndarray, v_leader: np.ndarray, a_leader: np.ndarray) -> None:
        """The leader is at p_leader (3,) ENU m flying v_leader (2,) m/s, accelerating a_leader (2,) m/s^2:
        kept once it is TRAIL_STEP_M from the last point kept; what lies more than keep_m of path behind it
        is forgotten."""
        if float(np.linalg.norm(p_leader - self.points[-1])) < TRAIL_STEP_M:
            return
        self.points = np.vstack([self.points, np.asarray(p_leader, dtype=float)[None, :]])
        self.velocities = np.vstack([self.velocities, np.asarray(v_leader, dtype=float)[None, :2]])
        self.accelerations = np.vstack([self.accelerations, np.asarray(a_leader, dtype=float)[None, :2]])
        excess = len(self.points) - int(self.keep_m / TRAIL_STEP_M) - 2
        if excess > 0:
            self.astern = self.points[excess - 1] - self.points[excess]
            self.astern /= max(float(np.linalg.norm(self.astern)), 1e-12)
            self.points = self.points[excess:]
            self.velocities, self.accelerations = self.velocities[excess:], self.accelerations[excess:]

    def behind(
        self, p_leader: np.ndarray, v_leader: np.ndarray, a_leader: np.ndarray, distances: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The column's slots on the path, the leader now at p_leader (3,) ENU m flying v_leader (2,) m/s,
        accelerating a_leader (2,) m/s^2, and its followers `distances` (F,) m >= 0 astern of it in the
        column: taken in order of distance, each slot is the first point back along the path at the
        horizontal straight-line distance from the slot before it (the leader for the first) that their
        distances astern differ by. Chords, not lengths of path: round a bend the column keeps its spacing
        between neighbours instead of folding (a turn of 120 deg brings the two points 3.5 m of path either
        side of it, 7 m apart along the path, to 3.5 m of each other; the leader's hook at a waypoint,
        closer still).

        Returns, per slot: the point (F, 2) ENU m horizontal; the leader's velocity (F, 2) m/s and
        acceleration (F, 2) m/s^2 there, interpolated between the kept points around it; and the length of
        path (F,) m from the leader to it (`pace`). Where the leader flew slower than CURVATURE_MIN_SPEED,
        the velocity is the unit vector along the path forward and the acceleration zero (its motion there
        tells neither its course nor its turn); beyond the oldest point, on the line astern, the same."""
        xy, vel, acc, arc = self._newest_first(p_leader, v_leader, a_leader)
        d = np.asarray(distances, dtype=float)
        points, velocities = np.zeros((len(d), 2)), np.zeros((len(d), 2))
        accelerations, arcs = np.zeros((len(d), 2)), np.zeros(len(d))
        astern = self.astern[:2] / max(float(np.hypot(*self.astern[:2])), 1e-12)
        piece, along, here, on_path, before = 0, 0.0, xy[0].copy(), True, 0.0
        for k in np.argsort(d, kind="stable"):
            chord, before = d[k] - before, d[k]
            if on_path and chord > 0.0:
                far = np.hypot(*(xy[piece + 1 :] - here).T) >= chord
                if far.any():  # the crossing lies on the piece ending at the first point that far
                    end = piece + 1 + int(np.argmax(far))
                    start = here if end - 1 == piece else xy[end - 1]
                    u = _circle_crossing(start, xy[end], here, chord)
                    along = along + u * (1.0 - along) if end - 1 == piece else u
                    piece = end - 1
                    here = xy[piece] + along * (xy[piece + 1] - xy[piece])
                else:  # beyond the path kept: on the line astern from its oldest point
                    on_path = False
                    here = xy[-1] + _ray_crossing(xy[-1], astern, here, chord) * astern
            elif chord > 0.0:
                here = here + chord * astern
            points[k] = here
            if not on_path:
                velocities[k] = -astern
                arcs[k] = arc[-1] + float(np.hypot(*(here - xy[-1])))
                continue
            velocities[k] = (1.0 - along) * vel[piece] + along * vel[piece + 1]
            accelerations[k] = (1.0 - along) * acc[piece] + along * acc[piece + 1]
            arcs[k] = arc[piece] + along * (arc[piece + 1] - arc[piece])
            forward = xy[piece] - xy[piece + 1]
            size = float(np.hypot(*forward))
            if np.hypot(*velocities[k]) < CURVATURE_MIN_SPEED and size > 1e-9:
                velocities[k], accelerations[k] = forward / size, 0.0
        return points, velocities, accelerations, arcs

    def _newest_first(
        self, p_leader: np.ndarray, v_leader: np.ndarray, a_leader: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The path from the leader now back, newest first: horizontal points (M + 1, 2) ENU m (the leader's
        p_leader first), the leader's velocities (M + 1, 2) m/s and accelerations (M + 1, 2) m/s^2 there
        (v_leader, a_leader first), and the length of path (M + 1,) m from the leader to each."""
        xy = np.vstack([np.asarray(p_leader, dtype=float)[None, :2], self.points[::-1, :2]])
        vel = np.vstack([np.asarray(v_leader, dtype=float)[None, :2], self.velocities[::-1]])
        acc = np.vstack([np.asarray(a_leader, dtype=float)[None, :2], self.accelerations[::-1]])
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        return xy, vel, acc, arc

    def pace(
        self, p_leader: np.ndarray, v_leader: np.ndarray, a_leader: np.ndarray, arcs: np.ndarray,
        turn_accel: float, brake: float,
    ) -> float:  # fmt: skip
        """The fastest m/s the leader (at p_leader (3,) ENU m flying v_leader (2,) m/s, accelerating a_leader
        (2,) m/s^2) may fly,
        its column's slots `arcs` (F,) m of path behind it (`behind`) moving along the path at its speed, so
        that each slot goes round every bend between it and the leader with at most `turn_accel` m/s^2 of
        centripetal acceleration, braking for it at `brake` m/s^2: min over slots k and kept points i ahead of
        them of sqrt(v_i^2 + 2 brake (s_k - s_i)), v_i = sqrt(turn_accel / kappa_i) the fastest round point
        i's curvature kappa_i = |a_i . n_i| / |v_i|^2 (as the leader turned there: `path_motion`), or
        CURVATURE_MIN_SPEED where the leader flew slower than that (its turn there unknown); inf without
        slots."""
        _, vel, acc, arc = self._newest_first(p_leader, v_leader, a_leader)
        speed = np.hypot(vel[:, 0], vel[:, 1])
        lateral = np.abs(vel[:, 0] * acc[:, 1] - vel[:, 1] * acc[:, 0]) / np.maximum(speed, 1e-12)
        with np.errstate(divide="ignore", invalid="ignore"):  # straight: inf; at rest: replaced below
            turn = np.sqrt(turn_accel * speed**2 / lateral)  # sqrt(turn_accel / kappa)
        turn = np.where(speed >= CURVATURE_MIN_SPEED, turn, CURVATURE_MIN_SPEED)
        behind = np.asarray(arcs, dtype=float)[:, None] - arc[None, :]  # (F, M): slot k's way to point i
        allowed = np.sqrt(turn[None, :] ** 2 + 2.0 * brake * np.maximum(behind, 0.0))
        return float(np.where(behind >= 0.0, allowed, np.inf).min(initial=math.inf))


def _circle_crossing(start: np.ndarray, end: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """The fraction u in [0, 1] along the segment start -> end (2,) m where it leaves the circle of `radius` m
    round centre (2,): start inside (or on) the circle, end outside or on it."""
    step = end - start
    a = float(step @ step)
    if a <= 0.0:
        return 0.0
    b = 2.0 * float((start - centre) @ step)
    c = float((start - centre) @ (start - centre)) - radius * radius
    return min(max((-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a), 0.0), 1.0)


def _ray_crossing(origin: np.ndarray, direction: np.ndarray, centre: np.ndarray, radius: float) -> float:
    """The distance t >= 0 along the ray origin + t direction (2,), direction a unit vector, where it leaves
    the circle of `radius` m round centre (2,), origin inside (or on) it."""
    b = float((origin - centre) @ direction)
    c = float((origin - centre) @ (origin - centre)) - radius * radius
    return max(-b + math.sqrt(max(b * b - c, 0.0)), 0.0)


def path_motion(
    velocities: np.ndarray, accelerations: np.ndarray, along_v: np.ndarray, along_a: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal velocity (F, 2) m/s and acceleration (F, 2) m/s^2 of points moving along the leader's
    path at along_v (F,) m/s, speeding up at along_a (F,) m/s^2, where the leader flew at velocities (F, 2)
    m/s with accelerations (F, 2) m/s^2 (`LeaderTrail.behind`): along the leader's course there, and turning
    as the leader turned, with its curvature kappa = (a . n) / |v|^2 (n the course's left normal), so the
    centripetal part is along_v^2 kappa n (`behind` gives a unit velocity and no acceleration where the
    leader's motion tells neither: no turn there)."""
    size = np.maximum(np.hypot(velocities[:, 0], velocities[:, 1]), 1e-12)
    tangent = velocities / size[:, None]
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    lateral = (accelerations * normal).sum(axis=1)
    kappa = lateral / size**2
    velocity = along_v[:, None] * tangent
    acceleration = along_a[:, None] * tangent + (along_v**2 * kappa)[:, None] * normal
    return velocity, acceleration


UNUSED = np.zeros(2)  # a velocity or acceleration not needed (slots_along_path: points only)


def slots_along_path(
    p_leader: np.ndarray,
    psi_leader: np.ndarray,
    leaders: np.ndarray,
    offsets: np.ndarray,
    follows: np.ndarray,
) -> np.ndarray:
    """The slots (T, N, 3) ENU m of a flight's columns that followed the leader's path, at T sample times:
    p_leader (T, 3) ENU m the leader's positions, psi_leader (T,) rad psi_L, leaders (T,) int the leader's
    row, offsets (T, N, 3) leader-frame m (spacing applied), follows (T,) bool whether the column followed
    the path then. A path begins, as in flight, where following begins or the leader changes; the column's
    slots are then `LeaderTrail.behind` at their distances astern, at the leader's height plus their
    offsets'.
    NaN wherever the column did not follow the path (rows and samples). Only the points are needed: the
    leader's velocity and acceleration are not."""
    slots = np.full(offsets.shape, np.nan)
    trail: LeaderTrail | None = None
    for k in np.flatnonzero(follows):
        rows = column_rows(offsets[k])
        if rows is None:
            continue
        lags = -offsets[k, rows, 0]
        if trail is None or k == 0 or not follows[k - 1] or leaders[k] != leaders[k - 1]:
            trail = LeaderTrail(p_leader[k], UNUSED, UNUSED, float(psi_leader[k]), float(lags.max()))
        trail.keep_m = max(trail.keep_m, float(lags.max()))
        trail.record(p_leader[k], UNUSED, UNUSED)
        slots[k, rows, :2] = trail.behind(p_leader[k], UNUSED, UNUSED, lags)[0]
        slots[k, rows, 2] = p_leader[k, 2] + offsets[k, rows, 2]
    return slots
