"""The site fence uploaded to the autopilots (issue 37 item 5, safety.geofence.upload): its fence items
(hand-checked: commands, vertex counts, positions back within 1.1 cm), the simulated ArduCopter's breach
rule on them (outside the inclusion polygon, inside an exclusion polygon or circle, AC_PolyFence_loader::
breached), and install_fence against a running sitl-sim: stored beside the obstacle circles, verified by
download, FENCE_* set, and the vehicle's own fence and parameters restored afterwards."""

from __future__ import annotations

import dataclasses
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from gcs_swarm.flight import geofence as fence
from gcs_swarm.link import frames
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.flight_params import FlightParams
from gcs_swarm.link.vehicle import VehicleConfig
from gcs_swarm.mission.loader import load_mission, parse_mission
from sitl_sim.autopilot import fence as sim_fence
from tests.sitl_sim.sim_process import SimProcess, start_sim

ROOT = Path(__file__).resolve().parents[3]
ORIGIN = (-35.0, 149.0, 500.0)
MISSION = """
origin: {lat: -35.0, lon: 149.0, alt: 500.0}
vehicles:
  - {name: lead, role: leader, start: {position: [0, 0, 0]}}
goal: [60, 0, 10]
formation: {altitude: 10}
world:
  obstacles:
    - {center: [40, -10, 10], radius: 2}
safety:
  geofence:
    polygon: [[-30, -25], [90, -25], [90, 30], [30, 40], [-30, 30]]
    exclusions:
      - {name: hangar, polygon: [[20, 20], [40, 20], [40, 30], [20, 30]]}
      - {name: pond, center: [70, -20], radius: 3}
    upload: true
  dead_gcs: {fence: {enabled: true, margin_m: 2}}
"""
PENTAGON = [[-30, -25], [90, -25], [90, 30], [30, 40], [-30, 30]]
HANGAR = [[20, 20], [40, 20], [40, 30], [20, 30]]


def _enu(item: fence.FenceItem) -> np.ndarray:
    return frames.geodetic_rows_to_enu([(item.lat_e7 * 1e-7, item.lon_e7 * 1e-7, ORIGIN[2])], ORIGIN)[0][:2]


def test_site_items_are_the_polygons_vertices_then_the_circles() -> None:
    mission = parse_mission(MISSION, "site.yaml")
    items = fence.site_items(mission.fence, mission.origin)
    expected = [(fence.POLYGON_INCLUSION, 5.0, v) for v in PENTAGON]
    expected += [(fence.POLYGON_EXCLUSION, 4.0, v) for v in HANGAR]
    expected += [(fence.CIRCLE_EXCLUSION, 3.0, [70, -20])]  # param1: the vertex count, or the radius m
    assert [(item.command, item.param1) for item in items] == [(c, p) for c, p, _ in expected]
    for item, (_, _, where) in zip(items, expected, strict=True):
        np.testing.assert_allclose(_enu(item), where, atol=0.02)  # 1e-7 deg is 1.1 cm


def test_the_simulated_arducopter_breaches_outside_the_polygon_and_inside_the_zones() -> None:
    mission = parse_mission(MISSION, "site.yaml")
    items = fence.site_items(mission.fence, mission.origin)
    assert (
        sim_fence.validate([sim_fence.FenceItem(i.command, i.lat_e7, i.lon_e7, i.param1) for i in items])
        is None
    )
    fences = sim_fence.Fences(1)
    fences.store(
        0,
        [sim_fence.FenceItem(i.command, i.lat_e7, i.lon_e7, i.param1) for i in items],
        np.array([_enu(i) for i in items]),
    )
    # (where, breached, distance m): 5 m east of the pentagon's east edge x = 90; 5 m into the hangar (its
    # edges y = 20 and 30 are 5 m away); 1 m into the pond (3 - 2); at the start, inside, 25 m from the south
    # edge (a negative distance: inside, as AC_Fence keeps it)
    for where, breached, distance in [
        ((95, 0), True, 5.0),
        ((30, 25), True, 5.0),
        ((70, -18), True, 1.0),
        ((0, 0), False, None),
    ]:
        hit, depth = fences.zones_breached(np.array([where], dtype=float))
        assert bool(hit[0]) == breached, where
        if distance is not None:
            assert depth[0] == pytest.approx(distance, abs=0.03), where


