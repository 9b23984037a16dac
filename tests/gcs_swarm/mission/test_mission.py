"""Mission loader: defaults, the Python view, one test per kind of mistake (naming file, line and field)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_swarm.guidance.params import (
    DeadGcsParams,
    FieldParams,
    Limits,
    PIDParams,
    ReferenceParams,
    SeparationParams,
    SMCAxisGains,
    SMCParams,
    TelemetryParams,
)
from gcs_swarm.mission import (
    LinkSpec,
    MissionError,
    OutageSpec,
    load_mission,
    load_world,
    parse_mission,
)

VEHICLES = """vehicles:
  - {name: lead, role: leader, start: {position: [0, 0, 0]}}
  - {name: f1, start: {position: [-10, 0, 0]}}
"""
GOAL = "goal: [100, 50, 10]\n"
MINIMAL = VEHICLES + GOAL


def error_of(text: str, source: str = "m.yaml") -> str:
    with pytest.raises(MissionError) as info:
        parse_mission(text, source)
    message = str(info.value)
    assert "\n" not in message, message
    return message


# ---------------------------------------------------------------- what a valid file gives


def test_minimal_mission_takes_the_spec_defaults() -> None:
    mission = parse_mission(MINIMAL, "missions/minimal.yaml")
    assert mission.name == "minimal"
    assert mission.description == ""
    assert mission.origin == (-35.363261, 149.165230, 584.0)
    assert mission.field == FieldParams()
    assert mission.reference == ReferenceParams()
    assert mission.smc == SMCParams()
    assert mission.pid == PIDParams()
    assert mission.limits == Limits()
    assert mission.safety.separation == SeparationParams()
    assert mission.safety.telemetry == TelemetryParams()
    assert mission.link == LinkSpec() and mission.world().link == LinkSpec()
    assert mission.controller == "smc"
    assert (mission.safety.min_altitude, mission.safety.collision_radius, mission.safety.gcs_failsafe) == (
        2.0,
        0.175,
        "land",
    )
    # LAND's stop (LOIT_BRK_ACCEL 2.5 m/s^2, LOIT_BRK_JERK 5 m/s^3) for the speed scheduling
    assert mission.safety.dead_gcs == DeadGcsParams(failsafe_timeout_s=3.0, brake_accel=2.5, brake_jerk=5.0)
    assert not mission.run.keep_params
    assert (mission.formation.shape, mission.formation.spacing, mission.formation.angle_deg) == (
        "v",
        10.0,
        45.0,
    )
    assert (mission.formation.topology, mission.formation.adjacency) == ("broadcast", None)
    assert (mission.run.control_rate_hz, mission.run.goal_tolerance_m, mission.run.hold_s) == (50.0, 1.0, 2.0)
    assert (mission.run.takeoff_timeout_s, mission.run.preflight_timeout_s, mission.run.land_timeout_s) == (
        60.0,
        60.0,
        300.0,
    )
    assert mission.run.simulator.embedded and mission.run.simulator.time_mode == "lockstep"
    assert mission.planner.speed == Limits().v_xy_leader
    assert mission.planner.start is None
    np.testing.assert_array_equal(mission.goal, [100, 50, 10])
    assert len(mission.waypoints) == 1 and mission.waypoints[0] is mission.goal


def test_vehicle_defaults_follow_vehicle_order() -> None:
    mission = parse_mission(VEHICLES.replace("name: lead, ", "").replace("name: f1, ", "") + GOAL)
    lead, follower = mission.vehicles
    assert (lead.name, lead.role, lead.connection) == ("uav1", "leader", "udpout:127.0.0.1:14540")
    assert (follower.name, follower.role, follower.connection) == (
        "uav2",
        "follower",
        "udpout:127.0.0.1:14541",
    )
    assert follower.sysid is None and follower.slot is None and follower.target is None
    np.testing.assert_array_equal(follower.start.velocity, [0, 0, 0])
    assert follower.start.yaw_deg == 0.0
    assert mission.leader_index == 0


@pytest.mark.parametrize("written", ["1e5", "1E5", "1.5e5", "100000", "1.0e+5", "+1e5"])
def test_exponent_numbers_are_floats(written: str) -> None:
    mission = parse_mission(MINIMAL + f"guidance: {{k_rep: {written}}}\n")
    assert mission.field.k_rep == pytest.approx(float(written))


def test_every_params_field_is_settable_and_nested_gains_keep_their_other_defaults() -> None:
    text = MINIMAL + (
        "guidance: {method: apf, d_g: 12.5, n: 1.2, reference: {leash: 3, paper_literal: true}}\n"
        "control: {controller: pid, smc: {xy: {c1: 1.0}, boundary_layer: 0.05}, pid: {kp_z: 4}}\n"
        "limits: {tilt_max_deg: 30, v_xy: 15}\n"
        "safety: {separation: {mode: formula, t_r: 0.3}, min_altitude: 3, gcs_failsafe: brake}\n"
    )
    mission = parse_mission(text)
    assert mission.field == dataclasses.replace(FieldParams(), method="apf", d_g=12.5, n=1.2)
    assert mission.reference == dataclasses.replace(ReferenceParams(), leash=3.0, paper_literal=True)
    assert mission.smc.xy == dataclasses.replace(SMCParams().xy, c1=1.0)
    assert mission.smc.z == SMCParams().z and mission.smc.boundary_layer == 0.05
    assert isinstance(mission.smc.xy, SMCAxisGains)
    assert mission.controller == "pid" and mission.pid.kp_z == 4.0
    assert mission.limits.tilt_max_deg == 30.0 and mission.limits.v_xy == 15.0
    assert mission.safety.separation.mode == "formula" and mission.safety.separation.t_r == 0.3
    assert mission.safety.gcs_failsafe == "brake"
    assert (mission.safety.dead_gcs.brake_accel, mission.safety.dead_gcs.brake_jerk) == (7.5, 5.0)  # BRAKE's


def test_waypoints_end_at_the_goal() -> None:
    mission = parse_mission(VEHICLES + "waypoints: [[50, 0, 10], [50, 50, 12], [100, 50, 10]]\n")
    assert len(mission.waypoints) == 3
    np.testing.assert_array_equal(mission.goal, [100, 50, 10])
    np.testing.assert_array_equal(mission.waypoints[1], [50, 50, 12])


def test_obstacles_move_at_their_velocity_and_wind_direction_wraps() -> None:
    text = MINIMAL + (
        "world:\n"
        "  obstacles:\n"
        "    - {center: [50, 20, 10], radius: 3, velocity: [1, -2, 0]}\n"
        "    - {center: [80, 0, 10], radius: 2}\n"
        "  wind: {speed: 4, direction_deg: -90, turbulence: 0.5}\n"
    )
    mission = parse_mission(text)
    moving, still = mission.obstacles
    np.testing.assert_allclose(moving.center_at(2.5), [52.5, 15, 10])
    np.testing.assert_array_equal(still.center_at(100.0), [80, 0, 10])
    assert still.radius == 2.0
    assert (mission.wind.speed, mission.wind.direction_deg, mission.wind.turbulence) == (4.0, 270.0, 0.5)


def test_link_faults_name_vehicles_and_reach_the_simulator_view() -> None:
    text = MINIMAL + (
        "world:\n"
        "  link:\n"
        "    loss: 0.1\n"
        "    delay_ms: 20\n"
        "    jitter_ms: 100\n"
        "    dup: 0.01\n"
        "    corrupt: 0.02\n"
        "    reorder: 0.03\n"
        "    from_s: 12\n"
        "    outages:\n"
        "      - {vehicle: f1, start_s: 15, duration_s: inf}\n"
        "      - {start_s: 30, duration_s: 2.5}\n"
        "      - {vehicle: lead, start_s: 0, duration_s: .inf}\n"
    )
    mission = parse_mission(text)
    assert mission.world().link == LinkSpec(
        loss=0.1,
        delay_ms=20.0,
        jitter_ms=100.0,
        dup=0.01,
        corrupt=0.02,
        reorder=0.03,
        from_s=12.0,
        outages=(OutageSpec(1, 15.0, math.inf), OutageSpec(None, 30.0, 2.5), OutageSpec(0, 0.0, math.inf)),
    )
    assert parse_mission(MINIMAL + "world: {link: {outages: null}}\n").link == LinkSpec()


def test_telemetry_ages_are_settable_and_partial() -> None:
    mission = parse_mission(MINIMAL + "safety: {telemetry: {lost_s: 5, degraded_speed: 0.7}}\n")
    assert mission.safety.telemetry == dataclasses.replace(TelemetryParams(), lost_s=5.0, degraded_speed=0.7)


def test_world_is_the_simulator_view() -> None:
    mission = parse_mission(MINIMAL + "world: {obstacles: [{center: [50, 20, 10], radius: 3}]}\n")
    world = mission.world()
    assert world.origin == mission.origin and world.wind == mission.wind
    assert world.obstacles == mission.obstacles
    assert world.starts == tuple(v.start for v in mission.vehicles)


def test_load_mission_and_load_world_read_files(tmp_path) -> None:
    path = tmp_path / "field_day.yaml"
    path.write_text(MINIMAL, encoding="utf-8")
    mission = load_mission(path)
    assert mission.name == "field_day" and mission.path == path
    assert load_world(str(path)) == mission.world()
    assert load_mission(path) == mission  # arrays compare by value


def test_loaded_missions_are_immutable() -> None:
    mission = parse_mission(MINIMAL)
    with pytest.raises(dataclasses.FrozenInstanceError):
        mission.name = "other"  # type: ignore[misc]
    with pytest.raises(ValueError):
        mission.goal[0] = 1.0
    with pytest.raises(ValueError):
        mission.vehicles[0].start.position[2] = 5.0


def test_unequal_missions_compare_unequal() -> None:
    assert parse_mission(MINIMAL) != parse_mission(VEHICLES + "goal: [100, 50, 11]\n")


def test_merge_keys_and_anchors_work() -> None:
    text = (
        MINIMAL
        + """world:
  obstacles:
    - &rock {center: [50, 20, 10], radius: 3, velocity: [1, 0, 0]}
    - {<<: *rock, center: [80, 0, 10]}
