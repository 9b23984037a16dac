"""Wind for N vehicles: steady speed and direction plus seeded turbulence (ArduPilot SIM_WIND_* style).

SIM_WIND_SPD -> speed (m/s), SIM_WIND_DIR -> direction_deg (the direction the wind comes FROM, 0 = from North,
90 = from East, as in ArduPilot), SIM_WIND_TURB -> turbulence (m/s). Turbulence is a per-vehicle, per-axis
first-order Gauss-Markov process (the first-order Dryden-like approximation) with correlation time
time_constant and standard deviation `turbulence` on each ENU axis, drawn from a numpy Generator seeded once,
so a run is reproducible for a seed whatever the settings changed at run time.
"""

from __future__ import annotations

import math

import numpy as np


class Wind:
    """Air velocity seen by each of N vehicles, ENU m/s; sample(dt) advances the turbulence."""

    def __init__(
        self,
        n: int,
        seed: int | None,
        speed: float = 0.0,
        direction_deg: float = 0.0,
        turbulence: float = 0.0,
        time_constant: float = 2.0,
    ) -> None:
        if not (isinstance(n, int | np.integer) and n >= 1):
            raise ValueError(f"wind vehicle count must be an integer >= 1, not {n!r}")
        if not (math.isfinite(time_constant) and time_constant > 0):
            raise ValueError(f"wind time_constant must be a finite number > 0 s, not {time_constant!r}")
        self.n = int(n)
        self.time_constant = float(time_constant)
        self._rng = np.random.default_rng(seed)
        self._unit_gust = self._rng.standard_normal((self.n, 3))  # stationary start: unit variance already
        self.set(speed, direction_deg, turbulence)

    def set(self, speed: float, direction_deg: float, turbulence: float) -> None:
        """Change the wind now: speed m/s >= 0, direction_deg (from, 0 = North), turbulence m/s >= 0."""
        values = {"speed": speed, "direction_deg": direction_deg, "turbulence": turbulence}
        for name, value in values.items():
            if not (isinstance(value, int | float | np.integer | np.floating) and math.isfinite(value)):
                raise ValueError(f"wind {name} must be a finite number, not {value!r}")
        if speed < 0 or turbulence < 0:
            raise ValueError(f"wind speed and turbulence must be >= 0 m/s, not {speed!r} and {turbulence!r}")
        self.speed = float(speed)
        self.direction_deg = float(direction_deg) % 360.0
        self.turbulence = float(turbulence)
        bearing = math.radians(self.direction_deg)
        # (3,) steady air velocity ENU m/s (blowing away from direction_deg)
        self.steady = np.array([-self.speed * math.sin(bearing), -self.speed * math.cos(bearing), 0.0])

    def sample(self, dt: float) -> np.ndarray:
        """Advance the turbulence by dt (s, >= 0) and return the (N,3) ENU wind velocity, m/s."""
        if not (math.isfinite(dt) and dt >= 0):
            raise ValueError(f"wind sample dt must be a finite number >= 0 s, not {dt!r}")
        decay = math.exp(-dt / self.time_constant)
        innovation = self._rng.standard_normal((self.n, 3))
        self._unit_gust = decay * self._unit_gust + math.sqrt(1.0 - decay * decay) * innovation
        return self.steady + self.turbulence * self._unit_gust
