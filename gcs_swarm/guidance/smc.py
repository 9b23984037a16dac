"""Sliding-mode position control per axis (spec 7, paper Eqs 29-50) with the fast power reaching law.

Inputs are (N, 3) world ENU arrays: reference position/velocity/acceleration and measured position/velocity.
The output U = (U_x, U_y, U_z) is the commanded thrust acceleration in m/s^2 (gravity added in z), which
`inversion` turns into attitude and thrust.
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.params import G, SMCAxisGains, SMCParams


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


class SMCController:
    """Stateless SMC behind the position-controller interface shared with `pid.PIDController`."""

    def __init__(self, params: SMCParams, g: float = G) -> None:
        self.params = params
        self.g = g
        self.s = np.zeros((0, 3))  # last sliding variable (N, 3), m/s, for diagnostics

    def reset(self, n: int) -> None:
        """Forget the state of all n vehicles."""
        self.s = np.zeros((n, 3))

    def reset_rows(self, rows: np.ndarray) -> None:
        """Forget the state of the vehicles selected by the (N,) bool mask (nothing to forget here)."""

    def __call__(
        self,
        x_d: np.ndarray,
        xd_dot: np.ndarray,
        xd_ddot: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Thrust acceleration U (N, 3), m/s^2 (dt unused: the law is static)."""
        u, self.s = smc_control(x_d, xd_dot, xd_ddot, x, v, self.params, self.g)
        return u
