"""The neutral site every importer produces: fences, no-fly zones, buildings, trees, a route and rally points
in latitude/longitude, whatever file they came from (docs/site.md).

Degrees are WGS-84 latitude/longitude; heights are metres above the mission origin (`alt`) or above mean sea
level (`amsl`). Every shape carries `name`, "file: feature", so a later complaint names where it came from.
"""

from __future__ import annotations

import dataclasses
import math

LatLon = tuple[float, float]  # lat deg, lon deg


class SiteError(Exception):
    """A site file that cannot be imported; str(e) is one sentence "file: feature: what is wrong"."""


@dataclasses.dataclass(frozen=True)
class SitePoint:
    """A point with a height: `alt` m above the origin or `amsl` m above mean sea level (exactly one)."""

    name: str
    lat: float
    lon: float
    alt: float | None = None
    amsl: float | None = None


@dataclasses.dataclass(frozen=True)
class Area:
    """A polygon: the inclusion fence, an exclusion zone, or a building (prism between bottom and top)."""

    name: str
    kind: str  # "inclusion" | "exclusion" | "prism"
    vertices: tuple[LatLon, ...]  # in order, not closed, at least 3
    bottom: float = 0.0  # m above the origin (prisms)
    top: float = 0.0  # m above the origin (prisms), > bottom


@dataclasses.dataclass(frozen=True)
class Circle:
    """A circle: an exclusion zone, or a tree or mast (cylinder between bottom and top)."""

    name: str
    kind: str  # "exclusion" | "cylinder"
    center: LatLon
    radius: float  # m
    bottom: float = 0.0  # m above the origin (cylinders)
    top: float = 0.0  # m above the origin (cylinders), > bottom


@dataclasses.dataclass(frozen=True)
class Site:
    """What one or more site files describe."""

    source: str  # the file(s), as given
    home: SitePoint | None = None  # the planned home (amsl): the mission origin when the mission gives none
    areas: tuple[Area, ...] = ()
    circles: tuple[Circle, ...] = ()
    waypoints: tuple[SitePoint, ...] = ()  # the route, in order
    rally: tuple[SitePoint, ...] = ()
    takeoff_alt: float | None = None  # m above the origin, the take-off item's altitude

    @property
    def fence(self) -> Area | None:
        """The inclusion polygon, if any (at most one: `merge_sites` and the importers see to it)."""
        return next((area for area in self.areas if area.kind == "inclusion"), None)


def merge_sites(sites: list[Site]) -> Site:
    """Several files as one site: shapes and rally points add up; at most one file may give the inclusion
    fence, one the route, one the take-off altitude; home positions must agree (within 1 cm)."""
    if not sites:
        return Site(source="")
    merged = sites[0]
    for site in sites[1:]:
        for what, mine, theirs in (
            ("the inclusion fence", merged.fence, site.fence),
            ("a route (waypoints)", merged.waypoints or None, site.waypoints or None),
            ("a take-off altitude", merged.takeoff_alt, site.takeoff_alt),
        ):
            if mine is not None and theirs is not None:
                raise SiteError(f"{site.source}: gives {what}, and so does {merged.source}; give it once")
        home = merged.home or site.home
        if merged.home is not None and site.home is not None and not _same_place(merged.home, site.home):
            raise SiteError(f"{site.source}: its home position differs from that of {merged.source}")
        merged = Site(
            source=f"{merged.source}, {site.source}",
            home=home,
            areas=merged.areas + site.areas,
            circles=merged.circles + site.circles,
            waypoints=merged.waypoints or site.waypoints,
            rally=merged.rally + site.rally,
            takeoff_alt=site.takeoff_alt if merged.takeoff_alt is None else merged.takeoff_alt,
        )
    return merged


def _same_place(a: SitePoint, b: SitePoint) -> bool:
    """Within 1 cm: 1e-7 deg of latitude is 1.1 cm, so 9e-8 deg; heights within 1 cm."""
    return (
        abs(a.lat - b.lat) < 9e-8
        and abs(a.lon - b.lon) * math.cos(math.radians(a.lat)) < 9e-8
        and abs((a.amsl or 0.0) - (b.amsl or 0.0)) < 0.01
    )
