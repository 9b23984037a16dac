"""Obstacles and collisions: swept tests between ticks, and a crash seen end to end from a mission file."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_sim.world import FUSELAGE_RADIUS, Obstacles, find_collisions
from tests.sitl_sim.sim_process import M, read_truth

NONE = np.zeros(3, dtype=bool)


def test_moving_obstacle_and_fast_vehicle_cannot_tunnel():
    obstacles = Obstacles(np.array([[10.0, 0.0, 5.0]]), np.array([1.0]), np.array([[0.0, -2.0, 0.0]]))
    assert np.allclose(obstacles.at(2.0), [[10.0, -4.0, 5.0]])
    pos0 = np.array([[8.0, 0.0, 5.0], [0.0, 50.0, 5.0], [0.0, 60.0, 5.0]])
    pos1 = np.array(
        [[12.0, 0.0, 5.0], [0.0, 51.0, 5.0], [0.0, 61.0, 5.0]]
    )  # vehicle 0 crosses it in one tick
    assert find_collisions(pos0, pos1, obstacles, 0.0, 0.01, NONE) == [(0, "collision with obstacle 0")]
    grazing = np.array([[8.0, 1.0 + FUSELAGE_RADIUS + 0.01, 5.0], *pos0[1:]])
    assert find_collisions(grazing, grazing + [4.0, 0.0, 0.0], obstacles, 0.0, 0.01, NONE) == []


def test_vehicles_collide_within_two_fuselage_radii():
    empty = Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
    pos0 = np.array([[0.0, 0.0, 5.0], [10.0, 0.3, 5.0], [0.0, 40.0, 5.0]])
    pos1 = np.array([[10.0, 0.0, 5.0], [0.0, 0.3, 5.0], [0.0, 40.0, 5.0]])  # head-on pass 0.3 m apart
    assert find_collisions(pos0, pos1, empty, 0.0, 0.01, NONE) == [
        (0, "collision with vehicle 1"),
        (1, "collision with vehicle 0"),
    ]
    assert find_collisions(pos0, pos1, empty, 0.0, 0.01, np.array([False, True, False])) == []
    apart = pos1 + [[0.0, -0.1, 0.0], [0.0, 0.2, 0.0], [0.0, 0.0, 0.0]]
    assert find_collisions(apart, apart, empty, 0.0, 0.01, NONE) == []


MISSION = """\
vehicles:
  - {role: leader, start: {position: [0, 0, 0]}}
  - {start: {position: [5, 0, 0]}}
goal: [50, 0, 10]
world:
  obstacles:
    - {center: [0, 0, 6], radius: 1}
    - {center: [30, 0, 10], radius: 2, velocity: [1, 0, 0]}
"""


def test_taking_off_into_an_obstacle_crashes(sitl, pilot_for, tmp_path):
    mission = tmp_path / "crash.yaml"
    mission.write_text(MISSION)
    log = tmp_path / "truth.csv"
    sim = sitl(
        "--mission", str(mission), "--lockstep", "--ready-delay", "1", "--truth-log", str(log), vehicles=2
    )
    pilot = pilot_for(sim)
    v = pilot[0]
    pilot.spin(lambda: v.ready, 5.0)
    assert pilot.set_mode(0, 4) == M.MAV_RESULT_ACCEPTED
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    assert pilot.command(0, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: "Crash: collision with obstacle 0" in v.texts, 10.0)
    pilot.spin(lambda: v.latest["HEARTBEAT"].system_status == M.MAV_STATE_EMERGENCY, 1.0)
    assert not v.armed
    assert pilot.command(0, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_FAILED
    pilot.spin(lambda: v.altitude < 0.05, 5.0)  # motors stopped: it falls
    assert sim.stop()[0] == 0
    truth = read_truth(log)
    crashed = truth[(truth["vehicle"] == 0) & (truth["crashed"] == 1)]
    assert len(crashed) and crashed["z"][0] == pytest.approx(6.0 - 1.0 - FUSELAGE_RADIUS, abs=0.06)
    assert not truth[truth["vehicle"] == 1]["crashed"].any()
    obstacles = np.genfromtxt(tmp_path / "truth.obstacles.csv", names=True, delimiter=",")
    moving = obstacles[obstacles["obstacle"] == 1]
    assert np.allclose(moving["x"], 30.0 + moving["t"], atol=1e-3) and np.all(moving["radius"] == 2.0)
