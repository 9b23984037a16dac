"""Connecting: HEARTBEAT, sysid checks, shared udpin routing (against simulated vehicles on 127.0.0.1, through
wire taps; on a udpin connection the taps send to the ground station, as vehicles behind radios do)."""

from __future__ import annotations

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import LinkError, new_parser
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig
from swarm_common.ports import free_udp_base
from tests.gcs_swarm.link.simulated_vehicles import ORIGIN, SPACING_M


def decoded(sender: mavlink2.MAVLink, msg: mavlink2.MAVLink_message) -> mavlink2.MAVLink_message:
    """The message as received from `sender` (header included)."""
    return new_parser().parse_buffer(bytes(msg.pack(sender)))[0]


def test_connect_binds_sysid_and_sends_gcs_heartbeat(simulator, fleet_of) -> None:
    wire = simulator(1, sysid_base=5).tap(0)
    fleet = fleet_of(wire, names=["lead"])
    fleet.connect(timeout_s=10.0)
    link = fleet.vehicle("lead")
    assert link.sysid == 5 and link.compid == 1
    assert fleet.alive.tolist() == [True]
    fleet.wait_until(
        lambda: any(m.get_srcSystem() == 255 for m in wire.sent("HEARTBEAT")), 2.0, "the GCS heartbeat"
    )


def test_connect_times_out_naming_the_silent_vehicle() -> None:
    port = free_udp_base(1)  # nothing listens there
    fleet = Fleet([VehicleConfig("lead", f"udpout:127.0.0.1:{port}")], ORIGIN)
    try:
        with pytest.raises(
            LinkError, match=rf"no HEARTBEAT within 0.3 s from lead \(udpout:127.0.0.1:{port}\)"
        ):
            fleet.connect(timeout_s=0.3)
    finally:
        fleet.close()


def test_wrong_sysid_is_refused(simulator, fleet_of) -> None:
    # at 20 x real time (not lockstep: nobody answers a vehicle it refuses) its 1 Hz HEARTBEATs come quickly
    vehicles = simulator(1, "--speedup", "20", "--ready-delay", "0", sysid_base=3)
    fleet = fleet_of(vehicles.tap(0), names=["lead"], sysids=[1])
    with pytest.raises(
        LinkError, match=r"^lead \(udpout:127.0.0.1:\d+\) reports sysid 3, but the mission gives it sysid 1"
    ):
        fleet.connect(timeout_s=10.0)


def test_two_endpoints_reporting_one_sysid_are_refused(simulator, fleet_of) -> None:
    vehicles = simulator(1)
    fleet = fleet_of(vehicles.tap(0), vehicles.tap(0), names=["f1", "f2"])  # two radios, one vehicle
    with pytest.raises(LinkError, match=r"^f1 \(udpout:.*\) and f2 \(udpout:.*\) both report sysid 1"):
        fleet.connect(timeout_s=10.0)


def test_fleet_configuration_mistakes() -> None:
    with pytest.raises(LinkError, match="used twice"):
        Fleet([VehicleConfig("a", "udpout:127.0.0.1:1"), VehicleConfig("a", "udpout:127.0.0.1:2")], ORIGIN)
    with pytest.raises(LinkError, match="a and b are both given sysid 2"):
        Fleet(
            [VehicleConfig("a", "udpout:127.0.0.1:1", 2), VehicleConfig("b", "udpout:127.0.0.1:2", 2)], ORIGIN
        )
    same = [VehicleConfig("a", "udpout:127.0.0.1:14541"), VehicleConfig("b", "udpout:127.0.0.1:14541")]
    with Fleet(same, ORIGIN) as fleet, pytest.raises(LinkError, match="a, b share the connection"):
        fleet.connect(timeout_s=0.5)
    shared = [VehicleConfig("a", "udpin:127.0.0.1:14551", 1), VehicleConfig("b", "udpin:127.0.0.1:14551")]
    with Fleet(shared, ORIGIN) as fleet, pytest.raises(LinkError, match="give each of them its sysid"):
        fleet.connect(timeout_s=0.5)


