"""Reference generator: the potential field becomes the SMC's desired state (spec 8 steps 3-6).

Per vehicle state (p_r, v_r), initialised to the measured (p, v). Each tick: leash p_r to the vehicle; the
caller evaluates the field at p_r; v_cmd = v_ff + (K_v/k_att) F, saturated; a_r = (v_cmd - v_r)/tau_v,
saturated; (p_r, v_r, a_r) go to the SMC; integrate to the next tick. Shapes (N, 3) ENU.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from gcs_swarm.guidance.params import FieldParams, G, Limits, ReferenceParams
from gcs_swarm.guidance.shaping import shape_vel_accel, shape_vel_accel_xy, sqrt_controller
from gcs_swarm.guidance.vector_ops import row_norms

# The shaped step 4 runs compiled when numba is there (extra "fast"; the same bits, tests/gcs_swarm/guidance/
# test_shaping_kernels.py); None selects the numpy reference (tests and benchmarks switch it to compare).
compiled_shaping: Callable[..., np.ndarray] | None
try:
    from gcs_swarm.guidance.shaping_kernels import shape_reference_acceleration

    compiled_shaping = shape_reference_acceleration
except ImportError:  # pragma: no cover - numba is optional
    compiled_shaping = None


def default_d_g(field: FieldParams, v_max: float, k_v: float) -> float:
    """Attraction segment boundary: the configured d_g, else v_max / K_v (spec 3.1 [ambig], spec 8 step 3)."""
    return field.d_g if field.d_g is not None else v_max / k_v


def saturate_split(vec: np.ndarray, xy_max: np.ndarray | float, z_max: float) -> np.ndarray:
    """Scale the horizontal part of vec (N, 3) to norm <= xy_max (N,) or scalar; clip z to +-z_max."""
    out = np.array(vec, dtype=float)
    xy = np.hypot(out[:, 0], out[:, 1])
    over = xy > xy_max
    if over.any():
        cap = xy_max[over] if isinstance(xy_max, np.ndarray) and xy_max.ndim else xy_max
        out[over, :2] *= (cap / xy[over])[:, None]
    out[:, 2] = np.clip(out[:, 2], -z_max, z_max)
    return out


def paper_literal_reference(
    slots: np.ndarray, slot_vel: np.ndarray, f_rep: np.ndarray, k_att: float, l0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spec 8 option `paper_literal` (Eq 53 as printed): x_d = s_i + K_f sum F_rep with K_f = 1/k_att and
    |K_f sum F_rep| <= l0, xd_dot = v_i^s, xd_ddot = 0. Returns (x_d, xd_dot, xd_ddot), each (N, 3)."""
    shift = f_rep / k_att
    size = row_norms(shift)
    over = size > l0
    shift[over] *= (l0 / size[over])[:, None]
    return slots + shift, np.array(slot_vel, dtype=float), np.zeros_like(slots)


