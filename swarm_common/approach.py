"""How close two points moving linearly come: the one rule behind the simulator's swept collision test
(sitl_sim.world) and the ground station's check that slots moving to a new shape keep apart
(gcs_swarm.guidance.slot_assignment)."""

from __future__ import annotations

import math

from swarm_common.jit import kernel


@kernel
def segment_min_norm(rx0: float, ry0: float, rz0: float, rx1: float, ry1: float, rz1: float) -> float:
    """Minimum norm m of the segment (rx0, ry0, rz0) -> (rx1, ry1, rz1) m: the closest two points come whose
    relative position moves linearly from the first to the second."""
    dx, dy, dz = rx1 - rx0, ry1 - ry0, rz1 - rz0
    length2 = dx * dx + dy * dy + dz * dz
    s = 0.0 if length2 <= 0.0 else min(max(-(rx0 * dx + ry0 * dy + rz0 * dz) / length2, 0.0), 1.0)
    return math.sqrt((rx0 + s * dx) ** 2 + (ry0 + s * dy) ** 2 + (rz0 + s * dz) ** 2)


__all__ = ["segment_min_norm"]
