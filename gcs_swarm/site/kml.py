"""KML (OGC 2.2) -> Site with fastkml, a maintained KML reader: every Placemark, in Documents and Folders at
any depth, read by `features.feature_shapes` with its ExtendedData as properties (docs/site.md). Heights:
a Placemark's `alt`/`height` data, or its coordinates' third value (m above mean sea level)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from fastkml import kml

from gcs_swarm.site.features import feature_shapes
from gcs_swarm.site.model import Area, Circle, Site, SiteError, SitePoint


def read_kml(text: str, source: str) -> Site:
    """The site of a KML file's text; SiteError "source: placemark k ('name'): what is wrong"."""
    try:
        document = kml.KML.from_string(text.encode("utf-8"), strict=False)  # type: ignore[arg-type]
    except Exception as exc:  # lxml/fastkml raise assorted errors on XML they cannot read
        detail = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise SiteError(f"{source}: not a KML document ({detail})") from None
    areas: list[Area] = []
    circles: list[Circle] = []
    waypoints: list[SitePoint] = []
    for k, placemark in enumerate(_placemarks(document)):
        name = getattr(placemark, "name", None)
        where = f"{source}: placemark {k}" + (f" ({name!r})" if name else "")
        geometry = getattr(placemark, "geometry", None)
        if geometry is None:
            raise SiteError(f"{where}: has no geometry")
        try:
            shape = geometry.__geo_interface__
        except Exception:  # pygeoif cannot describe it (an empty geometry)
            raise SiteError(f"{where}: its geometry cannot be read") from None
        found = feature_shapes(shape, _data(placemark), where, _z_means(placemark))
        areas += found[0]
        circles += found[1]
        if found[2] and waypoints:
            raise SiteError(f"{where}: a second route; give the waypoints as one LineString")
        waypoints += found[2]
    if not areas and not circles and not waypoints:
        raise SiteError(f"{source}: no Placemark with a geometry")
    fences = [area for area in areas if area.kind == "inclusion"]
    if len(fences) > 1:
        raise SiteError(f"{fences[1].name}: a second inclusion polygon; the mission has one fence polygon")
    return Site(source, areas=tuple(areas), circles=tuple(circles), waypoints=tuple(waypoints))


def _placemarks(container: Any) -> Iterator[Any]:
    """Placemarks below a KML object, in document order."""
    for feature in getattr(container, "features", None) or ():
        if type(feature).__name__ == "Placemark":
            yield feature
        else:
            yield from _placemarks(feature)


def _z_means(placemark: Any) -> str | None:
    """What the third coordinate of the Placemark's geometry is, by its altitudeMode (KML 2.2: clampToGround,
    the default, ignores it)."""
    mode = getattr(getattr(placemark, "kml_geometry", None), "altitude_mode", None)
    name = getattr(mode, "name", None) or "clampToGround"
    return {"absolute": "amsl", "relativeToGround": "alt", "relativeToSeaFloor": "alt"}.get(name)


def _data(placemark: Any) -> dict[str, object]:
    """The Placemark's ExtendedData <Data name="..."><value>...</value></Data> as properties (text)."""
    extended = getattr(placemark, "extended_data", None)
    return {
        item.name: item.value
        for item in getattr(extended, "elements", None) or ()
        if getattr(item, "name", None) and getattr(item, "value", None) is not None
    }
