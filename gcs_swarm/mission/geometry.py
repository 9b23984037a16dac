"""Formation geometry a mission implies: each vehicle's slot in the leader's frame and its final destination.
Offsets and positions in metres, leader frame / local ENU."""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.mission.model import Mission


def mission_offsets(mission: Mission, shape: str | None = None, spacing: float | None = None) -> np.ndarray:
    """Leader-frame slot offsets (N, 3): explicit `slot`s where given, else from the formation shape
    (`shape`/`spacing` override the mission's, for a live reshape)."""
    n = len(mission.vehicles)
    form = mission.formation
    shape = shape or form.shape
    followers = [i for i in range(n) if i != mission.leader_index]
    offsets = np.zeros((n, 3))
    if shape != "offsets":
        offsets[followers] = formation_offsets(shape, len(followers), spacing or form.spacing, form.angle_deg)
    if shape == form.shape:
        for i, v in enumerate(mission.vehicles):
            if v.slot is not None:
                offsets[i] = v.slot
    return offsets


def follower_targets(mission: Mission) -> np.ndarray | None:
    """Final destinations g_i (N, 3) when every follower names one, else None (controller default)."""
    targets = [v.target for i, v in enumerate(mission.vehicles) if i != mission.leader_index]
    if not targets or any(t is None for t in targets):
        return None
    out = np.array([mission.goal if v.target is None else v.target for v in mission.vehicles], dtype=float)
    out[mission.leader_index] = mission.goal
    return out
