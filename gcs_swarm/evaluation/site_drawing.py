"""The site on a matplotlib top view (m ENU): the fence polygon, the exclusion zones, the buildings (prisms)
and trees (cylinders) of a mission, drawn the same on report.png, fig_site.png and the replay's animation."""

from __future__ import annotations

from typing import Any

from gcs_swarm.mission import Mission

FENCE_COLOUR = "#c0392b"
ZONE_FILL = (0.75, 0.22, 0.17, 0.15)
SHAPE_FILL = (0.47, 0.33, 0.2, 0.45)  # buildings and trees
SHAPE_EDGE = "#6b4c2a"


def draw_site(ax: Any, mission: Mission) -> None:
    """Draw the mission's fence polygon (outline), exclusion zones (tinted), prisms' footprints and
    cylinders (filled) on the top view `ax`; nothing for a mission without them."""
    from matplotlib.patches import Circle, Polygon

    fence = mission.fence
    if fence.polygon is not None:
        ax.add_patch(Polygon(fence.polygon, closed=True, fill=False, ec=FENCE_COLOUR, lw=2))
    for zone in fence.exclusions:
        patch: Polygon | Circle
        if zone.polygon is not None:
            patch = Polygon(zone.polygon, closed=True)
        else:
            assert zone.center is not None  # a zone is a polygon or a circle (model.Zone)
            patch = Circle((float(zone.center[0]), float(zone.center[1])), zone.radius)
        patch.set(fc=ZONE_FILL, ec=FENCE_COLOUR)
        ax.add_patch(patch)
    for prism in mission.prisms:
        ax.add_patch(Polygon(prism.footprint, closed=True, fc=SHAPE_FILL, ec=SHAPE_EDGE))
    for cylinder in mission.cylinders:
        centre = (float(cylinder.center[0]), float(cylinder.center[1]))
        ax.add_patch(Circle(centre, cylinder.radius, fc=SHAPE_FILL, ec=SHAPE_EDGE))


def has_site(mission: Mission) -> bool:
    """The mission has a site to draw (a fence polygon, zones, buildings or trees) or legs to mark."""
    fence = mission.fence
    return bool(
        fence.polygon is not None or fence.exclusions or mission.prisms or mission.cylinders or mission.legs
    )