@pytest.fixture
def sim_fleet() -> Iterator[tuple[SimProcess, Fleet]]:
    """A lockstep sitl-sim of one vehicle at the mission's origin, a connected Fleet."""
    sim = start_sim("--lockstep", "--ready-delay", "1", "--home=-35.0,149.0,500.0", vehicles=1)
    fleet = Fleet([VehicleConfig("lead", f"udpout:127.0.0.1:{sim.port(0)}", 1)], ORIGIN)
    try:
        fleet.connect(timeout_s=10.0)
        yield sim, fleet
    finally:
        fleet.close()
        sim.stop(signal.SIGKILL if sim.proc.poll() is None else signal.SIGTERM, timeout_s=5.0)


def test_install_fence_uploads_the_site_with_the_obstacle_circles_and_restores(sim_fleet) -> None:
    _, fleet = sim_fleet
    mission = parse_mission(MISSION, "site.yaml")
    link = fleet.vehicle("lead")
    flight, events, said = FlightParams(fleet), list[str](), list[str]()
    install = fence.install_fence(fleet, flight, mission, events, said.append)
    # one obstacle circle, then 5 + 4 vertices and the pond
    assert install is not None and len(install.items) == 1 + 5 + 4 + 1
    assert install.items[0].command == fence.CIRCLE_EXCLUSION
    assert install.items[1:] == fence.site_items(mission.fence, mission.origin)
    stored = fleet.run([fence.op_download_fence(link)])[0]
    assert len(stored) == 11 and all(a.same_as(b) for a, b in zip(stored, install.items, strict=True))
    assert [
        fleet.run([link.parameters.op_get(name)])[0]
        for name in ("FENCE_TYPE", "FENCE_ACTION", "FENCE_ENABLE")
    ] == [4, 4, 1]
    assert "the site fence (10 items)" in said[-1]
    flight.restore()  # disarmed: the vehicle's empty fence and its parameters come back
    assert fleet.run([fence.op_download_fence(link)]) == [[]]
    assert [
        fleet.run([link.parameters.op_get(name)])[0]
        for name in ("FENCE_TYPE", "FENCE_ACTION", "FENCE_ENABLE")
    ] == [7, 1, 0]


RALLY_MISSION = MISSION.replace(
    "  dead_gcs: {fence: {enabled: true, margin_m: 2}}\n",
    "  dead_gcs: {fence: {enabled: true, margin_m: 2}}\n  rally: [[80, 10, 12.4], [-20, 20, 15.6]]\n",
)


def test_rally_items_are_points_above_home_in_whole_metres() -> None:
    mission = parse_mission(RALLY_MISSION, "site.yaml")
    items = fence.rally_items(mission.rally, mission.origin)
    # MAV_CMD_NAV_RALLY_POINT, no param1, z rounded to whole metres (ArduPilot's RallyLocation.alt: int16)
    assert [(item.command, item.param1, item.alt_m) for item in items] == [
        (fence.RALLY_POINT, 0.0, 12.0),
        (fence.RALLY_POINT, 0.0, 16.0),
    ]
    np.testing.assert_allclose(_enu(items[0]), [80, 10], atol=0.02)
    np.testing.assert_allclose(_enu(items[1]), [-20, 20], atol=0.02)


def test_rally_points_are_shared_out_one_a_vehicle_by_least_total_distance() -> None:
    mission = load_mission(ROOT / "missions" / "quickstart.yaml")  # starts lead (0, 0), right (-1.5, -10),
    # left (-10, 1.5)
    points = [np.array(p) for p in ([10.0, -35.0, 15.0], [-35.0, 10.0, 15.0], [25.0, 20.0, 15.0])]
    got = fence.rally_by_vehicle(dataclasses.replace(mission, rally=tuple(points)))
    # by hand: lead-(25, 20) 32.0 m, right-(10, -35) 27.5 m, left-(-35, 10) 26.4 m, 85.9 m in all; every
    # other one-to-one choice is longer (e.g. lead-(10, -35) 36.4 + right-(25, 20) 40.0 + left 26.4 = 102.8)
    assert {name: [tuple(p[:2]) for p in given] for name, given in got.items()} == {
        "lead": [(25.0, 20.0)],
        "right": [(10.0, -35.0)],
        "left": [(-35.0, 10.0)],
    }
    # one point for three: the vehicle nearest to it (left, 26.4 m) holds it, the others none (home)
    got = fence.rally_by_vehicle(dataclasses.replace(mission, rally=(points[1],)))
    assert [len(got[name]) for name in ("lead", "right", "left")] == [0, 0, 1]
    assert fence.rally_by_vehicle(mission) == {}


