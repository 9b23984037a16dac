"""The last guard before commands reach the vehicles: whatever the guidance computed, what goes out stays
within the vehicles' limits (defence in depth; the guidance already limits tilt and thrust, spec 5). Attitude
commands (`guard_attitude_commands`, below) and the position command mode's trajectory targets
(`guard_position_targets`, at the end) are each guarded by one compiled loop over the vehicles.

Rules, per vehicle row (one compiled loop over the vehicles):
- a non-finite row (roll, pitch, yaw or thrust) becomes level at the vehicle's measured yaw with hover thrust;
- tilt (angle of the body z axis from vertical, acos(cos r cos p)) <= tilt_max: if steeper, roll and pitch
  are scaled down together to hypot(r, p) = tilt_max (spherical Pythagoras: the tilt is then <= tilt_max);
- thrust in [0, min(1, hover * thrust_max_g)] (normalised, GUID_OPTIONS bit 3);
- outside the geofence radius: a tilt that accelerates further out is replaced by level, unless it only
  brakes (given the velocity): the vehicle is moving inward, the tilt opposes its velocity (a . v < 0) and
  points outward no more steeply than straight braking does (a_r / |a| <= -v_r / |v|), so it slows the
  vehicle down without steering it outward (`_pushes_out`); above the fence ceiling thrust <= hover; below
  the minimum altitude thrust >= hover (never accelerate down);
- the site fence (`GuardFence`: the inclusion polygon, exclusion polygons and circles, horizontal ENU m, at
  every height; and the buildings' footprints and the trees' circles as exclusion zones between their bottom
  and top heights, so that a vehicle above a roof is free to fly over it): the
  same rule as the radius's, with the normal n of the nearest edge (or of the circle) pointing into the
  forbidden side instead of the radial direction, for every zone the vehicle is in or about to enter: its
  signed depth into the forbidden side s (m, > 0 outside the polygon or inside an exclusion zone) is
  s >= -(v . n)^2 / (2 brake) when it closes in at v . n > 0, i.e. it could no longer stop short of the edge
  braking at `brake` m/s^2 (the guard's braking margin; 0 when it does not close in or its velocity is
  unknown). Inside the margin a tilt with a . n > 0 is levelled unless it only brakes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.link.autopilots.thrust import nan_to_num
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip, maximum, minimum

FloatArray = NDArray[np.float64]
TILT_SLACK = 1e-9  # rad: the guidance's own limit, met to rounding, is left untouched
INCLUSION, EXCLUSION = 1, -1  # GuardFence.kinds: the vehicle stays inside / outside the ring


class ZoneShape(Protocol):
    """An exclusion zone as the mission gives it (gcs_swarm.mission.model.Zone): a polygon (K, 2) m, or a
    circle (center (2,) m, radius m)."""

    @property
    def polygon(self) -> np.ndarray | None: ...
    @property
    def center(self) -> np.ndarray | None: ...
    @property
    def radius(self) -> float: ...


class PrismShape(Protocol):
    """A building as the mission gives it (gcs_swarm.mission.model.Prism): a footprint (K, 2) m between bottom
    and top m above the origin."""

    @property
    def footprint(self) -> np.ndarray: ...
    @property
    def bottom(self) -> float: ...
    @property
    def top(self) -> float: ...


class CylinderShape(Protocol):
    """A tree or mast as the mission gives it (gcs_swarm.mission.model.Cylinder): center (2,) m, radius m,
    between bottom and top m above the origin."""

    @property
    def center(self) -> np.ndarray: ...
    @property
    def radius(self) -> float: ...
    @property
    def bottom(self) -> float: ...
    @property
    def top(self) -> float: ...


@dataclass(frozen=True, eq=False)
class GuardFence:
    """The site fence as the guard's arrays, horizontal ENU m: polygon rings (vertices in order, not closed)
    stacked in `vertices` (K, 2), ring r being vertices[rings[r]:rings[r + 1]] (rings (R + 1,) int64) of kind
    kinds[r] (INCLUSION or EXCLUSION) acting between the heights heights[r] (R, 2) (bottom, top m above the
    origin; -inf, inf for the fence's own zones); exclusion circles (C, 5) rows (east, north, radius, bottom,
    top); `brake` m/s^2, the horizontal deceleration the braking margin assumes."""

    vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    rings: np.ndarray = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    kinds: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    heights: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    circles: np.ndarray = field(default_factory=lambda: np.zeros((0, 5)))
    brake: float = 1.0

    @classmethod
    def of(
        cls,
        polygon: np.ndarray | None,
        exclusions: Sequence[ZoneShape],
        brake: float,
        prisms: Sequence[PrismShape] = (),
        cylinders: Sequence[CylinderShape] = (),
    ) -> GuardFence:
        """The arrays of an inclusion polygon (K, 2) m (None: none), exclusion zones (at every height), and
        buildings' footprints and trees' circles (exclusion zones between their bottom and top); brake m/s^2
        > 0."""
        always = (-math.inf, math.inf)
        rings = (
            [(np.asarray(polygon, dtype=np.float64), INCLUSION, always)] if polygon is not None else []
        ) + [
            (np.asarray(zone.polygon, dtype=np.float64), EXCLUSION, always)
            for zone in exclusions
            if zone.polygon is not None
        ]
        rings += [(np.asarray(p.footprint, dtype=np.float64), EXCLUSION, (p.bottom, p.top)) for p in prisms]
        circles = [
            (float(zone.center[0]), float(zone.center[1]), float(zone.radius), *always)
            for zone in exclusions
            if zone.polygon is None and zone.center is not None
        ]
        circles += [(float(c.center[0]), float(c.center[1]), c.radius, c.bottom, c.top) for c in cylinders]
        sizes = [len(ring) for ring, _, _ in rings]
        return cls(
            vertices=np.ascontiguousarray(
                np.concatenate([r for r, _, _ in rings]) if rings else np.zeros((0, 2))
            ),
            rings=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
            kinds=np.array([kind for _, kind, _ in rings], dtype=np.int64),
            heights=np.array([h for _, _, h in rings], dtype=np.float64).reshape(-1, 2),
            circles=np.array(circles, dtype=np.float64).reshape(-1, 5),
            brake=float(brake),
        )


@dataclass(frozen=True)
class CommandLimits:
    """Vehicle limits in the units of the guard: rad, normalised thrust multiples, metres above the origin."""

    tilt_max: float  # rad
    thrust_max_g: float  # maximum collective thrust / weight
    min_altitude: float  # m (ENU z)
    geofence_radius: float  # m, horizontal, around the origin
    geofence_max_alt: float  # m (ENU z)
    fence: GuardFence = field(default_factory=GuardFence)  # the site fence (none by default)

    @property
    def bounds(self) -> tuple[float, float, float, float, float]:
        """The scalar fields in order, as floats: what the compiled guards take as `limits`."""
        return (
            float(self.tilt_max),
            float(self.thrust_max_g),
            float(self.min_altitude),
            float(self.geofence_radius),
            float(self.geofence_max_alt),
        )


def guard_attitude_commands(
    roll: FloatArray,
    pitch: FloatArray,
    yaw: FloatArray,
    thrust: FloatArray,
    pos: FloatArray,
    measured_yaw: FloatArray,
    hover: FloatArray,
    limits: CommandLimits,
    vel: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, NDArray[np.bool_]]:
    """(roll, pitch, yaw, thrust, changed): the (N,) commands made safe, and which rows were changed.

    roll, pitch, yaw: (N,) rad body FLU in world ENU; thrust, hover: (N,) normalised; pos: (N,3) ENU m
    (NaN rows skip the position rules); measured_yaw: (N,) rad (fallback heading of a non-finite row);
    vel: (N,3) ENU m/s, lets a vehicle outside the fence brake (None, or a NaN row: no outward tilt at all).
    """
    r, p, y, t, h, heading = (
        np.ascontiguousarray(a, dtype=np.float64) for a in (roll, pitch, yaw, thrust, hover, measured_yaw)
    )
    x = np.ascontiguousarray(pos, dtype=np.float64)
    v = np.full_like(x, np.nan) if vel is None else np.ascontiguousarray(vel, dtype=np.float64)
    # numpy's own arccos: on AVX-512 machines it differs from the C library's acos in the last bit for
    # about one value in ten, and numpy's is the one the guard has always used
    with np.errstate(invalid="ignore"):
        tilt = np.arccos(np.clip(np.cos(r) * np.cos(p), -1.0, 1.0))
    bounds, fence = limits.bounds, limits.fence
    return _guard(  # type: ignore[no-any-return]
        r, p, y, t, tilt, x, v, heading, h, bounds, TILT_SLACK,
        fence.vertices, fence.rings, fence.kinds, fence.heights, fence.circles, fence.brake,
    )  # fmt: skip


@kernel
def ring_distance(
    x: float, y: float, vertices: np.ndarray, start: int, end: int
) -> tuple[bool, float, float, float]:
    """(inside, distance, n_e, n_n) of the point (x, y) m and the polygon ring vertices[start:end] (in order,
    not closed): inside by the crossing number (even-odd, as shapely's `contains` off the boundary), the
    distance m to its nearest edge (shapely's exterior.distance), and the unit normal n of that edge pointing
    away from the polygon's interior (from the nearest point to the point outside, towards it inside; on the
    edge itself the edge's outward normal by the ring's orientation, shoelace)."""
    inside = False
    best, c_e, c_n, e_e, e_n = np.inf, 0.0, 0.0, 0.0, 0.0
    twice_area = 0.0
    j = end - 1
    for k in range(start, end):
        x1, y1, x2, y2 = vertices[j, 0], vertices[j, 1], vertices[k, 0], vertices[k, 1]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
        d_e, d_n = x2 - x1, y2 - y1
        length2 = d_e * d_e + d_n * d_n
        s = clip(((x - x1) * d_e + (y - y1) * d_n) / length2, 0.0, 1.0) if length2 > 0.0 else 0.0
        p_e, p_n = x1 + s * d_e, y1 + s * d_n
        d = np.hypot(x - p_e, y - p_n)
        if d < best:
            best, c_e, c_n, e_e, e_n = d, p_e, p_n, d_e, d_n
        twice_area += x1 * y2 - x2 * y1
        j = k
    if best > 0.0:
        side = -1.0 if inside else 1.0
        return inside, best, side * (x - c_e) / best, side * (y - c_n) / best
    length = maximum(np.hypot(e_e, e_n), 1e-300)
    turn = 1.0 if twice_area > 0.0 else -1.0  # counter-clockwise: the outward normal is the edge turned right
    return inside, best, turn * e_n / length, -turn * e_e / length


@kernel
def _pushes_out(a_e: float, a_n: float, v_e: float, v_n: float, n_e: float, n_n: float) -> bool:
    """Whether the horizontal thrust direction (a_e, a_n) accelerates along n (a . n > 0; n need not be
    unit) other than by only braking: it only brakes when it opposes the velocity (a . v < 0) and its part
    along n, relative to its size, is at most that of -v (a_n / |a| <= -v_n / |v|, both sides times |a| |v|
    |n|); a NaN velocity never brakes."""
    a_out = a_e * n_e + a_n * n_n
    if not a_out > 0:
        return False
    opposes = a_e * v_e + a_n * v_n < 0
    v_out = v_e * n_e + v_n * n_n
    not_steeper = a_out * math.hypot(v_e, v_n) <= -v_out * math.hypot(a_e, a_n)
    return not (opposes and not_steeper)


@kernel
def _fence_pushes_out(
    x: float,
    y: float,
    z: float,
    a_e: float,
    a_n: float,
    v_e: float,
    v_n: float,
    vertices: np.ndarray,
    rings: np.ndarray,
    kinds: np.ndarray,
    heights: np.ndarray,
    circles: np.ndarray,
    brake: float,
) -> bool:
    """Whether the site fence levels the horizontal thrust direction (a_e, a_n) of a vehicle at (x, y, z) m
    moving at (v_e, v_n) m/s (module doc: for each zone acting at height z, depth s and normal n into the
    forbidden side; a NaN z meets every zone)."""
    for r in range(kinds.shape[0]):
        if z < heights[r, 0] or z > heights[r, 1]:
            continue
        inside, d, n_e, n_n = ring_distance(x, y, vertices, rings[r], rings[r + 1])
        forbidden = inside if kinds[r] == EXCLUSION else not inside
        depth = d if forbidden else -d
        if kinds[r] == EXCLUSION:
            n_e, n_n = -n_e, -n_n
        if _in_margin(depth, v_e * n_e + v_n * n_n, brake) and _pushes_out(a_e, a_n, v_e, v_n, n_e, n_n):
            return True
    for c in range(circles.shape[0]):
        if z < circles[c, 3] or z > circles[c, 4]:
            continue
        o_e, o_n = circles[c, 0] - x, circles[c, 1] - y
        d = np.hypot(o_e, o_n)
        if not d > 0.0:
            continue  # at the very centre every direction leads out
        n_e, n_n = o_e / d, o_n / d
        depth = circles[c, 2] - d
        if _in_margin(depth, v_e * n_e + v_n * n_n, brake) and _pushes_out(a_e, a_n, v_e, v_n, n_e, n_n):
            return True
    return False


@kernel
def _in_margin(depth: float, closing: float, brake: float) -> bool:
    """depth m into the forbidden side (> 0 inside it) is within the braking margin of a vehicle closing in
    at `closing` m/s (v . n): depth >= -closing^2 / (2 brake), the margin 0 when it does not close in."""
    reach = closing * closing / (2.0 * brake) if closing > 0.0 else 0.0
    return depth >= -reach


@kernel
def _guard(
    roll: np.ndarray,
    pitch: np.ndarray,
    yaw: np.ndarray,
    thrust: np.ndarray,
    commanded_tilt: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    measured_yaw: np.ndarray,
    hover: np.ndarray,
    limits: tuple[float, float, float, float, float],
    tilt_slack: float,
    vertices: np.ndarray,
    rings: np.ndarray,
    kinds: np.ndarray,
    heights: np.ndarray,
    circles: np.ndarray,
    brake: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """guard_attitude_commands, one loop over the N vehicles; commanded_tilt (N,) rad: arccos(cos roll cos
    pitch) of the commands; `limits`: CommandLimits' scalar fields in order; vertices .. brake: GuardFence's
    fields."""
    tilt_max, thrust_max_g, min_altitude, geofence_radius, geofence_max_alt = limits
    n = roll.shape[0]
    r_out, p_out, y_out, t_out = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    changed = np.empty(n, dtype=np.bool_)
    for i in range(n):
        r, p, y, t = roll[i], pitch[i], yaw[i], thrust[i]
        bad = not (math.isfinite(r) and math.isfinite(p) and math.isfinite(y) and math.isfinite(t))
        if bad:
            r, p, t = 0.0, 0.0, hover[i]
            y = nan_to_num(measured_yaw[i])
        steep = not bad and commanded_tilt[i] > tilt_max + tilt_slack  # a bad row is level: tilt 0
        if steep:
            scale = tilt_max / maximum(math.hypot(r, p), 1e-12)
            r, p = r * scale, p * scale
        x_e, y_n, z_u = pos[i, 0], pos[i, 1], pos[i, 2]
        outward = False
        beyond = math.hypot(x_e, y_n) >= geofence_radius
        fenced = kinds.shape[0] + circles.shape[0] > 0 and math.isfinite(x_e) and math.isfinite(y_n)
        if beyond or fenced:
            # horizontal thrust direction of ZYX (yaw, pitch, roll): Rz(yaw) (sin p cos r, -sin r)
            h1, h2 = math.sin(p) * math.cos(r), -math.sin(r)
            a_e = math.cos(y) * h1 - math.sin(y) * h2
            a_n = math.sin(y) * h1 + math.cos(y) * h2
            v_e, v_n = vel[i, 0], vel[i, 1]
            outward = beyond and _pushes_out(a_e, a_n, v_e, v_n, x_e, y_n)  # the radial direction
            if fenced and not outward:
                outward = _fence_pushes_out(
                    x_e, y_n, z_u, a_e, a_n, v_e, v_n, vertices, rings, kinds, heights, circles, brake
                )
        if outward:
            r, p = 0.0, 0.0
        if z_u >= geofence_max_alt:
            t = minimum(t, hover[i])
        if z_u <= min_altitude:
            t = maximum(t, hover[i])
        t = clip(t, 0.0, minimum(1.0, hover[i] * thrust_max_g))
        r_out[i], p_out[i], y_out[i], t_out[i] = r, p, y, t
        changed[i] = bad or steep or outward or t != thrust[i]
    return r_out, p_out, y_out, t_out, changed


class PositionTargets(NamedTuple):
    """Trajectory targets as guarded: position (N, 3) ENU m, velocity (N, 3) m/s, acceleration (N, 3) m/s^2,
    and whether the guard changed each row (N,)."""

    pos: FloatArray
    vel: FloatArray
    acc: FloatArray
    changed: NDArray[np.bool_]


def guard_position_targets(
    target_pos: FloatArray,
    target_vel: FloatArray,
    target_acc: FloatArray,
    pos: FloatArray,
    limits: CommandLimits,
    g: float,
) -> PositionTargets:
    """The position command mode's targets (the guidance's reference: target_pos (N, 3) ENU m, target_vel
    (N, 3) m/s, target_acc (N, 3) m/s^2) made safe for vehicles measured at pos (N, 3) ENU m, with gravity
    g m/s^2. Per row (one compiled loop, `_guard_targets`):

    - a non-finite row becomes a hold at the measured position (zero velocity and acceleration; a row whose
      measured position is not finite either is left as it is: the fleet sends it nothing);
    - the altitude: z in [min_altitude, geofence_max_alt], the vertical velocity and acceleration that lead
      further out at a bound removed;
    - the geofence radius: a target beyond it is moved in radially onto it, and the outward radial parts of
      its velocity and acceleration removed;
    - the site fence (`GuardFence`): a target on the forbidden side of a zone (signed depth s > 0 along the
      normal n of the nearest edge, or of a circle, into the forbidden side: as the attitude guard's) is moved
      back onto the edge, p - s n, and the parts of its velocity and acceleration along n removed, for each
      zone in turn;
    - the acceleration feed-forward within what the attitude limits allow: horizontal |a| <= g tan(tilt_max)
      (scaled down), vertical in [-g, g (thrust_max_g - 1)].
    """
    p_d, v_d, a_d, x = (
        np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 3)
        for a in (target_pos, target_vel, target_acc, pos)
    )
    bounds, fence = limits.bounds, limits.fence
    out = _guard_targets(
        p_d,
        v_d,
        a_d,
        x,
        bounds,
        float(g),
        fence.vertices,
        fence.rings,
        fence.kinds,
        fence.heights,
        fence.circles,
    )
    return PositionTargets(*out)


@kernel
def _without_outward(v: np.ndarray, n_e: float, n_n: float, n_u: float) -> bool:
    """Remove from v (3,) in place its part along the unit vector (n_e, n_n, n_u) when positive; whether it
    had one."""
    along = v[0] * n_e + v[1] * n_n + v[2] * n_u
    if not along > 0.0:
        return False
    v[0] -= along * n_e
    v[1] -= along * n_n
    v[2] -= along * n_u
    return True


@kernel
def _guard_targets(
    target_pos: np.ndarray,
    target_vel: np.ndarray,
    target_acc: np.ndarray,
    pos: np.ndarray,
    limits: tuple[float, float, float, float, float],
    g: float,
    vertices: np.ndarray,
    rings: np.ndarray,
    kinds: np.ndarray,
    heights: np.ndarray,
    circles: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """guard_position_targets, one loop over the N vehicles; `limits`: CommandLimits' scalar fields in order;
    vertices .. circles: GuardFence's fields."""
    tilt_max, thrust_max_g, min_altitude, geofence_radius, geofence_max_alt = limits
    n = target_pos.shape[0]
    p_out, v_out, a_out = target_pos.copy(), target_vel.copy(), target_acc.copy()
    changed = np.zeros(n, dtype=np.bool_)
    a_h_max = g * math.tan(tilt_max)
    for i in range(n):
        p, v, a = p_out[i], v_out[i], a_out[i]
        finite = True
        for k in range(3):
            finite = finite and math.isfinite(p[k]) and math.isfinite(v[k]) and math.isfinite(a[k])
        if not finite:
            if not (math.isfinite(pos[i, 0]) and math.isfinite(pos[i, 1]) and math.isfinite(pos[i, 2])):
                continue
            for k in range(3):
                p[k], v[k], a[k] = pos[i, k], 0.0, 0.0
            changed[i] = True
        if p[2] < min_altitude:
            p[2] = min_altitude
            changed[i] = True
        if p[2] == min_altitude:  # at the floor: nothing further down
            changed[i] |= _without_outward(v, 0.0, 0.0, -1.0) | _without_outward(a, 0.0, 0.0, -1.0)
        if p[2] > geofence_max_alt:
            p[2] = geofence_max_alt
            changed[i] = True
        if p[2] >= geofence_max_alt:  # at the ceiling: nothing further up
            changed[i] |= _without_outward(v, 0.0, 0.0, 1.0) | _without_outward(a, 0.0, 0.0, 1.0)
        r = math.hypot(p[0], p[1])
        if r > geofence_radius:
            p[0], p[1] = p[0] * geofence_radius / r, p[1] * geofence_radius / r
            changed[i] = True
        if r >= geofence_radius and r > 0.0:
            u_e, u_n = p[0] / math.hypot(p[0], p[1]), p[1] / math.hypot(p[0], p[1])
            changed[i] |= _without_outward(v, u_e, u_n, 0.0) | _without_outward(a, u_e, u_n, 0.0)
        for z in range(kinds.shape[0]):
            if p[2] < heights[z, 0] or p[2] > heights[z, 1]:
                continue  # a building's footprint acts between its bottom and top only
            inside, d, n_e, n_n = ring_distance(p[0], p[1], vertices, rings[z], rings[z + 1])
            if kinds[z] == EXCLUSION:
                n_e, n_n = -n_e, -n_n
            forbidden = inside if kinds[z] == EXCLUSION else not inside
            if forbidden or d == 0.0:
                if forbidden:
                    p[0], p[1] = p[0] - d * n_e, p[1] - d * n_n
                    changed[i] = True
                changed[i] |= _without_outward(v, n_e, n_n, 0.0) | _without_outward(a, n_e, n_n, 0.0)
        for c in range(circles.shape[0]):
            if p[2] < circles[c, 3] or p[2] > circles[c, 4]:
                continue
            o_e, o_n = circles[c, 0] - p[0], circles[c, 1] - p[1]
            d = math.hypot(o_e, o_n)
            depth = circles[c, 2] - d
            if depth >= 0.0 and d > 0.0:  # inside or on the circle: out along the radius
                n_e, n_n = o_e / d, o_n / d  # into the circle
                p[0], p[1] = p[0] - depth * n_e, p[1] - depth * n_n
                changed[i] |= depth > 0.0
                changed[i] |= _without_outward(v, n_e, n_n, 0.0) | _without_outward(a, n_e, n_n, 0.0)
        a_h = math.hypot(a[0], a[1])
        if a_h > a_h_max:
            a[0], a[1] = a[0] * a_h_max / a_h, a[1] * a_h_max / a_h
            changed[i] = True
        a_up = clip(a[2], -g, g * (thrust_max_g - 1.0))
        if a_up != a[2]:
            a[2] = a_up
            changed[i] = True
    return p_out, v_out, a_out, changed
