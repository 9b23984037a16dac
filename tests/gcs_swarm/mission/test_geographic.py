"""Missions in latitude/longitude (issue 37 item 1), fences as data (item 2's data side), and the refusal to
fly legs too near the fence.

Expected values are reasoned independently of the loader: a geographic mission is written from an ENU one with
pymap3d.enu2geodetic (the inverse the loader does not use), and distances on the ellipsoid come from the
meridian and prime-vertical radii of curvature written out below.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest
import yaml

from gcs_swarm.mission import MissionError, load_mission, parse_mission
from gcs_swarm.mission.schema import DEFAULT_ORIGIN

ROOT = Path(__file__).resolve().parents[3]
ORIGIN = (-35.363261, 149.165230, 584.0)
WGS84_A, WGS84_F = 6378137.0, 1 / 298.257223563


def geo(point: list[float], origin: tuple[float, float, float] = ORIGIN, ground: bool = False) -> dict:
    """[x, y, z] m ENU about `origin` as {lat, lon, amsl} (pymap3d's inverse); `ground`: {lat, lon}."""
    lat, lon, h = pymap3d.enu2geodetic(*point, *origin)
    if ground:
        return {"lat": float(lat), "lon": float(lon)}
    return {"lat": float(lat), "lon": float(lon), "amsl": float(h)}


def as_geographic(document: dict) -> dict:
    """The quickstart-like document with every position written in latitude/longitude."""
    out = yaml.safe_load(yaml.safe_dump(document))
    for vehicle in out["vehicles"]:
        vehicle["start"]["position"] = geo(vehicle["start"]["position"], ground=True)
        if vehicle.get("target") is not None:
            vehicle["target"] = geo(vehicle["target"])
    if "goal" in out:
        out["goal"] = geo(out["goal"])
    for obstacle in out["world"]["obstacles"]:
        obstacle["center"] = geo(obstacle["center"])
    return out


def test_a_mission_in_latitude_longitude_loads_as_the_same_mission_in_enu_within_1_cm() -> None:
    document = yaml.safe_load((ROOT / "missions" / "quickstart.yaml").read_text())
    enu = parse_mission(yaml.safe_dump(document), "enu.yaml")
    flown = parse_mission(yaml.safe_dump(as_geographic(document)), "geo.yaml")
    assert flown.origin == enu.origin == ORIGIN
    pairs = [(enu.goal, flown.goal)]
    pairs += [(a.start.position, b.start.position) for a, b in zip(enu.vehicles, flown.vehicles, strict=True)]
    pairs += [(a.center, b.center) for a, b in zip(enu.obstacles, flown.obstacles, strict=True)]
    for a, b in pairs:
        np.testing.assert_allclose(a, b, atol=0.01)
    # a ground start written without a height stands exactly on the ground
    assert all(v.start.position[2] == 0.0 for v in flown.vehicles)


def test_alt_is_height_above_the_origin_and_amsl_above_sea_level() -> None:
    # at the origin's own latitude/longitude the ENU offset is straight up: alt 10 and amsl 594 (584 + 10)
    text = """
origin: {lat: -35.363261, lon: 149.165230, alt: 584}
vehicles: [{role: leader, start: {position: [0, 0, 0]}}]
waypoints: [{lat: -35.363261, lon: 149.165230, alt: 10}, {lat: -35.363261, lon: 149.165230, amsl: 594}]
"""
    mission = parse_mission(text)
    for point in mission.waypoints:
        np.testing.assert_allclose(point, [0.0, 0.0, 10.0], atol=1e-6)


def test_north_and_east_offsets_match_the_radii_of_curvature() -> None:
    # 0.001 deg north and east of the origin: north = M dphi, east = N cos(phi) dlambda, with the meridian
    # radius M = a (1 - e^2) / (1 - e^2 sin^2 phi)^1.5 and prime vertical N = a / sqrt(1 - e^2 sin^2 phi);
    # over ~100 m the tangent plane departs from these arcs by well under a millimetre
    lat0, lon0, _ = ORIGIN
    e2 = WGS84_F * (2 - WGS84_F)
    s2 = math.sin(math.radians(lat0)) ** 2
    meridian = WGS84_A * (1 - e2) / (1 - e2 * s2) ** 1.5
    normal = WGS84_A / math.sqrt(1 - e2 * s2)
    # the mid-latitude of the step for the east arc (its latitude is lat0 + 0.001)
    north = meridian * math.radians(0.001)
    east = normal * math.cos(math.radians(lat0 + 0.001)) * math.radians(0.001)
    text = f"""
origin: {{lat: {lat0}, lon: {lon0}, alt: 584}}
vehicles: [{{role: leader, start: {{position: [0, 0, 0]}}}}]
goal: {{lat: {lat0 + 0.001}, lon: {lon0 + 0.001}, alt: 10}}
"""
    goal = parse_mission(text).goal
    assert goal[0] == pytest.approx(east, abs=0.01)
    assert goal[1] == pytest.approx(north, abs=0.01)


def _origin_of(text: str) -> tuple[float, float, float]:
    return parse_mission(text, to_fly=False).origin


def test_the_origin_is_implied_by_the_fence_then_the_first_start_then_the_first_waypoint() -> None:
    home = "{lat: -35.0, lon: 149.0, amsl: 577}"
    fence = "[{lat: -35.001, lon: 148.999}, {lat: -35.001, lon: 149.001}, {lat: -34.999, lon: 149.0}]"
    route = "waypoints: [{lat: -35.0, lon: 149.0002, alt: 20}]"
    fenced = "vehicles: [{role: leader, start: {position: {lat: -35.0, lon: 149.0}}}]\n"
    fenced += f"{route}\nsafety: {{geofence: {{polygon: {fence}}}}}\n"
    assert _origin_of(fenced) == (-35.001, 148.999, 0.0)  # the fence's first vertex, 0 m AMSL
    started = f"vehicles: [{{role: leader, start: {{position: {home}}}}}]\n{route}\n"
    assert _origin_of(started) == (-35.0, 149.0, 577.0)  # the first vehicle's start, its amsl the origin's
    routed = f"vehicles: [{{role: leader, start: {{position: [0, 0, 0]}}}}]\n{route}\n"
    assert _origin_of(routed) == (-35.0, 149.0002, 0.0)  # the first waypoint, at 0 m AMSL
    plain = "vehicles: [{role: leader, start: {position: [0, 0, 0]}}]\ngoal: [10, 0, 10]\n"
    assert _origin_of(plain) == DEFAULT_ORIGIN  # no geographic position: CMAC as before


def test_a_geographic_position_the_origin_cannot_be_taken_from_needs_an_origin() -> None:
    text = """vehicles: [{role: leader, start: {position: [0, 0, 0]}}]
goal: [10, 0, 10]
world:
  obstacles: [{center: {lat: -35.0, lon: 149.0, alt: 10}, radius: 2}]
"""
    with pytest.raises(MissionError, match=r"<string>:4: world.obstacles\[0\].center: .*needs an origin"):
        parse_mission(text)


@pytest.mark.parametrize(
    ("goal", "message"),
    [
        ("{lat: -35.36, lon: 149.16}", r"<string>:3: goal: give the height: alt .* or amsl"),
        ("{lat: -35.36, lon: 149.16, alt: 10, amsl: 600}", r"goal.amsl: give alt .* or amsl .* not both"),
        ("{lat: -95, lon: 149.16, alt: 10}", r"goal.lat: must be >= -90 deg, got -95"),
        ("{lat: -35.36, lon: 149.16, alt: 10, height: 3}", r"goal.height: unknown key"),
        ("[1, 2]", r"goal: expected 3 numbers, got 2"),
    ],
)
def test_a_bad_geographic_position_is_one_clear_error(goal: str, message: str) -> None:
    text = "origin: {lat: -35.363261, lon: 149.165230}\n"
    text += f"vehicles: [{{role: leader, start: {{position: [0, 0, 0]}}}}]\ngoal: {goal}\n"
    with pytest.raises(MissionError, match=message):
        parse_mission(text)


SITE = """
vehicles:
  - {role: leader, start: {position: [0, 0, 0]}}
  - {start: {position: [-5, 0, 0]}}
goal: [40, 0, 10]
safety:
  geofence:
    polygon: [[-20, -20], [60, -20], [60, 20], [-20, 20]]
    exclusions:
      - {name: pond, center: [20, 15], radius: 3}
      - {polygon: [[20, -20], [30, -20], [30, -10]]}
world:
  prisms: [{name: hangar, polygon: [[10, 5], [15, 5], [15, 10], [10, 10]], top: 8}]
  cylinders: [{name: mast, center: [30, 10], radius: 0.5, top: 20}]
"""


def test_fences_prisms_and_cylinders_are_carried_in_enu() -> None:
    mission = parse_mission(SITE, to_fly=False)
    np.testing.assert_array_equal(mission.fence.polygon, [[-20, -20], [60, -20], [60, 20], [-20, 20]])
    pond, triangle = mission.fence.exclusions
    assert (pond.name, pond.radius) == ("pond", 3.0)
    np.testing.assert_array_equal(pond.center, [20, 15])
    assert triangle.name == "safety.geofence.exclusions[1]" and triangle.center is None
    (hangar,) = mission.prisms
    assert (hangar.name, hangar.bottom, hangar.top) == ("hangar", 0.0, 8.0)
    (mast,) = mission.cylinders
    assert (mast.name, mast.radius, mast.top) == ("mast", 0.5, 20.0)
    # prisms and cylinders are flown (spec 2.2): loading it to fly stops at the pond (too near the goal's leg,
    # line 5 of SITE, whose line 1 is empty)
    with pytest.raises(MissionError, match=r"<string>:5: goal: .*exclusion zone 'pond'"):
        parse_mission(SITE)


def test_a_fence_too_near_the_route_is_refused_for_flight_with_one_error() -> None:
    # the fence is flown (issue 37 item 5) if the formation keeps clear of it: the pond (centre (20, 15),
    # radius 3) is 15 - 3 = 12 m from the leg along y = 0, the formation needs its widest slot 10 m (default
    # spacing) + the vehicle radius 0.175 m + the braking margin 10^2 / (2 * 9.8 * tan 35 deg) = 7.29 m
    text = SITE.split("world:")[0]
    message = r"<string>:5: goal: the leg from the leader's start to the goal comes within 12.00 m of .*pond"
    with pytest.raises(MissionError, match=message + r".* needs 17.46 m"):
        parse_mission(text)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("[-5, 0, 0]", "[-25, 0, 0]", r"vehicles\[1\].start.position: .*not inside the fence polygon"),
        ("goal: [40, 0, 10]", "goal: [20, 14, 10]", r"goal: the goal lies in exclusion zone 'pond'"),
        ("goal: [40, 0, 10]", "goal: [12, 7, 5]", r"goal: the goal lies inside prism 'hangar'"),
        ("goal: [40, 0, 10]", "goal: [30, 10.3, 10]", r"goal: the goal lies inside cylinder 'mast'"),
        ("[60, 20], [-20, 20]]", "[-20, 20], [60, 20]]", r"safety.geofence.polygon: not a simple polygon"),
        ("top: 8}", "bottom: 9, top: 8}", r"world.prisms\[0\].top: must be above bottom \(9 m\)"),
        ("center: [20, 15], radius: 3}", "center: [20, 15]}", r"exclusions\[0\].radius: 'radius' is missing"),
        ("[[20, -20], [30, -20], [30, -10]]", "[[20, -20], [30, -20]]", r"at least 3 distinct vertices"),
    ],
)
def test_a_bad_site_is_one_clear_error(old: str, new: str, message: str) -> None:
    assert old in SITE
    with pytest.raises(MissionError, match=message):
        parse_mission(SITE.replace(old, new, 1), to_fly=False)


