"""Values read from a site file, checked one by one: each check names the file, the feature and what is
wrong in one SiteError (docs/site.md). Shared by the importers."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence

import shapely
from shapely.geometry import Polygon

from gcs_swarm.site.model import LatLon, SiteError


def json_mapping(text: str, source: str) -> Mapping[str, object]:
    """A JSON file's text as its top-level mapping; SiteError "source: not JSON: line L column C: why", or
    when it is nested too deeply or not a mapping."""
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise SiteError(f"{source}: not JSON: line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    except RecursionError:
        raise SiteError(f"{source}: the JSON is nested too deeply") from None
    return mapping(document, source)


def describe(value: object) -> str:
    """How a file's value reads in a message."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int | float):
        return f"{value:g}" if isinstance(value, float) else str(value)[:24]
    if isinstance(value, str):
        return repr(value if len(value) <= 40 else value[:37] + "...")
    if isinstance(value, Sequence):
        return f"a list of {len(value)}"
    return "a mapping" if isinstance(value, Mapping) else type(value).__name__


def number(value: object, where: str, *, text_ok: bool = False) -> float:
    """A finite number (JSON number; with `text_ok` also text such as "12.5", as KML data and some GeoJSON
    properties write them)."""
    if isinstance(value, str) and text_ok:
        try:
            value = float(value.strip())
        except ValueError:
            raise SiteError(f"{where}: expected a number, got {describe(value)}") from None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SiteError(f"{where}: expected a number, got {describe(value)}")
    x = float(value) if abs(value) < 1e300 else math.inf
    if not math.isfinite(x):
        raise SiteError(f"{where}: expected a finite number, got {describe(value)}")
    return x


def mapping(value: object, where: str) -> Mapping[str, object]:
    if not isinstance(value, Mapping):
        raise SiteError(f"{where}: expected a mapping (JSON object), got {describe(value)}")
    return value


def sequence(value: object, where: str) -> Sequence[object]:
    if isinstance(value, str) or not isinstance(value, Sequence):
        raise SiteError(f"{where}: expected a list, got {describe(value)}")
    return value


def lat_lon(lat: object, lon: object, where: str) -> LatLon:
    """(lat, lon) deg, each in range."""
    la, lo = number(lat, f"{where}: latitude"), number(lon, f"{where}: longitude")
    if not -90.0 <= la <= 90.0:
        raise SiteError(f"{where}: latitude {la:g} is outside -90..90 deg")
    if not -180.0 <= lo <= 180.0:
        raise SiteError(f"{where}: longitude {lo:g} is outside -180..180 deg")
    return la, lo


def simple_polygon(vertices: list[LatLon], where: str) -> tuple[LatLon, ...]:
    """The vertices (a trailing copy of the first dropped) of a simple polygon (at least 3 distinct vertices,
    no self-intersection, non-zero area: shapely's validity, tested in lon/lat degrees, which a site's
    projection keeps)."""
    if len(vertices) > 1 and vertices[0] == vertices[-1]:
        vertices = vertices[:-1]
    if len(set(vertices)) < 3:
        raise SiteError(f"{where}: a polygon needs at least 3 distinct vertices, got {len(set(vertices))}")
    polygon = Polygon([(lon, lat) for lat, lon in vertices])
    if not polygon.is_valid or polygon.area == 0.0:
        raise SiteError(f"{where}: not a simple polygon ({shapely.is_valid_reason(polygon)})")
    return tuple(vertices)
