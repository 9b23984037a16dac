"""The route as legs (mission key `legs`, model.Leg): each leg resolved from the one before, its waypoints in
the mission's route, and one clear error, at the leg's own key, for each mistake."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
import yaml

from gcs_swarm.mission import MissionError, parse_mission
from gcs_swarm.mission.model import leg_at
from tests.e2e.flights import MISSIONS

QUICKSTART = yaml.safe_load((MISSIONS / "quickstart.yaml").read_text())
ORIGIN = (QUICKSTART["origin"]["lat"], QUICKSTART["origin"]["lon"], QUICKSTART["origin"]["alt"])
LEGS = [
    {"name": "east", "waypoints": [[80, 0, 10]]},
    {
        "name": "north",
        "waypoints": [[80, 50, 10], [80, 100, 10]],
        "formation": {"shape": "line", "spacing": 8},
    },
    {"waypoints": [{"lat": -35.3625, "lon": 149.1655}], "altitude": 15, "speed": 6},
    {"waypoints": [[0, 0, 15]], "formation": {"spacing": 12}},
]


def _text(legs: object, **more: object) -> str:
    data = {key: value for key, value in QUICKSTART.items() if key != "goal"}
    data.update(legs=legs, **more)
    return yaml.safe_dump(data, sort_keys=False)


def test_each_leg_keeps_what_it_does_not_set_from_the_leg_before() -> None:
    mission = parse_mission(_text(LEGS))
    legs = mission.legs
    assert [leg.name for leg in legs] == ["east", "north", "legs[2]", "legs[3]"]
    assert [leg.first for leg in legs] == [0, 1, 3, 4]  # the leg's first waypoint in the whole route
    # the first leg flies the mission's formation (a V 10 m apart) at limits.v_xy_leader (10 m/s)
    assert [(leg.shape, leg.spacing, leg.speed) for leg in legs] == [
        ("v", 10.0, 10.0),
        ("line", 8.0, 10.0),
        ("line", 8.0, 6.0),
        ("line", 12.0, 6.0),
    ]
    assert (mission.formation.shape, mission.formation.spacing) == ("v", 10.0)
    assert [leg_at(legs, k) for k in range(5)] == [0, 1, 1, 2, 3]


def test_the_legs_waypoints_are_the_route_and_a_legs_altitude_is_its_waypoints_height() -> None:
    mission = parse_mission(_text(LEGS))
    # the {lat, lon} point at the leg's altitude, 15 m above the origin, by pymap3d's own conversion
    east, north, up = pymap3d.geodetic2enu(-35.3625, 149.1655, ORIGIN[2] + 15.0, *ORIGIN)
    expected = [[80, 0, 10], [80, 50, 10], [80, 100, 10], [east, north, up], [0, 0, 15]]
    np.testing.assert_allclose(np.array(mission.waypoints), expected, atol=0.01)
    np.testing.assert_allclose(mission.goal, [0, 0, 15])


def test_the_first_legs_formation_is_flown_from_the_start() -> None:
    first = dict(LEGS[0], formation={"shape": "column", "spacing": 7})
    mission = parse_mission(_text([first, *LEGS[1:]]))
    assert (mission.formation.shape, mission.formation.spacing) == ("column", 7.0)


@pytest.mark.parametrize(
    ("legs", "more", "message"),
    [
        ([], {}, "legs: the list is empty; give at least one leg"),
        ([{"waypoints": []}], {}, "legs[0].waypoints: the list is empty; give at least the leg's end"),
        (
            LEGS,
            {"goal": [1, 2, 10]},
            "legs: give the route once: 'goal', 'waypoints' (whose last point is the goal)",
        ),
        (
            [{"waypoints": [[10, 0, 12]], "altitude": 15}],
            {},
            "legs[0].waypoints[0]: the leg's altitude (15 m)",
        ),
        (
            [{"waypoints": [{"lat": -35.3625, "lon": 149.1655, "amsl": 600}], "altitude": 15}],
            {},
            "legs[0].waypoi",
        ),
        ([{"waypoints": [{"lat": -35.3625, "lon": 149.1655}]}], {}, "legs[0].waypoints[0]: give the height"),
        ([{"waypoints": [[10, 0, 10]], "formation": {"shape": "offsets"}}], {}, "legs[0].formation.shape"),
        ([{"waypoints": [[10, 0, 10]], "speed": 12}], {}, "legs[0].speed: 12 m/s is above the leader's cap"),
        ([{"waypoints": [[10, 0, 10]], "sped": 5}], {}, "legs[0].sped: unknown key; did you mean 'speed'?"),
        # a leg's waypoint inside the quickstart's first obstacle (centre [60, 47, 10], radius 4)
        (
            [LEGS[0], {"waypoints": [[0, 0, 10], [60, 47, 10]]}],
            {},
            "legs[1].waypoints[1]: this waypoint lies",
        ),
    ],
)
def test_a_bad_leg_is_one_clear_error_at_its_key(legs: list, more: dict, message: str) -> None:
    with pytest.raises(MissionError) as caught:
        parse_mission(_text(legs, **more))
    assert message in str(caught.value)
