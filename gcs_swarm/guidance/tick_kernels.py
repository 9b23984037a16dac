"""Compiled twins of the tick's per-vehicle stages: formation targets (gcs_swarm.guidance.formation,
obstacles.push_out_horizontally), the reference generator's leash, braking point and steps 3-5 (reference),
the SMC's Eq 49 with its estimates (smc), the inversion (inversion) and the tilt slew (attitude_slew).

The same rules as field_kernels: the numpy code's IEEE operations in its order, numpy's reduction orders and
NaN/signed-zero rules, no transcendental function (cos, sin, arctan2, arcsin, powers: numpy's SIMD versions
differ from libm in the last bit). Where one is needed a stage ends and the caller evaluates it with numpy on
the array the numpy code would: the SMC's |s|^xi between `smc_sliding` and `smc_output`, arctan2 and arcsin
between `inversion_terms` and `commands`. Shapes (N, 3) ENU / (N,), SI units, rad.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gcs_swarm.guidance.field_kernels import _minimum, _norm3
from gcs_swarm.guidance.shaping_kernels import (
    _clip_to_scalars,
    _maximum,
    _shape_vel_accel,
    _shape_vel_accel_xy,
    _sign,
    _sqrt_controller,
)

_kernel = njit(cache=True, error_model="numpy")
_scalar = njit(cache=True, error_model="numpy", inline="always")


@_kernel
def formation_targets(
    heard: np.ndarray, cos_psi: np.ndarray, sin_psi: np.ndarray, offsets: np.ndarray, spacing: float,
    centres: np.ndarray, radii: np.ndarray, slot_margin: float, lead: int, goal: np.ndarray,
    follower_targets: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Spec 8 step 1 as FleetController.tick computes it: from the leader state each vehicle heard (N, 11)
    (p, v, psi, rate, a) and cos, sin of its psi (N,), the slots (N, 3) (pushed out of the obstacles when
    slot_margin > 0; the leader's row its goal (3,)), their velocity and acceleration feed-forward (N, 3)
    (the leader's rows zero) and the adaptive factor's destinations (N, 3): goal + the world offset, or
    `follower_targets` (N, 3) when it has rows."""
    n = heard.shape[0]
    targets = np.empty((n, 3))
    v_ff = np.empty((n, 3))
    a_ff = np.empty((n, 3))
    dest = np.empty((n, 3))
    for i in range(n):
        c, s = cos_psi[i], sin_psi[i]
        o0, o1, o2 = offsets[i, 0] * spacing, offsets[i, 1] * spacing, offsets[i, 2] * spacing
        w0, w1, w2 = o0 * c - o1 * s, o0 * s + o1 * c, o2  # formation.rotate_z
        rate = heard[i, 7]
        targets[i, 0], targets[i, 1], targets[i, 2] = heard[i, 0] + w0, heard[i, 1] + w1, heard[i, 2] + w2
        v_ff[i, 0] = heard[i, 3] + -rate * w1  # formation.turn_velocity
        v_ff[i, 1] = heard[i, 4] + rate * w0
        v_ff[i, 2] = heard[i, 5] + 0.0
        rate_sq = rate * rate
        a_ff[i, 0] = heard[i, 8] - rate_sq * w0
        a_ff[i, 1] = heard[i, 9] - rate_sq * w1
        a_ff[i, 2] = heard[i, 10] - rate_sq * 0.0
        if follower_targets.shape[0] == 0:
            dest[i, 0], dest[i, 1], dest[i, 2] = goal[0] + w0, goal[1] + w1, goal[2] + w2
        else:
            dest[i, 0], dest[i, 1], dest[i, 2] = (
                follower_targets[i, 0],
                follower_targets[i, 1],
                follower_targets[i, 2],
            )
        if slot_margin > 0.0:  # obstacles.push_out_horizontally, one obstacle after the other
            for k in range(radii.shape[0]):
                dz = targets[i, 2] - centres[k, 2]
                grown = radii[k] + slot_margin
                reach_sq = grown * grown - dz * dz
                h0, h1 = targets[i, 0] - centres[k, 0], targets[i, 1] - centres[k, 1]
                dist = math.hypot(h0, h1)
                if reach_sq > 0.0 and dist * dist < reach_sq:
                    ring = math.sqrt(_maximum(reach_sq, 0.0))
                    if dist > 0.0:
                        d0, d1 = h0 / dist, h1 / dist
                    else:
                        d0, d1 = 1.0, 0.0
                    targets[i, 0], targets[i, 1] = centres[k, 0] + d0 * ring, centres[k, 1] + d1 * ring
    for d in range(3):
        targets[lead, d] = goal[d]
        v_ff[lead, d] = 0.0
        a_ff[lead, d] = 0.0
        dest[lead, d] = goal[d]
    return targets, v_ff, a_ff, dest


