"""Sites from the files operators already have (docs/site.md): QGroundControl .plan, GeoJSON and KML, read
into one neutral `Site` (latitude/longitude) and written in the mission file's vocabulary.

site = read_site("field.plan")          # SiteError: "field.plan: geoFence.polygons[1]: what is wrong"
fragment = mission_fragment(site)       # {"safety": {"geofence": {"polygon": [...]}}, "world": {...}, ...}
"""

from __future__ import annotations

from pathlib import Path

from gcs_swarm.site.document import mission_fragment
from gcs_swarm.site.geojson import read_geojson
from gcs_swarm.site.kml import read_kml
from gcs_swarm.site.model import Area, Circle, Site, SiteError, SitePoint, merge_sites
from gcs_swarm.site.qgc_plan import read_plan

READERS = {".plan": read_plan, ".geojson": read_geojson, ".json": read_geojson, ".kml": read_kml}
MAX_BYTES = 50_000_000  # a site file larger than this is refused (no field needs one)


def read_site(path: str | Path, name: str | None = None) -> Site:
    """The site of one file, by its suffix (.plan, .geojson/.json, .kml); `name` names it in messages (default
    the path as given). SiteError on any mistake."""
    source = name or str(path)
    reader = READERS.get(Path(path).suffix.lower())
    if reader is None:
        raise SiteError(f"{source}: unknown kind of site file (expected {', '.join(READERS)})")
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise SiteError(f"{source}: file not found") from None
    except IsADirectoryError:
        raise SiteError(f"{source}: is a directory, not a site file") from None
    except OSError as exc:
        raise SiteError(f"{source}: cannot read the file ({exc.strerror or exc})") from None
    if len(data) > MAX_BYTES:
        raise SiteError(f"{source}: {len(data)} bytes is more than a site file may have ({MAX_BYTES})")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SiteError(f"{source}: not UTF-8 text (bad byte at offset {exc.start})") from None
    return reader(text, source)


__all__ = [
    "Area",
    "Circle",
    "Site",
    "SiteError",
    "SitePoint",
    "merge_sites",
    "mission_fragment",
    "read_site",
]