def test_shared_udpin_routes_two_lockstep_vehicles_by_sysid(simulator) -> None:
    port = free_udp_base(1)
    connection = f"udpin:127.0.0.1:{port}"
    gcs = ("127.0.0.1", port)
    vehicles = simulator(2)  # sysids 1 and 2, standing at x = 0 and 5 m
    w1, w2 = vehicles.tap(0, gcs_address=gcs), vehicles.tap(1, gcs_address=gcs)
    configs = [VehicleConfig("west", connection, 1), VehicleConfig("east", connection, 2)]
    with Fleet(configs, ORIGIN) as fleet:
        fleet.connect(timeout_s=10.0)
        for _ in range(20):  # the simulated clock only advances if each vehicle gets its own answers
            assert fleet.wait_tick(timeout_s=3.0)
            fleet.answer_frame()
        np.testing.assert_allclose(fleet.pos[:, :2], [[0.0, 0.0], [SPACING_M, 0.0]], atol=0.02)
        hover = fleet.run([fleet.vehicle("east").parameters.op_get("MOT_THST_HOVER")])[0]
        assert hover == w2.received("PARAM_VALUE")[-1].param_value
    assert {m.target_system for m in w1.sent("COMMAND_LONG")} == {1}
    assert {m.target_system for m in w2.sent("COMMAND_LONG")} == {2}
    assert w1.sent("PARAM_REQUEST_READ") == []  # the east parameter request went to east only
    assert vehicles.dropped(w1) == [] and vehicles.dropped(w2) == []
    for wire in (w1, w2):  # 20 answered frames of 20 ms each
        assert max(getattr(m, "time_boot_ms", 0) for m in wire.downlink) >= 400


def test_packets_of_another_sysid_on_a_connection_are_ignored(simulator) -> None:
    port = free_udp_base(1)
    gcs = ("127.0.0.1", port)
    vehicles = simulator(2)
    vehicles.tap(1, gcs_address=gcs)  # sysid 2, at x = 5 m
    with Fleet([VehicleConfig("lead", f"udpin:127.0.0.1:{port}")], ORIGIN) as fleet:
        fleet.connect(timeout_s=10.0)
        assert fleet.vehicle("lead").sysid == 2
        vehicles.tap(0, gcs_address=gcs)  # sysid 1, at x = 0, on the same port
        fleet.wait_until(lambda: any("sysid 1" in e.text for e in fleet.events), 3.0, "the event")
        fleet.wait_until(lambda: fleet.vehicle("lead").channel.stats.ignored > 2, 3.0, "ignored packets")
        assert fleet.pos[0, 0] == pytest.approx(SPACING_M, abs=0.02)
        event = next(e for e in fleet.events if "sysid 1" in e.text)
        assert event.vehicle == "lead" and "ignored" in event.text


def test_sysid_heard_from_two_addresses_on_a_shared_udpin_is_refused(simulator) -> None:
    port = free_udp_base(1)
    gcs = ("127.0.0.1", port)
    vehicles = simulator(1, sysid_base=2)
    vehicles.tap(0, gcs_address=gcs)  # one vehicle behind two radios
    vehicles.tap(0, gcs_address=gcs)
    connection = f"udpin:127.0.0.1:{port}"
    configs = [VehicleConfig("a", connection, 1), VehicleConfig("b", connection, 2)]
    with Fleet(configs, ORIGIN) as fleet:
        with pytest.raises(LinkError, match=r"b's sysid 2 is heard from several addresses on udpin"):
            fleet.connect(timeout_s=10.0)


def test_heartbeat_from_a_gcs_does_not_bind(simulator, fleet_of) -> None:
    fleet = fleet_of(simulator(1, sysid_base=7).tap(0), names=["lead"])
    fleet.connect(timeout_s=10.0)
    link = fleet.vehicle("lead")
    gcs = mavlink2.MAVLink(None, 7, 190)
    fleet.network.accept(link, decoded(gcs, gcs.heartbeat_encode(mavlink2.MAV_TYPE_GCS, 8, 0, 0, 4)), 0.0)
    other = mavlink2.MAVLink(None, 9, 1)
    fleet.network.accept(link, decoded(other, other.heartbeat_encode(2, 3, 0, 0, 3)), 0.0)
    assert (
        link.sysid == 7
        and fleet.network.foreign_heartbeats[link.index] == {9: 1}
        and link.channel.stats.ignored >= 2
    )
