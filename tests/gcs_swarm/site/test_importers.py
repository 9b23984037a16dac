"""Importers (issue 37 item 3) on real files written by QGroundControl and Google Earth
(tests/data/site/README.md), the `gcs-swarm import` command, and one clear error naming file and feature
for each kind of mistake.

Expected vertices are read from the files with `json` / by eye, not through the importers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pymap3d
import pytest

from gcs_swarm.cli import main
from gcs_swarm.mission import load_mission
from gcs_swarm.site import SiteError, merge_sites, read_site
from gcs_swarm.site.geojson import read_geojson
from gcs_swarm.site.qgc_plan import read_plan

DATA = Path(__file__).resolve().parents[2] / "data" / "site"
CM_IN_DEG = 0.01 / 111_000.0  # 1 cm of latitude (and at most that of longitude) in degrees


def test_a_qgroundcontrol_plan_imports_to_the_fence_qgroundcontrol_shows(tmp_path: Path) -> None:
    plan_path = DATA / "qgc_geofence_home_base.plan"
    written = json.loads(plan_path.read_text())["geoFence"]["polygons"]
    mission_path = tmp_path / "m.yaml"
    mission_path.write_text(
        f"vehicles: [{{role: leader, start: {{position: [0, 0, 0]}}}}]\ngoal: [0, 0, 5]\n"
        f"world: {{import: [{plan_path}]}}\n"
    )
    mission = load_mission(mission_path, to_fly=False)
    # the plan's home is the origin: plannedHomePosition [lat, lon, alt AMSL]
    assert mission.origin == (38.75084010396389, -77.49721463637287, 30.0)
    fence = mission.fence.polygon
    (exclusion,) = mission.fence.exclusions
    assert fence is not None and exclusion.polygon is not None
    for enu, polygon in ((fence, written[0]), (exclusion.polygon, written[1])):
        lat, lon, _ = pymap3d.enu2geodetic(enu[:, 0], enu[:, 1], np.zeros(len(enu)), *mission.origin)
        np.testing.assert_allclose(np.column_stack([lat, lon]), polygon["polygon"], rtol=0, atol=CM_IN_DEG)
    assert written[0]["inclusion"] is True and written[1]["inclusion"] is False
    assert "geoFence.polygons[1]" in exclusion.name


def test_a_qgroundcontrol_mission_gives_take_off_altitude_and_route() -> None:
    site = read_site(DATA / "qgc_simple_square.plan")
    assert site.home is not None and (site.home.lat, site.home.lon, site.home.amsl) == (
        47.397742,
        8.545594,
        488,
    )
    assert site.takeoff_alt == 20
    # items 1..4 are NAV_WAYPOINT (16) in frame 3 (above home) at 20 m
    expected = [(47.398742, 8.546594), (47.398742, 8.544594), (47.396742, 8.544594), (47.396742, 8.546594)]
    assert [(p.lat, p.lon, p.alt) for p in site.waypoints] == [(*ll, 20) for ll in expected]


def test_a_plan_with_a_camera_item_is_refused_naming_the_item_and_command() -> None:
    with pytest.raises(
        SiteError,
        match=r"mavsdk_qgroundcontrol_sample.plan: mission.items\[2\]: command 2000 "
        r"\(MAV_CMD_IMAGE_START_CAPTURE\) is not supported",
    ):
        read_site(DATA / "mavsdk_qgroundcontrol_sample.plan")


def test_a_google_earth_kml_polygon_is_the_inclusion_fence() -> None:
    site = read_site(DATA / "qgc_polygon_good.kml")
    assert site.fence is not None and "Untitled Polygon" in site.fence.name
    # the file's ring, [lon, lat, 0], closed: the importer keeps the four distinct vertices as (lat, lon)
    assert site.fence.vertices == (
        (47.65965281788451, -122.1059149362712),
        (47.66002598220988, -122.1044593196253),
        (47.66034166158975, -122.1047336695092),
        (47.6599810708829, -122.1061470943783),
    )


def test_geojson_buildings_trees_exclusions_and_route() -> None:
    site = read_site(DATA / "cmac_buildings.geojson")
    (hangar,) = [a for a in site.areas if a.kind == "prism"]
    assert (hangar.bottom, hangar.top, len(hangar.vertices)) == (0.0, 9.5, 4)
    trees = [c for c in site.circles if c.kind == "cylinder"]
    assert [(c.center, c.radius, c.top) for c in trees] == [
        ((-35.3635, 149.1660), 2.5, 12.0),
        ((-35.3635, 149.1662), 2.5, 12.0),
    ]
    (pond,) = [c for c in site.circles if c.kind == "exclusion"]
    assert (pond.center, pond.radius) == ((-35.3625, 149.1645), 15.0)
    assert [(p.lat, p.lon, p.alt) for p in site.waypoints] == [
        (-35.3631, 149.1654, 15),
        (-35.3624, 149.1664, 15),
    ]


def test_gcs_swarm_import_writes_a_mission_that_loads(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "square.yaml"
    assert main(["import", str(DATA / "qgc_simple_square.plan"), "--out", str(out), "--vehicles", "2"]) == 0
    assert "4 waypoints" in capsys.readouterr().out
    mission = load_mission(out)
    assert len(mission.vehicles) == 2 and mission.formation.altitude == 20.0
    assert mission.origin == (47.397742, 8.545594, 488.0)


def test_gcs_swarm_import_of_buildings_gives_a_mission_that_flies(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "cmac.yaml"
    files = [str(DATA / "cmac_buildings.geojson")]
    assert main(["import", *files, "--out", str(out), "--vehicles", "1"]) == 0
    printed = capsys.readouterr().out
    assert "1 prisms, 2 cylinders" in printed and "cannot be flown yet" not in printed
    mission = load_mission(out)  # prisms and cylinders are flown (spec 2.2)
    assert len(mission.prisms) == 1 and len(mission.cylinders) == 2
    assert main(["check", str(out)]) == 0
    checked = capsys.readouterr().out
    assert ": ok: mission 'cmac'" in checked and "cannot be flown yet" not in checked


def test_gcs_swarm_import_of_a_bad_file_is_one_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "x.geojson"
    bad.write_text(
        '{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {"name": "shed",'
        ' "height": "tall"}, "geometry": {"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1]]]}}]}'
    )
    assert main(["import", str(bad), "--out", str(tmp_path / "m.yaml")]) == 2
    assert capsys.readouterr().out.strip() == (
        f"error: {bad}: feature 0 ('shed'): height: expected a number, got 'tall'"
    )


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", r"p.plan: not JSON: line 1 column 2"),
        ('{"fileType": "Mission"}', r'fileType: expected "Plan"'),
        (
            '{"fileType": "Plan", "version": 2}',
            r"p.plan: version 2 is not supported \(QGroundControl writes 1\)",
        ),
        (
            '{"fileType": "Plan", "version": 1, "geoFence": {"version": 1}}',
            r"geoFence: version 1 is not supported",
        ),
        (
            '{"fileType": "Plan", "version": 1, "geoFence": {"version": 2, "circles": [{"inclusion": true, '
            '"circle": {"center": [1, 2], "radius": 5}}]}}',
            r"geoFence.circles\[0\]: inclusion circles are not supported",
        ),
        (
            '{"fileType": "Plan", "version": 1, "geoFence": {"version": 2, "polygons": [{"inclusion": false, '
            '"polygon": [[0, 0], [1, 1], [0, 1], [1, 0]]}]}}',
            r"geoFence.polygons\[0\]: not a simple polygon \(Self-intersection",
        ),
        (
            '{"fileType": "Plan", "version": 1, "mission": {"version": 2, "items": [{"type": "ComplexItem", '
            '"complexItemType": "survey"}]}}',
            r"mission.items\[0\]: 'survey' items are not supported",
        ),
        (
            '{"fileType": "Plan", "version": 1, "mission": {"version": 2, "items": [{"type": "SimpleItem", '
            '"command": 16, "frame": 10, "params": [0, 0, 0, null, 1, 2, 30]}]}}',
            r"mission.items\[0\].frame: 10 is not supported",
        ),
        (
            '{"fileType": "Plan", "version": 1, "rallyPoints": {"version": 2, "points": [[91, 0, 10]]}}',
            r"rallyPoints.points\[0\]: latitude 91 is outside -90..90 deg",
        ),
    ],
)
def test_a_bad_plan_is_one_clear_error(text: str, message: str) -> None:
    with pytest.raises(SiteError, match=message):
        read_plan(text, "p.plan")


@pytest.mark.parametrize(
    ("feature", "message"),
    [
        (
            '{"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 0]], [[0.1, 0.1], [0.2, 0.1], '
            "[0.2, 0.2], [0.1, 0.1]]]}",
            r"g.geojson: feature 0: a polygon with 1 hole\(s\) is not supported",
        ),
        ('{"type": "Point", "coordinates": [149, -35]}', r"feature 0: a waypoint needs a height"),
        (
            '{"type": "GeometryCollection", "geometries": []}',
            r"geometry 'GeometryCollection' is not supported",
        ),
        ('{"type": "Point", "coordinates": [200, -35, 5]}', r"feature 0: longitude 200 is outside"),
    ],
)
def test_a_bad_geojson_feature_is_one_clear_error(feature: str, message: str) -> None:
    text = f'{{"type": "Feature", "properties": null, "geometry": {feature}}}'
    with pytest.raises(SiteError, match=message):
        read_geojson(text, "g.geojson")


def test_two_files_may_not_both_give_the_fence() -> None:
    site = read_site(DATA / "qgc_polygon_good.kml")
    with pytest.raises(SiteError, match=r"gives the inclusion fence, and so does"):
        merge_sites([site, site])