class ReferenceGenerator:
    """Per-vehicle reference state (p_r, v_r, a_r) driven by the field (spec 8 steps 3-6)."""

    def __init__(
        self, params: ReferenceParams, limits: Limits, k_att: float, g: float = G, z_min: float | None = None
    ) -> None:
        """`z_min` m: altitude floor of the references ([add] safety.min_altitude), None for none."""
        self.params = params
        self.z_min = z_min
        self.limits = limits
        self.gain = params.k_v / k_att  # (m/s) per field unit
        # step 4; [add] the shaped reference keeps to accel_xy_max, the rest of the tilt is for drag and wind
        tilt_accel = g * math.tan(limits.tilt_max)
        self.a_xy_evasive = min(limits.a_xy, tilt_accel)
        self.a_xy_max = min(self.a_xy_evasive, params.accel_xy_max if params.jerk_max > 0 else tilt_accel)
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

    def leash(self, pos: np.ndarray, rows: np.ndarray) -> None:
        """Step 6: put references farther than `leash` m from their vehicle (N, 3) back on that sphere
        (only the (N,) bool-selected rows)."""
        gap = self.p - pos
        dist = row_norms(gap)
        over = rows & (dist > self.params.leash)
        self.p[over] = pos[over] + gap[over] * (self.params.leash / dist[over])[:, None]

    def _acceleration(
        self, v_cmd: np.ndarray, a_ff: np.ndarray, dt: float, evasive: np.ndarray
    ) -> np.ndarray:
        """Step 4, a_r (N, 3) toward v_cmd (N, 3). With `jerk_max` > 0 [add]: ArduPilot's jerk-limited
        shaping (gcs_swarm.guidance.shaping), horizontal and vertical, with the feed-forward a_ff (N, 3);
        with 0: the spec's first-order a_r = sat((v_cmd - v_r) / tau_v), which steps with the demand.
        Rows of `evasive` (N,) bool (an emergency separation is on, spec 4 Eq 19) are shaped with the whole
        tilt's acceleration and `evasive_jerk_max`: comfort never slows a vehicle getting out of the way."""
        params = self.params
        if params.jerk_max <= 0.0:
            return saturate_split((v_cmd - self.v) / params.tau_v, self.a_xy_max, self.limits.a_z)
        accel_xy = np.where(evasive, float(self.a_xy_evasive), float(self.a_xy_max))
        jerk_xy = np.where(
            evasive, float(max(params.evasive_jerk_max, params.jerk_max)), float(params.jerk_max)
        )
        jerk_z = np.where(
            evasive, float(max(params.evasive_jerk_max, params.jerk_max_z)), float(params.jerk_max_z)
        )
        if compiled_shaping is not None:
            return compiled_shaping(
                v_cmd, a_ff, self.v, self.a, accel_xy, jerk_xy, float(self.limits.a_z), jerk_z, dt
            )
        a = np.empty_like(v_cmd)
        a[:, :2] = shape_vel_accel_xy(
            v_cmd[:, :2], a_ff[:, :2], self.v[:, :2], self.a[:, :2], accel_xy, jerk_xy, dt
        )
        a[:, 2] = shape_vel_accel(
            v_cmd[:, 2], a_ff[:, 2], self.v[:, 2], self.a[:, 2], self.limits.a_z, jerk_z, dt
        )
        return a

    def _stopping_curve(self, v_rel: np.ndarray, to_target: np.ndarray, v_now_rel: np.ndarray) -> np.ndarray:
        """[add] Speed scheduling toward the attraction target: the part of the demand v_rel (N, 3) m/s
        (relative to the target's own motion) along to_target (N, 3) m is capped at
        sqrt_controller(d, K_v, stop_accel), K_v d close in and the braking curve sqrt(2 a d) farther out, so
        the reference can stop at the target. d is the distance less what the reference covers, at its
        present approach speed (from v_now_rel (N, 3)), while its deceleration ramps up to stop_accel at
        jerk_max. Near the target this is spec 8 step 3 (v = K_v (T - p)); the field itself is unchanged."""
        dist = row_norms(to_target)
        unit = np.divide(to_target, dist[:, None], out=np.zeros_like(to_target), where=dist[:, None] > 0.0)
        if self.params.jerk_max > 0.0:
            approach = np.maximum(np.einsum("nd,nd->n", v_now_rel, unit), 0.0)
            dist = np.maximum(dist - approach * self.params.stop_accel / self.params.jerk_max, 0.0)
        cap = sqrt_controller(dist, self.params.k_v, self.params.stop_accel, 0.0)
        along = np.einsum("nd,nd->n", v_rel, unit)
        excess = np.maximum(along - cap, 0.0)
        return v_rel - unit * excess[:, None]

    def lookahead_points(self) -> np.ndarray:
        """(N, 3) m: where each reference would stop if it braked now at `brake_accel`, p_r + v_r |v_r| /
        (2 a_b) [add]: the obstacle field is felt there, so a reference meets the strong part of a repulsion
        no faster than it can brake. `brake_accel` 0: the reference point itself (spec 8 step 2)."""
        a_b = self.params.brake_accel
        if a_b <= 0.0:
            return self.p
        speed = row_norms(self.v)
        return self.p + self.v * (speed / (2.0 * a_b))[:, None]

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
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Steps 3-5 for the (N,) bool-selected vehicles: from the field force (N, 3) at the current reference
        points, the velocity feed-forward (N, 3) and horizontal speed caps (N,), return the desired state
        (p_r, v_r, a_r) of this instant (each (N, 3)) and advance the state by dt s for the next tick.
        `a_ff` (N, 3) m/s^2: acceleration feed-forward of the shaped step 4 (a follower's slot acceleration);
        `targets` (N, 3) m: the attraction targets, for the stopping curve (`stop_accel`); `evasive` (N,)
        bool: vehicles in an emergency separation, shaped with the full limits.

        [add] The SMC gets the reference of the current instant, not the one integrated to t + dt (spec 8
        step 7 after step 5): otherwise a moving slot leaves a steady v dt offset (0.2 m at 10 m/s, 50 Hz).
        """
        a_ff = np.zeros_like(force) if a_ff is None else a_ff
        v_cmd = saturate_split(v_ff + self.gain * force, v_xy_max, self.limits.v_z)  # step 3
        if targets is not None and self.params.stop_accel > 0.0:
            v_cmd = v_ff + self._stopping_curve(v_cmd - v_ff, targets - self.p, self.v - v_ff)
        if self.z_min is not None:
            # [add] altitude floor: the allowed descent rate shrinks to zero at z_min (climb below it), so no
            # field (an obstacle pushing down, say) can drive a reference into the ground.
            # With the stopping curve on, the allowed descent follows the braking curve to the floor.
            height = np.maximum(self.p[:, 2] - self.z_min, 0.0)
            if self.params.stop_accel > 0.0:
                floor_rate = -sqrt_controller(height, self.params.k_v, self.params.stop_accel, 0.0)
            else:
                floor_rate = -self.params.k_v * height
            if self.params.jerk_max > 0.0:
                # the shaped vertical velocity follows a demand change exponentially at rate jerk_max_z / a_z
                # (1/s, shape_vel_accel's linear region): from a descent w it needs about w / rate to stop.
                # Half that rate leaves room for the jerk ramp and the vehicle's own lag (a 4-obstacle world
                # in 4.8 m/s wind drove a reference to -4 m and a vehicle into the ground at 6.8 m/s)
                rate = 0.5 * self.params.jerk_max_z / self.limits.a_z
                floor_rate = np.maximum(floor_rate, -rate * height)
            v_cmd[:, 2] = np.maximum(v_cmd[:, 2], np.minimum(floor_rate, self.limits.v_z))
        evasive = np.zeros(len(force), dtype=bool) if evasive is None else evasive
        a = self._acceleration(v_cmd, a_ff, dt, evasive)  # step 4
        a = np.where(rows[:, None], a, self.a)
        now = (self.p.copy(), self.v.copy(), a)
        v = self.v + a * dt  # step 5
        p = self.p + v * dt
        if self.z_min is not None:  # [add] whatever the shaping did, a reference never sinks below the floor
            low = p[:, 2] < self.z_min
            p[low, 2] = self.z_min
            v[low, 2] = np.maximum(v[low, 2], 0.0)
            a[low, 2] = np.maximum(a[low, 2], 0.0)
        sel = rows[:, None]
        self.p = np.where(sel, p, self.p)
        self.v = np.where(sel, v, self.v)
        self.a = a
        return now
