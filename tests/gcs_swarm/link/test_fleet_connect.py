"""Connecting: HEARTBEAT, sysid checks, shared udpin routing (against fake vehicles on 127.0.0.1)."""

from __future__ import annotations

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import LinkError, new_parser
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig
from tests.gcs_swarm.link.fake_vehicle import ORIGIN, free_udp_port

FAST_HEARTBEAT = {"HEARTBEAT": 10.0}


def decoded(sender: mavlink2.MAVLink, msg: mavlink2.MAVLink_message) -> mavlink2.MAVLink_message:
    """The message as received from `sender` (header included)."""
    return new_parser().parse_buffer(bytes(msg.pack(sender)))[0]


def test_connect_binds_sysid_and_sends_gcs_heartbeat(fake, fleet_of) -> None:
    vehicle = fake(5)
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    link = fleet.vehicle("lead")
    assert link.sysid == 5 and link.compid == 1
    assert fleet.alive.tolist() == [True]
    fleet.wait_until(lambda: vehicle.received["HEARTBEAT"] > 0, 2.0, "the GCS heartbeat at the vehicle")
    assert vehicle.received["HEARTBEAT"] >= 1


def test_connect_times_out_naming_the_silent_vehicle(fleet_of) -> None:
    port = free_udp_port()
    fleet = Fleet([VehicleConfig("lead", f"udpout:127.0.0.1:{port}")], ORIGIN)
    try:
        with pytest.raises(
            LinkError, match=rf"no HEARTBEAT within 0.3 s from lead \(udpout:127.0.0.1:{port}\)"
        ):
            fleet.connect(timeout_s=0.3)
    finally:
        fleet.close()


def test_wrong_sysid_is_refused(fake, fleet_of) -> None:
    fleet = fleet_of(fake(3, streams=FAST_HEARTBEAT), names=["lead"], sysids=[1])
    with pytest.raises(
        LinkError, match=r"^lead \(udpout:127.0.0.1:\d+\) reports sysid 3, but the mission gives it sysid 1"
    ):
        fleet.connect(timeout_s=3.0)


def test_two_endpoints_reporting_one_sysid_are_refused(fake, fleet_of) -> None:
    fleet = fleet_of(fake(1), fake(1), names=["f1", "f2"])
    with pytest.raises(LinkError, match=r"^f1 \(udpout:.*\) and f2 \(udpout:.*\) both report sysid 1"):
        fleet.connect(timeout_s=3.0)


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


def test_shared_udpin_routes_two_lockstep_vehicles_by_sysid(fake) -> None:
    port = free_udp_port()
    connection = f"udpin:127.0.0.1:{port}"
    gcs = ("127.0.0.1", port)
    v1 = fake(1, lockstep=True, gcs_address=gcs, position=(10.0, 0.0, 0.0))
    v2 = fake(2, lockstep=True, gcs_address=gcs, position=(0.0, -20.0, 0.0))
    configs = [VehicleConfig("north", connection, 1), VehicleConfig("south", connection, 2)]
    with Fleet(configs, ORIGIN) as fleet:
        fleet.connect(timeout_s=3.0)
        fleet.request_streams_all(50.0)
        for _ in range(20):  # both simulated clocks only advance if each gets its own answers
            assert fleet.wait_tick(timeout_s=3.0)
            fleet.answer_frame()
        np.testing.assert_allclose(fleet.pos[:, :2], [[10.0, 0.0], [0.0, -20.0]], atol=0.02)
        assert fleet.run([fleet.vehicle("south").parameters.op_get("MOT_THST_HOVER")])[0] == pytest.approx(
            0.35
        )
    assert {target for _, _, target in v1.commands} == {1}
    assert {target for _, _, target in v2.commands} == {2}
    assert v1.lockstep_drops == 0 and v2.lockstep_drops == 0
    assert v1.t_ms >= 400 and v2.t_ms >= 400


def test_packets_of_another_sysid_on_a_connection_are_ignored(fake) -> None:
    port = free_udp_port()
    gcs = ("127.0.0.1", port)
    fake(
        1, gcs_address=gcs, streams={**FAST_HEARTBEAT, "GLOBAL_POSITION_INT": 10.0}, position=(5.0, 0.0, 0.0)
    )
    with Fleet([VehicleConfig("lead", f"udpin:127.0.0.1:{port}")], ORIGIN) as fleet:
        fleet.connect(timeout_s=3.0)
        assert fleet.vehicle("lead").sysid == 1
        fake(
            2,
            gcs_address=gcs,
            streams={**FAST_HEARTBEAT, "GLOBAL_POSITION_INT": 10.0},
            position=(-5.0, 0.0, 0.0),
        )
        fleet.wait_until(lambda: any("sysid 2" in e.text for e in fleet.events), 3.0, "the event")
        fleet.wait_until(lambda: fleet.vehicle("lead").channel.stats.ignored > 2, 3.0, "ignored packets")
        assert fleet.pos[0, 0] == pytest.approx(5.0, abs=0.02)
        event = next(e for e in fleet.events if "sysid 2" in e.text)
        assert event.vehicle == "lead" and "ignored" in event.text


def test_sysid_heard_from_two_addresses_on_a_shared_udpin_is_refused(fake) -> None:
    port = free_udp_port()
    gcs = ("127.0.0.1", port)
    fake(2, gcs_address=gcs, streams=FAST_HEARTBEAT)
    fake(2, gcs_address=gcs, streams=FAST_HEARTBEAT)
    connection = f"udpin:127.0.0.1:{port}"
    configs = [VehicleConfig("a", connection, 1), VehicleConfig("b", connection, 2)]
    with Fleet(configs, ORIGIN) as fleet:
        with pytest.raises(LinkError, match=r"b's sysid 2 is heard from several addresses on udpin"):
            fleet.connect(timeout_s=3.0)


def test_heartbeat_from_a_gcs_does_not_bind(fake, fleet_of) -> None:
    vehicle = fake(7)
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
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