def test_world_import_merges_a_qgroundcontrol_plan_relative_to_the_mission(tmp_path: Path) -> None:
    plan = ROOT / "tests" / "data" / "site" / "qgc_simple_square.plan"
    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "square.plan").write_bytes(plan.read_bytes())
    mission_path = tmp_path / "m.yaml"
    mission_path.write_text(
        "vehicles:\n  - {role: leader, start: {position: [0, 0, 0]}}\n  - {start: {position: [-3, 0, 0]}}\n"
        "world:\n  import: [site/square.plan]\n"
    )
    mission = load_mission(mission_path)
    # the plan's home is the origin, its take-off altitude the formation's, its four waypoints the route
    assert mission.origin == (47.397742, 8.545594, 488.0)
    assert mission.formation.altitude == 20.0
    assert len(mission.waypoints) == 4
    # first waypoint: +0.001 deg in latitude and longitude from home (the radii as in the test above)
    lat0 = math.radians(47.397742)
    e2 = WGS84_F * (2 - WGS84_F)
    meridian = WGS84_A * (1 - e2) / (1 - e2 * math.sin(lat0) ** 2) ** 1.5
    normal = WGS84_A / math.sqrt(1 - e2 * math.sin(lat0) ** 2)
    east = normal * math.cos(math.radians(47.398742)) * math.radians(0.001)
    np.testing.assert_allclose(mission.waypoints[0][:2], [east, meridian * math.radians(0.001)], atol=0.01)
    assert mission.waypoints[0][2] == pytest.approx(20.0, abs=0.01)  # alt 20 m above home, less the drop


