"""Slew limit on the commanded tilt [add]: the roll/pitch a vehicle is told to fly move toward the
controller's demand at most `rate_max` rad/s, so no command steps (an autopilot's rate loop would saturate on
a step, and a real airframe would not fly it the way a model does).

The limit acts on the (roll, pitch) pair as a vector: a change of direction is slewed as one rotation of the
tilt, not axis by axis. Shapes (N,), rad, FLU body / ENU world ZYX Euler (spec 1.1).
"""

from __future__ import annotations

import numpy as np


class TiltSlew:
    """Per-vehicle slewed roll/pitch commands. `rate_max` rad/s; 0 or less: no limit (the spec's plain
    inversion output)."""

    def __init__(self, rate_max: float) -> None:
        self.rate_max = rate_max
        self.roll = np.zeros(0)
        self.pitch = np.zeros(0)

    def reset(self, roll: np.ndarray, pitch: np.ndarray) -> None:
        """Start from the measured attitude (N,) rad (NaN rows start at the first demand)."""
        self.roll = np.array(roll, dtype=float)
        self.pitch = np.array(pitch, dtype=float)

    def reset_rows(self, rows: np.ndarray, roll: np.ndarray, pitch: np.ndarray) -> None:
        """Restart the (N,) bool-selected vehicles at their measured attitude."""
        self.roll[rows] = roll[rows]
        self.pitch[rows] = pitch[rows]

    def __call__(
        self, roll_d: np.ndarray, pitch_d: np.ndarray, dt: float, rows: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Commanded (roll, pitch) (N,) rad after one step of dt s toward the demand (N,) for the selected
        rows; other rows keep their last command."""
        unknown = ~(np.isfinite(self.roll) & np.isfinite(self.pitch))
        self.roll = np.where(unknown, roll_d, self.roll)
        self.pitch = np.where(unknown, pitch_d, self.pitch)
        d_roll, d_pitch = roll_d - self.roll, pitch_d - self.pitch
        if self.rate_max > 0.0:
            step = np.hypot(d_roll, d_pitch)
            limit = self.rate_max * dt
            scale = np.divide(limit, step, out=np.ones_like(step), where=step > limit)
            d_roll, d_pitch = d_roll * scale, d_pitch * scale
        self.roll = np.where(rows, self.roll + d_roll, self.roll)
        self.pitch = np.where(rows, self.pitch + d_pitch, self.pitch)
        return self.roll.copy(), self.pitch.copy()
