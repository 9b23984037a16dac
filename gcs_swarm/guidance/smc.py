"""Sliding-mode position control per axis (spec 7, paper Eqs 29-50) with the fast power reaching law.

Inputs are (N, 3) world ENU arrays: reference position/velocity/acceleration and measured position/velocity.
The output U = (U_x, U_y, U_z) is the commanded thrust acceleration in m/s^2 (gravity added in z), which
`inversion` turns into attitude and thrust. Two compiled kernels (swarm_common.jit), `smc_sliding` and
`smc_output`, with the powers |s|^xi taken by numpy between them; SMCController holds the state.

[add] Disturbance estimate (integral sliding-mode action), per channel, off by default (`disturbance_gain`
k_d = 0 leaves Eq 49 bit for bit): U = Eq 49 + d_hat with d_hat_dot = k_d s. For a plant v_dot = U + d with an
unmodelled d (the simulator's drag, -0.28 m/s^2 per m/s) the sliding dynamics become
s_dot = reaching_law(s) - (d + d_hat): without the estimate s settles where the reaching law balances d (with
the spec 7.3 xy gains s = 1.55 m/s, e1 = s / c1 = 1.9 m behind at 10 m/s); with it a steady state needs s = 0,
so d_hat = -d and e1 -> 0 along e1_dot = -c1 e1. Near s = 0 and for constant d the linear part is
s_ddot + k1 s_dot + k_d s = 0: stable for any k_d > 0, critically damped at k_d = k1^2 / 4 (0.56 1/s for xy).
Anti-windup: |d_hat| <= disturbance_max (xy: the horizontal norm), and while the spec 5 limits cut U a channel
does not integrate in the direction that pushes U further into the limit (conditional integration).

[add] Drag adaptation, horizontal, off by default (`drag_adaptation` gamma = 0 leaves Eq 49 as it is): the
disturbance a formation meets at cruise is mostly drag, d = -c v with an unknown c per vehicle, so instead of
integrating d itself (which then has to unwind at every stop and overshoots the goal) the controller adds
c_hat v_xy to U and adapts c_hat_dot = gamma (s_x v_x + s_y v_y). With V = s^2 / 2 + (c_hat - c)^2 / (2 gamma)
the sliding dynamics s_dot = reaching_law(s) - (c_hat - c) v give V_dot = s reaching_law(s) <= 0 (the
standard adaptive-control argument), so s -> 0 and the trail behind a moving slot vanishes; at rest v = 0 and
the term does nothing. c_hat is kept in [0, drag_max] and does not adapt while the spec 5 limits cut U.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from gcs_swarm.guidance.inversion import limited_thrust
from gcs_swarm.guidance.params import G, Limits, SMCAxisGains, SMCParams
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip_to_scalars, maximum, norm3, sign


def _per_axis(params: SMCParams, name: str) -> np.ndarray:
    """(3,) the gain `name` of the x, y, z channels."""
    gains: tuple[SMCAxisGains, ...] = (params.xy, params.xy, params.z)
    return np.array([getattr(a, name) for a in gains])


class SMCSettings(NamedTuple):
    """The scalar settings of `smc_output`, its last parameters in this order (SMCController builds them
    from SMCParams and Limits)."""

    boundary_layer: float  # m/s, Phi; 0: sgn
    g: float  # m/s^2
    drag_adaptation: float  # 1/m^2, gamma; 0: off
    drag_max: float  # 1/s, c_hat's bound
    has_limits: bool  # the spec 5 limits hold the estimates
    tan_tilt: float  # tan(tilt_max)
    uz_floor: float  # m/s^2, uz_min_g g
    thrust_cap: float  # m/s^2, thrust_max_g g
    d_max_xy: float  # m/s^2, |d_hat_xy| bound
    d_max_z: float  # m/s^2, |d_hat_z| bound
    estimate: bool  # any k_d > 0: the disturbance estimate is on


@kernel
def smc_sliding(
    x_d: np.ndarray, xd_dot: np.ndarray, x: np.ndarray, v: np.ndarray, c1: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e1 = x_d - x, s = e2 = c1 e1 + xd_dot - v (spec 7.1) and |s|, each (N, 3); c1 (3,) per axis."""
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


