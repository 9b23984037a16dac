"""Checks and conversions of incoming MAVLink message fields shared by the message handlers."""

from __future__ import annotations

import math

import numpy as np


def finite(*values: float) -> bool:
    """Whether every value is a finite number (no NaN, no infinity)."""
    return all(math.isfinite(v) for v in values)


def ned_to_enu(v: tuple[float, float, float] | list[float]) -> np.ndarray:
    """A NED vector (3,) as ENU (3,), same units (spec 1.1)."""
    return np.array([v[1], v[0], -v[2]], dtype=float)


def param_name(raw: bytes | str) -> str:
    """A PARAM_* message's param_id as text (NUL-padded up to 16 characters)."""
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return raw.split("\0", 1)[0].strip()
