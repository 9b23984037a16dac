"""`gcs-swarm import FILE... --out mission.yaml`: site files (QGroundControl .plan, GeoJSON, KML) -> a mission
file (docs/site.md). The fence, exclusion zones, buildings, trees, route and rally points are written in
latitude/longitude about the files' home (else a point inside the fence, else the first waypoint); a fleet of
`vehicles` stands in a row west of the origin on the ground. The written file is then loaded as the ground
station will load it, and what is wrong or not yet flyable is said.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from shapely.geometry import Polygon

from gcs_swarm.mission import MissionError, load_mission
from gcs_swarm.mission.checks import flight_refusal
from gcs_swarm.mission.yaml_tree import parse_yaml
from gcs_swarm.site import Site, SiteError, merge_sites, mission_fragment, read_site

EXIT_USER_ERROR = 2
DEFAULT_ALTITUDE_M = 10.0  # the formation altitude when no file gives a take-off altitude (the schema's)


def import_command(files: list[str], out: str, vehicles: int, spacing: float) -> int:
    """Read `files`, write the mission to `out`, load it back; 0 when it loads (a note when it may not fly
    yet), 2 on a mistake in the files or in the written mission."""
    try:
        site = merge_sites([read_site(path) for path in files])
    except SiteError as exc:
        print(f"error: {exc}")
        return EXIT_USER_ERROR
    document = site_mission(site, Path(out).stem, vehicles, spacing)
    text = f"# written by `gcs-swarm import {' '.join(files)}` (docs/site.md)\n" + yaml.safe_dump(
        document, sort_keys=False, default_flow_style=None, width=110
    )
    Path(out).write_text(text)
    try:
        mission = load_mission(out, to_fly=False)
    except MissionError as exc:
        print(f"wrote {out}, but it does not load: {exc}")
        return EXIT_USER_ERROR
    fence = "yes" if mission.fence.polygon is not None else "no"
    print(
        f"wrote {out}: {len(mission.waypoints)} waypoints, fence polygon {fence}, "
        f"{len(mission.fence.exclusions)} exclusion zones, {len(mission.prisms)} prisms, "
        f"{len(mission.cylinders)} cylinders, {len(mission.rally)} rally points, "
        f"{len(mission.vehicles)} vehicles"
    )
    refusal = flight_refusal(mission, parse_yaml(text, out))
    if refusal is not None:
        print(f"note: it cannot be flown yet: {refusal}")
    if not site.waypoints:
        print("note: the files give no route; the goal is above the leader's start: edit it")
    return 0


def site_mission(site: Site, name: str, vehicles: int, spacing: float) -> dict[str, Any]:
    """The mission file's data for `site` with a fleet of `vehicles` (leader first) `spacing` m apart."""
    fragment = mission_fragment(site)
    origin = fragment.pop("origin", None) or _origin(site)
    altitude = fragment.pop("formation", {}).get("altitude", DEFAULT_ALTITUDE_M)
    document: dict[str, Any] = {
        "mission": {"name": _name(name), "description": f"imported from {site.source}"},
        "origin": origin,
        "vehicles": [
            {"role": "leader" if i == 0 else "follower", "start": {"position": [0.0 - spacing * i, 0.0, 0.0]}}
            for i in range(vehicles)
        ],
        "formation": {"altitude": altitude},
    }
    if "waypoints" not in fragment:
        document["goal"] = [0.0, 0.0, altitude]
    document.update(fragment)
    return document


def _origin(site: Site) -> dict[str, float]:
    """Without a home: a point inside the inclusion fence (shapely's point_on_surface, in degrees), else the
    first waypoint, else the first shape's first vertex or centre; at 0 m above mean sea level."""
    if site.fence is not None:
        point = Polygon([(lon, lat) for lat, lon in site.fence.vertices]).point_on_surface()
        return {"lat": point.y, "lon": point.x, "alt": 0.0}
    if site.waypoints:
        return {"lat": site.waypoints[0].lat, "lon": site.waypoints[0].lon, "alt": 0.0}
    first = [area.vertices[0] for area in site.areas] + [circle.center for circle in site.circles]
    if not first:
        return {"lat": 0.0, "lon": 0.0, "alt": 0.0}
    return {"lat": first[0][0], "lon": first[0][1], "alt": 0.0}


def _name(stem: str) -> str:
    """A mission name from the output file's stem (NAME_PATTERN)."""
    cleaned = "".join(c if c.isalnum() or c in "_.-" else "_" for c in stem)[:64].lstrip("_.-")
    return cleaned or "imported"