@kernel
def smc_output(
    e1: np.ndarray, s: np.ndarray, power1: np.ndarray, power2: np.ndarray, xd_ddot: np.ndarray, v: np.ndarray,
    gains: np.ndarray, c_hat: np.ndarray, d_hat: np.ndarray, dt: float, boundary_layer: float, g: float,
    drag_adaptation: float, drag_max: float, has_limits: bool, tan_tilt: float, uz_floor: float,
    thrust_cap: float, d_max_xy: float, d_max_z: float, estimate: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """U (N, 3) m/s^2 from e1, s (N, 3) and power1, power2 = |s|^xi1, |s|^xi2 (N, 3): Eq 49
    U = xd_ddot - c1^2 e1 + c1 s - reaching law (+g in z), the reaching law
    -k1 s - k2 |s|^xi1 sw(s) - k3 |s|^xi2 sw(s) with sw = sgn, or sat(s / Phi) with a boundary layer Phi > 0
    (spec 7.1, 7.4); then the drag adaptation (U_xy += c_hat v_xy) and the disturbance estimate
    (U += d_hat) with their next values c_hat (N,), d_hat (N, 3) (module docstring; rows without a finite
    state do not integrate). `gains` (5, 3): rows c1, k1, k2, k3, k_d per axis; the settings are SMCSettings'
    fields (called with *settings)."""
    phi, gamma = boundary_layer, drag_adaptation
    n = s.shape[0]
    u = np.empty((n, 3))
    c_next = c_hat.copy()
    d_next = d_hat.copy()
    for i in range(n):
        for d in range(3):
            if phi <= 0.0:
                switch = sign(s[i, d])
            else:
                switch = clip_to_scalars(s[i, d] / phi, -1.0, 1.0)
            reaching = -gains[1, d] * s[i, d] - gains[2, d] * (power1[i, d] * switch)
            reaching = reaching - gains[3, d] * (power2[i, d] * switch)
            c1 = gains[0, d]
            u[i, d] = xd_ddot[i, d] - c1 * c1 * e1[i, d] + c1 * s[i, d] - reaching
        u[i, 2] += g
        if gamma > 0.0:  # [add] drag adaptation, held while the tilt limit cuts U
            vx = v[i, 0] if np.isfinite(v[i, 0]) else 0.0
            vy = v[i, 1] if np.isfinite(v[i, 1]) else 0.0
            u[i, 0] += c_hat[i] * vx
            u[i, 1] += c_hat[i] * vy
            sx = s[i, 0] if np.isfinite(s[i, 0]) else 0.0
            sy = s[i, 1] if np.isfinite(s[i, 1]) else 0.0
            step = gamma * (0.0 + sx * vx + sy * vy) * dt
            if has_limits and np.hypot(u[i, 0], u[i, 1]) > maximum(u[i, 2], 0.0) * tan_tilt and step > 0.0:
                step = 0.0
            c_next[i] = clip_to_scalars(c_hat[i] + step, 0.0, drag_max)
        if not estimate:
            continue
        for d in range(3):
            u[i, d] = u[i, d] + d_hat[i, d]
        st0 = gains[4, 0] * s[i, 0] * dt if np.isfinite(s[i, 0]) else 0.0
        st1 = gains[4, 1] * s[i, 1] * dt if np.isfinite(s[i, 1]) else 0.0
        st2 = gains[4, 2] * s[i, 2] * dt if np.isfinite(s[i, 2]) else 0.0
        if has_limits:  # [add] conditional integration: no step further into a spec 5 limit
            u0, u1, u2 = u[i, 0], u[i, 1], u[i, 2]
            tilted = np.hypot(u0, u1) > maximum(u2, uz_floor) * tan_tilt
            l0, l1, l2 = limited_thrust(u0, u1, u2, uz_floor, tan_tilt)
            capped = norm3(l0, l1, l2) > thrust_cap
            if (tilted or capped) and st0 * u0 > 0:
                st0 = 0.0
            if (tilted or capped) and st1 * u1 > 0:
                st1 = 0.0
            if (u2 < uz_floor and st2 < 0) or (capped and st2 > 0):
                st2 = 0.0
        x0, x1, x2 = d_hat[i, 0] + st0, d_hat[i, 1] + st1, d_hat[i, 2] + st2  # within disturbance_max
        norm = np.hypot(x0, x1)
        if norm > d_max_xy:
            scale = d_max_xy / norm
            x0, x1 = x0 * scale, x1 * scale
        d_next[i, 0], d_next[i, 1], d_next[i, 2] = x0, x1, clip_to_scalars(x2, -d_max_z, d_max_z)
    return u, c_next, d_next


class SMCController:
    """Eq 49 as a `gcs_swarm.guidance.controller.PositionController`, plus the optional disturbance estimate
    d_hat and drag adaptation c_hat [add] (module docstring)."""

    def __init__(self, params: SMCParams, g: float = G, limits: Limits | None = None) -> None:
        """`limits`: the spec 5 limits the inversion applies, so the estimates hold while they cut U; None:
        only the disturbance_max clamp."""
        self.params = params
        self.g = g
        self.limits = limits
        names = ("c1", "k1", "k2", "k3", "disturbance_gain")
        self.gains = np.array([_per_axis(params, name) for name in names])  # (5, 3), smc_output's rows
        self.xi1, self.xi2 = _per_axis(params, "xi1"), _per_axis(params, "xi2")
        self.settings = SMCSettings(
            boundary_layer=float(params.boundary_layer), g=float(g),
            drag_adaptation=float(params.drag_adaptation), drag_max=float(params.drag_max),
            has_limits=limits is not None, tan_tilt=float(np.tan(limits.tilt_max)) if limits else 0.0,
            uz_floor=float(limits.uz_min_g * g) if limits else 0.0,
            thrust_cap=float(limits.thrust_max_g * g) if limits else 0.0,
            d_max_xy=float(params.xy.disturbance_max), d_max_z=float(params.z.disturbance_max),
            estimate=bool(self.gains[4].any()),
        )  # fmt: skip
        self.s = np.zeros((0, 3))  # last sliding variable (N, 3), m/s, for diagnostics
        self.d_hat = np.zeros((0, 3))  # disturbance estimate (N, 3), m/s^2, added to U
        self.c_hat = np.zeros(0)  # horizontal drag estimate (N,), 1/s

    def reset(self, n: int) -> None:
        """Forget the state of all n vehicles; the drag estimate stays (a property of the airframe)."""
        self.s = np.zeros((n, 3))
        self.d_hat = np.zeros((n, 3))
        if self.c_hat.shape != (n,):
            self.c_hat = np.zeros(n)

    def reset_rows(self, rows: np.ndarray) -> None:
        """Forget the disturbance estimate of the vehicles selected by the (N,) bool mask."""
        self.d_hat[rows] = 0.0

    def __call__(
        self,
        x_d: np.ndarray,
        xd_dot: np.ndarray,
        xd_ddot: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Thrust acceleration U (N, 3), m/s^2; dt (s) since the previous call integrates the estimates
        (unused with both off, where the law is static Eq 49). Without a reset the estimates start at
        zero."""
        n = len(x)
        if self.c_hat.shape != (n,):
            self.c_hat = np.zeros(n)
        if self.d_hat.shape != (n, 3):
            if self.settings.estimate and len(self.d_hat):
                raise ValueError(f"SMCController was reset for {len(self.d_hat)} vehicles, got {n}")
            self.d_hat = np.zeros((n, 3))
        x, v = np.ascontiguousarray(x), np.ascontiguousarray(v)
        e1, self.s, abs_s = smc_sliding(x_d, xd_dot, x, v, self.gains[0])
        u, self.c_hat, self.d_hat = smc_output(
            e1, self.s, abs_s**self.xi1, abs_s**self.xi2, xd_ddot, v, self.gains, self.c_hat, self.d_hat,
            float(dt), *self.settings,
        )  # fmt: skip
        return u
