"""PID position controller, the baseline the SMC is compared against (a
`gcs_swarm.guidance.controller.PositionController`, like smc.SMCController).

U = xd_ddot + kp e + kd (xd_dot - v) + ki integral(e) (+g in z), (N, 3) m/s^2, with the integral term
clamped to +-i_limit m/s^2 (anti-windup).
"""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.params import G, PIDParams


class PIDController:
    """Per-axis PID with acceleration feed-forward."""

    def __init__(self, params: PIDParams, g: float = G) -> None:
        self.params = params
        self.g = g
        p = params
        self.kp = np.array([p.kp_xy, p.kp_xy, p.kp_z])
        self.ki = np.array([p.ki_xy, p.ki_xy, p.ki_z])
        self.kd = np.array([p.kd_xy, p.kd_xy, p.kd_z])
        self.integral = np.zeros((0, 3))  # ki * integral of e, m/s^2

    def reset(self, n: int) -> None:
        """Zero the integrators of all n vehicles."""
        self.integral = np.zeros((n, 3))

    def reset_rows(self, rows: np.ndarray) -> None:
        """Zero the integrators of the vehicles selected by the (N,) bool mask."""
        self.integral[rows] = 0.0

    def __call__(
        self,
        x_d: np.ndarray,
        xd_dot: np.ndarray,
        xd_ddot: np.ndarray,
        x: np.ndarray,
        v: np.ndarray,
        dt: float,
    ) -> np.ndarray:
        """Thrust acceleration U (N, 3), m/s^2; dt (s) is the time since the previous call."""
        e = x_d - x
        lim = self.params.i_limit
        self.integral = np.clip(self.integral + self.ki * e * dt, -lim, lim)
        u = xd_ddot + self.kp * e + self.kd * (xd_dot - v) + self.integral
        u[:, 2] += self.g
        return u
