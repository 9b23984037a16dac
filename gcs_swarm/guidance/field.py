"""The potential field of the configured method (FieldParams.law: the APF baseline, spec 2, or the IAAPF,
spec 3), 3-D, for N points at once; the potentials whose gradients these forces are sit in apf.py and
iaapf.py.

Obstacle terms are evaluated for the (vehicle, obstacle) pairs whose evaluation point lies within l0 of the
obstacle's surface ([add] a follower's: within its slot's clearance less a margin, `slot_ranges`). With
`ahead` [add], the evaluation point of obstacle k for vehicle i is the point of the segment q[i] -> ahead[i]
(the reference's braking path, gcs_swarm.guidance.reference) nearest to k's surface (a sphere's: nearest
its centre; a cylinder's or prism's: swarm_common.obstacle_shapes.segment_nearest): an obstacle ahead is
felt as soon as the vehicle could no longer stop short of it, one alongside or behind exactly as at q.

The pairs and the forces are compiled kernels (swarm_common.jit), joined by the kernel
`obstacle_repulsion_force`, which the tick (through `obstacle_repulsion`, the settings from FieldParams) and
the leader's predicted path (gcs_swarm.guidance.leader_path, from inside its own kernel) both call; rho^n is
libm's pow, compiled and interpreted alike. Shapes: N points, K obstacles, P pairs; ENU m; forces in field
units (k_att m).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gcs_swarm.guidance.params import FieldMethod, FieldParams
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip_to_scalars, dot3, maximum, norm3
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays, segment_nearest, sphere_surface, surface

HEAD_ON_BIAS = 0.05  # share of the right-hand side mixed into the way round, so a dead-ahead obstacle has one


class AttractionConfig(NamedTuple):
    """The settings of `attraction_force`, its last parameters in this order (`attraction_config`)."""

    k_att: float  # attraction gain, field units per m
    d_g: float  # m, the segment boundary
    segmented: bool  # the IAAPF's segmented attraction (spec 3.1), else the APF's (spec 2)


class RepulsionConfig(NamedTuple):
    """The settings of `obstacle_repulsion_force`, its last parameters in this order (`repulsion_config`)."""

    l0: float  # m, influence distance from the surface
    l_min: float  # m, distance floor
    adaptive: bool  # the IAAPF's adaptive repulsion (spec 3.2), else the APF's (spec 2)
    k_rep: float  # repulsion gain
    n_exp: float  # the adaptive factor's exponent n
    rho_eps: float  # m, F*_rep2 is zero closer than this to the destination
    circulation: float  # the tangential companion's gain [add]
    obstacle_vertical: float  # weight of the vertical component [add]


def attraction_config(fp: FieldParams, d_g: float) -> AttractionConfig:
    """`attraction_force`'s settings for the method fp.law and the segment boundary d_g m."""
    return AttractionConfig(float(fp.k_att), float(d_g), fp.law is FieldMethod.IAAPF)


def repulsion_config(fp: FieldParams, circulation: float | None = None) -> RepulsionConfig:
    """`obstacle_repulsion_force`'s settings for the method fp.law; `circulation` overrides fp.circulation
    (the 2-D planner: 0)."""
    gain = fp.circulation if circulation is None else circulation
    return RepulsionConfig(
        float(fp.l0), float(fp.l_min), fp.law is FieldMethod.IAAPF, float(fp.k_rep), float(fp.n),
        float(fp.rho_eps), float(gain), float(fp.obstacle_vertical),
    )  # fmt: skip


