"""Reference generator: the potential field becomes the position controller's desired state (spec 8 steps
3-6), compiled per vehicle (swarm_common.jit).

Per vehicle state (p_r, v_r, a_r), initialised to the measured (p, v). Each tick: leash p_r to the vehicle
and find where the field is felt (`leash_and_lookahead`); the caller evaluates the field there; `step`:
v_cmd = v_ff + (K_v/k_att) F, saturated; a_r toward v_cmd; (p_r, v_r, a_r) go to the position controller;
integrate to the next tick. Shapes (N, 3) ENU m, m/s, m/s^2.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from gcs_swarm.guidance.capability import within_budget
from gcs_swarm.guidance.params import FieldParams, G, Limits, ReferenceParams
from gcs_swarm.guidance.shaping import shape_vel_accel, shape_vel_accel_xy
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip_to_scalars, maximum, minimum, norm3
from swarm_common.shaping import sqrt_controller


def default_d_g(field: FieldParams, v_max: float, k_v: float) -> float:
    """Attraction segment boundary: the configured d_g, else v_max / K_v (spec 3.1 [ambig], spec 8 step 3)."""
    return field.d_g if field.d_g is not None else v_max / k_v


def paper_literal_reference(
    slots: np.ndarray, slot_vel: np.ndarray, f_rep: np.ndarray, k_att: float, l0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spec 8 option `paper_literal` (Eq 53 as printed): x_d = s_i + K_f sum F_rep with K_f = 1/k_att and
    |K_f sum F_rep| <= l0, xd_dot = v_i^s, xd_ddot = 0. Returns (x_d, xd_dot, xd_ddot), each (N, 3)."""
    shift = f_rep / k_att
    size = np.linalg.norm(shift, axis=1)
    over = size > l0
    shift[over] *= (l0 / size[over])[:, None]
    return slots + shift, np.array(slot_vel, dtype=float), np.zeros_like(slots)


def no_budgets(n: int) -> np.ndarray:
    """(n, 4): `reference_step`'s budgets for n rows none of which has an acceleration budget."""
    budgets = np.zeros((n, 4))
    budgets[:, 3] = math.inf
    return budgets


class ReferenceConfig(NamedTuple):
    """The settings of `reference_step`, its last parameters in this order (ReferenceGenerator builds them
    from ReferenceParams and Limits)."""

    gain: float  # K_v / k_att, (m/s) per field unit
    v_z: float  # m/s, vertical speed limit
    stop_accel: float  # m/s^2, the stopping curve's deceleration; 0: no stopping curve
    k_v: float  # 1/s, K_v
    jerk_max: float  # m/s^3, horizontal jerk limit; 0: the spec's first-order step 4
    has_z_min: bool  # an altitude floor is set
    z_min: float  # m, the altitude floor
    jerk_max_z: float  # m/s^3, vertical jerk limit
    a_z: float  # m/s^2, vertical acceleration limit
    tau_v: float  # s, the first-order step 4's time constant
    a_xy_max: float  # m/s^2, horizontal acceleration limit
    a_xy_evasive: float  # m/s^2, horizontal acceleration limit of evasive rows
    jerk_xy_evasive: float  # m/s^3, horizontal jerk limit of evasive rows
    jerk_z_evasive: float  # m/s^3, vertical jerk limit of evasive rows


@kernel
def leash_and_lookahead(
    p: np.ndarray, v: np.ndarray, pos: np.ndarray, rows: np.ndarray, leash: np.ndarray, brake_accel: float
) -> np.ndarray:
    """Step 6, then where the field is felt: references p (N, 3) farther than their `leash` (N,) m from
    their vehicle pos (N, 3) are put back on that sphere, in place, for the (N,) bool rows; returns the
    braking points (N, 3) p + v |v| / (2 a_b) [add] (v (N, 3) the reference velocities, a_b = brake_accel
    m/s^2), where each reference would stop if it braked now, so that a reference meets the strong part of
    a repulsion no faster than it can brake; p itself when brake_accel <= 0 (spec 8 step 2)."""
    n = p.shape[0]
    for i in range(n):
        g0, g1, g2 = p[i, 0] - pos[i, 0], p[i, 1] - pos[i, 1], p[i, 2] - pos[i, 2]
        dist = norm3(g0, g1, g2)
        if rows[i] and dist > leash[i]:
            scale = leash[i] / dist
            p[i, 0], p[i, 1], p[i, 2] = pos[i, 0] + g0 * scale, pos[i, 1] + g1 * scale, pos[i, 2] + g2 * scale
    if brake_accel <= 0.0:
        return p
    ahead = np.empty((n, 3))
    for i in range(n):
        scale = norm3(v[i, 0], v[i, 1], v[i, 2]) / (2.0 * brake_accel)
        for d in range(3):
            ahead[i, d] = p[i, d] + v[i, d] * scale
    return ahead


