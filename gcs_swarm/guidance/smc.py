"""Sliding-mode position control per axis (spec 7, paper Eqs 29-50) with the fast power reaching law.

Inputs are (N, 3) world ENU arrays: reference position/velocity/acceleration and measured position/velocity.
The output U = (U_x, U_y, U_z) is the commanded thrust acceleration in m/s^2 (gravity added in z), which
`inversion` turns into attitude and thrust.

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

import numpy as np

from gcs_swarm.guidance.inversion import limit_thrust_vector
from gcs_swarm.guidance.params import G, Limits, SMCAxisGains, SMCParams
from gcs_swarm.guidance.vector_ops import row_norms


def _per_axis(params: SMCParams, name: str) -> np.ndarray:
    gains: tuple[SMCAxisGains, ...] = (params.xy, params.xy, params.z)
    return np.array([getattr(a, name) for a in gains])


def power_term(s: np.ndarray, xi: np.ndarray, boundary_layer: float) -> np.ndarray:
    """|s|^xi sgn(s), or |s|^xi sat(s/Phi) with a boundary layer Phi > 0 (spec 7.4)."""
    switch = np.sign(s) if boundary_layer <= 0.0 else np.clip(s / boundary_layer, -1.0, 1.0)
    return np.abs(s) ** xi * switch


def reaching_law(s: np.ndarray, params: SMCParams) -> np.ndarray:
    """s_dot = -k1 s - k2 |s|^xi1 sgn(s) - k3 |s|^xi2 sgn(s), (N, 3) (spec 7.1)."""
    k1, k2, k3 = (_per_axis(params, k) for k in ("k1", "k2", "k3"))
    xi1, xi2 = _per_axis(params, "xi1"), _per_axis(params, "xi2")
    phi = params.boundary_layer
    return -k1 * s - k2 * power_term(s, xi1, phi) - k3 * power_term(s, xi2, phi)


def sliding_variable(
    x_d: np.ndarray, xd_dot: np.ndarray, x: np.ndarray, v: np.ndarray, params: SMCParams
) -> tuple[np.ndarray, np.ndarray]:
    """e1 = x_d - x and s = e2 = c1 e1 + xd_dot - v, each (N, 3) (spec 7.1)."""
    e1 = x_d - x
    return e1, _per_axis(params, "c1") * e1 + xd_dot - v


def smc_control(
    x_d: np.ndarray,
    xd_dot: np.ndarray,
    xd_ddot: np.ndarray,
    x: np.ndarray,
    v: np.ndarray,
    params: SMCParams,
    g: float = G,
) -> tuple[np.ndarray, np.ndarray]:
    """U = xd_ddot - c1^2 e1 + c1 e2 - reaching_law(s) (+g in z), and s; both (N, 3) (spec 7.1, Eq 49)."""
    c1 = _per_axis(params, "c1")
    e1, s = sliding_variable(x_d, xd_dot, x, v, params)
    u = xd_ddot - c1 * c1 * e1 + c1 * s - reaching_law(s, params)
    u[:, 2] += g
    return u, s


def clamp_estimate(d_hat: np.ndarray, params: SMCParams) -> np.ndarray:
    """d_hat (N, 3) m/s^2 with its horizontal norm at most xy.disturbance_max and |z| at most
    z.disturbance_max [add]."""
    out = np.array(d_hat, dtype=float)
    cap = params.xy.disturbance_max
    norm = np.hypot(out[:, 0], out[:, 1])
    over = norm > cap
    out[over, :2] *= (cap / norm[over])[:, None]
    out[:, 2] = np.clip(out[:, 2], -params.z.disturbance_max, params.z.disturbance_max)
    return out


def winding(u: np.ndarray, step: np.ndarray, limits: Limits, g: float = G) -> np.ndarray:
    """(N, 3) bool: channels whose estimate step (N, 3) would push U (N, 3) further into a spec 5 limit that
    the inversion applies: xy beyond the tilt cone (limit 2) or the thrust cap (limit 3, taken as
    |U| <= thrust_max_g g); z below the U_z floor (limit 1) or above the thrust cap [add]."""
    floor = limits.uz_min_g * g
    tilted = np.hypot(u[:, 0], u[:, 1]) > np.maximum(u[:, 2], floor) * np.tan(limits.tilt_max)
    capped = row_norms(limit_thrust_vector(u, limits, g)) > limits.thrust_max_g * g
    out = np.empty(u.shape, dtype=bool)
    out[:, :2] = (tilted | capped)[:, None] & (step[:, :2] * u[:, :2] > 0)
    out[:, 2] = ((u[:, 2] < floor) & (step[:, 2] < 0)) | (capped & (step[:, 2] > 0))
    return out


class SMCController:
    """Eq 49 as a `gcs_swarm.guidance.controller.PositionController`, plus the optional disturbance estimate
    d_hat and drag adaptation c_hat [add] (module docstring)."""

    def __init__(self, params: SMCParams, g: float = G, limits: Limits | None = None) -> None:
        """`limits`: the spec 5 limits the inversion applies, so the estimate holds while they cut U; None:
        only the disturbance_max clamp."""
        self.params = params
        self.g = g
        self.limits = limits
        self.k_d = _per_axis(params, "disturbance_gain")
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
        """Thrust acceleration U (N, 3), m/s^2; dt (s) since the previous call integrates d_hat (unused at
        k_d = 0, where the law is static Eq 49). Without a reset the estimate starts at zero."""
        u, self.s = smc_control(x_d, xd_dot, xd_ddot, x, v, self.params, self.g)
        if self.params.drag_adaptation > 0.0:
            u = self._drag_compensated(u, v, dt)
        if not self.k_d.any():
            return u
        if self.d_hat.shape != u.shape:
            if len(self.d_hat):
                raise ValueError(f"SMCController was reset for {len(self.d_hat)} vehicles, got {len(u)}")
            self.d_hat = np.zeros_like(u)
        u = u + self.d_hat
        # Explicit Euler of d_hat_dot = k_d s; rows without a finite state (no telemetry yet) hold.
        step = np.where(np.isfinite(self.s), self.k_d * self.s * dt, 0.0)
        if self.limits is not None:
            step[winding(u, step, self.limits, self.g)] = 0.0
        self.d_hat = clamp_estimate(self.d_hat + step, self.params)
        return u

    def _drag_compensated(self, u: np.ndarray, v: np.ndarray, dt: float) -> np.ndarray:
        """U (N, 3) plus c_hat v_xy; one Euler step of c_hat_dot = gamma s_xy . v_xy (module docstring)."""
        if self.c_hat.shape != (len(u),):
            self.c_hat = np.zeros(len(u))
        v_xy = np.where(np.isfinite(v[:, :2]), v[:, :2], 0.0)
        out = u.copy()
        out[:, :2] += self.c_hat[:, None] * v_xy
        s_xy = np.where(np.isfinite(self.s[:, :2]), self.s[:, :2], 0.0)
        step = self.params.drag_adaptation * np.einsum("nd,nd->n", s_xy, v_xy) * dt
        if self.limits is not None:  # no adaptation while the tilt or thrust limits cut U (anti-windup)
            tilted = np.hypot(out[:, 0], out[:, 1]) > np.maximum(out[:, 2], 0.0) * np.tan(
                self.limits.tilt_max
            )
            step = np.where(tilted & (step > 0.0), 0.0, step)
        self.c_hat = np.clip(self.c_hat + step, 0.0, self.params.drag_max)
        return out
