"""What a map feature (a GeoJSON Feature, a KML Placemark) is, from its geometry and properties: the one rule
both importers follow (docs/site.md, "GeoJSON and KML").

- Polygon / MultiPolygon: `fence: inclusion | exclusion` makes it the fence or an exclusion zone; a `height`
  (or `top`) makes it a building (prism) from `min_height` (or `bottom`, default 0) to that height, m above
  the origin; with neither it is the inclusion fence (as QGroundControl's fence editor loads a KML polygon).
  Holes are refused.
- Point / MultiPoint: with `radius` and `height` a tree or mast (cylinder); with `radius` and
  `fence: exclusion` an exclusion circle; otherwise a waypoint, its height the `alt` property (m above the
  origin) or the third coordinate (m above mean sea level).
- LineString: with `radius` and `height` a row of trees (a cylinder at each vertex); otherwise waypoints.
Any other geometry, or properties that do not fit, is one SiteError naming the feature.
"""

from __future__ import annotations

from collections.abc import Mapping

from gcs_swarm.site.model import Area, Circle, SiteError, SitePoint
from gcs_swarm.site.values import describe, lat_lon, number, simple_polygon

FENCE_KINDS = ("inclusion", "exclusion")
SUPPORTED = "Polygon, MultiPolygon, Point, MultiPoint, LineString"

Shapes = tuple[list[Area], list[Circle], list[SitePoint]]


def feature_shapes(
    geometry: Mapping[str, object], properties: Mapping[str, object], where: str, z_means: str | None = "amsl"
) -> Shapes:
    """The shapes of one feature. `geometry` is GeoJSON-like ({"type": ..., "coordinates": ...}, positions
    [lon, lat(, z)]); `properties` its properties (KML: its ExtendedData, values as text); `z_means` what a
    third coordinate is: "amsl" (m above mean sea level), "alt" (m above the origin) or None (no height: KML
    clampToGround)."""
    kind = geometry.get("type")
    coordinates = geometry.get("coordinates")
    fence = properties.get("fence")
    if fence is not None and fence not in FENCE_KINDS:
        raise SiteError(f"{where}: fence: expected 'inclusion' or 'exclusion', got {describe(fence)}")
    if kind in ("Polygon", "MultiPolygon"):
        polygons = [coordinates] if kind == "Polygon" else _list(coordinates, where)
        areas = [
            _area(rings, properties, f"{where} part {k}" if kind == "MultiPolygon" else where)
            for k, rings in enumerate(polygons)
        ]
        return areas, [], []
    if kind in ("Point", "MultiPoint", "LineString"):
        positions = [coordinates] if kind == "Point" else _list(coordinates, where)
        if not positions:
            raise SiteError(f"{where}: the {kind} has no coordinates")
        named = [(f"{where} vertex {k}" if len(positions) > 1 else where, p) for k, p in enumerate(positions)]
        if "radius" in properties:
            return [], [_circle(p, properties, at) for at, p in named], []
        if kind == "MultiPoint":
            raise SiteError(f"{where}: a MultiPoint needs 'radius' (cylinders or exclusion circles)")
        for key in ("height", "top", "fence"):
            if key in properties:
                raise SiteError(f"{where}: a {kind} with '{key}' needs 'radius' too (a cylinder or circle)")
        return [], [], [_waypoint(p, properties, at, z_means) for at, p in named]
    raise SiteError(f"{where}: geometry {describe(kind)} is not supported ({SUPPORTED})")


def _list(value: object, where: str) -> list[object]:
    if not isinstance(value, list | tuple):
        raise SiteError(f"{where}: expected a list of coordinates, got {describe(value)}")
    return list(value)


def _position(value: object, where: str) -> tuple[float, float, float | None]:
    """lat, lon deg and the third coordinate (None: not given) of a [lon, lat(, z)] position."""
    values = _list(value, where)
    if len(values) not in (2, 3):
        raise SiteError(f"{where}: expected a position [lon, lat] or [lon, lat, z], got {describe(values)}")
    lat, lon = lat_lon(values[1], values[0], where)
    return lat, lon, number(values[2], f"{where}: third coordinate") if len(values) == 3 else None


def _heights(properties: Mapping[str, object], where: str) -> tuple[float, float]:
    """(bottom, top) m above the origin from `min_height`/`bottom` and `height`/`top`."""
    top_key = "height" if "height" in properties else "top"
    bottom_key = "min_height" if "min_height" in properties else "bottom"
    top = number(properties[top_key], f"{where}: {top_key}", text_ok=True)
    bottom = number(properties.get(bottom_key, 0.0), f"{where}: {bottom_key}", text_ok=True)
    if top <= bottom:
        raise SiteError(f"{where}: {top_key} ({top:g} m) must be above {bottom_key} ({bottom:g} m)")
    return bottom, top


def _area(rings: object, properties: Mapping[str, object], where: str) -> Area:
    rings = _list(rings, where)
    if len(rings) != 1:
        raise SiteError(
            f"{where}: a polygon with {len(rings) - 1} hole(s) is not supported"
            if rings
            else f"{where}: the polygon has no ring"
        )
    vertices = [_position(p, f"{where} vertex {i}")[:2] for i, p in enumerate(_list(rings[0], where))]
    polygon = simple_polygon(vertices, where)  # type: ignore[arg-type]
    fence = properties.get("fence")
    if fence is not None:
        return Area(where, str(fence), polygon)
    if "height" in properties or "top" in properties:
        bottom, top = _heights(properties, where)
        return Area(where, "prism", polygon, bottom, top)
    return Area(where, "inclusion", polygon)


def _circle(position: object, properties: Mapping[str, object], where: str) -> Circle:
    lat, lon, _ = _position(position, where)
    radius = number(properties["radius"], f"{where}: radius", text_ok=True)
    if radius <= 0.0:
        raise SiteError(f"{where}: radius must be > 0 m, got {radius:g}")
    fence = properties.get("fence")
    if fence == "inclusion":
        raise SiteError(f"{where}: inclusion circles are not supported; draw the fence as a polygon")
    if fence == "exclusion":
        return Circle(where, "exclusion", (lat, lon), radius)
    if "height" not in properties and "top" not in properties:
        raise SiteError(f"{where}: a circle needs 'height' (a tree or mast) or 'fence': 'exclusion'")
    bottom, top = _heights(properties, where)
    return Circle(where, "cylinder", (lat, lon), radius, bottom, top)


def _waypoint(
    position: object, properties: Mapping[str, object], where: str, z_means: str | None
) -> SitePoint:
    lat, lon, z = _position(position, where)
    if "alt" in properties:
        return SitePoint(where, lat, lon, alt=number(properties["alt"], f"{where}: alt", text_ok=True))
    if z is None or z_means is None:
        raise SiteError(
            f"{where}: a waypoint needs a height: an 'alt' property (m above the origin) or a third "
            "coordinate (KML: with altitudeMode absolute or relativeToGround)"
        )
    return SitePoint(where, lat, lon, alt=z) if z_means == "alt" else SitePoint(where, lat, lon, amsl=z)
