"""QGroundControl .plan files (JSON) -> Site (docs/site.md).

The format as QGroundControl writes it (PlanMasterController, GeoFenceController, QGCMapPolygon,
QGCMapCircle / QGCFenceCircle, RallyPointController, MissionController, SimpleMissionItem):

    {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
     "geoFence": {"version": 2,
                  "polygons": [{"inclusion": true, "polygon": [[lat, lon], ...], "version": 1}],
                  "circles": [{"inclusion": false, "circle": {"center": [lat, lon], "radius": m},
                               "version": 1}]},
     "rallyPoints": {"version": 2, "points": [[lat, lon, alt m above home], ...]},
     "mission": {"version": 2, "plannedHomePosition": [lat, lon, alt m AMSL],
                 "items": [{"type": "SimpleItem", "command": 16, "frame": 3,
                            "params": [hold s, acceptance m, pass m, yaw deg, lat, lon, alt]}, ...]}}

What becomes what: the inclusion polygon is the fence (one at most); exclusion polygons and circles are
exclusion zones; an inclusion circle is refused (draw the fence as a polygon); rally points are kept; the
mission items NAV_WAYPOINT are the route, NAV_TAKEOFF gives the take-off altitude, a last NAV_LAND ends the
route (at its position when it has one), a last NAV_RETURN_TO_LAUNCH ends it above home. Any other item
(camera, speed, loiter, spline, ROI, survey and other complex items) is refused with its number and name:
the formation flight has no meaning for it, and nothing is dropped silently.
"""

from __future__ import annotations

from collections.abc import Mapping

from pymavlink.dialects.v20 import common as mavlink

from gcs_swarm.site.model import Area, Circle, Site, SiteError, SitePoint
from gcs_swarm.site.values import describe, json_mapping, lat_lon, mapping, number, sequence, simple_polygon

