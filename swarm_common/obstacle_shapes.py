"""The distance from a point to an obstacle's surface and the surface's outward normal, for every obstacle
shape the project flies (docs/iaapf-smc-spec.md 2.1 and 2.2): the paper's sphere, a vertical cylinder (a tree,
a mast) and a vertical prism (a building: a simple polygon footprint between a bottom and a top height).

`surface` is the one rule; the other kernels here are the queries the consumers ask of it (the nearest point
of a segment, the first point of a horizontal ray within a clearance, the distances of many points). Shapes
are packed as plain arrays numba takes (`ShapeArrays`, built by `pack_shapes`):

- `kinds` (S,) int64: SPHERE, CYLINDER or PRISM;
- `params` (S, 6) float64: sphere (cx, cy, cz, r, 0, 0); cylinder (cx, cy, r, 0, bottom, top); prism
  (first, count, 0, 0, bottom, top), its footprint the rows first .. first + count - 1 of `vertices`;
- `vertices` (V, 2) float64: the prisms' footprints, each counter-clockwise, not closed.

ENU metres, z up. Distances are signed: negative inside, with the normal of the nearest face (a cylinder's or
a prism's extrusion distance, exact: the footprint's signed distance h and the slab's v = max(bottom - z,
z - top) combine as |max((h, v), 0)| + min(max(h, v), 0)).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from swarm_common.jit import kernel
from swarm_common.numpy_rules import dot3

SPHERE, CYLINDER, PRISM = 0, 1, 2
SEGMENT_SAMPLES = 8  # intervals a segment is sampled in before its nearest point is refined (segment_nearest)
GOLDEN_STEPS = 40  # golden-section steps of that refinement: the bracket shrinks to 0.618^40 ~ 4e-9 of it
NEAREST_TOLERANCE = 1e-6  # m, segment_nearest's point is at most this much farther than the segment's nearest
SEARCH_LEVELS = 64  # rows of the interval stack of a segment's search through a notched prism (_deepest)
SEARCH_NODES = 1 << 16  # points that search evaluates at most (a guard: 1 km through a 6-tooth comb: < 200)
TRACE_STEPS = 200  # sphere-tracing steps of a ray before it stops where it got to (course_entry)
TRACE_TOLERANCE = 1e-4  # m, a ray is at the grown surface once this close to it
VERTEX_TOLERANCE = 1e-9  # m, nearer a footprint's vertex than this the normal is its edge's (no direction)


class ShapeArrays(NamedTuple):
    """Packed shapes (module docstring): kinds (S,) int64, params (S, 6), vertices (V, 2)."""

    kinds: np.ndarray
    params: np.ndarray
    vertices: np.ndarray

    @property
    def number(self) -> int:
        """S, the number of shapes."""
        return int(self.kinds.shape[0])


def pack_shapes(
    spheres: Iterable[tuple[object, float]] = (),
    cylinders: Iterable[tuple[object, float, float, float]] = (),
    prisms: Iterable[tuple[object, float, float]] = (),
) -> ShapeArrays:
    """Pack spheres (centre (3,), radius), cylinders (centre (2,), radius, bottom, top) and prisms (footprint
    (K, 2) in either order, bottom, top), in that order, m ENU. A footprint is turned counter-clockwise (by
    the sign of its shoelace area); ValueError for a footprint of fewer than 3 vertices or a shape with top <=
    bottom or a negative radius (the mission loader refuses these before)."""
    kinds: list[int] = []
    rows: list[list[float]] = []
    chunks: list[np.ndarray] = []
    first = 0
    for centre, radius in spheres:
        c = np.asarray(centre, dtype=float).reshape(3)
        _check(float(radius) >= 0.0, "a sphere's radius must be >= 0")
        kinds.append(SPHERE)
        rows.append([c[0], c[1], c[2], float(radius), 0.0, 0.0])
    for centre, radius, bottom, top in cylinders:
        c = np.asarray(centre, dtype=float).reshape(-1)[:2]
        _check(
            float(radius) >= 0.0 and float(top) > float(bottom), "a cylinder needs radius >= 0, top > bottom"
        )
        kinds.append(CYLINDER)
        rows.append([c[0], c[1], float(radius), 0.0, float(bottom), float(top)])
    for footprint, bottom, top in prisms:
        ring = np.asarray(footprint, dtype=float).reshape(-1, 2)
        _check(
            len(ring) >= 3 and float(top) > float(bottom), "a prism needs 3 vertices or more, top > bottom"
        )
        x, y = ring[:, 0], ring[:, 1]
        if float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) < 0.0:  # clockwise: reverse
            ring = ring[::-1]
        kinds.append(PRISM)
        rows.append([float(first), float(len(ring)), 0.0, 0.0, float(bottom), float(top)])
        chunks.append(ring)
        first += len(ring)
    return ShapeArrays(
        np.array(kinds, dtype=np.int64),
        np.array(rows, dtype=float).reshape(-1, 6),
        np.ascontiguousarray(np.vstack(chunks) if chunks else np.zeros((0, 2))),
    )


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise ValueError(message)


NO_SHAPES = pack_shapes()


@kernel
def sphere_surface(
    x: float, y: float, z: float, cx: float, cy: float, cz: float, r: float
) -> tuple[float, float, float, float]:
    """The paper's sphere (spec 2.1): l = |q - c| - r and n_o = (q - c) / |q - c| (+z on the centre)."""
    d0, d1, d2 = x - cx, y - cy, z - cz
    d = math.sqrt(dot3(d0, d1, d2, d0, d1, d2))
    safe = 1.0 if d == 0.0 else d
    n0, n1, n2 = d0 / safe, d1 / safe, d2 / safe
    if d == 0.0:
        n2 = 1.0
    return d - r, n0, n1, n2