def test_install_fence_uploads_rally_points_and_restores(sim_fleet) -> None:
    _, fleet = sim_fleet
    mission = parse_mission(RALLY_MISSION, "site.yaml")
    link = fleet.vehicle("lead")
    flight, events, said = FlightParams(fleet), list[str](), list[str]()
    install = fence.install_fence(fleet, flight, mission, events, said.append)
    # the one vehicle holds the point nearer its start (0, 0): (-20, 20) 28.3 m, not (80, 10) 80.6 m
    mine = fence.rally_items(mission.rally, mission.origin)[1:]
    assert install is not None and install.rally == {"lead": mine}
    stored = fleet.run([fence.op_download_fence(link, mission_type=fence.RALLY)])[0]
    assert len(stored) == 1 and stored[0].same_as(mine[0])
    assert len(fleet.run([fence.op_download_fence(link)])[0]) == 11  # the fence beside them, unchanged
    names = ("RALLY_TOTAL", "RALLY_INCL_HOME", "RALLY_LIMIT_KM")
    # RALLY_TOTAL follows the upload; home excluded and no distance limit: RTL takes the vehicle's point
    assert [fleet.run([link.parameters.op_get(name)])[0] for name in names] == [1, 0, 0]
    assert "2 rally point(s), one a vehicle" in said[-1]
    rows = {c.name: c for c in flight.changes}
    assert (rows["rally items"].original, rows["rally items"].flown) == (0.0, 1.0)
    flight.restore()
    assert fleet.run([fence.op_download_fence(link, mission_type=fence.RALLY)]) == [[]]
    # Copter's defaults back (sitl_sim params.py: RALLY_INCL_HOME 1, RALLY_LIMIT_KM 0.3)
    got = [fleet.run([link.parameters.op_get(name)])[0] for name in names]
    assert got[:2] == [0, 1] and got[2] == pytest.approx(0.3)
    assert all(c.restored for c in flight.changes)


@pytest.fixture
def px4_fleet() -> Iterator[Fleet]:
    """A lockstep sitl-sim of one PX4 vehicle at the mission's origin, a connected Fleet."""
    sim = start_sim(
        "--lockstep", "--ready-delay", "1", "--home=-35.0,149.0,500.0", "--autopilot", "px4", vehicles=1
    )
    fleet = Fleet([VehicleConfig("lead", f"udpout:127.0.0.1:{sim.port(0)}", 1)], ORIGIN)
    try:
        fleet.connect(timeout_s=10.0)
        yield fleet
    finally:
        fleet.close()
        sim.stop(signal.SIGKILL if sim.proc.poll() is None else signal.SIGTERM, timeout_s=5.0)


@pytest.mark.sim  # px4_fleet starts a sitl-sim (tests/conftest.py)
def test_install_on_px4_sets_gf_action_and_rtl_type_reports_violations_and_restores(px4_fleet) -> None:
    fleet = px4_fleet
    mission = parse_mission(RALLY_MISSION, "site.yaml")
    link = fleet.vehicle("lead")
    flight, events, said = FlightParams(fleet), list[str](), list[str]()
    install = fence.install_fence(fleet, flight, mission, events, said.append)
    assert install is not None and len(fleet.run([fence.op_download_fence(link)])[0]) == 11
    assert len(fleet.run([fence.op_download_fence(link, mission_type=fence.RALLY)])[0]) == 1
    # dead_gcs.fence.action brake -> GF_ACTION 2 (Hold mode), PX4's default already: no change row; RTL_TYPE
    # from 0 to 1 (rally points before home); no ArduPilot parameter asked
    assert [fleet.run([link.parameters.op_get(name)])[0] for name in ("GF_ACTION", "RTL_TYPE")] == [2, 1]
    assert [c.name for c in flight.changes] == ["fence items", "rally items", "RTL_TYPE"]
    link.handle(_statustext("Geofence violation"), time.monotonic())  # as PX4's navigator says it
    assert events[-1].endswith("lead: Geofence violation: its autopilot takes over (fence action brake)")
    flight.restore()
    assert all(c.restored for c in flight.changes)
    assert fleet.run([fence.op_download_fence(link)]) == [[]]
    assert fleet.run([fence.op_download_fence(link, mission_type=fence.RALLY)]) == [[]]
    assert fleet.run([link.parameters.op_get("RTL_TYPE")])[0] == 0


def _statustext(text: str):  # noqa: ANN202 - a pymavlink message
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    return mavlink2.MAVLink_statustext_message(mavlink2.MAV_SEVERITY_CRITICAL, text.encode())