@_kernel
def leash_and_lookahead(
    p: np.ndarray, v: np.ndarray, pos: np.ndarray, rows: np.ndarray, leash: float, brake_accel: float
) -> np.ndarray:
    """ReferenceGenerator.leash on p (N, 3) in place for the (N,) bool rows, then lookahead_points: the
    braking points (N, 3), p itself when brake_accel <= 0."""
    n = p.shape[0]
    for i in range(n):
        g0, g1, g2 = p[i, 0] - pos[i, 0], p[i, 1] - pos[i, 1], p[i, 2] - pos[i, 2]
        dist = _norm3(g0, g1, g2)
        if rows[i] and dist > leash:
            scale = leash / dist
            p[i, 0], p[i, 1], p[i, 2] = pos[i, 0] + g0 * scale, pos[i, 1] + g1 * scale, pos[i, 2] + g2 * scale
    if brake_accel <= 0.0:
        return p
    ahead = np.empty((n, 3))
    for i in range(n):
        scale = _norm3(v[i, 0], v[i, 1], v[i, 2]) / (2.0 * brake_accel)
        for d in range(3):
            ahead[i, d] = p[i, d] + v[i, d] * scale
    return ahead


@_kernel
def reference_step(
    p: np.ndarray, v: np.ndarray, a_prev: np.ndarray, force: np.ndarray, v_ff: np.ndarray, a_ff: np.ndarray,
    targets: np.ndarray, v_xy_max: np.ndarray, rows: np.ndarray, evasive: np.ndarray, dt: float,
    config: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """ReferenceGenerator.step (steps 3-5) with a_ff and targets given: returns the desired acceleration
    a_r (N, 3) of this instant and the next reference state p, v (N, 3) (the caller keeps the present p, v as
    the desired position and velocity, and a_r as the generator's new a). `config` (REFERENCE_CONFIG order):
    gain, v_z, stop_accel, k_v, jerk_max, has_z_min, z_min, jerk_max_z, a_z, tau_v, a_xy_max, a_xy_evasive,
    jerk_xy_evasive, jerk_z_evasive."""
    gain, v_z, stop_accel, k_v, jerk_max = config[0], config[1], config[2], config[3], config[4]
    has_z_min, z_min, jerk_max_z, a_z, tau_v = config[5] > 0.0, config[6], config[7], config[8], config[9]
    a_xy_max, a_xy_evasive, jerk_xy_evasive, jerk_z_evasive = config[10], config[11], config[12], config[13]
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
        xy = math.hypot(c0, c1)  # reference.saturate_split, step 3
        if xy > v_xy_max[i]:
            scale = v_xy_max[i] / xy
            c0, c1 = c0 * scale, c1 * scale
        c2 = _clip_to_scalars(c2, -v_z, v_z)
        if stop_accel > 0.0:  # ReferenceGenerator._stopping_curve
            t0, t1, t2 = targets[i, 0] - p[i, 0], targets[i, 1] - p[i, 1], targets[i, 2] - p[i, 2]
            dist = _norm3(t0, t1, t2)
            if dist > 0.0:
                u0, u1, u2 = t0 / dist, t1 / dist, t2 / dist
            else:
                u0, u1, u2 = 0.0, 0.0, 0.0
            if jerk_max > 0.0:
                n0, n1, n2 = v[i, 0] - v_ff[i, 0], v[i, 1] - v_ff[i, 1], v[i, 2] - v_ff[i, 2]
                approach = _maximum((n0 * u0 + n2 * u2) + n1 * u1 + 0.0, 0.0)
                dist = _maximum(dist - approach * stop_accel / jerk_max, 0.0)
            cap = _sqrt_controller(dist, k_v, stop_accel, 0.0)
            r0, r1, r2 = c0 - v_ff[i, 0], c1 - v_ff[i, 1], c2 - v_ff[i, 2]
            excess = _maximum((r0 * u0 + r2 * u2) + r1 * u1 + 0.0 - cap, 0.0)
            c0 = v_ff[i, 0] + (r0 - u0 * excess)
            c1 = v_ff[i, 1] + (r1 - u1 * excess)
            c2 = v_ff[i, 2] + (r2 - u2 * excess)
        if has_z_min:  # altitude floor
            height = _maximum(p[i, 2] - z_min, 0.0)
            if stop_accel > 0.0:
                floor_rate = -_sqrt_controller(height, k_v, stop_accel, 0.0)
            else:
                floor_rate = -k_v * height
            if jerk_max > 0.0:
                rate = 0.5 * jerk_max_z / a_z
                floor_rate = _maximum(floor_rate, -rate * height)
            c2 = _maximum(c2, _minimum(floor_rate, v_z))
        if not rows[i]:
            a0, a1, a2 = a_prev[i, 0], a_prev[i, 1], a_prev[i, 2]
        elif jerk_max <= 0.0:  # the spec's first-order step 4 (saturate_split with scalar limits)
            a0, a1, a2 = (c0 - v[i, 0]) / tau_v, (c1 - v[i, 1]) / tau_v, (c2 - v[i, 2]) / tau_v
            xy = math.hypot(a0, a1)
            if xy > a_xy_max:
                scale = a_xy_max / xy
                a0, a1 = a0 * scale, a1 * scale
            a2 = _clip_to_scalars(a2, -a_z, a_z)
        else:  # jerk-limited step 4 (shaping_kernels)
            accel_xy = a_xy_evasive if evasive[i] else a_xy_max
            jerk_xy = jerk_xy_evasive if evasive[i] else jerk_max
            jerk_z = jerk_z_evasive if evasive[i] else jerk_max_z
            a0, a1 = _shape_vel_accel_xy(
                c0, c1, a_ff[i, 0], a_ff[i, 1], v[i, 0], v[i, 1], a_prev[i, 0], a_prev[i, 1], accel_xy,
                jerk_xy, dt,
            )  # fmt: skip
            a2 = _shape_vel_accel(c2, a_ff[i, 2], v[i, 2], a_prev[i, 2], a_z, jerk_z, dt)
        w0, w1, w2 = v[i, 0] + a0 * dt, v[i, 1] + a1 * dt, v[i, 2] + a2 * dt  # step 5
        q0, q1, q2 = p[i, 0] + w0 * dt, p[i, 1] + w1 * dt, p[i, 2] + w2 * dt
        if has_z_min and q2 < z_min:
            q2 = z_min
            w2 = _maximum(w2, 0.0)
            a2 = _maximum(a2, 0.0)
        accel[i, 0], accel[i, 1], accel[i, 2] = a0, a1, a2
        if rows[i]:
            p_next[i, 0], p_next[i, 1], p_next[i, 2] = q0, q1, q2
            v_next[i, 0], v_next[i, 1], v_next[i, 2] = w0, w1, w2
        else:
            p_next[i, 0], p_next[i, 1], p_next[i, 2] = p[i, 0], p[i, 1], p[i, 2]
            v_next[i, 0], v_next[i, 1], v_next[i, 2] = v[i, 0], v[i, 1], v[i, 2]
    return accel, p_next, v_next


@_scalar
def _limited_thrust(
    u0: float, u1: float, u2: float, uz_floor: float, tan_tilt: float
) -> tuple[float, float, float]:
    """inversion.limit_thrust_vector of one U: U_z >= uz_floor, U_xy shortened to U_z tan(tilt_max)."""
    z = _maximum(u2, uz_floor)
    u_xy = math.hypot(u0, u1)
    cap = z * tan_tilt
    if u_xy > cap:
        scale = cap / u_xy
        return u0 * scale, u1 * scale, z
    return u0, u1, z


@_kernel
def smc_sliding(
    x_d: np.ndarray, xd_dot: np.ndarray, x: np.ndarray, v: np.ndarray, c1: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """smc.sliding_variable: e1 = x_d - x, s = c1 e1 + xd_dot - v and |s|, each (N, 3); c1 (3,) per axis."""
    n = x.shape[0]
    e1 = np.empty((n, 3))
    s = np.empty((n, 3))
    abs_s = np.empty((n, 3))
    for i in range(n):
        for d in range(3):
            e1[i, d] = x_d[i, d] - x[i, d]
            s[i, d] = c1[d] * e1[i, d] + xd_dot[i, d] - v[i, d]
            abs_s[i, d] = abs(s[i, d])
    return e1, s, abs_s


@_kernel
def smc_output(
    e1: np.ndarray, s: np.ndarray, power1: np.ndarray, power2: np.ndarray, xd_ddot: np.ndarray, v: np.ndarray,
    gains: np.ndarray, c_hat: np.ndarray, d_hat: np.ndarray, dt: float, config: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """SMCController.__call__ after the sliding variable: U (N, 3) (Eq 49 with the drag adaptation and the
    disturbance estimate) and the next c_hat (N,) and d_hat (N, 3). power1, power2 = |s|^xi1, |s|^xi2 (N, 3)
    from numpy; `gains` (5, 3) rows c1, k1, k2, k3, k_d per axis; `config` (SMC_CONFIG order): boundary layer
    Phi, g, drag_adaptation, drag_max, has_limits, tan(tilt_max), uz_min_g g, thrust_max_g g,
    xy.disturbance_max, z.disturbance_max, estimate on (any k_d > 0)."""
    phi, g, gamma, drag_max, has_limits = config[0], config[1], config[2], config[3], config[4] > 0.0
    tan_tilt, uz_floor, thrust_cap, d_max_xy, d_max_z = config[5], config[6], config[7], config[8], config[9]
    estimate = config[10] > 0.0
    n = s.shape[0]
    u = np.empty((n, 3))
    c_next = c_hat.copy()
    d_next = d_hat.copy()
    for i in range(n):
        for d in range(3):
            if phi <= 0.0:
                switch = _sign(s[i, d])
            else:
                switch = _clip_to_scalars(s[i, d] / phi, -1.0, 1.0)
            reaching = -gains[1, d] * s[i, d] - gains[2, d] * (power1[i, d] * switch)
            reaching = reaching - gains[3, d] * (power2[i, d] * switch)
            c1 = gains[0, d]
            u[i, d] = xd_ddot[i, d] - c1 * c1 * e1[i, d] + c1 * s[i, d] - reaching
        u[i, 2] += g
        if gamma > 0.0:  # SMCController._drag_compensated
            vx = v[i, 0] if np.isfinite(v[i, 0]) else 0.0
            vy = v[i, 1] if np.isfinite(v[i, 1]) else 0.0
            u[i, 0] += c_hat[i] * vx
            u[i, 1] += c_hat[i] * vy
            sx = s[i, 0] if np.isfinite(s[i, 0]) else 0.0
            sy = s[i, 1] if np.isfinite(s[i, 1]) else 0.0
            step = gamma * (0.0 + sx * vx + sy * vy) * dt
            if has_limits and math.hypot(u[i, 0], u[i, 1]) > _maximum(u[i, 2], 0.0) * tan_tilt and step > 0.0:
                step = 0.0
            c_next[i] = _clip_to_scalars(c_hat[i] + step, 0.0, drag_max)
        if not estimate:
            continue
        for d in range(3):
            u[i, d] = u[i, d] + d_hat[i, d]
        st0 = gains[4, 0] * s[i, 0] * dt if np.isfinite(s[i, 0]) else 0.0
        st1 = gains[4, 1] * s[i, 1] * dt if np.isfinite(s[i, 1]) else 0.0
        st2 = gains[4, 2] * s[i, 2] * dt if np.isfinite(s[i, 2]) else 0.0
        if has_limits:  # smc.winding
            u0, u1, u2 = u[i, 0], u[i, 1], u[i, 2]
            tilted = math.hypot(u0, u1) > _maximum(u2, uz_floor) * tan_tilt
            l0, l1, l2 = _limited_thrust(u0, u1, u2, uz_floor, tan_tilt)
            capped = _norm3(l0, l1, l2) > thrust_cap
            if (tilted or capped) and st0 * u0 > 0:
                st0 = 0.0
            if (tilted or capped) and st1 * u1 > 0:
                st1 = 0.0
            if (u2 < uz_floor and st2 < 0) or (capped and st2 > 0):
                st2 = 0.0
        x0, x1, x2 = d_hat[i, 0] + st0, d_hat[i, 1] + st1, d_hat[i, 2] + st2  # smc.clamp_estimate
        norm = math.hypot(x0, x1)
        if norm > d_max_xy:
            scale = d_max_xy / norm
            x0, x1 = x0 * scale, x1 * scale
        d_next[i, 0], d_next[i, 1], d_next[i, 2] = x0, x1, _clip_to_scalars(x2, -d_max_z, d_max_z)
    return u, c_next, d_next


@_kernel
def inversion_terms(
    u: np.ndarray, cos_yaw: np.ndarray, sin_yaw: np.ndarray, uz_floor: float, tan_tilt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """inversion.invert up to its inverse trigonometry: the limited U (N, 3), |U| (N,), the arctan2 numerator
    U_x cos psi + U_y sin psi (N,) (its denominator is U_z) and the clipped arcsin argument (N,)."""
    n = u.shape[0]
    ul = np.empty((n, 3))
    norm = np.empty(n)
    pitch_num = np.empty(n)
    roll_arg = np.empty(n)
    for i in range(n):
        l0, l1, l2 = _limited_thrust(u[i, 0], u[i, 1], u[i, 2], uz_floor, tan_tilt)
        ul[i, 0], ul[i, 1], ul[i, 2] = l0, l1, l2
        norm[i] = _norm3(l0, l1, l2)
        pitch_num[i] = l0 * cos_yaw[i] + l1 * sin_yaw[i]
        roll_arg[i] = _clip_to_scalars((l0 * sin_yaw[i] - l1 * cos_yaw[i]) / norm[i], -1.0, 1.0)
    return ul, norm, pitch_num, roll_arg


@_kernel
def commands(
    ul: np.ndarray, norm: np.ndarray, roll_d: np.ndarray, pitch_d: np.ndarray, tilt_cos: np.ndarray,
    cos_tilt_max: float, thrust_cap: float, slew_roll: np.ndarray, slew_pitch: np.ndarray, rate_max: float,
    dt: float, active: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The end of inversion.invert and TiltSlew.__call__: thrust U1/m (N,) (Eq 36 from tilt_cos = cos phi
    cos theta of the measured attitude (N,), or |U| when tilt_cos is empty; capped at thrust_cap), the slewed
    roll, pitch (N,), and the slew's next state (N,) each. Returns (roll, pitch, thrust, u (N, 3)) with NaN in
    the rows not `active`, then the slew state roll, pitch."""
    n = ul.shape[0]
    roll = np.empty(n)
    pitch = np.empty(n)
    thrust = np.empty(n)
    u = np.empty((n, 3))
    next_roll = np.empty(n)
    next_pitch = np.empty(n)
    limit = rate_max * dt
    for i in range(n):
        if tilt_cos.shape[0]:
            t = ul[i, 2] / _maximum(tilt_cos[i], cos_tilt_max)
        else:
            t = norm[i]
        t = _minimum(t, thrust_cap)
        r, q = slew_roll[i], slew_pitch[i]
        if not (np.isfinite(r) and np.isfinite(q)):
            r, q = roll_d[i], pitch_d[i]
        d_roll, d_pitch = roll_d[i] - r, pitch_d[i] - q
        if rate_max > 0.0:
            step = math.hypot(d_roll, d_pitch)
            scale = limit / step if step > limit else 1.0
            d_roll, d_pitch = d_roll * scale, d_pitch * scale
        if active[i]:
            r, q = r + d_roll, q + d_pitch
        next_roll[i], next_pitch[i] = r, q
        if active[i]:
            roll[i], pitch[i], thrust[i] = r, q, t
            u[i, 0], u[i, 1], u[i, 2] = ul[i, 0], ul[i, 1], ul[i, 2]
        else:
            roll[i] = pitch[i] = thrust[i] = np.nan
            u[i, 0] = u[i, 1] = u[i, 2] = np.nan
    return roll, pitch, thrust, u, next_roll, next_pitch