@kernel
def footprint_distance(
    x: float, y: float, kind: int, row: np.ndarray, vertices: np.ndarray
) -> tuple[float, float, float]:
    """The signed horizontal distance h (m, < 0 inside) from (x, y) to a cylinder's circle or a prism's
    footprint polygon (`row` its params (6,)) and the outward horizontal unit normal (nx, ny) at the nearest
    boundary point: the edge's outward normal where that point lies inside an edge (exact, and well defined on
    the edge itself), the direction from or to the vertex where it is a vertex (the edge's normal within
    VERTEX_TOLERANCE of it); on a cylinder's axis +x."""
    if kind == CYLINDER:
        h0, h1 = x - row[0], y - row[1]
        rho = math.sqrt(h0 * h0 + h1 * h1)
        if rho > 0.0:
            return rho - row[2], h0 / rho, h1 / rho
        return -row[2], 1.0, 0.0
    first, count = int(row[0]), int(row[1])
    best, bx, by = np.inf, 0.0, 0.0  # squared distance to the nearest boundary point, that point
    ex, ey = 1.0, 0.0  # the outward normal of the nearest edge (counter-clockwise ring: (dy, -dx) / length)
    at_vertex = False  # the nearest point is an end of its edge (else inside it: the normal is the edge's)
    inside = False
    for j in range(count):
        ax, ay = vertices[first + j, 0], vertices[first + j, 1]
        k = first + (j + 1) % count
        cx, cy = vertices[k, 0], vertices[k, 1]
        sx, sy = cx - ax, cy - ay
        length_sq = sx * sx + sy * sy
        s = ((x - ax) * sx + (y - ay) * sy) / length_sq if length_sq > 0.0 else 0.0
        clamped = not 0.0 < s < 1.0
        s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
        px, py = ax + s * sx, ay + s * sy
        dist_sq = (x - px) * (x - px) + (y - py) * (y - py)
        if dist_sq < best:
            best, bx, by, at_vertex = dist_sq, px, py, clamped
            length = math.sqrt(length_sq)
            ex, ey = (sy / length, -sx / length) if length > 0.0 else (1.0, 0.0)
        if (ay > y) != (cy > y) and x < ax + (y - ay) * sx / sy:  # crossing number (a ray toward +x)
            inside = not inside
    h = math.sqrt(best)
    if inside:
        h = -h
    if not at_vertex or h * h <= VERTEX_TOLERANCE * VERTEX_TOLERANCE:
        return h, ex, ey
    return h, (x - bx) / h, (y - by) / h


