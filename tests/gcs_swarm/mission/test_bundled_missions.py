"""Every bundled mission loads, has the fleet its header documents, and carries the paper's values."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from gcs_swarm.guidance.params import (
    DeadGcsParams,
    FieldParams,
    Limits,
    PIDParams,
    ReferenceParams,
    SeparationParams,
    SMCParams,
    TelemetryParams,
)
from gcs_swarm.mission import LinkSpec, Mission, load_mission, load_world

MISSIONS = Path(__file__).resolve().parents[3] / "missions"
# file stem -> (vehicle count, leader index, formation shape)
DOCUMENTED = {
    "quickstart": (3, 0, "v"),
    "quickstart_faulty": (3, 0, "v"),
    "paper_static_6": (6, 0, "offsets"),
    "paper_dense_6": (6, 0, "offsets"),
    "paper_dynamic_6": (6, 0, "offsets"),
    "paper_nine_9": (9, 0, "v"),
    "paper_table1_2d": (1, 0, "v"),
    "ardupilot_sitl_3": (3, 0, "v"),
    "mixed_fleet": (4, 0, "v"),
    "px4_sitl_3": (3, 0, "v"),
    "site_shapes_3": (3, 0, "v"),
    "cmac_site": (3, 0, "v"),
}
# flown against running vehicles (udpin), not the embedded simulator: the port vehicle 0 sends to (ArduCopter
# SITL --serial0 udpclient:127.0.0.1:14550+K, docs/ardupilot-sitl.md; PX4 SITL's API link 14540+K)
REAL_VEHICLES = {"ardupilot_sitl_3": 14550, "px4_sitl_3": 14540}
BUNDLED = sorted(MISSIONS.glob("*.yaml"))

TABLE2_XY = [(0, 40), (0, 20), (20, 40), (0, 0), (20, 20), (20, 0)]
TABLE2_VELOCITY = [(5, 6, 5), (3, 4, 2), (2, 7, 5), (4, 4, 8), (2, 5, 3), (3, 1, 3)]
TABLE3_TARGETS = [
    (4470, 4470, 200),
    (4530, 4470, 200),
    (4440, 4440, 200),
    (4500, 4440, 200),
    (4560, 4440, 200),
]
TABLE3_OBSTACLES = [
    (250, 160, 200),
    (520, 350, 200),
    (400, 500, 200),
    (780, 500, 200),
    (720, 600, 200),
    (910, 810, 200),
]
TABLE4_OBSTACLES = [(300, 300, 160), (600, 620, 240), (700, 770, 200), (520, 600, 200)]
PAPER_RING = [
    [0, 1, 1, 0, 0, 0],
    [1, 0, 0, 1, 0, 0],
    [1, 0, 0, 0, 0, 1],
    [0, 1, 0, 0, 1, 0],
    [0, 0, 0, 1, 0, 1],
    [0, 0, 1, 0, 1, 0],
]
SIX = ["paper_static_6", "paper_dense_6", "paper_dynamic_6"]


def load(stem: str) -> Mission:
    return load_mission(MISSIONS / f"{stem}.yaml")


def test_every_bundled_mission_is_documented_here() -> None:
    assert {path.stem for path in BUNDLED} == set(DOCUMENTED)


@pytest.mark.parametrize("path", BUNDLED, ids=[p.stem for p in BUNDLED])
def test_bundled_mission_loads_with_its_documented_fleet(path: Path) -> None:
    mission = load_mission(path)
    count, leader, shape = DOCUMENTED[path.stem]
    assert mission.name == path.stem
    assert mission.description
    assert len(mission.vehicles) == count
    assert mission.leader_index == leader
    assert [v.role for v in mission.vehicles].count("leader") == 1
    assert mission.formation.shape == shape
    base = mission.run.simulator.base_port
    for index, vehicle in enumerate(mission.vehicles):
        if path.stem in REAL_VEHICLES:
            assert vehicle.connection == f"udpin:127.0.0.1:{REAL_VEHICLES[path.stem] + index}"
        else:
            assert vehicle.connection == f"udpout:127.0.0.1:{base + index}"
        assert vehicle.sysid == index + 1
    if path.stem in REAL_VEHICLES:
        assert not mission.run.simulator.embedded and mission.run.preflight_timeout_s >= 120
    else:
        assert mission.run.simulator.embedded and mission.run.simulator.time_mode == "lockstep"


@pytest.mark.parametrize("path", BUNDLED, ids=[p.stem for p in BUNDLED])
def test_world_matches_the_mission(path: Path) -> None:
    mission = load_mission(path)
    world = load_world(path)
    assert world == mission.world()
    assert world.origin == mission.origin
    assert len(world.starts) == len(mission.vehicles)
    for start, vehicle in zip(world.starts, mission.vehicles, strict=True):
        np.testing.assert_array_equal(start.position, vehicle.start.position)
        np.testing.assert_array_equal(start.velocity, vehicle.start.velocity)
    assert world.obstacles == mission.obstacles


def test_quickstart_spells_out_the_defaults() -> None:
    """The commented example names every parameter of the guidance, reference and limits sections (so a
    new parameter cannot go undocumented there) and each has its default value."""
    data = yaml.safe_load((MISSIONS / "quickstart.yaml").read_text())
    sections: dict[str, tuple[dict, Any]] = {
        "guidance": (data["guidance"], FieldParams()),
        "guidance.reference": (data["guidance"]["reference"], ReferenceParams()),
        "limits": (data["limits"], Limits()),
        "safety.dead_gcs": (data["safety"]["dead_gcs"], DeadGcsParams()),
    }
    for where, (section, params) in sections.items():
        missing = [f.name for f in dataclasses.fields(params) if f.name not in section]
        assert not missing, f"quickstart.yaml {where} does not show {missing}"
    assert "assign_slots" in data["formation"]
    mission = load("quickstart")
    assert mission.field == FieldParams()
    assert mission.reference == ReferenceParams()
    assert mission.smc == SMCParams()
    assert mission.pid == PIDParams()
    assert mission.limits == Limits()
    assert mission.safety.separation == SeparationParams()
    assert mission.safety.telemetry == TelemetryParams() and mission.link == LinkSpec()
    assert (
        mission.safety.dead_gcs == DeadGcsParams(failsafe_timeout_s=3.0, brake_accel=2.5, brake_jerk=5.0)
        and mission.safety.gcs_failsafe == "land"
    )
    assert not mission.run.airborne_start
    assert mission.formation.altitude == 10.0 and mission.formation.spacing == 10.0


def test_quickstart_is_short() -> None:
    mission = load("quickstart")
    leader = mission.vehicles[mission.leader_index]
    distance = float(np.linalg.norm(mission.goal[:2] - leader.start.position[:2]))
    assert 150 <= distance <= 200
    assert distance / mission.limits.v_xy_leader < 30  # s of cruise, leaving room for take-off and hold
    assert 2 <= len(mission.obstacles) <= 3
    assert all(3 <= obstacle.radius <= 5 for obstacle in mission.obstacles)


def test_quickstart_faulty_is_quickstart_over_a_lossy_jittery_link() -> None:
    faulty, plain = load("quickstart_faulty"), load("quickstart")
    assert (faulty.link.loss, faulty.link.jitter_ms, faulty.link.from_s, faulty.link.outages) == (
        0.1,
        100,
        0,
        (),
    )
    assert faulty.world().link == faulty.link
    assert faulty.safety.telemetry == TelemetryParams()
    for a, b in zip(faulty.vehicles, plain.vehicles, strict=True):
        assert (a.name, a.role, a.sysid, a.start) == (b.name, b.role, b.sysid, b.start)
    assert faulty.obstacles == plain.obstacles and np.array_equal(faulty.goal, plain.goal)


@pytest.mark.parametrize("stem", SIX)
def test_six_uav_missions_carry_tables_2_and_3(stem: str) -> None:
    mission = load(stem)
    assert mission.run.airborne_start
    for vehicle, xy, velocity in zip(mission.vehicles, TABLE2_XY, TABLE2_VELOCITY, strict=True):
        np.testing.assert_array_equal(vehicle.start.position, [*xy, 200])
        np.testing.assert_array_equal(vehicle.start.velocity, velocity)
    np.testing.assert_array_equal(mission.goal, [4500, 4500, 200])
    for vehicle, target in zip(mission.vehicles[1:], TABLE3_TARGETS, strict=True):
        np.testing.assert_array_equal(vehicle.target, target)
    assert mission.formation.adjacency is not None
    np.testing.assert_array_equal(mission.formation.adjacency, PAPER_RING)
    assert mission.formation.topology == "broadcast"
    assert (mission.field.l0, mission.field.n, mission.field.k_rep) == (20.0, 0.8, 1e5)
    assert (mission.safety.separation.d_max, mission.safety.separation.d_emg) == (10.0, 3.0)
    assert (mission.limits.v_xy, mission.limits.v_z, mission.limits.a_xy, mission.limits.a_z) == (
        20,
        20,
        20,
        15,
    )


@pytest.mark.parametrize("stem", SIX)
def test_six_uav_slots_are_spec_reading_a(stem: str) -> None:
    """delta_i = R(-45 deg) (target_i - target_1): turned by the final heading, the slots give the targets."""
    mission = load(stem)
    c, s = math.cos(math.radians(45)), math.sin(math.radians(45))
    for vehicle in mission.vehicles[1:]:
        assert vehicle.slot is not None and vehicle.target is not None
        dx, dy, dz = vehicle.slot
        world_offset = [c * dx - s * dy, s * dx + c * dy, dz]
        np.testing.assert_allclose(mission.goal + world_offset, vehicle.target, atol=0.01)


def test_static_and_dense_obstacles() -> None:
    static, dense = load("paper_static_6"), load("paper_dense_6")
    assert [tuple(o.center) for o in static.obstacles] == TABLE3_OBSTACLES
    assert [tuple(o.center) for o in dense.obstacles] == TABLE3_OBSTACLES + TABLE4_OBSTACLES
    for obstacle in dense.obstacles:
        assert obstacle.radius == 3.0
        assert not obstacle.velocity.any()


def test_dynamic_obstacles_move_as_table_5() -> None:
    mission = load("paper_dynamic_6")
    velocities = [tuple(o.velocity) for o in mission.obstacles]
    assert velocities == [(2, -2, 0)] * 3 + [(5, -5, 0)] * 3
    np.testing.assert_array_equal(mission.obstacles[0].center_at(10.0), [310, 480, 200])


def test_nine_uav_mission_follows_spec_9_3() -> None:
    mission = load("paper_nine_9")
    table7 = [
        (200, 0),
        (-300, -200),
        (200, -300),
        (0, -500),
        (-300, -550),
        (-200, -600),
        (200, -800),
        (0, -900),
    ]
    table7.append((-400, -1000))
    for vehicle, xy in zip(mission.vehicles, table7, strict=True):
        np.testing.assert_array_equal(vehicle.start.position[:2], xy)
        assert vehicle.start.position[2] == 200
        assert vehicle.slot is None
    formation = mission.formation
    assert (formation.shape, formation.spacing, formation.angle_deg, formation.altitude) == ("v", 20, 45, 200)
    assert mission.field.k_uav == 130 and mission.field.k_att == 100
    assert (mission.limits.v_xy_leader, mission.limits.v_xy) == (10, 20)
    assert [tuple(o.center) for o in mission.obstacles] == [(1000, 15500, 1000), (-800, 10000, 200)]


def test_table1_mission_is_the_2d_planner_scenario() -> None:
    mission = load("paper_table1_2d")
    planner = mission.planner
    assert (planner.dimensions, planner.dt, planner.time_limit_s, planner.speed) == (2, 0.01, 60, 15)
    assert (planner.goal_radius, planner.step, planner.start) == (0.5, "proportional", None)
    np.testing.assert_array_equal(mission.vehicles[0].start.position, [5, 5, 0])
    np.testing.assert_array_equal(mission.goal, [95, 70, 0])
    circles = [(tuple(o.center[:2]), o.radius) for o in mission.obstacles]
    assert circles == [((25, 75), 9), ((81, 30), 8), ((70, 70), 18), ((32, 27), 14)]
    assert all(o.center[2] == 0 for o in mission.obstacles)
    field = mission.field
    assert (field.k_att, field.k_rep, field.l0, field.n, field.d_g) == (100, 1e5, 20, 0.8, 15)