@kernel
def attraction_force(
    q: np.ndarray, target: np.ndarray, k_att: float, d_g: float, segmented: bool
) -> np.ndarray:
    """(N, 3) toward target (N, 3): F*_att = -k_att (q - q_g) min(1, d_g / rho) (IAAPF, spec 3.1 Eq 8,
    `segmented`), or F_att = -k_att (q - q_g) (APF, spec 2 Eq 2)."""
    n = q.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        d0, d1, d2 = q[i, 0] - target[i, 0], q[i, 1] - target[i, 1], q[i, 2] - target[i, 2]
        if segmented:
            rho = norm3(d0, d1, d2)
            scale = -k_att * (1.0 if rho <= d_g else d_g / maximum(rho, d_g))
            out[i, 0], out[i, 1], out[i, 2] = scale * d0, scale * d1, scale * d2
        else:
            out[i, 0], out[i, 1], out[i, 2] = -k_att * d0, -k_att * d1, -k_att * d2
    return out


@kernel
def segment_sphere(
    s0: float, s1: float, s2: float, g0: float, g1: float, g2: float, c0: float, c1: float, c2: float,
    radius: float,
) -> tuple[float, float, float, float, float, float, float]:  # fmt: skip
    """The surface distance l m of the sphere of centre (c0, c1, c2), `radius` (ENU m) at the point of the
    segment (s0, s1, s2) + f (g0, g1, g2) (f in [0, 1]) nearest its centre, that point (a0, a1, a2) and the
    unit vector centre -> point there (o0, o1, o2; +z on the centre, spec 2.1): (l, a0, a1, a2, o0, o1, o2).
    Scalars only, so that the loops over pairs calling it pass no arrays."""
    length_sq = dot3(g0, g1, g2, g0, g1, g2)
    along = dot3(c0 - s0, c1 - s1, c2 - s2, g0, g1, g2)
    frac = clip_to_scalars(along / length_sq if length_sq > 0.0 else 0.0, 0.0, 1.0)
    a0, a1, a2 = s0 + g0 * frac, s1 + g1 * frac, s2 + g2 * frac
    raw, o0, o1, o2 = sphere_surface(a0, a1, a2, c0, c1, c2, radius)
    return raw, a0, a1, a2, o0, o1, o2


@kernel
def segment_shape(
    s0: float, s1: float, s2: float, g0: float, g1: float, g2: float, shape: int, kinds: np.ndarray,
    params: np.ndarray, vertices: np.ndarray, reach: float,
) -> tuple[float, float, float, float, float, float, float]:  # fmt: skip
    """As `segment_sphere` for the cylinder or prism `shape` of kinds, params, vertices (spec 2.2; its outward
    normal at the point), the point found by `segment_nearest`; a shape no point of the segment can be within
    `reach` m of gives l = inf (the rest zero) without the search."""
    length = math.sqrt(dot3(g0, g1, g2, g0, g1, g2))
    # the surface distance is 1-Lipschitz: no point of the segment is nearer than this
    if surface(s0, s1, s2, shape, kinds, params, vertices)[0] - length > reach:
        return np.inf, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    frac = segment_nearest(s0, s1, s2, s0 + g0, s1 + g1, s2 + g2, shape, kinds, params, vertices)
    a0, a1, a2 = s0 + g0 * frac, s1 + g1 * frac, s2 + g2 * frac
    raw, o0, o1, o2 = surface(a0, a1, a2, shape, kinds, params, vertices)
    return raw, a0, a1, a2, o0, o1, o2