@kernel
def surface(
    x: float, y: float, z: float, k: int, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray
) -> tuple[float, float, float, float]:
    """The signed distance l (m) from (x, y, z) to the surface of shape k and the outward unit normal (n0, n1,
    n2) at its nearest point (module docstring; spec 2.2): beside a wall the wall's normal, above a roof +z,
    near an edge the direction from the edge, inside the normal of the nearest face."""
    row = params[k]
    kind = kinds[k]
    if kind == SPHERE:
        return sphere_surface(x, y, z, row[0], row[1], row[2], row[3])
    h, hx, hy = footprint_distance(x, y, kind, row, vertices)
    below, above = row[4] - z, z - row[5]
    v, vz = (above, 1.0) if above >= below else (below, -1.0)
    if h > 0.0 and v > 0.0:  # beside an edge of the roof or the floor
        d = math.sqrt(h * h + v * v)
        return d, h * hx / d, h * hy / d, v * vz / d
    if h > 0.0 or h >= v:  # beside a wall, or inside and nearer a wall than the roof or floor
        return h, hx, hy, 0.0
    return v, 0.0, 0.0, vz  # above the roof, below the floor, or inside nearer them than a wall


@kernel
def segment_nearest(
    x0: float, y0: float, z0: float, x1: float, y1: float, z1: float, k: int, kinds: np.ndarray,
    params: np.ndarray, vertices: np.ndarray,
) -> float:  # fmt: skip
    """The fraction f in [0, 1] of the segment (x0, y0, z0) -> (x1, y1, z1) whose point is nearest the surface
    of shape k (the least signed distance: inside the shape, the deepest point), within NEAREST_TOLERANCE m.

    A sphere: the point nearest its centre (exact). A cylinder or a prism: the best of SEGMENT_SAMPLES + 1
    evenly spaced points, refined by golden-section search in the intervals beside it. When the shape is
    convex (a cylinder, a prism whose footprint is) its signed distance is a convex function along the
    segment, so the minimum lies within one interval of the best sample and the search converges to it: to
    0.25 * 0.618^GOLDEN_STEPS ~ 1e-9 of the segment, within the tolerance for segments up to a kilometre. A
    footprint with a notch can put two valleys in one interval (a roof's edge over the notch and a wall's
    corner beyond it), and the search may settle in the wrong one: there its point is kept when it is within
    the tolerance of the segment's nearest (`_certified_nearest`), else the nearest is returned, so the
    search's right answers are returned unchanged."""
    g0, g1, g2 = x1 - x0, y1 - y0, z1 - z0
    length_sq = dot3(g0, g1, g2, g0, g1, g2)
    if not length_sq > 0.0:
        return 0.0
    if kinds[k] == SPHERE:
        c0, c1, c2 = params[k, 0], params[k, 1], params[k, 2]
        along = dot3(c0 - x0, c1 - y0, c2 - z0, g0, g1, g2) / length_sq
        return 0.0 if along < 0.0 else (1.0 if along > 1.0 else along)
    f, l = _sampled_nearest(x0, y0, z0, g0, g1, g2, k, kinds, params, vertices)
    if kinds[k] == CYLINDER or _convex_footprint(int(params[k, 0]), int(params[k, 1]), vertices):
        return f
    return _certified_nearest(x0, y0, z0, g0, g1, g2, math.sqrt(length_sq), k, kinds, params, vertices, f, l)


