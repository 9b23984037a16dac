"""The tracking reference of spec 11.2 that the SMC and PID tests follow."""

from __future__ import annotations

import math

import numpy as np


def spec_reference(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """5 sin(0.5 t) + 2 t on every axis (spec 11.2), (1, 3) position, velocity, acceleration."""
    one = np.ones((1, 3))
    return (
        one * (5 * math.sin(0.5 * t) + 2 * t),
        one * (2.5 * math.cos(0.5 * t) + 2),
        one * (-1.25 * math.sin(0.5 * t)),
    )