"""
    )
    first, second = parse_mission(text).obstacles
    np.testing.assert_array_equal(second.center, [80, 0, 10])
    assert second.radius == first.radius == 3.0
    np.testing.assert_array_equal(second.velocity, [1, 0, 0])


def test_shared_listening_endpoint_needs_sysids() -> None:
    shared = """vehicles:
  - {name: lead, role: leader, sysid: 1, connection: "udpin:0.0.0.0:14550", start: {position: [0, 0, 0]}}
  - {name: f1, sysid: 2, connection: "udpin:0.0.0.0:14550", start: {position: [-10, 0, 0]}}
goal: [100, 50, 10]
run: {simulator: {embedded: false}}
"""
    mission = parse_mission(shared)
    assert {v.connection for v in mission.vehicles} == {"udpin:0.0.0.0:14550"}
    message = error_of(shared.replace("sysid: 2, ", ""))
    assert message.startswith("m.yaml:3: vehicles[1].connection: ")


def test_relay_topology_keeps_the_adjacency() -> None:
    text = MINIMAL + "formation: {topology: relay, adjacency: [[0, 1], [1, 0]]}\n"
    adjacency = parse_mission(text).formation.adjacency
    assert adjacency is not None
    np.testing.assert_array_equal(adjacency, [[0, 1], [1, 0]])


def test_offsets_shape_with_every_slot() -> None:
    text = VEHICLES.replace("name: f1,", "name: f1, slot: [-5, 5, 0], target: [95, 55, 10],") + GOAL
    mission = parse_mission(text + "formation: {shape: offsets}\n")
    np.testing.assert_array_equal(mission.vehicles[1].slot, [-5, 5, 0])
    np.testing.assert_array_equal(mission.vehicles[1].target, [95, 55, 10])


# ---------------------------------------------------------------- every kind of mistake
# Each case: (id, text, field path, fragment). The line blamed is the one marked "# <-".


def _v(old: str, new: str) -> str:
    return VEHICLES.replace(old, new, 1)


def _mark(text: str, old: str) -> str:
    """Append the marker comment to the first line containing `old`."""
    lines = text.splitlines()
    index = next(i for i, line in enumerate(lines) if old in line)
    lines[index] += "  # <-"
    return "\n".join(lines) + "\n"


MISTAKES = [
    # unknown keys and misplaced sections
    (
        "typo",
        MINIMAL + "world: {obstacles: [{center: [50, 20, 10], radus: 3}]}  # <-\n",
        "world.obstacles[0].radus",
        "did you mean 'radius'?",
    ),
    ("typo-top", MINIMAL + "planer: {dt: 0.1}  # <-\n", "planer", "did you mean 'planner'?"),
    ("misplaced", MINIMAL + "obstacles: []  # <-\n", "obstacles", "belongs under 'world'"),
    (
        "unknown-vehicle-key",
        _mark(_v("name: f1,", "name: f1, colour: red,"), "colour") + GOAL,
        "vehicles[1].colour",
        "unknown key",
    ),
    # wrong types
    ("text-number", MINIMAL + "guidance: {k_att: '100'}  # <-\n", "guidance.k_att", "expected a number"),
    ("bool-number", MINIMAL + "limits: {v_xy: true}  # <-\n", "limits.v_xy", "got the boolean true"),
    ("null-number", MINIMAL + "run: {hold_s: null}  # <-\n", "run.hold_s", "expected a number"),
    # link faults and telemetry ages
    ("link-probability", MINIMAL + "world: {link: {loss: 1.5}}  # <-\n", "world.link.loss", "must be <= 1"),
    ("link-negative", MINIMAL + "world: {link: {dup: -0.1}}  # <-\n", "world.link.dup", "must be >= 0"),
    (
        "link-delay",
        MINIMAL + "world: {link: {jitter_ms: 20000}}  # <-\n",
        "world.link.jitter_ms",
        "must be <= 10000 ms",
    ),
    ("link-from", MINIMAL + "world: {link: {from_s: -1}}  # <-\n", "world.link.from_s", "must be >= 0 s"),
    ("link-typo", MINIMAL + "world: {link: {los: 0.1}}  # <-\n", "world.link.los", "did you mean 'loss'?"),
    (
        "outage-unknown-vehicle",
        MINIMAL + "world: {link: {outages: [{vehicle: f9, start_s: 1, duration_s: 2}]}}  # <-\n",
        "world.link.outages[0].vehicle",
        "expected the name of a vehicle, got the text 'f9' (vehicles: lead, f1)",
    ),
    (
        "outage-vehicle-index",
        MINIMAL + "world: {link: {outages: [{vehicle: 1, start_s: 1, duration_s: 2}]}}  # <-\n",
        "world.link.outages[0].vehicle",
        "expected the name of a vehicle, got the number 1",
    ),
    (
        "outage-start",
        MINIMAL + "world: {link: {outages: [{start_s: -1, duration_s: 2}]}}  # <-\n",
        "world.link.outages[0].start_s",
        "must be >= 0 s",
    ),
    (
        "outage-duration",
        MINIMAL + "world: {link: {outages: [{start_s: 1, duration_s: 0}]}}  # <-\n",
        "world.link.outages[0].duration_s",
        "must be > 0 s (or inf: for good)",
    ),
    (
        "outage-duration-text",
        MINIMAL + "world: {link: {outages: [{start_s: 1, duration_s: forever}]}}  # <-\n",
        "world.link.outages[0].duration_s",
        "expected seconds or inf",
    ),
    (
        "outage-no-duration",
        MINIMAL + "world: {link: {outages: [{start_s: 1}]}}  # <-\n",
        "world.link.outages[0].duration_s",
        "required key is missing",
    ),
    (
        "telemetry-order",
        MINIMAL + "safety: {telemetry: {hold_s: 5}}  # <-\n",
        "safety.telemetry.hold_s",
        "0 <= predict_s < hold_s < lost_s",
    ),
    (
        "telemetry-typo",
        MINIMAL + "safety: {telemetry: {lost: 5}}  # <-\n",
        "safety.telemetry.lost",
        "did you mean 'lost_s'?",
    ),
    ("infinite", MINIMAL + "guidance: {k_att: .inf}  # <-\n", "guidance.k_att", "finite"),
    ("nan", MINIMAL + "guidance: {l0: .nan}  # <-\n", "guidance.l0", "finite"),
    (
        "short-vector",
        _mark(_v("[-10, 0, 0]", "[-10, 0]"), "[-10, 0]") + GOAL,
        "vehicles[1].start.position",
        "expected 3 numbers, got 2",
    ),
    ("vector-of-text", VEHICLES + "goal: [100, fifty, 10]  # <-\n", "goal[1]", "expected a number"),
    (
        "bool-flag",
        MINIMAL + "run: {airborne_start: 1}  # <-\n",
        "run.airborne_start",
        "expected true or false",
    ),
    ("float-int", MINIMAL + "run: {simulator: {seed: 1.5}}  # <-\n", "run.simulator.seed", "whole number"),
    ("bad-choice", MINIMAL + "formation: {shape: lien}  # <-\n", "formation.shape", "did you mean 'line'?"),
    ("bad-method", MINIMAL + "guidance: {method: potential}  # <-\n", "guidance.method", "'apf', 'iaapf'"),
    ("section-not-mapping", MINIMAL + "limits: [10, 20]  # <-\n", "limits", "expected a mapping"),
    ("vehicles-not-list", "vehicles: {name: lead}  # <-\n" + GOAL, "vehicles", "expected a list"),
    (
        "name-with-space",
        _mark(_v("name: f1,", "name: 'f 1',"), "'f 1'") + GOAL,
        "vehicles[1].name",
        "no spaces",
    ),
    ("bad-tag", MINIMAL + "run: !!python/object:os.system {}  # <-\n", "run", "unsupported YAML tag"),
    (
        "bad-connection",
        _mark(_v("name: f1,", "name: f1, connection: 'udp:14541',"), "udp:")
        + GOAL
        + "run: {simulator: {embedded: false}}\n",
        "vehicles[1].connection",
        "pymavlink connection string",
    ),
    # impossible values and ranges
    (
        "negative-radius",
        MINIMAL + "world: {obstacles: [{center: [50, 20, 10], radius: -3}]}  # <-\n",
        "world.obstacles[0].radius",
        "must be > 0",
    ),
    ("zero-spacing", MINIMAL + "formation: {spacing: 0}  # <-\n", "formation.spacing", "must be > 0"),
    ("tilt-80", MINIMAL + "limits: {tilt_max_deg: 80}  # <-\n", "limits.tilt_max_deg", "(0, 80)"),
    ("zero-rate", MINIMAL + "run: {control_rate_hz: 0}  # <-\n", "run.control_rate_hz", "must be > 0"),
    (
        "physics-below-control",
        MINIMAL + "run: {simulator: {rate_hz: 20}}  # <-\n",
        "run.simulator.rate_hz",
        "must be >= 50",
    ),
    (
        "smc-stability",
        MINIMAL + "control:\n  smc:\n    xy: {c1: 0.1, k1: 2.0}  # <-\n",
        "control.smc.xy.c1",
        "k1*c1 > 1/4",
    ),
    ("smc-exponents", MINIMAL + "control: {smc: {z: {xi2: 2.5}}}  # <-\n", "control.smc.z.xi2", "xi2"),
    ("n-uav", MINIMAL + "guidance: {n_uav: 2}  # <-\n", "guidance.n_uav", "(0, 2)"),
    ("d-emg", MINIMAL + "safety: {separation: {d_emg: 12}}  # <-\n", "safety.separation.d_emg", "d_max"),
    ("leader-too-fast", MINIMAL + "limits: {v_xy_leader: 20}  # <-\n", "limits.v_xy_leader", "below"),
    ("latitude", MINIMAL + "origin: {lat: 95, lon: 0}  # <-\n", "origin.lat", "must be <= 90"),
    (
        "sysid-range",
        _mark(_v("name: f1,", "name: f1, sysid: 255,"), "sysid") + GOAL,
        "vehicles[1].sysid",
        "must be <= 254",
    ),
    ("planner-dimensions", MINIMAL + "planner: {dimensions: 4}  # <-\n", "planner.dimensions", "<= 3"),
    ("planner-dt", MINIMAL + "planner: {dt: 100}  # <-\n", "planner.dt", "below planner.time_limit_s"),
    ("formation-altitude", MINIMAL + "formation: {altitude: 400}  # <-\n", "formation.altitude", "max_alt"),
    (
        "fence-ceiling",
        MINIMAL + "safety: {min_altitude: 50, geofence: {max_alt: 40}}  # <-\n",
        "safety.geofence.max_alt",
        "must be > 50",
    ),
    # fleet consistency
    (
        "duplicate-name",
        _mark(_v("name: f1,", "name: lead,"), "name: lead, start: {position: [-10") + GOAL,
        "vehicles[1].name",
        "already used by vehicles[0]",
    ),
    (
        "duplicate-endpoint",
        _mark(_v("name: f1,", "name: f1, connection: 'udpout:127.0.0.1:14540',"), "name: f1")
        + GOAL
        + "run: {simulator: {embedded: false}}\n",
        "vehicles[1].connection",
        "already used by vehicles[0]",
    ),
    (
        "duplicate-endpoint-localhost",
        _mark(
            VEHICLES.replace("name: lead,", "name: lead, connection: 'udpout:localhost:14560',").replace(
                "name: f1,", "name: f1, connection: 'udpout:127.0.0.1:14560',"
            ),
            "name: f1",
        )
        + GOAL
        + "run: {simulator: {embedded: false}}\n",
        "vehicles[1].connection",
        "already used",
    ),
    (
        "duplicate-sysid",
        _mark(
            VEHICLES.replace("name: lead,", "name: lead, sysid: 3,").replace(
                "name: f1,", "name: f1, sysid: 3,"
            ),
            "name: f1",
        )
        + GOAL
        + "run: {simulator: {embedded: false}}\n",
        "vehicles[1].sysid",
        "already used",
    ),
    (
        "embedded-port",
        _mark(_v("name: f1,", "name: f1, connection: 'udpout:127.0.0.1:14600',"), "14600") + GOAL,
        "vehicles[1].connection",
        "base_port + 1",
    ),
    (
        "embedded-sysid",
        _mark(_v("name: f1,", "name: f1, sysid: 5,"), "sysid") + GOAL,
        "vehicles[1].sysid",
        "has sysid 2",
    ),
    (
        "no-leader",
        _mark(VEHICLES.replace("role: leader, ", ""), "vehicles:") + GOAL,
        "vehicles",
        "exactly one must lead",
    ),
    (
        "two-leaders",
        _mark(_v("name: f1,", "name: f1, role: leader,"), "name: f1") + GOAL,
        "vehicles[1].role",
        "second leader",
    ),
    ("empty-vehicles", "vehicles: []  # <-\n" + GOAL, "vehicles", "the list is empty"),
    (
        "leader-slot",
        _mark(_v("role: leader,", "role: leader, slot: [1, 0, 0],"), "slot") + GOAL,
        "vehicles[0].slot",
        "the leader has no slot",
    ),
    (
        "offsets-without-slot",
        _mark(VEHICLES, "name: f1") + GOAL + "formation: {shape: offsets}\n",
        "vehicles[1].slot",
        "every follower needs its slot",
    ),
    (
        "slot-on-leader",
        _mark(_v("name: f1,", "name: f1, slot: [0.1, 0, 0],"), "slot") + GOAL,
        "vehicles[1].slot",
        "slot of the leader",
    ),
    # placement
    (
        "start-in-obstacle",
        _mark(VEHICLES, "name: lead") + GOAL + "world: {obstacles: [{center: [0, 0, 3], radius: 2.9}]}\n",
        "vehicles[0].start.position",
        "inside obstacle world.obstacles[0]",
    ),
    (
        "goal-in-obstacle",
        VEHICLES
        + "goal: [100, 50, 10]  # <-\n"
        + "world: {obstacles: [{center: [101, 50, 10], radius: 1}]}\n",
        "goal",
        "the goal lies inside obstacle",
    ),
    (
        "waypoint-in-obstacle",
        VEHICLES
        + "waypoints:\n  - [50, 0, 10]  # <-\n  - [100, 50, 10]\n"
        + "world: {obstacles: [{center: [50, 0, 12], radius: 3}]}\n",
        "waypoints[0]",
        "this waypoint lies inside",
    ),
    (
        "target-in-obstacle",
        _mark(_v("name: f1,", "name: f1, target: [80, 0, 10],"), "target")
        + GOAL
        + "world: {obstacles: [{center: [80, 0, 10], radius: 3}]}\n",
        "vehicles[1].target",
        "inside obstacle",
    ),
    ("goal-outside-fence", VEHICLES + "goal: [3000, 0, 10]  # <-\n", "goal", "outside the geofence"),
    ("goal-too-low", VEHICLES + "goal: [100, 50, 1]  # <-\n", "goal", "below safety.min_altitude"),
    (
        "starts-overlap",
        _mark(_v("[-10, 0, 0]", "[0.2, 0, 0]"), "[0.2, 0, 0]") + GOAL,
        "vehicles[1].start.position",
        "from the start of vehicles[0]",
    ),
    (
        "ground-start-in-air",
        _mark(_v("[-10, 0, 0]", "[-10, 0, 5]"), "[-10, 0, 5]") + GOAL,
        "vehicles[1].start.position",
        "ground start needs z = 0",
    ),
    (
        "ground-start-moving",
        _mark(_v("{position: [-10, 0, 0]}", "{position: [-10, 0, 0], velocity: [1, 0, 0]}"), "velocity")
        + GOAL,
        "vehicles[1].start.velocity",
        "zero velocity",
    ),
    (
        "airborne-start-too-low",
        _mark(VEHICLES, "name: lead") + GOAL + "run: {airborne_start: true}\n",
        "vehicles[0].start.position",
        "airborne start",
    ),
    # topology
    (
        "relay-without-adjacency",
        MINIMAL + "formation: {topology: relay}  # <-\n",
        "formation.topology",
        "needs formation.adjacency",
    ),
    (
        "adjacency-rows",
        MINIMAL + "formation: {adjacency: [[0, 1]]}  # <-\n",
        "formation.adjacency",
        "expected 2 rows",
    ),
    (
        "adjacency-columns",
        MINIMAL + "formation:\n  adjacency:\n    - [0, 1, 0]  # <-\n    - [1, 0]\n",
        "formation.adjacency[0]",
        "expected 2 entries",
    ),
    (
        "adjacency-not-binary",
        MINIMAL + "formation: {adjacency: [[0, 1], [2, 0]]}  # <-\n",
        "formation.adjacency[1][0]",
        "expected 0 or 1",
    ),
    (
        "adjacency-diagonal",
        MINIMAL + "formation: {adjacency: [[1, 1], [1, 0]]}  # <-\n",
        "formation.adjacency[0][0]",
        "diagonal",
    ),
    (
        "relay-unreachable",
        MINIMAL + "formation: {topology: relay, adjacency: [[0, 1], [0, 0]]}  # <-\n",
        "formation.adjacency",
        "never hears the leader",
    ),
    # structure of the file
    ("missing-goal", _mark(VEHICLES, "vehicles:"), "goal", "required key is missing"),
    ("missing-vehicles", "goal: [100, 50, 10]  # <-\n", "vehicles", "required key is missing"),
    (
        "missing-start",
        _mark(_v("name: f1, start: {position: [-10, 0, 0]}", "name: f1"), "name: f1") + GOAL,
        "vehicles[1].start",
        "required key is missing",
    ),
    ("goal-and-waypoints", VEHICLES + GOAL + "waypoints: [[1, 2, 10]]  # <-\n", "waypoints", "not both"),
    (
        "duplicate-key",
        VEHICLES + GOAL + "goal: [1, 2, 10]  # <-\n",
        "goal",
        "duplicate key (first given on line 4)",
    ),
    (
        "duplicate-nested-key",
        MINIMAL + "run:\n  hold_s: 1\n  hold_s: 2  # <-\n",
        "run.hold_s",
        "duplicate key",
    ),
    (
        "recursive-alias",
        MINIMAL + "mission: &m {name: x, description: *m}  # <-\n",
        "mission.description",
        "contains it",
    ),
]


@pytest.mark.parametrize(
    ("text", "field", "fragment"), [c[1:] for c in MISTAKES], ids=[c[0] for c in MISTAKES]
)
def test_each_mistake_names_file_line_and_field(text: str, field: str, fragment: str) -> None:
    line = next(i for i, content in enumerate(text.splitlines(), 1) if "# <-" in content)
    message = error_of(text, "missions/bad.yaml")
    assert message.startswith(f"missions/bad.yaml:{line}: {field}: "), message
    assert fragment in message, message


@pytest.mark.parametrize(
    ("text", "line", "fragment"),
    [
        ("", 1, "the file is empty"),
        ("# only a comment\n", 1, "the file is empty"),
        ("- lead\n- f1\n", 1, "top level must be a mapping"),
        ("just text\n", 1, "top level must be a mapping"),
        (MINIMAL + "run: {hold_s: [1, 2\n", 6, "YAML syntax error"),
        (MINIMAL + "run:\n\thold_s: 1\n", 6, "YAML syntax error"),
        ("a: 1\n---\nb: 2\n", 2, "single document"),
        ("a: \x00\n", 1, "U+0000"),
        ("[" * 3000, 1, "nested too deeply"),
        ("? [a, b]\n: 1\n", 1, "plain words"),
    ],
    ids=[
        "empty",
        "comment-only",
        "list",
        "scalar",
        "syntax",
        "tab",
        "two-documents",
        "nul",
        "deep",
        "complex-key",
    ],
)
def test_file_level_mistakes_name_file_and_line(text: str, line: int, fragment: str) -> None:
    message = error_of(text, "missions/bad.yaml")
    assert message.startswith(f"missions/bad.yaml:{line}: "), message
    assert fragment in message, message


def test_alias_bombs_are_refused() -> None:
    lines = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 8):
        previous = chr(ord("a") + i - 1)
        lines.append(f"{chr(ord('a') + i)}: &{chr(ord('a') + i)} [" + ", ".join([f"*{previous}"] * 10) + "]")
    assert "more than" in error_of("\n".join(lines) + "\n")


def test_missing_file_names_the_file(tmp_path) -> None:
    path = tmp_path / "nowhere.yaml"
    with pytest.raises(MissionError, match=rf"^{path}: mission file not found$"):
        load_mission(path)


def test_directory_is_not_a_mission(tmp_path) -> None:
    with pytest.raises(MissionError, match="is a directory"):
        load_mission(tmp_path)


def test_binary_file_names_file_and_line(tmp_path) -> None:
    path = tmp_path / "binary.yaml"
    path.write_bytes(MINIMAL.encode() + b"run: {hold_s: \xff}\n")
    with pytest.raises(MissionError, match=rf"^{path}:5: the file is not UTF-8"):
        load_mission(path)


def test_unreadable_path_is_a_mission_error(tmp_path) -> None:
    not_a_folder = tmp_path / "mission.yaml"
    not_a_folder.write_text(MINIMAL)
    path = not_a_folder / "inner.yaml"
    with pytest.raises(MissionError, match=rf"^{path}: cannot read the mission file \(Not a directory\)$"):
        load_mission(path)


def test_load_world_validates_like_load_mission(tmp_path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(VEHICLES + "goal: [100, 50]\n")
    with pytest.raises(MissionError, match=rf"^{path}:4: goal: expected 3 numbers, got 2$"):
        load_world(path)


# ---------------------------------------------------------------- nothing but MissionError, ever (issue 7)

VALID = {
    "mission": {"name": "fuzz"},
    "vehicles": [
        {"name": "lead", "role": "leader", "sysid": 1, "start": {"position": [0, 0, 0], "yaw_deg": 10}},
        {"name": "f1", "slot": [-5, 5, 0], "target": [95, 55, 10], "start": {"position": [-10, 0, 0]}},
        {"name": "f2", "start": {"position": [0, -10, 0]}},
    ],
    "formation": {
        "shape": "v",
        "spacing": 8,
        "topology": "relay",
        "adjacency": [[0, 1, 1], [1, 0, 0], [1, 0, 0]],
    },
    "waypoints": [[50, 0, 10], [100, 50, 10]],
    "world": {
        "obstacles": [{"center": [50, 20, 10], "radius": 3, "velocity": [1, 0, 0]}],
        "wind": {"speed": 2},
        "link": {
            "loss": 0.1,
            "jitter_ms": 100,
            "outages": [{"vehicle": "f2", "start_s": 5, "duration_s": 2}],
        },
    },
    "guidance": {"k_rep": 1e5, "d_g": None, "reference": {"leash": 4}},
    "control": {"smc": {"xy": {"c1": 1.0}}, "pid": {"kp_xy": 1.0}},
    "limits": {"v_xy": 18},
    "safety": {"separation": {"mode": "constant"}, "geofence": {"radius": 500}, "telemetry": {"lost_s": 4}},
    "run": {"time_limit_s": 60, "simulator": {"seed": 3}},
    "planner": {"dimensions": 2, "start": [0, 0, 0]},
}

scalars = (
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=12)
    | st.sampled_from(["leader", "follower", "v", "relay", "udpout:127.0.0.1:14541", "1e5", "0", "-1"])
)
structures = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)
yaml_tokens = st.sampled_from(
    [
        "vehicles:",
        "goal:",
        "\n",
        "  ",
        "- ",
        "{",
        "}",
        "[",
        "]",
        ":",
        ", ",
        "1e5",
        ".inf",
        "null",
        "true",
        "&a ",
        "*a",
        "<<: *a",
        "!!int ",
        "!!float ",
        "!!binary ",
        "'",
        '"',
        "# x",
        "? ",
        "|",
        ">",
        "~",
        "0x1F",
        "12:30",
        "2001-13-45",
        "position: [0, 0, 0]",
        "role: leader",
        "start:",
        "--- ",
        "...",
        "%YAML 1.1\n",
        "\t",
        "\ufeff",
    ]
)


def _parse_or_mission_error(text: str) -> None:
    try:
        parse_mission(text, "fuzz.yaml")
    except MissionError as exc:
        message = str(exc)
        assert message.startswith("fuzz.yaml:") and "\n" not in message, message


def test_the_fuzz_base_is_valid() -> None:
    mission = parse_mission(yaml.safe_dump(VALID), "fuzz.yaml")
    assert mission.formation.topology == "relay" and mission.planner.dimensions == 2
    assert mission.link.outages[0].vehicle == 2 and mission.safety.telemetry.lost_s == 4


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200))
def test_random_text_raises_only_mission_error(text: str) -> None:
    _parse_or_mission_error(text)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(yaml_tokens, max_size=40))
def test_yaml_like_text_raises_only_mission_error(tokens: list[str]) -> None:
    _parse_or_mission_error("".join(tokens))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(structures)
def test_random_structures_raise_only_mission_error(document: object) -> None:
    _parse_or_mission_error(yaml.safe_dump(document))


def _paths(node: object, prefix: tuple = ()) -> list[tuple]:
    found = [prefix] if prefix else []
    if isinstance(node, dict):
        for key, value in node.items():
            found += _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            found += _paths(value, (*prefix, index))
    return found


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_mutated_valid_missions_raise_only_mission_error(data: st.DataObject) -> None:
    document = yaml.safe_load(yaml.safe_dump(VALID))  # a deep copy
    for _ in range(data.draw(st.integers(1, 3))):
        paths = _paths(document)
        path = data.draw(st.sampled_from(paths))
        parent = document
        for step in path[:-1]:
            parent = parent[step]
        action = data.draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "replace":
            parent[path[-1]] = data.draw(structures)
        elif action == "delete" and isinstance(parent, dict):
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[data.draw(st.text(max_size=8))] = data.draw(structures)
        else:
            parent.append(data.draw(structures))
    _parse_or_mission_error(yaml.safe_dump(document))


def test_numbers_beyond_float_range_are_mission_errors() -> None:
    message = error_of(MINIMAL + f"guidance: {{k_att: {10**400}}}\n")
    assert message.startswith("m.yaml:5: guidance.k_att: "), message


def test_signing_key_file_is_relative_to_the_mission_file(tmp_path) -> None:
    assert parse_mission(MINIMAL).run.signing_key_file is None
    path = tmp_path / "m.yaml"
    path.write_text(MINIMAL + "run:\n  signing_key_file: keys/swarm.key\n")
    assert load_mission(path).run.signing_key_file == tmp_path / "keys" / "swarm.key"
    absolute = parse_mission(MINIMAL + "run:\n  signing_key_file: /etc/swarm.key\n")
    assert str(absolute.run.signing_key_file) == "/etc/swarm.key"
    assert "signing_key_file" in error_of(MINIMAL + "run:\n  signing_key_file: [1, 2]\n")


@pytest.mark.parametrize(
    ("key", "value", "autopilot_range"),
    [  # each autopilot's own range for the timing it is given (its dialect's failsafe_ranges)
        ("guided_timeout_s", 5.5, "0.1..5 s (ArduCopter's GUID_TIMEOUT range)"),
        ("guided_timeout_s", 0.05, "0.1..5 s (ArduCopter's GUID_TIMEOUT range)"),
        ("offboard_loss_timeout_s", 61, "0.1..60 s (PX4's COM_OF_LOSS_T range)"),
        ("failsafe_timeout_s", 121, "2..120 s (ArduCopter's FS_GCS_TIMEOUT range)"),
    ],
)
def test_failsafe_timings_outside_an_autopilots_range_are_refused(
    key: str, value: float, autopilot_range: str
):
    message = error_of(MINIMAL + f"safety: {{dead_gcs: {{{key}: {value}}}}}\n")
    assert f"safety.dead_gcs.{key}: {key} ({value:g} s) must lie in {autopilot_range}" in message


def test_failsafe_timings_at_the_ends_of_the_ranges_load() -> None:
    dead_gcs = "{guided_timeout_s: 5, offboard_loss_timeout_s: 0.1, failsafe_timeout_s: 120}"
    mission = parse_mission(MINIMAL + f"safety: {{dead_gcs: {dead_gcs}}}\n")
    assert (mission.safety.dead_gcs.guided_timeout_s, mission.safety.dead_gcs.failsafe_timeout_s) == (5, 120)


def test_a_defaulted_failsafe_timeout_outside_the_range_says_what_to_lower() -> None:
    message = error_of(MINIMAL + "safety: {telemetry: {lost_s: 130}}\n")
    assert "failsafe_timeout_s (130 s) must lie in 2..120 s" in message and "lower that" in message