@kernel
def _sampled_nearest(
    x0: float, y0: float, z0: float, g0: float, g1: float, g2: float, k: int, kinds: np.ndarray,
    params: np.ndarray, vertices: np.ndarray,
) -> tuple[float, float]:  # fmt: skip
    """The fraction f of the segment (x0, y0, z0) + f (g0, g1, g2) found by sampling and golden-section search
    (`segment_nearest`), and the signed distance l there."""
    best_f, best_l = 0.0, np.inf
    for j in range(SEGMENT_SAMPLES + 1):
        f = j / SEGMENT_SAMPLES
        l = surface(x0 + g0 * f, y0 + g1 * f, z0 + g2 * f, k, kinds, params, vertices)[0]
        if l < best_l:
            best_f, best_l = f, l
    lo = best_f - 1.0 / SEGMENT_SAMPLES
    hi = best_f + 1.0 / SEGMENT_SAMPLES
    lo, hi = (0.0 if lo < 0.0 else lo), (1.0 if hi > 1.0 else hi)
    ratio = 0.5 * (math.sqrt(5.0) - 1.0)
    a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    la = surface(x0 + g0 * a, y0 + g1 * a, z0 + g2 * a, k, kinds, params, vertices)[0]
    lb = surface(x0 + g0 * b, y0 + g1 * b, z0 + g2 * b, k, kinds, params, vertices)[0]
    for _ in range(GOLDEN_STEPS):
        if la <= lb:
            hi, b, lb = b, a, la
            a = hi - ratio * (hi - lo)
            la = surface(x0 + g0 * a, y0 + g1 * a, z0 + g2 * a, k, kinds, params, vertices)[0]
        else:
            lo, a, la = a, b, lb
            b = lo + ratio * (hi - lo)
            lb = surface(x0 + g0 * b, y0 + g1 * b, z0 + g2 * b, k, kinds, params, vertices)[0]
    f, l = (a, la) if la <= lb else (b, lb)
    return (f, l) if l < best_l else (best_f, best_l)


@kernel
def _convex_footprint(first: int, count: int, vertices: np.ndarray) -> bool:
    """Whether the counter-clockwise footprint vertices[first:first + count] turns left (or goes straight) at
    every vertex: a convex polygon (footprints are simple)."""
    for j in range(count):
        ax, ay = vertices[first + j, 0], vertices[first + j, 1]
        bx, by = vertices[first + (j + 1) % count, 0], vertices[first + (j + 1) % count, 1]
        cx, cy = vertices[first + (j + 2) % count, 0], vertices[first + (j + 2) % count, 1]
        if (bx - ax) * (cy - by) - (by - ay) * (cx - bx) < 0.0:
            return False
    return True