def test_world_import_names_the_file_and_feature_of_a_mistake(tmp_path: Path) -> None:
    (tmp_path / "bad.plan").write_text(
        '{"fileType": "Plan", "version": 1, "geoFence": {"version": 2, '
        '"polygons": [{"inclusion": true, "polygon": [[1, 2], [3, 4]]}]}}'
    )
    mission_path = tmp_path / "m.yaml"
    mission_path.write_text(
        "vehicles: [{role: leader, start: {position: [0, 0, 0]}}]\ngoal: [5, 0, 10]\n"
        "world:\n  import:\n    - bad.plan\n"
    )
    with pytest.raises(
        MissionError,
        match=r"m.yaml:5: world.import\[0\]: bad.plan: geoFence.polygons\[0\]: "
        r"a polygon needs at least 3 distinct vertices",
    ):
        load_mission(mission_path)


def test_a_route_given_by_the_mission_and_an_import_is_refused(tmp_path: Path) -> None:
    plan = ROOT / "tests" / "data" / "site" / "qgc_simple_square.plan"
    mission_path = tmp_path / "m.yaml"
    mission_path.write_text(
        "vehicles: [{role: leader, start: {position: [0, 0, 0]}}]\ngoal: [5, 0, 10]\n"
        f"world:\n  import: [{plan}]\n"
    )
    with pytest.raises(MissionError, match=r"waypoints: is given here and by world.import"):
        load_mission(mission_path)
