"""The quadrotor airframe's parameters (SI units) and the quantities derived from them; the wrench its motors
produce is computed in the physics step (sitl_sim.vehicle_model.dynamics.advance)."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class QuadParams:
    """Airframe parameters, SI units. Table 2 (mass, arm, inertias, g) and Table 6 (k_t, k_d) [paper]."""

    mass: float = 0.9  # kg
    arm: float = 0.175  # m, motor distance from the centre
    ixx: float = 8.276e-3  # kg m^2
    iyy: float = 8.276e-3
    izz: float = 1.612e-2  # spec 9.2 reading of "1.612 x 10 3"
    g: float = 9.8  # m/s^2
    k_t: float = 1e-3  # kg m, thrust = k_t w^2
    k_d: float = 2e-5  # kg m^2, reaction torque = k_d w^2
    thrust_to_weight: float = 2.5  # [add] all motors at full thrust / weight
    motor_tau: float = 0.02  # s, first-order motor lag [add]
    # [add] linear drag on air-relative velocity, N per m/s: at the 30 deg default ANGLE_MAX the level-flight
    # terminal speed is m g tan(30 deg) / drag_lin = 20.4 m/s (24.7 m/s at 35 deg), the spec's v_max 20 m/s.
    drag_lin: float = 0.25
    # [add] rotational drag on body rates, N m per rad/s: weak damping (time constant I/drag ~ 4 s) that
    # bounds tumbling after a crash without affecting the controller.
    drag_rot: float = 2e-3

    def __post_init__(self) -> None:
        for name in ("mass", "arm", "ixx", "iyy", "izz", "g", "k_t", "k_d", "motor_tau"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"quadrotor parameter {name} must be a finite number > 0, not {value!r}")
        for name in ("drag_lin", "drag_rot"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"quadrotor parameter {name} must be a finite number >= 0, not {value!r}")
        if not (math.isfinite(self.thrust_to_weight) and self.thrust_to_weight > 1):
            raise ValueError("thrust_to_weight must be > 1 (the vehicle must be able to hover)")

    @property
    def f_max(self) -> float:
        """Maximum thrust of one motor, N."""
        return self.thrust_to_weight * self.mass * self.g / 4.0

    @property
    def thrust_max(self) -> float:
        """Maximum total thrust of the four motors, N."""
        return 4.0 * self.f_max

    @property
    def hover_fraction(self) -> float:
        """Hover thrust as a fraction of thrust_max (ArduCopter MOT_THST_HOVER), 0.4 by default."""
        return self.mass * self.g / self.thrust_max

    @property
    def yaw_coef(self) -> float:
        """Rotor reaction torque per newton of thrust, k_d / k_t (m)."""
        return self.k_d / self.k_t