@kernel
def _certified_nearest(
    x0: float, y0: float, z0: float, g0: float, g1: float, g2: float, length: float, k: int,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, f: float, l: float,
) -> float:  # fmt: skip
    """The fraction f of the segment (x0, y0, z0) + f (g0, g1, g2) (`length` m) nearest the surface of prism k
    within NEAREST_TOLERANCE m, given a candidate f (its distance l): that one when it is within the
    tolerance, so a right candidate is returned unchanged.

    The prism's boundary is its walls (vertical rectangles), roof and floor, and |l| is the distance to the
    nearest of them. A segment that stays outside (no point of it nearer than the tolerance to the surface at
    an end, on a wall, or where it crosses the roof's or the floor's plane) comes nearest at an end or at a
    wall, and the distance to a wall is convex along the segment, its minimum exact (`_wall_nearest`): the
    minimum over the walls is the segment's, unless an end is nearer, which the candidate already is not.
    Otherwise (the segment touches or enters the shape) `_deepest` searches it."""
    row = params[k]
    first, count, bottom, top = int(row[0]), int(row[1]), row[4], row[5]
    wall_f, wall_sq = 0.0, np.inf
    for j in range(count):
        ax, ay = vertices[first + j, 0], vertices[first + j, 1]
        cx, cy = vertices[first + (j + 1) % count, 0], vertices[first + (j + 1) % count, 1]
        fj, sq = _wall_nearest(x0 - ax, y0 - ay, z0, g0, g1, g2, cx - ax, cy - ay, bottom, top)
        if sq < wall_sq:
            wall_f, wall_sq = fj, sq
    wall_l = math.sqrt(wall_sq)
    touch = l if l < wall_l else wall_l
    if g2 != 0.0:  # where the segment crosses the roof's and the floor's planes (0 there: on them)
        for level in (bottom, top):
            fz = (level - z0) / g2 if abs(level - z0) <= abs(g2) else -1.0
            if 0.0 <= fz <= 1.0:
                lz = surface(x0 + g0 * fz, y0 + g1 * fz, z0 + g2 * fz, k, kinds, params, vertices)[0]
                touch = lz if lz < touch else touch
    if touch > NEAREST_TOLERANCE:
        return f if l <= wall_l + NEAREST_TOLERANCE else wall_f
    lw = surface(x0 + g0 * wall_f, y0 + g1 * wall_f, z0 + g2 * wall_f, k, kinds, params, vertices)[0]
    best_f, best_l = (f, l) if l <= lw else (wall_f, lw)
    best_f, best_l = _deepest(x0, y0, z0, g0, g1, g2, length, k, kinds, params, vertices, best_f, best_l)
    return f if l <= best_l + 0.5 * NEAREST_TOLERANCE else best_f


@kernel
def _wall_nearest(
    x0: float, y0: float, z0: float, g0: float, g1: float, g2: float, sx: float, sy: float, bottom: float,
    top: float,
) -> tuple[float, float]:  # fmt: skip
    """The fraction f in [0, 1] of the segment (x0, y0, z0) + f (g0, g1, g2) nearest the wall from (0, 0) to
    (sx, sy) between the heights bottom and top (x, y relative to the wall's first vertex), and the squared
    distance there, exact. With u along the wall and w across it (both linear in f), the squared distance
    q = w^2 + (u beyond 0..|s|)^2 + (z beyond bottom..top)^2 is convex and piecewise quadratic in f, so its
    derivative is piecewise linear, continuous and non-decreasing: its root lies between the last of the
    ends and breakpoints (where u or z reaches a bound) where it is <= 0 and the first where it is >= 0,
    and is linear in between."""
    span = math.sqrt(sx * sx + sy * sy)
    ex, ey = (sx / span, sy / span) if span > 0.0 else (1.0, 0.0)
    u0, u1 = x0 * ex + y0 * ey, g0 * ex + g1 * ey
    w0, w1 = x0 * ey - y0 * ex, g0 * ey - g1 * ex
    lo, hi = 0.0, 1.0
    slope_lo = _wall_slope(0.0, u0, u1, w0, w1, z0, g2, span, bottom, top)
    slope_hi = _wall_slope(1.0, u0, u1, w0, w1, z0, g2, span, bottom, top)
    if slope_lo >= 0.0:
        hi, slope_hi = 0.0, slope_lo
    elif slope_hi <= 0.0:
        lo, slope_lo = 1.0, slope_hi
    else:
        breaks = (
            -u0 / u1 if abs(u0) < abs(u1) else -1.0,  # only fractions within 1 (no overflow, nor 0 / 0)
            (span - u0) / u1 if abs(span - u0) < abs(u1) else -1.0,
            (bottom - z0) / g2 if abs(bottom - z0) < abs(g2) else -1.0,
            (top - z0) / g2 if abs(top - z0) < abs(g2) else -1.0,
        )
        for c in breaks:
            if 0.0 < c < 1.0:
                slope = _wall_slope(c, u0, u1, w0, w1, z0, g2, span, bottom, top)
                if slope <= 0.0 and c > lo:
                    lo, slope_lo = c, slope
                if slope >= 0.0 and c < hi:
                    hi, slope_hi = c, slope
    f = lo + (hi - lo) * (-slope_lo / (slope_hi - slope_lo)) if slope_hi > slope_lo else lo
    f = lo if f < lo else (hi if f > hi else f)
    u, w, z = u0 + u1 * f, w0 + w1 * f, z0 + g2 * f
    du = u if u < 0.0 else (u - span if u > span else 0.0)
    dz = z - bottom if z < bottom else (z - top if z > top else 0.0)
    return f, w * w + du * du + dz * dz