@kernel
def obstacle_pairs(
    q: np.ndarray, ahead: np.ndarray, dest: np.ndarray, centres: np.ndarray, radii: np.ndarray, l0: float,
    l_min: float, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, ranges: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The (vehicle, obstacle) pairs whose evaluation point (module docstring; ahead = q: q itself) is within
    the pair's influence distance of the surface, in (i, k) order, the spheres centres (K, 3), radii (K,)
    first, then the packed shapes kinds, params, vertices (swarm_common.obstacle_shapes, spec 2.2): the
    vehicle index i (P,), l = max(surface distance, l_min) (P,), the unit vectors n_o (P, 3) (a sphere's
    centre -> point, +z on the centre, spec 2.1; a shape's outward normal at its point nearest the
    evaluation point) and n_g point -> dest[i] (P, 3) (zero at dest), rho (P,) the point's distance to
    dest[i] (spec 3.2) and the pair's influence distance (P,) m: ranges[i, k] ((N, K + S) m, `slot_ranges`),
    or l0 for every pair when `ranges` has no rows."""
    n, k_obs = q.shape[0], radii.shape[0]
    k_all = k_obs + kinds.shape[0]
    size = n * k_all
    per_pair = ranges.shape[0] > 0
    vehicle = np.empty(size, dtype=np.intp)
    l_out = np.empty(size)
    rho_out = np.empty(size)
    range_out = np.empty(size)
    n_o = np.empty((size, 3))
    n_g = np.empty((size, 3))
    p = 0
    for i in range(n):
        s0, s1, s2 = q[i, 0], q[i, 1], q[i, 2]
        g0, g1, g2 = ahead[i, 0] - s0, ahead[i, 1] - s1, ahead[i, 2] - s2
        for k in range(k_all):
            reach = ranges[i, k] if per_pair else l0
            if k < k_obs:
                c0, c1, c2 = centres[k, 0], centres[k, 1], centres[k, 2]
                raw, a0, a1, a2, o0, o1, o2 = segment_sphere(s0, s1, s2, g0, g1, g2, c0, c1, c2, radii[k])
            else:
                raw, a0, a1, a2, o0, o1, o2 = segment_shape(
                    s0, s1, s2, g0, g1, g2, k - k_obs, kinds, params, vertices, reach
                )
            if not raw <= reach:
                continue
            vehicle[p] = i
            range_out[p] = reach
            l_out[p] = maximum(raw, l_min)
            n_o[p, 0], n_o[p, 1], n_o[p, 2] = o0, o1, o2
            e0, e1, e2 = dest[i, 0] - a0, dest[i, 1] - a1, dest[i, 2] - a2
            rho = norm3(e0, e1, e2)
            div = rho if rho > 0.0 else 1.0
            n_g[p, 0], n_g[p, 1], n_g[p, 2] = e0 / div, e1 / div, e2 / div
            rho_out[p] = rho
            p += 1
    return vehicle[:p], l_out[:p], n_o[:p], n_g[:p], rho_out[:p], range_out[:p]


@kernel
def obstacle_forces(
    n: int, vehicle: np.ndarray, l: np.ndarray, n_o: np.ndarray, n_g: np.ndarray, rho: np.ndarray,
    l0: np.ndarray, adaptive: bool, k_rep: float, n_exp: float, rho_eps: float, circulation: float,
    obstacle_vertical: float,
) -> np.ndarray:  # fmt: skip
    """The summed obstacle repulsion (n, 3) on n points of the pairs of `obstacle_pairs` (n in the formulas
    below is the exponent n_exp; rho^n is libm's pow; l0 (P,) m each pair's influence distance).

    `adaptive` (IAAPF, spec 3.2 Eqs 10-12): F*_rep1 = k_rep (1/l - 1/l0) rho^n / l^2 along n_o plus
    F*_rep2 = 0.5 n k_rep (1/l - 1/l0)^2 rho^(n-1) along n_g (0 closer than rho_eps to dest); else (APF,
    spec 2 Eq 4) F_rep = k_rep (1/l - 1/l0) / l^2 along n_o. Both 0 beyond l0.
    [add] `circulation` > 0: a tangential companion, gain * |F_rep1| * max(0, -n_o . n_g) along the
    horizontal unit vector across n_o on the side where the goal lies, times clip(rho / l - 1, 0, 1), i.e.
    only while the obstacle stands between the vehicle and its goal (the goal beyond the surface). The
    paper's repulsion pushes straight back from an obstacle ahead, so a goal behind it is a saddle where the
    vehicle stalls (head-on, for ever); this turns the push into a way round, as a vortex field does; an
    obstacle dead ahead is passed on the right (HEAD_ON_BIAS keeps the side continuous). [add] The vertical
    component is weighted by `obstacle_vertical` (1: the paper's)."""
    force = np.zeros((n, 3))
    bracket_scale = 0.5 * n_exp * k_rep
    for p in range(vehicle.shape[0]):
        lp, l0p = l[p], l0[p]
        o0, o1, o2 = n_o[p, 0], n_o[p, 1], n_o[p, 2]
        g0, g1, g2 = n_g[p, 0], n_g[p, 1], n_g[p, 2]
        if adaptive:
            bracket = 1.0 / lp - 1.0 / l0p if lp <= l0p else 0.0
            rho_n = rho[p] ** n_exp  # libm's pow both compiled and interpreted (a numpy scalar's **)
            f1 = k_rep * bracket * rho_n / (lp * lp)
            if rho[p] < rho_eps:
                f2 = 0.0
            else:
                f2 = bracket_scale * bracket * bracket * rho_n / rho[p]
            x0, x1, x2 = f1 * o0 + f2 * g0, f1 * o1 + f2 * g1, f1 * o2 + f2 * g2
        else:
            f1 = k_rep * (1.0 / lp - 1.0 / l0p) / (lp * lp) if lp <= l0p else 0.0
            x0, x1, x2 = f1 * o0, f1 * o1, f1 * o2
        if circulation > 0.0:
            r0, r1, r2 = -o1, o0, 0.0  # right of the travel, -n_o
            dot = dot3(g0, g1, g2, o0, o1, o2)
            t0, t1, t2 = g0 - dot * o0, g1 - dot * o1, 0.0  # the goal direction across n_o, horizontal
            bias = HEAD_ON_BIAS * dot3(r0, r1, r2, r0, r1, r2)
            w0, w1, w2 = t0 + bias * r0, t1 + bias * r1, t2 + bias * r2
            length = norm3(w0, w1, w2)
            if length > 0.0:
                w0, w1, w2 = w0 / length, w1 / length, w2 / length
            else:
                w0, w1, w2 = 0.0, 0.0, 0.0
            # the obstacle stands between the vehicle and its destination only when the destination lies
            # beyond its surface: the share fades in from rho = l to rho = 2 l, so no vortex circles a
            # destination beside the obstacle (a follower whose slot is there would orbit it for ever)
            beyond = clip_to_scalars(rho[p] / lp - 1.0, 0.0, 1.0)
            blocking = maximum(-dot3(o0, o1, o2, g0, g1, g2), 0.0) * beyond
            c = circulation * f1 * blocking
            x0, x1, x2 = x0 + c * w0, x1 + c * w1, x2 + c * w2
        x2 = x2 * obstacle_vertical
        i = vehicle[p]
        force[i, 0] += x0
        force[i, 1] += x1
        force[i, 2] += x2
    return force


@kernel
def obstacle_repulsion_force(
    q: np.ndarray, ahead: np.ndarray, dest: np.ndarray, centres: np.ndarray, radii: np.ndarray,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, ranges: np.ndarray, l0: float, l_min: float,
    adaptive: bool, k_rep: float, n_exp: float, rho_eps: float, circulation: float, obstacle_vertical: float,
) -> np.ndarray:  # fmt: skip
    """Summed obstacle repulsion (N, 3) at the points q (N, 3), evaluated along the segments to `ahead`
    (N, 3) (q itself: at q), with the adaptive factor's destinations dest (N, 3), of the spheres centres
    (K, 3), radii (K,) and the shapes packed as kinds, params, vertices (spec 2.2), each (point, obstacle)
    pair within its influence distance ranges (N, K + S) m (no rows: l0 for all, `slot_ranges`):
    `obstacle_pairs`, then `obstacle_forces`. The settings are RepulsionConfig's fields (called with
    *repulsion_config(...))."""
    vehicle, l, n_o, n_g, rho, reach = obstacle_pairs(
        q, ahead, dest, centres, radii, l0, l_min, kinds, params, vertices, ranges
    )
    return obstacle_forces(
        q.shape[0], vehicle, l, n_o, n_g, rho, reach, adaptive, k_rep, n_exp, rho_eps, circulation,
        obstacle_vertical,
    )  # fmt: skip


@kernel
def slot_ranges(
    slots: np.ndarray, braking: np.ndarray, followers: np.ndarray, centres: np.ndarray, radii: np.ndarray,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, l0: float, margin: float, floor: float,
) -> np.ndarray:  # fmt: skip
    """[add] Each follower's influence distance (N, K + S) m from each obstacle (the spheres centres (K, 3),
    radii (K,) first, then the packed shapes): the clearance from the obstacle's surface of its slot's
    braking path, the segment slots[i] -> slots[i] + braking[i] ((N, 3) ENU m each; braking: the follower's
    own evaluation segment, ahead - q of `obstacle_pairs`), less `margin` m, within [floor, l0]; l0 in the
    rows not among the (N,) bool `followers`.

    The paper's repulsion reaches l0 = 20 m from every surface with a gain that grows with the distance to
    the destination (rho^n): 50-100 m from the goal, a follower 10 m from a surface is pushed off at the
    equivalent of 20 m/s, so a follower whose slot passes 10 m from an obstacle flies metres wide of it. A
    follower whose slot clears an obstacle needs its repulsion only once it strays more than `margin` m
    toward it; within `floor` m of a surface every follower feels it whatever its slot does. The slot is
    looked ahead along the same braking path as the follower: a follower on its slot, its path reaching
    towards a gap its slot will pass 8 m from each side, is not held back from it while its slot is still
    40 m short of it (docs/metrics.md)."""
    n, k_obs = slots.shape[0], radii.shape[0]
    k_all = k_obs + kinds.shape[0]
    reach = l0 + margin  # a shape's clearance beyond this gives l0 whatever it is
    out = np.full((n, k_all), l0)
    for i in range(n):
        if not followers[i]:
            continue
        s0, s1, s2 = slots[i, 0], slots[i, 1], slots[i, 2]
        g0, g1, g2 = braking[i, 0], braking[i, 1], braking[i, 2]
        for k in range(k_all):
            if k < k_obs:
                c0, c1, c2 = centres[k, 0], centres[k, 1], centres[k, 2]
                clear = segment_sphere(s0, s1, s2, g0, g1, g2, c0, c1, c2, radii[k])[0]
            else:
                clear = segment_shape(s0, s1, s2, g0, g1, g2, k - k_obs, kinds, params, vertices, reach)[0]
            out[i, k] = clip_to_scalars(clear - margin, floor, l0)
    return out


NO_RANGES = np.zeros((0, 0))  # `obstacle_repulsion_force`'s ranges when every pair reaches l0


def obstacle_repulsion(
    q: np.ndarray,
    ahead: np.ndarray,
    dest: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    fp: FieldParams,
    circulation: float | None = None,
    shapes: ShapeArrays = NO_SHAPES,
    ranges: np.ndarray = NO_RANGES,
) -> np.ndarray:
    """Summed obstacle repulsion (N, 3) at the points q (N, 3) of the method fp.law, evaluated along the
    segments to `ahead` (N, 3) (q itself: at q), with the adaptive factor's destinations dest (N, 3); K
    spheres centres (K, 3), radii (K,) and the cylinders and prisms `shapes` (spec 2.2); each pair within
    ranges (N, K + S) m (`slot_ranges`; no rows: fp.l0). `circulation` overrides fp.circulation (the 2-D
    planner: 0)."""
    args = (q, ahead, dest, centres, radii, *shapes, ranges, *repulsion_config(fp, circulation))
    return obstacle_repulsion_force(*args)


def attraction(q: np.ndarray, target: np.ndarray, fp: FieldParams, d_g: float) -> np.ndarray:
    """The attraction (N, 3) of the method fp.law toward target (N, 3), segment boundary d_g m."""
    return attraction_force(q, target, *attraction_config(fp, d_g))
