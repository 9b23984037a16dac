"""The ground station's geofence (gcs_swarm.flight.geofence): which obstacles become exclusion circles and how
big (hand-worked), and the mission protocol against a running sitl-sim, also under 20 % packet loss each way:
upload, verify by download, clear, a refused fence, install_fence in preflight and its restore."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator

import numpy as np
import pytest

from gcs_swarm.flight import geofence as fence
from gcs_swarm.link import frames
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.flight_params import FlightParams
from gcs_swarm.link.vehicle import VehicleConfig
from gcs_swarm.mission.loader import parse_mission
from tests.sitl_sim.sim_process import SimProcess, start_sim

ORIGIN = (-35.0, 149.0, 500.0)

MISSION = """
origin: {lat: -35.0, lon: 149.0, alt: 500.0}
vehicles:
  - {name: lead, role: leader, start: {position: [0, 0, 0]}}
goal: [200, 0, 10]
formation: {altitude: 10}
world:
  obstacles:
    - {center: [100, 20, 10], radius: 4}                 # A: at the formation's altitude
    - {center: [60, -30, 16], radius: 5}                 # B: its centre 6 m above the formation
    - {center: [150, 0, 30], radius: 5}                  # C: 20 m above: out of the band
    - {center: [120, 40, 10], radius: 2, velocity: [1, 0, 0]}   # D: moves
    - {center: [0, 13, 10], radius: 4}                   # E: 13 m from the start
    - {center: [0, -5, 10], radius: 4}                   # F: 5 m from the start
safety:
  collision_radius: 0.5
  dead_gcs: {fence: {enabled: true, margin_m: 8}}