@kernel
def _wall_slope(
    f: float, u0: float, u1: float, w0: float, w1: float, z0: float, g2: float, span: float, bottom: float,
    top: float,
) -> float:  # fmt: skip
    """Half the derivative in f of `_wall_nearest`'s squared distance q at f."""
    u, z = u0 + u1 * f, z0 + g2 * f
    du = u if u < 0.0 else (u - span if u > span else 0.0)
    dz = z - bottom if z < bottom else (z - top if z > top else 0.0)
    return w1 * (w0 + w1 * f) + u1 * du + g2 * dz


@kernel
def _deepest(
    x0: float, y0: float, z0: float, g0: float, g1: float, g2: float, length: float, k: int,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, best_f: float, best_l: float,
) -> tuple[float, float]:  # fmt: skip
    """The fraction f of the segment (x0, y0, z0) + f (g0, g1, g2) (`length` m) with the least signed distance
    to prism k's surface, within NEAREST_TOLERANCE / 2 m, and that distance; best_f, best_l a point found
    before (kept unless a point is nearer).

    Branch and bound over the fractions 0..1: an interval a..b is bisected until no point of it can be
    nearer than the best found less the tolerance, by either of two lower bounds of l on it: the distance
    is 1-Lipschitz, so l >= (l(a) + l(b) - |b - a| length) / 2; and -l <= min(every wall's horizontal
    distance d_j, top - z, z - bottom) everywhere (equal inside), each of them convex along the segment,
    so at most its larger value at a and b (`_depth_bound`). The first bound alone ends the bisection once
    an interval is shorter than the tolerance (SEARCH_LEVELS levels bisect a segment of up to
    NEAREST_TOLERANCE * 2^(SEARCH_LEVELS - 2) m that far); the second prunes the intervals inside the shape
    where one face stays the nearest. SEARCH_NODES bounds the work on non-finite input (inf, NaN)."""
    stack = np.empty((SEARCH_LEVELS, 4))
    l_a = surface(x0, y0, z0, k, kinds, params, vertices)[0]
    l_b = surface(x0 + g0, y0 + g1, z0 + g2, k, kinds, params, vertices)[0]
    if l_a < best_l:
        best_f, best_l = 0.0, l_a
    if l_b < best_l:
        best_f, best_l = 1.0, l_b
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0.0, 1.0, l_a, l_b
    size, nodes = 1, 0
    slack = 0.5 * NEAREST_TOLERANCE
    while size > 0 and nodes < SEARCH_NODES:
        size -= 1
        a, b, l_a, l_b = stack[size, 0], stack[size, 1], stack[size, 2], stack[size, 3]
        if 0.5 * (l_a + l_b - (b - a) * length) >= best_l - slack:
            continue
        if -_depth_bound(x0, y0, z0, g0, g1, g2, a, b, params[k], vertices) >= best_l - slack:
            continue
        m = 0.5 * (a + b)
        l_m = surface(x0 + g0 * m, y0 + g1 * m, z0 + g2 * m, k, kinds, params, vertices)[0]
        nodes += 1
        if l_m < best_l:
            best_f, best_l = m, l_m
        if size + 2 <= SEARCH_LEVELS:
            stack[size, 0], stack[size, 1], stack[size, 2], stack[size, 3] = m, b, l_m, l_b
            stack[size + 1, 0], stack[size + 1, 1], stack[size + 1, 2], stack[size + 1, 3] = a, m, l_a, l_m
            size += 2
    return best_f, best_l