@kernel
def reference_step(
    p: np.ndarray, v: np.ndarray, a_prev: np.ndarray, force: np.ndarray, v_ff: np.ndarray, a_ff: np.ndarray,
    targets: np.ndarray, v_xy_max: np.ndarray, rows: np.ndarray, evasive: np.ndarray, budgets: np.ndarray,
    dt: float,
    gain: float, v_z: float, stop_accel: float, k_v: float, jerk_max: float, has_z_min: bool, z_min: float,
    jerk_max_z: float, a_z: float, tau_v: float, a_xy_max: float, a_xy_evasive: float, jerk_xy_evasive: float,
    jerk_z_evasive: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Steps 3-5 from the reference state p, v, a_prev (N, 3), the field force (N, 3) at p, the feed-forwards
    v_ff, a_ff (N, 3), the attraction targets (N, 3), the horizontal speed caps v_xy_max (N,) m/s, the (N,)
    bool rows to advance, the (N,) bool `evasive` rows, each row's acceleration budget (N, 4) (the fields of
    capability.AccelBudget; budget inf: none) and dt s: the desired acceleration a_r (N, 3) of this
    instant (a_prev in rows not advanced) and the next reference state p, v (N, 3) (p, v themselves in rows
    not advanced). The settings are ReferenceConfig's fields (called with *config); ReferenceGenerator
    documents the rules."""
    n = p.shape[0]
    accel = np.empty((n, 3))
    p_next = np.empty((n, 3))
    v_next = np.empty((n, 3))
    for i in range(n):
        c0, c1, c2 = (
            v_ff[i, 0] + gain * force[i, 0],
            v_ff[i, 1] + gain * force[i, 1],
            v_ff[i, 2] + gain * force[i, 2],
        )
        xy = np.hypot(c0, c1)  # step 3: saturate
        if xy > v_xy_max[i]:
            scale = v_xy_max[i] / xy
            c0, c1 = c0 * scale, c1 * scale
        c2 = clip_to_scalars(c2, -v_z, v_z)
        if stop_accel > 0.0:  # [add] the stopping curve
            t0, t1, t2 = targets[i, 0] - p[i, 0], targets[i, 1] - p[i, 1], targets[i, 2] - p[i, 2]
            dist = norm3(t0, t1, t2)
            if dist > 0.0:
                u0, u1, u2 = t0 / dist, t1 / dist, t2 / dist
            else:
                u0, u1, u2 = 0.0, 0.0, 0.0
            if jerk_max > 0.0:
                n0, n1, n2 = v[i, 0] - v_ff[i, 0], v[i, 1] - v_ff[i, 1], v[i, 2] - v_ff[i, 2]
                approach = maximum((n0 * u0 + n2 * u2) + n1 * u1 + 0.0, 0.0)
                dist = maximum(dist - approach * stop_accel / jerk_max, 0.0)
            cap = sqrt_controller(dist, k_v, stop_accel, 0.0)
            r0, r1, r2 = c0 - v_ff[i, 0], c1 - v_ff[i, 1], c2 - v_ff[i, 2]
            excess = maximum((r0 * u0 + r2 * u2) + r1 * u1 + 0.0 - cap, 0.0)
            c0 = v_ff[i, 0] + (r0 - u0 * excess)
            c1 = v_ff[i, 1] + (r1 - u1 * excess)
            c2 = v_ff[i, 2] + (r2 - u2 * excess)
        if has_z_min:  # altitude floor
            height = maximum(p[i, 2] - z_min, 0.0)
            if stop_accel > 0.0:
                floor_rate = -sqrt_controller(height, k_v, stop_accel, 0.0)
            else:
                floor_rate = -k_v * height
            if jerk_max > 0.0:
                rate = 0.5 * jerk_max_z / a_z
                floor_rate = maximum(floor_rate, -rate * height)
            c2 = maximum(c2, minimum(floor_rate, v_z))
        if not rows[i]:
            a0, a1, a2 = a_prev[i, 0], a_prev[i, 1], a_prev[i, 2]
        elif jerk_max <= 0.0:  # the spec's first-order step 4
            a0, a1, a2 = (c0 - v[i, 0]) / tau_v, (c1 - v[i, 1]) / tau_v, (c2 - v[i, 2]) / tau_v
            xy = np.hypot(a0, a1)
            if xy > a_xy_max:
                scale = a_xy_max / xy
                a0, a1 = a0 * scale, a1 * scale
            a2 = clip_to_scalars(a2, -a_z, a_z)
        else:  # [add] jerk-limited step 4 (gcs_swarm.guidance.shaping)
            accel_xy = a_xy_evasive if evasive[i] else a_xy_max
            jerk_xy = jerk_xy_evasive if evasive[i] else jerk_max
            jerk_z = jerk_z_evasive if evasive[i] else jerk_max_z
            a0, a1 = shape_vel_accel_xy(
                c0, c1, a_ff[i, 0], a_ff[i, 1], v[i, 0], v[i, 1], a_prev[i, 0], a_prev[i, 1], accel_xy,
                jerk_xy, dt,
            )  # fmt: skip
            a2 = shape_vel_accel(c2, a_ff[i, 2], v[i, 2], a_prev[i, 2], a_z, jerk_z, dt)
        if rows[i] and not evasive[i]:  # [add] within what the slowest follower can make (spec 6b)
            a0, a1 = within_budget(
                a0, a1, v[i, 0], v[i, 1], budgets[i, 0], budgets[i, 1], budgets[i, 2], budgets[i, 3]
            )
        w0, w1, w2 = v[i, 0] + a0 * dt, v[i, 1] + a1 * dt, v[i, 2] + a2 * dt  # step 5
        q0, q1, q2 = p[i, 0] + w0 * dt, p[i, 1] + w1 * dt, p[i, 2] + w2 * dt
        if has_z_min and q2 < z_min:
            q2 = z_min
            w2 = maximum(w2, 0.0)
            a2 = maximum(a2, 0.0)
        accel[i, 0], accel[i, 1], accel[i, 2] = a0, a1, a2
        if rows[i]:
            p_next[i, 0], p_next[i, 1], p_next[i, 2] = q0, q1, q2
            v_next[i, 0], v_next[i, 1], v_next[i, 2] = w0, w1, w2
        else:
            p_next[i, 0], p_next[i, 1], p_next[i, 2] = p[i, 0], p[i, 1], p[i, 2]
            v_next[i, 0], v_next[i, 1], v_next[i, 2] = v[i, 0], v[i, 1], v[i, 2]
    return accel, p_next, v_next


class ReferenceGenerator:
    """Per-vehicle reference state (p_r, v_r, a_r) driven by the field (spec 8 steps 3-6).

    Step 3: v_cmd = v_ff + (K_v / k_att) F, its horizontal part within the vehicle's speed cap, its vertical
    part within v_z. [add] Stopping curve (`stop_accel` > 0): the part of v_cmd - v_ff along the direction
    to the attraction target is capped at sqrt_controller(d, K_v, stop_accel) (K_v d close in, the braking
    curve sqrt(2 a d) farther out), d the target distance less what the reference covers at its present
    approach speed while its deceleration ramps up at jerk_max; near the target this is spec 8 step 3
    (v = K_v (T - p)), and the field itself is unchanged. [add] Altitude floor (`z_min`): the allowed descent
    rate shrinks to zero at z_min (following the braking curve with the stopping curve on), and with jerk
    limits to at most half the rate jerk_max_z / a_z at which the shaped vertical velocity follows a demand,
    so no field (an obstacle pushing down, say) can drive a reference into the ground (a 4-obstacle world in
    4.8 m/s wind drove a reference to -4 m and a vehicle into the ground at 6.8 m/s before); whatever the
    shaping does, the integrated reference never sinks below the floor.

    Step 4: `jerk_max` 0: the spec's first-order a_r = sat((v_cmd - v_r) / tau_v), which steps with the
    demand; > 0 [add]: ArduPilot's jerk-limited shaping (gcs_swarm.guidance.shaping) with the feed-forward
    a_ff, within accel_xy_max (the rest of the tilt is for drag and wind). Rows in an emergency separation
    (`evasive`, spec 4 Eq 19) are shaped with the whole tilt's acceleration and `evasive_jerk_max`: comfort
    never slows a vehicle getting out of the way. [add] A row with an acceleration budget (the leader, spec
    6b) keeps its horizontal a_r within what its slowest follower can make at its speed
    (capability.within_budget). Step 5: v_r += a_r dt, p_r += v_r dt.

    [add] The position controller gets the reference of the current instant, not the one integrated to
    t + dt (spec 8 step 7 after step 5): otherwise a moving slot leaves a steady v dt offset (0.2 m at
    10 m/s, 50 Hz).
    """

    def __init__(
        self, params: ReferenceParams, limits: Limits, k_att: float, g: float = G, z_min: float | None = None
    ) -> None:
        """`z_min` m: altitude floor of the references ([add] safety.min_altitude), None for none."""
        self.params = params
        self.z_min = z_min
        self.limits = limits
        self.gain = params.k_v / k_att  # (m/s) per field unit
        tilt_accel = g * math.tan(limits.tilt_max)
        self.a_xy_evasive = min(limits.a_xy, tilt_accel)
        self.a_xy_max = min(self.a_xy_evasive, params.accel_xy_max if params.jerk_max > 0 else tilt_accel)
        self.config = ReferenceConfig(
            gain=float(self.gain), v_z=float(limits.v_z), stop_accel=float(params.stop_accel),
            k_v=float(params.k_v), jerk_max=float(params.jerk_max), has_z_min=z_min is not None,
            z_min=0.0 if z_min is None else float(z_min), jerk_max_z=float(params.jerk_max_z),
            a_z=float(limits.a_z), tau_v=float(params.tau_v), a_xy_max=float(self.a_xy_max),
            a_xy_evasive=float(self.a_xy_evasive),
            jerk_xy_evasive=float(max(params.evasive_jerk_max, params.jerk_max)),
            jerk_z_evasive=float(max(params.evasive_jerk_max, params.jerk_max_z)),
        )  # fmt: skip
        self.p = np.zeros((0, 3))
        self.v = np.zeros((0, 3))
        self.a = np.zeros((0, 3))

    def reset(self, pos: np.ndarray, vel: np.ndarray) -> None:
        """Start every reference at the measured state."""
        self.p = np.array(pos, dtype=float)
        self.v = np.array(vel, dtype=float)
        self.a = np.zeros_like(self.p)

    def reset_rows(self, rows: np.ndarray, pos: np.ndarray, vel: np.ndarray) -> None:
        """Restart the references of the (N,) bool-selected vehicles at their measured state."""
        self.p[rows] = pos[rows]
        self.v[rows] = vel[rows]
        self.a[rows] = 0.0

    def leash_and_lookahead(
        self, pos: np.ndarray, rows: np.ndarray, leash: np.ndarray | None = None
    ) -> np.ndarray:
        """Step 6 for the (N,) bool rows (references farther than their leash (N,) m, default the params'
        `leash` for every row, from their vehicle pos (N, 3) go back on that sphere), then the points (N, 3)
        where the field is felt (`leash_and_lookahead`)."""
        leash = np.full(len(pos), float(self.params.leash)) if leash is None else leash
        return leash_and_lookahead(self.p, self.v, pos, rows, leash, float(self.params.brake_accel))

    def step(
        self,
        force: np.ndarray,
        v_ff: np.ndarray,
        v_xy_max: np.ndarray,
        dt: float,
        rows: np.ndarray,
        a_ff: np.ndarray | None = None,
        targets: np.ndarray | None = None,
        evasive: np.ndarray | None = None,
        budgets: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steps 3-5 for the (N,) bool-selected vehicles from the field force (N, 3) at the current reference
        points, the velocity feed-forward (N, 3), horizontal speed caps (N,) m/s, the acceleration
        feed-forward a_ff (N, 3) m/s^2 (None: zero), the attraction targets (N, 3) m for the stopping curve
        (None: none), the (N,) bool evasive rows (None: none) and the acceleration budgets (N, 4)
        (capability.AccelBudget's fields; None: none): returns the desired state (p_r, v_r, a_r) of this
        instant (each (N, 3)) and advances the state by dt s for the next tick."""
        n = len(force)
        a_ff = np.zeros((n, 3)) if a_ff is None else a_ff
        evasive = np.zeros(n, dtype=bool) if evasive is None else evasive
        budgets = no_budgets(n) if budgets is None else budgets
        targets = self.p if targets is None else targets  # its own point: no stopping curve
        p, v = self.p, self.v
        self.a, self.p, self.v = reference_step(
            p, v, self.a, force, v_ff, a_ff, targets, v_xy_max, rows, evasive, budgets, float(dt),
            *self.config,
        )  # fmt: skip
        return p, v, self.a
