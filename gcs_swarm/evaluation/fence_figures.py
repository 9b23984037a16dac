"""The site fence in a run's ground truth (issue 37): how often a vehicle crossed into the forbidden side
(outside the inclusion polygon, or inside an exclusion polygon or circle) and how close it came to a fence
edge. Measured with shapely (polygons) and the circle's own distance, independently of the command guard's
geometry (gcs_swarm.link.command_limits), so the report checks the guard rather than repeating it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gcs_swarm.evaluation.metrics import rounded


def fence_margins(xy: np.ndarray, fence: Any) -> np.ndarray:
    """(P,) m: the signed horizontal distance of each point xy (P, 2) m ENU to the site fence `fence`
    (gcs_swarm.mission.model.Fence), > 0 on the allowed side: the smallest of the distances inside the
    inclusion polygon's edge and outside each exclusion zone's (negative when breaching); +inf without a
    fence."""
    import shapely
    from shapely.geometry import Polygon

    points = shapely.points(xy)
    margin = np.full(len(xy), np.inf)
    zones = [(fence.polygon, True)] if fence.polygon is not None else []
    zones += [(zone.polygon, False) for zone in fence.exclusions if zone.polygon is not None]
    for vertices, inclusion in zones:
        polygon = Polygon(vertices)
        inside = shapely.contains_xy(polygon, xy[:, 0], xy[:, 1])
        distance = shapely.distance(polygon.exterior, points)
        margin = np.minimum(margin, np.where(inside == inclusion, distance, -distance))
    for zone in fence.exclusions:
        if zone.polygon is None:
            margin = np.minimum(margin, np.hypot(*(xy - zone.center).T) - zone.radius)
    return margin


def fence_figures(pos: np.ndarray, mission: Any) -> dict[str, Any]:
    """From ground-truth positions pos (T, N, 3) m ENU: `fence_breaches`, the number of times a vehicle went
    from the allowed side to the forbidden side (a vehicle on the forbidden side at its first sample counts
    once), and `min_fence_margin_m`, the smallest fence_margins of a vehicle's centre over the run (None
    without a sample). Empty (no keys) for a mission without a site fence."""
    fence = getattr(mission, "fence", None)
    if fence is None or (fence.polygon is None and not fence.exclusions):
        return {}
    breaches, closest = 0, np.inf
    for i in range(pos.shape[1]):
        xy = pos[:, i, :2]
        xy = xy[np.isfinite(xy).all(axis=1)]
        if not len(xy):
            continue
        margin = fence_margins(xy, fence)
        outside = margin < 0.0
        breaches += int(outside[0]) + int(np.count_nonzero(outside[1:] & ~outside[:-1]))
        closest = min(closest, float(margin.min()))
    return {
        "fence_breaches": breaches,
        "min_fence_margin_m": rounded(closest),
    }