@kernel
def _depth_bound(
    x0: float, y0: float, z0: float, g0: float, g1: float, g2: float, a: float, b: float, row: np.ndarray,
    vertices: np.ndarray,
) -> float:  # fmt: skip
    """An upper bound of -l (the depth inside prism `row`) over the fractions a..b of the segment (x0, y0, z0)
    + f (g0, g1, g2): min over the faces of the larger of their distances at a and b (`_deepest`)."""
    first, count, bottom, top = int(row[0]), int(row[1]), row[4], row[5]
    z_a, z_b = z0 + g2 * a, z0 + g2 * b
    below = z_a - bottom if z_a > z_b else z_b - bottom
    above = top - z_a if z_a < z_b else top - z_b
    bound = below if below < above else above
    xa, ya, xb, yb = x0 + g0 * a, y0 + g1 * a, x0 + g0 * b, y0 + g1 * b
    for j in range(count):
        ax, ay = vertices[first + j, 0], vertices[first + j, 1]
        cx, cy = vertices[first + (j + 1) % count, 0], vertices[first + (j + 1) % count, 1]
        d_a, d_b = (
            _edge_distance(xa - ax, ya - ay, cx - ax, cy - ay),
            _edge_distance(xb - ax, yb - ay, cx - ax, cy - ay),
        )
        larger = d_a if d_a > d_b else d_b
        bound = larger if larger < bound else bound
    return bound


@kernel
def _edge_distance(x: float, y: float, sx: float, sy: float) -> float:
    """The distance from (x, y) to the segment from (0, 0) to (sx, sy)."""
    length_sq = sx * sx + sy * sy
    s = (x * sx + y * sy) / length_sq if length_sq > 0.0 else 0.0
    s = 0.0 if s < 0.0 else (1.0 if s > 1.0 else s)
    dx, dy = x - s * sx, y - s * sy
    return math.sqrt(dx * dx + dy * dy)


@kernel
def course_entry(
    x: float, y: float, z: float, u0: float, u1: float, clearance: float, horizon: float, k: int,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray,
) -> float:  # fmt: skip
    """How far (m) the point (x, y, z) goes along the horizontal unit direction (u0, u1) before it comes
    within `clearance` m of shape k's surface: 0 if it is already; inf if it does not within `horizon` m.
    Sphere tracing (J. C. Hart, 1996): the surface distance is 1-Lipschitz, so a step of (distance -
    clearance) never passes the grown surface; after TRACE_STEPS steps (a ray grazing it) where it got to,
    which is short of the entry (on the safe side)."""
    t = 0.0
    for _ in range(TRACE_STEPS):
        gap = surface(x + u0 * t, y + u1 * t, z, k, kinds, params, vertices)[0] - clearance
        if gap <= TRACE_TOLERANCE:
            return t
        t += gap
        if t > horizon:
            return np.inf
    return t


@kernel
def surface_distances(
    points: np.ndarray, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray
) -> np.ndarray:
    """(M, S) m: the signed surface distance of every point (M, 3) to every shape (`surface`)."""
    m, s = points.shape[0], kinds.shape[0]
    out = np.empty((m, s))
    for i in range(m):
        for k in range(s):
            out[i, k] = surface(points[i, 0], points[i, 1], points[i, 2], k, kinds, params, vertices)[0]
    return out


__all__ = [
    "CYLINDER",
    "NO_SHAPES",
    "PRISM",
    "SPHERE",
    "ShapeArrays",
    "course_entry",
    "footprint_distance",
    "pack_shapes",
    "segment_nearest",
    "sphere_surface",
    "surface",
    "surface_distances",
]
