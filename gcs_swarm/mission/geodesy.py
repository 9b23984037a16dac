"""Positions written in latitude/longitude -> local ENU metres about the mission origin, and the origin a
mission implies when it gives none (docs/mission-schema.md, "Geographic positions").

Conversion is pymap3d.geodetic2enu (WGS-84) about the origin (lat0, lon0, alt0 m AMSL), the same geodesy the
ground station applies to the vehicles' GLOBAL_POSITION_INT (gcs_swarm.link.frames): a point written
{lat, lon, alt} is at height alt0 + alt, one written {lat, lon, amsl} at height amsl, and flying to its ENU
position puts a vehicle at that latitude, longitude and altitude. A vertex {lat, lon} (fences, footprints) is
taken at the origin's height and keeps east and north. A ground start written {lat, lon} (no height) stands on
the ground: z = 0.
"""

from __future__ import annotations

import numpy as np
import pymap3d

from gcs_swarm.mission.schema import DEFAULT_ORIGIN, GeoPoint, GeoVertex, MissionFile

Origin = tuple[float, float, float]  # lat deg, lon deg, alt m AMSL


def position_enu(value: list[float] | GeoPoint, origin: Origin) -> np.ndarray | None:
    """(3,) m ENU of a position as written ([x, y, z] or GeoPoint); None for a GeoPoint with neither `alt` nor
    `amsl` (its height is not given: the caller decides, e.g. a ground start stands at z = 0)."""
    if not isinstance(value, GeoPoint):
        return np.array(value, dtype=float)
    if value.alt is None and value.amsl is None:
        return None
    height = origin[2] + value.alt if value.alt is not None else float(value.amsl)  # type: ignore[arg-type]
    return np.array(pymap3d.geodetic2enu(value.lat, value.lon, height, *origin), dtype=float)


def ground_enu(value: list[float] | GeoPoint, origin: Origin) -> np.ndarray:
    """(3,) m ENU of a start position: as `position_enu`; a GeoPoint without a height stands on the ground
    (z = 0)."""
    enu = position_enu(value, origin)
    if enu is not None:
        return enu
    east, north = vertex_enu(GeoVertex(lat=value.lat, lon=value.lon), origin)  # type: ignore[union-attr]
    return np.array([east, north, 0.0])


def vertex_enu(value: list[float] | GeoVertex, origin: Origin) -> np.ndarray:
    """(2,) m east, north of a horizontal point as written ([x, y] or GeoVertex)."""
    if not isinstance(value, GeoVertex):
        return np.array(value, dtype=float)
    east, north, _ = pymap3d.geodetic2enu(value.lat, value.lon, origin[2], *origin)
    return np.array([east, north], dtype=float)


def implied_origin(file: MissionFile) -> tuple[Origin, tuple[str | int, ...] | None]:
    """The origin (lat, lon, alt) and the key path it was taken from (None: written as `origin`, or the
    default). Order: `origin` as written; the first vertex of safety.geofence.polygon; the first vehicle's
    start position; the first waypoint (or the goal); CMAC (DEFAULT_ORIGIN) when none of these is
    geographic. The origin's altitude is the start's `amsl` when the start is taken (the vehicle's home on the
    ground), else 0 m AMSL (a waypoint flies above the origin, a fence vertex has no height)."""
    if "origin" in file.model_fields_set:
        return (file.origin.lat, file.origin.lon, file.origin.alt), None
    polygon = file.safety.geofence.polygon or []
    routed = "waypoints" in file.model_fields_set
    route = file.waypoints if routed else [file.goal]
    candidates: list[tuple[object, tuple[str | int, ...]]] = [
        (polygon[0] if polygon else None, ("safety", "geofence", "polygon", 0)),
        (file.vehicles[0].start.position if file.vehicles else None, ("vehicles", 0, "start", "position")),
        (route[0] if route else None, ("waypoints", 0) if routed else ("goal",)),
    ]
    for value, loc in candidates:
        if isinstance(value, GeoVertex | GeoPoint):
            home = isinstance(value, GeoPoint) and loc[0] == "vehicles" and value.amsl is not None
            amsl = float(value.amsl) if home else 0.0  # type: ignore[union-attr, arg-type]
            return (value.lat, value.lon, amsl), loc
    return DEFAULT_ORIGIN, None