PLAN_VERSION = 1  # PlanMasterController::kPlanFileVersion
GEOFENCE_VERSION = 2  # GeoFenceController::_jsonCurrentVersion
MISSION_VERSION = 2  # MissionController::_missionFileVersion
RALLY_VERSION = 2  # RallyPointController::_jsonCurrentVersion
NAV_WAYPOINT = mavlink.MAV_CMD_NAV_WAYPOINT
NAV_TAKEOFF = mavlink.MAV_CMD_NAV_TAKEOFF
NAV_LAND = mavlink.MAV_CMD_NAV_LAND
NAV_RTL = mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH
# altitude frames of a position item: above home (alt) or above mean sea level (amsl)
RELATIVE_FRAMES = (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
AMSL_FRAMES = (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_INT)


def read_plan(text: str, source: str) -> Site:
    """The site of a .plan file's text; SiteError "source: where: what is wrong" on any mistake."""
    plan = json_mapping(text, source)
    if plan.get("fileType") != "Plan":
        raise SiteError(f'{source}: fileType: expected "Plan", got {describe(plan.get("fileType"))}')
    _version(plan, PLAN_VERSION, source)
    home = _home(plan, source)
    areas, circles = _fence(plan.get("geoFence"), f"{source}: geoFence")
    waypoints, takeoff_alt = _route(plan.get("mission"), home, f"{source}: mission")
    rally = _rally(plan.get("rallyPoints"), f"{source}: rallyPoints")
    return Site(source, home, areas, circles, waypoints, rally, takeoff_alt)


def _version(section: Mapping[str, object], expected: int, where: str, also: tuple[int, ...] = ()) -> None:
    version = section.get("version")
    if version not in (expected, *also) or isinstance(version, bool):
        raise SiteError(
            f"{where}: version {describe(version)} is not supported (QGroundControl writes {expected})"
        )


def _home(plan: Mapping[str, object], source: str) -> SitePoint | None:
    mission = plan.get("mission")
    if not isinstance(mission, Mapping) or mission.get("plannedHomePosition") is None:
        return None
    where = f"{source}: mission.plannedHomePosition"
    values = sequence(mission["plannedHomePosition"], where)
    if len(values) != 3:
        raise SiteError(f"{where}: expected [lat, lon, alt], got {describe(values)}")
    lat, lon = lat_lon(values[0], values[1], where)
    return SitePoint(where, lat, lon, amsl=number(values[2], f"{where}: altitude"))


def _fence(value: object, where: str) -> tuple[tuple[Area, ...], tuple[Circle, ...]]:
    if value is None:
        return (), ()
    fence = mapping(value, where)
    _version(fence, GEOFENCE_VERSION, where)
    areas: list[Area] = []
    for k, entry in enumerate(sequence(fence.get("polygons", []), f"{where}.polygons")):
        at = f"{where}.polygons[{k}]"
        polygon = mapping(entry, at)
        inclusion = _flag(polygon.get("inclusion"), f"{at}.inclusion")
        vertices = [
            _lat_lon_pair(vertex, f"{at}.polygon[{i}]")
            for i, vertex in enumerate(sequence(polygon.get("polygon"), f"{at}.polygon"))
        ]
        kind = "inclusion" if inclusion else "exclusion"
        if inclusion and any(area.kind == "inclusion" for area in areas):
            raise SiteError(f"{at}: a second inclusion polygon; the mission has one fence polygon")
        areas.append(Area(at, kind, simple_polygon(vertices, at)))
    circles: list[Circle] = []
    for k, entry in enumerate(sequence(fence.get("circles", []), f"{where}.circles")):
        at = f"{where}.circles[{k}]"
        circle = mapping(entry, at)
        if _flag(circle.get("inclusion"), f"{at}.inclusion"):
            raise SiteError(f"{at}: inclusion circles are not supported; draw the fence as a polygon")
        shape = mapping(circle.get("circle"), f"{at}.circle")
        center = _lat_lon_pair(shape.get("center"), f"{at}.circle.center")
        radius = number(shape.get("radius"), f"{at}.circle.radius")
        if radius <= 0.0:
            raise SiteError(f"{at}.circle.radius: must be > 0 m, got {radius:g}")
        circles.append(Circle(at, "exclusion", center, radius))
    return tuple(areas), tuple(circles)


def _flag(value: object, where: str) -> bool:
    if not isinstance(value, bool):
        raise SiteError(f"{where}: expected true or false, got {describe(value)}")
    return value


def _lat_lon_pair(value: object, where: str) -> tuple[float, float]:
    values = sequence(value, where)
    if len(values) not in (2, 3):
        raise SiteError(f"{where}: expected [lat, lon], got {describe(values)}")
    return lat_lon(values[0], values[1], where)


def _route(value: object, home: SitePoint | None, where: str) -> tuple[tuple[SitePoint, ...], float | None]:
    """The waypoints and the take-off altitude (m above home) of the mission items."""
    if value is None:
        return (), None
    mission = mapping(value, where)
    _version(mission, MISSION_VERSION, where)
    items = sequence(mission.get("items", []), f"{where}.items")
    route: list[SitePoint] = []
    takeoff_alt: float | None = None
    for k, entry in enumerate(items):
        at = f"{where}.items[{k}]"
        item = mapping(entry, at)
        if item.get("type") != "SimpleItem":
            kind = item.get("complexItemType", item.get("type"))
            raise SiteError(f"{at}: {describe(kind)} items are not supported (only simple mission items)")
        command = item.get("command")
        last = k == len(items) - 1
        if command == NAV_WAYPOINT:
            point = _item_position(item, home, at)
            hold = number(_params(item, at)[0] or 0.0, f"{at}.params[0] (hold time)")
            if hold != 0.0:
                raise SiteError(f"{at}: a hold time ({hold:g} s) at a waypoint is not supported")
            route.append(point)
        elif command == NAV_TAKEOFF:
            if takeoff_alt is not None or route:
                raise SiteError(f"{at}: a take-off after the first take-off or waypoint is not supported")
            takeoff_alt = _item_position(item, home, at).alt
        elif command == NAV_LAND and last:
            lat, lon = (number(x, f"{at}.params") for x in _params(item, at)[4:6])
            if (lat, lon) != (0.0, 0.0):  # 0, 0: land where it is
                route.append(SitePoint(at, *lat_lon(lat, lon, at), alt=_last_alt(route, takeoff_alt, at)))
        elif command == NAV_RTL and last:
            if home is None:
                raise SiteError(f"{at}: return to launch needs mission.plannedHomePosition")
            route.append(SitePoint(at, home.lat, home.lon, alt=_last_alt(route, takeoff_alt, at)))
        else:
            raise SiteError(f"{at}: {_command_name(command)} is not supported here{_supported()}")
    return tuple(route), takeoff_alt


def _params(item: Mapping[str, object], where: str) -> list[object]:
    params = list(sequence(item.get("params"), f"{where}.params"))
    if len(params) != 7:
        raise SiteError(f"{where}.params: expected 7 values, got {len(params)}")
    return params


def _item_position(item: Mapping[str, object], home: SitePoint | None, where: str) -> SitePoint:
    """params[4..6] in the item's frame as a point with its altitude above home."""
    params = _params(item, where)
    lat, lon = lat_lon(params[4], params[5], f"{where}.params")
    altitude = number(params[6], f"{where}.params[6] (altitude)")
    frame = item.get("frame")
    if frame in RELATIVE_FRAMES and not isinstance(frame, bool):
        return SitePoint(where, lat, lon, alt=altitude)
    if frame in AMSL_FRAMES and not isinstance(frame, bool):
        if home is None or home.amsl is None:
            raise SiteError(f"{where}: an altitude above mean sea level needs mission.plannedHomePosition")
        return SitePoint(where, lat, lon, alt=altitude - home.amsl)
    raise SiteError(
        f"{where}.frame: {describe(frame)} is not supported (3: above home, 0: above mean sea level; "
        "terrain-following frames are not)"
    )


def _last_alt(route: list[SitePoint], takeoff_alt: float | None, where: str) -> float:
    """The altitude (above home) the route ends at before landing: the last waypoint's, else the
    take-off's."""
    if route:
        return float(route[-1].alt)  # type: ignore[arg-type]
    if takeoff_alt is not None:
        return takeoff_alt
    raise SiteError(f"{where}: a landing with no waypoint or take-off before it")


def _command_name(command: object) -> str:
    if isinstance(command, int) and not isinstance(command, bool):
        entry = mavlink.enums["MAV_CMD"].get(command)
        return f"command {command}" + (f" ({entry.name})" if entry is not None else "")
    return f"command {describe(command)}"


def _supported() -> str:
    return (
        " (supported: NAV_WAYPOINT 16, NAV_TAKEOFF 22, and as the last item NAV_LAND 21 or "
        "NAV_RETURN_TO_LAUNCH 20)"
    )


def _rally(value: object, where: str) -> tuple[SitePoint, ...]:
    if value is None:
        return ()
    rally = mapping(value, where)
    points = sequence(rally.get("points", []), f"{where}.points")
    _version(rally, RALLY_VERSION, where, also=(1,) if not points else ())
    out = []
    for k, entry in enumerate(points):
        at = f"{where}.points[{k}]"
        values = sequence(entry, at)
        if len(values) != 3:
            raise SiteError(f"{at}: expected [lat, lon, alt], got {describe(values)}")
        lat, lon = lat_lon(values[0], values[1], at)
        out.append(SitePoint(at, lat, lon, alt=number(values[2], f"{at}: altitude")))
    return tuple(out)
