"""A route flown as legs (mission key `legs`), end to end in lockstep against the embedded simulator: four
vehicles fly east in a V, north in a line 8 m apart at most 6 m/s, and west in a column climbing to 15 m.
Every figure is read from the simulator's ground truth (truth.csv), against the route's own directions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from tests.e2e.flights import derived_mission, fly

LEGS = [
    {"name": "east", "waypoints": [[80, 0, 10]]},
    {"name": "north", "waypoints": [[80, 100, 10]], "formation": {"shape": "line", "spacing": 8}, "speed": 6},
    {"name": "west", "waypoints": [[0, 100, 15]], "formation": {"shape": "column"}, "speed": 8},
]
TAIL = {"name": "tail", "sysid": 4, "start": {"position": [-12, -12, 0], "yaw_deg": 37}}


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, np.ndarray]:
    """The run folder, its flight.json and truth.csv."""
    folder = tmp_path_factory.mktemp("legs")
    mission = derived_mission(folder, "quickstart.yaml", "legs", legs=LEGS)
    data = yaml.safe_load(mission.read_text())
    del data["goal"]  # the legs are the route
    data["vehicles"].append(TAIL)
    data["world"]["obstacles"] = [{"center": [30.0, 50.0, 10.0], "radius": 4.0}]  # well clear of every leg
    mission.write_text(yaml.safe_dump(data, sort_keys=False))
    run = fly(mission, folder / "run", timeout_s=600, extra=["--time-mode", "lockstep"])
    assert run.status == 0, run.output[-3000:]
    flight = json.loads((run.run_dir / "flight.json").read_text())
    truth = np.genfromtxt(run.run_dir / "truth.csv", delimiter=",", names=True)
    return run.run_dir, flight, truth


def _positions(truth: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """(T, 4, 3) true positions of the four vehicles at the truth samples in [t0, t1] s."""
    rows = [truth[(truth["vehicle"] == v) & (truth["t"] >= t0) & (truth["t"] <= t1)] for v in range(4)]
    return np.stack([np.column_stack([r["x"], r["y"], r["z"]]) for r in rows], axis=1)


def test_each_leg_starts_in_order_as_an_event_and_a_row(flown) -> None:
    run_dir, flight, _ = flown
    legs = flight["legs"]
    assert [(row["index"], row["name"], row["shape"], row["speed_m_s"]) for row in legs] == [
        (0, "east", "v", 10.0),
        (1, "north", "line", 6.0),
        (2, "west", "column", 8.0),
    ]
    times = [row["t_s"] for row in legs]
    assert times == sorted(times) and times[0] >= flight["t_formation_start"]
    assert sum("leg 2 of 3 (north): line 8 m apart, leader at most 6 m/s" in e for e in flight["events"]) == 1
    report = json.loads((run_dir / "report.json").read_text())
    assert report["reached"] and report["collisions"] == 0
    assert report["legs"] == legs
    assert "| 2 (north) |" in (run_dir / "report.md").read_text()


def test_the_line_is_abreast_across_the_north_leg_and_the_leader_keeps_its_speed(flown) -> None:
    _, flight, truth = flown
    north, west = flight["legs"][1]["t_s"], flight["legs"][2]["t_s"]
    p = _positions(truth, west - 3.0, west)  # the end of the north leg, the line long formed
    rel = p - p[:, :1]  # from the leader; heading north: along = y, right of the heading = +x
    assert np.abs(rel[..., 1]).max() < 2.0  # abreast of the leader
    across = np.sort(rel[..., 0], axis=1)
    np.testing.assert_allclose(np.diff(across, axis=1), 8.0, atol=1.5)  # neighbours 8 m apart
    lead = truth[truth["vehicle"] == 0]
    speed = np.hypot(lead["vx"], lead["vy"])
    on_north = (lead["t"] > north + 3.0) & (lead["t"] < west)
    on_east = (lead["t"] > flight["t_formation_start"]) & (lead["t"] < north)
    assert speed[on_north].max() <= 6.0 * 1.05  # the leg's cap (5 % for the speed controller's overshoot)
    assert speed[on_east].max() > 7.0  # and a real change: the first leg flew faster


def test_the_formation_arrives_as_a_column_at_the_last_legs_altitude(flown) -> None:
    _, flight, truth = flown
    end = flight["t_formation_end"]
    p = _positions(truth, end - 1.0, end)
    rel = p - p[:, :1]  # heading west: along = -x, left of the heading = -y
    assert np.abs(rel[..., 1]).max() < 1.5  # astern of the leader, in its wake
    behind = np.sort(rel[..., 0], axis=1)
    np.testing.assert_allclose(np.diff(behind, axis=1), 8.0, atol=1.5)  # 8 m apart, the line's spacing kept
    np.testing.assert_allclose(p[..., 2], 15.0, atol=1.0)
