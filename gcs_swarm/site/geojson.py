"""GeoJSON (RFC 7946) -> Site: a FeatureCollection or a Feature, each feature read by
`features.feature_shapes` (docs/site.md). Positions are [lon, lat(, height m)]."""

from __future__ import annotations

from gcs_swarm.site.features import feature_shapes
from gcs_swarm.site.model import Area, Circle, Site, SiteError, SitePoint
from gcs_swarm.site.values import describe, json_mapping, mapping, sequence


def read_geojson(text: str, source: str) -> Site:
    """The site of a GeoJSON file's text; SiteError "source: feature k ('name'): what is wrong"."""
    document = json_mapping(text, source)
    kind = document.get("type")
    if kind == "FeatureCollection":
        features = list(sequence(document.get("features"), f"{source}: features"))
    elif kind == "Feature":
        features = [document]
    else:
        raise SiteError(f"{source}: type: expected 'FeatureCollection' or 'Feature', got {describe(kind)}")
    areas: list[Area] = []
    circles: list[Circle] = []
    waypoints: list[SitePoint] = []
    from_line = False
    for k, entry in enumerate(features):
        feature = mapping(entry, f"{source}: feature {k}")
        properties = feature.get("properties") or {}
        properties = mapping(properties, f"{source}: feature {k}: properties")
        name = properties.get("name")
        where = f"{source}: feature {k}" + (f" ({name!r})" if isinstance(name, str) and name else "")
        if feature.get("type") != "Feature":
            raise SiteError(f"{where}: type: expected 'Feature', got {describe(feature.get('type'))}")
        geometry = mapping(feature.get("geometry"), f"{where}: geometry")
        found = feature_shapes(geometry, properties, where)
        areas += found[0]
        circles += found[1]
        if found[2]:  # the route: one LineString, or Points in file order
            line = geometry.get("type") == "LineString"
            if waypoints and (line or from_line):
                raise SiteError(f"{where}: a second route; give the waypoints as one LineString or as Points")
            from_line = line
            waypoints += found[2]
    fences = [area for area in areas if area.kind == "inclusion"]
    if len(fences) > 1:
        raise SiteError(f"{fences[1].name}: a second inclusion polygon; the mission has one fence polygon")
    return Site(source, areas=tuple(areas), circles=tuple(circles), waypoints=tuple(waypoints))
