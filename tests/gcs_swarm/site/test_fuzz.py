"""Every input gives a site (or mission) or one clear error, never another exception (issue 37): hypothesis
mutates the real files of tests/data/site and the mission's new keys."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_swarm.mission import MissionError, parse_mission
from gcs_swarm.site import Site, SiteError
from gcs_swarm.site.geojson import read_geojson
from gcs_swarm.site.kml import read_kml
from gcs_swarm.site.qgc_plan import read_plan

DATA = Path(__file__).resolve().parents[2] / "data" / "site"
PLANS = [
    json.loads((DATA / name).read_text())
    for name in ("qgc_geofence_home_base.plan", "qgc_simple_square.plan")
]
GEOJSON = json.loads((DATA / "cmac_buildings.geojson").read_text())
KML = (DATA / "qgc_polygon_good.kml").read_text()

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**30), max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.sampled_from(
        ["Plan", "Feature", "Polygon", "Point", "LineString", "SimpleItem", "inclusion", "exclusion"]
    ),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=5),
        st.dictionaries(st.sampled_from(["lat", "lon", "type", "x", "version"]), inner),
    ),
    max_leaves=12,
)
FAST = settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])


def mutate(data: Any, draw: Any) -> Any:
    """`data` with one value somewhere in it replaced by a drawn one (or a key dropped)."""
    if isinstance(data, dict) and data and draw(st.booleans()):
        key = draw(st.sampled_from(sorted(data)))
        out = dict(data)
        if draw(st.integers(0, 4)) == 0:
            del out[key]
        else:
            out[key] = mutate(data[key], draw)
        return out
    if isinstance(data, list) and data and draw(st.booleans()):
        k = draw(st.integers(0, len(data) - 1))
        return [*data[:k], mutate(data[k], draw), *data[k + 1 :]]
    return draw(values)


def site_or_error(read: Any, text: str, source: str) -> None:
    try:
        assert isinstance(read(text, source), Site)
    except SiteError as exc:
        assert str(exc).startswith(source) and "\n" not in str(exc)


@FAST
@given(st.data())
def test_a_mutated_plan_gives_a_site_or_one_error(data: st.DataObject) -> None:
    plan = mutate(data.draw(st.sampled_from(PLANS)), data.draw)
    site_or_error(read_plan, json.dumps(plan), "p.plan")


@FAST
@given(st.data())
def test_a_mutated_geojson_gives_a_site_or_one_error(data: st.DataObject) -> None:
    site_or_error(read_geojson, json.dumps(mutate(GEOJSON, data.draw)), "g.geojson")


@FAST
@given(st.integers(0, len(KML)), st.integers(0, 40), st.text(max_size=30))
def test_a_mutated_kml_gives_a_site_or_one_error(at: int, cut: int, insert: str) -> None:
    site_or_error(read_kml, KML[:at] + insert + KML[at + cut :], "k.kml")


@FAST
@given(st.text(max_size=200))
def test_any_text_gives_a_site_or_one_error(text: str) -> None:
    for read, source in ((read_plan, "p.plan"), (read_geojson, "g.geojson"), (read_kml, "k.kml")):
        site_or_error(read, text, source)


MISSION = {
    "vehicles": [{"role": "leader", "start": {"position": {"lat": -35.36, "lon": 149.16}}}],
    "goal": {"lat": -35.3599, "lon": 149.16, "alt": 10},
    "safety": {
        "geofence": {
            "polygon": [{"lat": -35.361, "lon": 149.159}, {"lat": -35.361, "lon": 149.161}, [0, 200]],
            "exclusions": [{"center": [50, 50], "radius": 3}, {"polygon": [[60, 60], [70, 60], [70, 70]]}],
        },
        "rally": [{"lat": -35.36, "lon": 149.1601, "alt": 20}],
    },
    "world": {
        "obstacles": [{"center": {"lat": -35.3595, "lon": 149.1605, "amsl": 12}, "radius": 2}],
        "prisms": [{"polygon": [[-30, -30], [-20, -30], [-20, -20]], "top": 5}],
        "cylinders": [{"center": {"lat": -35.3601, "lon": 149.1601}, "radius": 1, "top": 8}],
        "import": [],
    },
}


@settings(max_examples=200, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_the_new_mission_keys_give_a_mission_or_one_error(data: st.DataObject) -> None:
    document = mutate(MISSION, data.draw)
    text = json.dumps(document)  # JSON is YAML
    try:
        parse_mission(text, "m.yaml", to_fly=data.draw(st.booleans()))
    except MissionError as exc:
        assert str(exc).startswith("m.yaml:") and "\n" not in str(exc)
