"""A Site in the mission file's vocabulary (docs/mission-schema.md): plain data with the geographic forms
{lat, lon} and {lat, lon, alt | amsl}, as `gcs-swarm import` writes it and `world.import` merges it."""

from __future__ import annotations

from typing import Any

from gcs_swarm.site.model import Area, Circle, Site, SitePoint


def mission_fragment(site: Site) -> dict[str, Any]:
    """The mission keys the site gives (only those it has): origin (the home), formation.altitude (the
    take-off altitude), waypoints, safety.geofence.polygon and .exclusions, safety.rally, world.prisms and
    world.cylinders. Each list entry that has a name carries it ("file: feature")."""
    out: dict[str, Any] = {}
    if site.home is not None:
        out["origin"] = {"lat": site.home.lat, "lon": site.home.lon, "alt": site.home.amsl or 0.0}
    if site.takeoff_alt is not None:
        out["formation"] = {"altitude": site.takeoff_alt}
    if site.waypoints:
        out["waypoints"] = [_point(p) for p in site.waypoints]
    geofence: dict[str, Any] = {}
    if site.fence is not None:
        geofence["polygon"] = _vertices(site.fence)
    exclusions = [_exclusion(a) for a in site.areas if a.kind == "exclusion"]
    exclusions += [_exclusion(c) for c in site.circles if c.kind == "exclusion"]
    if exclusions:
        geofence["exclusions"] = exclusions
    safety: dict[str, Any] = {"geofence": geofence} if geofence else {}
    if site.rally:
        safety["rally"] = [_point(p) for p in site.rally]
    if safety:
        out["safety"] = safety
    world: dict[str, Any] = {}
    prisms = [a for a in site.areas if a.kind == "prism"]
    if prisms:
        world["prisms"] = [
            {"name": a.name, "polygon": _vertices(a), "bottom": a.bottom, "top": a.top} for a in prisms
        ]
    cylinders = [c for c in site.circles if c.kind == "cylinder"]
    if cylinders:
        world["cylinders"] = [
            {
                "name": c.name,
                "center": _vertex(c.center),
                "radius": c.radius,
                "bottom": c.bottom,
                "top": c.top,
            }
            for c in cylinders
        ]
    if world:
        out["world"] = world
    return out


def _vertex(lat_lon: tuple[float, float]) -> dict[str, float]:
    return {"lat": lat_lon[0], "lon": lat_lon[1]}


def _vertices(area: Area) -> list[dict[str, float]]:
    return [_vertex(v) for v in area.vertices]


def _point(point: SitePoint) -> dict[str, float]:
    height = {"alt": point.alt} if point.alt is not None else {"amsl": point.amsl}
    return {"lat": point.lat, "lon": point.lon, **height}  # type: ignore[dict-item]


def _exclusion(shape: Area | Circle) -> dict[str, Any]:
    if isinstance(shape, Area):
        return {"name": shape.name, "polygon": _vertices(shape)}
    return {"name": shape.name, "center": _vertex(shape.center), "radius": shape.radius}