"""


def test_exclusion_circles_by_hand():
    mission = parse_mission(MISSION, "fence.yaml")
    circles, notes = fence.exclusion_circles(mission, 8.0)
    # the band is the formation's 10 m (slot and waypoints) +- 3 m = 7..13 m
    # A: cross-section 4 m + body 0.5 + margin 8 = 12.5 m
    # B: the band's nearest height 13 m is 3 m below its centre: cross-section sqrt(5^2 - 3^2) = 4 m -> 12.5 m
    # C: 17 m above the band's top, more than its radius + body: left out
    # D: moving: left out
    # E: would be 4 + 0.5 + 8 = 12.5 m, but must stay 0.5 + 1 m clear of the start 13 m away: 11.5 m
    # F: the start is 5 m away: 5 - 1.5 = 3.5 m would not even cover the obstacle + body (4.5 m): left out
    assert [(c.obstacle, c.centre, c.radius) for c in circles] == [
        (0, (100.0, 20.0), 12.5),
        (1, (60.0, -30.0), 12.5),
        (4, (0.0, 13.0), 11.5),
    ]
    assert len(notes) == 4
    assert "obstacle 2 does not reach" in notes[0] and "obstacle 3 moves" in notes[1]
    assert "obstacle 4: fence radius 11.5 m instead of 12.5 m" in notes[2]
    assert "obstacle 5 stands too close" in notes[3]


def test_circle_items_are_the_centres_in_degE7():
    circle = fence.FenceCircle(0, (100.0, 20.0), 12.5)
    (item,) = fence.circle_items([circle], ORIGIN)
    assert item.command == fence.CIRCLE_EXCLUSION and item.param1 == 12.5
    back = frames.geodetic_rows_to_enu([(item.lat_e7 * 1e-7, item.lon_e7 * 1e-7, ORIGIN[2])], ORIGIN)[0]
    assert np.allclose(back[:2], (100.0, 20.0), atol=0.02)  # 1e-7 deg is 1.1 cm


@pytest.fixture
def sim_fleet(request: pytest.FixtureRequest) -> Iterator[tuple[SimProcess, Fleet]]:
    """A lockstep sitl-sim of one vehicle (extra arguments: indirect parametrisation), a connected Fleet."""
    args = ["--lockstep", "--ready-delay", "1", "--home=-35.0,149.0,500.0", *getattr(request, "param", [])]
    sim = start_sim(*args, vehicles=1)
    fleet = Fleet([VehicleConfig("lead", f"udpout:127.0.0.1:{sim.port(0)}", 1)], ORIGIN)
    try:
        fleet.connect(timeout_s=10.0)
        yield sim, fleet
    finally:
        fleet.close()
        sim.stop(signal.SIGKILL if sim.proc.poll() is None else signal.SIGTERM, timeout_s=5.0)


def _circles(k: int) -> list[fence.FenceItem]:
    return fence.circle_items([fence.FenceCircle(j, (30.0 * j, 50.0), 5.0 + j) for j in range(k)], ORIGIN)


@pytest.mark.parametrize(
    "sim_fleet", [["--link-loss", "0.2", "--link-jitter-ms", "30", "--seed", "7"]], indirect=True
)
def test_upload_verify_and_clear_under_packet_loss(sim_fleet):
    sim, fleet = sim_fleet
    link = fleet.vehicle("lead")
    items = _circles(6)
    assert fleet.run([fence.op_download_fence(link)]) == [[]]
    fleet.run([fence.op_put_fence(link, items)])  # upload, then read back and compare
    stored = fleet.run([fence.op_download_fence(link)])[0]
    assert len(stored) == 6 and all(a.same_as(b) for a, b in zip(stored, items, strict=True))
    fleet.run([fence.op_put_fence(link, [])])  # clear, verified
    assert fleet.run([fence.op_download_fence(link)]) == [[]]
    code, err = sim.stop(signal.SIGTERM)
    assert code == 0 and "link_lost=0" not in err  # packets were really lost on the way


def test_a_refused_fence_is_an_error_with_the_vehicles_reason(sim_fleet):
    _, fleet = sim_fleet
    link = fleet.vehicle("lead")
    bad = [fence.FenceItem(fence.CIRCLE_EXCLUSION, -350_000_000, 1_490_000_000, 0.0)]
    with pytest.raises(LinkError, match=r"refused the fence: MISSION_ACK ERROR .*Fence validation failed"):
        fleet.run([fence.op_upload_fence(link, bad)])
    with pytest.raises(LinkError, match="NO_SPACE"):
        fleet.run([fence.op_upload_fence(link, _circles(1) * 71)])


def test_install_fence_sets_the_params_reports_breaches_and_restores(sim_fleet):
    _, fleet = sim_fleet
    mission = parse_mission(MISSION, "fence.yaml")
    link = fleet.vehicle("lead")
    old = _circles(2)
    fleet.run([fence.op_put_fence(link, old)])  # the vehicle had a fence of its own
    flight, events, said = FlightParams(fleet), [], []
    install = fence.install_fence(fleet, flight, mission, events, said.append)
    assert install is not None and len(install.items) == 3
    stored = fleet.run([fence.op_download_fence(link)])[0]
    assert all(a.same_as(b) for a, b in zip(stored, install.items, strict=True))
    assert [
        fleet.run([link.parameters.op_get(name)])[0]
        for name in ("FENCE_TYPE", "FENCE_ACTION", "FENCE_ENABLE")
    ] == [4, 4, 1]
    assert [c.name for c in flight.changes] == ["fence items", "FENCE_TYPE", "FENCE_ACTION", "FENCE_ENABLE"]
    assert len([e for e in events if e.startswith("fence: obstacle")]) == 4
    link.handle(_statustext("Polygon fence breached"), time.monotonic())  # as the vehicle says it
    assert events[-1].endswith("lead: Polygon fence breached: its autopilot takes over (fence action brake)")
    assert said[-1].startswith("! t=")
    flight.restore()  # disarmed: everything goes back, the old fence too
    assert all(c.restored for c in flight.changes)
    stored = fleet.run([fence.op_download_fence(link)])[0]
    assert len(stored) == 2 and all(a.same_as(b) for a, b in zip(stored, old, strict=True))
    assert [
        fleet.run([link.parameters.op_get(name)])[0]
        for name in ("FENCE_TYPE", "FENCE_ACTION", "FENCE_ENABLE")
    ] == [7, 1, 0]


def _statustext(text: str):  # noqa: ANN202 - a pymavlink message
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    return mavlink2.MAVLink_statustext_message(mavlink2.MAV_SEVERITY_NOTICE, text.encode())
