"""Signing both ways: with a key, the ground station refuses unsigned, forged and replayed packets from a
vehicle's endpoint before they reach its state (the arrays guidance reads), and counts them per vehicle.

The vehicle is a plain UDP socket speaking pymavlink on loopback; the fleet listens on a udpin endpoint and
is driven through Network.receive only (no heartbeats, no stream requests)."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig
from swarm_common.ports import free_udp_base
from swarm_common.signing_keys import timestamp_now

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
ORIGIN = (47.397742, 8.545594, 488.0)
LAT0, LON0 = 473977420, 85455940  # 1e7 deg: the origin
NORTH_1M = 90  # 1e7 deg of latitude per ~1 m (1e7 / 111 km)


class Vehicle:
    """A vehicle of sysid 1 on its own socket: packs with `mav` (signed with `key` unless None)."""

    def __init__(self, port: int, key: bytes | None, link_id: int = 0) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.gcs = ("127.0.0.1", port)
        self.mav = mavlink2.MAVLink(None, 1, 1)
        if key is not None:
            signing.sign_outgoing(self.mav, key, link_id)

    def pack_position(self, t_ms: int, north_m: float) -> bytes:
        lat = LAT0 + int(north_m * NORTH_1M)
        return bytes(
            self.mav.global_position_int_encode(t_ms, lat, LON0, 498000, 10000, 0, 0, 0, 0).pack(self.mav)
        )

    def heartbeat(self) -> bytes:
        return bytes(
            self.mav.heartbeat_encode(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3, 3
            ).pack(self.mav)
        )

    def send(self, packet: bytes) -> None:
        self.sock.sendto(packet, self.gcs)


@pytest.fixture
def signed_fleet() -> Iterator[tuple[Fleet, int]]:
    """A fleet of one vehicle (sysid 1) listening on udpin 127.0.0.1:PORT, with KEY: (fleet, PORT)."""
    port = free_udp_base(1)
    fleet = Fleet([VehicleConfig("v0", f"udpin:127.0.0.1:{port}", sysid=1)], ORIGIN, signing_key=KEY)
    fleet.network.open(1.0, None)
    yield fleet, port
    fleet.close()


def settle(fleet: Fleet) -> None:
    """Read what loopback delivered (a few short polls)."""
    for _ in range(5):
        fleet.network.receive(0.05)


def test_spoofed_positions_never_reach_the_state_guidance_reads(signed_fleet) -> None:
    fleet, port = signed_fleet
    genuine = Vehicle(port, KEY)
    genuine.send(genuine.heartbeat() + genuine.pack_position(1000, 0.0))
    settle(fleet)
    link = fleet.links[0]
    assert link.sysid == 1
    assert int(fleet.state.position_count[0]) == 1
    north0 = fleet.pos[0, 1]

    held_back = genuine.pack_position(
        5000, 40.0
    )  # signed now, delivered late: a replay of an older signature
    newer = genuine.pack_position(4000, 1.0)
    genuine.send(newer)
    settle(fleet)
    assert int(fleet.state.position_count[0]) == 2
    expected = fleet.pos.copy()
    assert expected[0, 1] - north0 == pytest.approx(1.0, abs=0.05)

    unsigned = Vehicle(port, None)  # a spoofer on another address, claiming sysid 1
    forged = Vehicle(port, OTHER_KEY)  # signed, with the wrong key
    old_stream = Vehicle(port, KEY, link_id=7)  # the right key, but a new stream timestamped 2 min ago
    old_stream.mav.signing.timestamp = timestamp_now() - 12_000_000
    for spoofer in (unsigned, forged):
        spoofer.send(spoofer.pack_position(9000, 100.0))
    old_stream.send(old_stream.pack_position(9000, 100.0))
    genuine.send(held_back)  # its time_boot_ms is the newest yet: only the signature timestamp refuses it
    genuine.send(newer)  # the same bytes again
    settle(fleet)

    assert int(fleet.state.position_count[0]) == 2
    np.testing.assert_array_equal(fleet.pos, expected)
    assert int(fleet.time_ms[0]) == 4000
    stats = fleet.stats()["v0"]
    assert stats["unsigned"] == 1
    assert stats["bad_signature"] == 4  # forged, old stream, held back, replayed
    assert stats["bad"] == 0
    router = link.channel.endpoint
    assert router is not None
    assert router.addresses[1] == [genuine.sock.getsockname()]  # a spoofer's address is never learnt

    genuine.send(genuine.pack_position(6000, 2.0))  # the genuine link keeps working
    settle(fleet)
    assert int(fleet.state.position_count[0]) == 3
    assert fleet.pos[0, 1] - north0 == pytest.approx(2.0, abs=0.05)
    for v in (genuine, unsigned, forged, old_stream):
        v.sock.close()


def test_unsigned_heartbeat_does_not_bind_a_signed_fleet(signed_fleet) -> None:
    fleet, port = signed_fleet
    spoofer = Vehicle(port, None)
    spoofer.send(spoofer.heartbeat() + spoofer.pack_position(1000, 5.0))
    settle(fleet)
    assert fleet.links[0].sysid is None
    assert int(fleet.state.position_count[0]) == 0
    assert fleet.stats()["v0"]["unsigned"] == 2
    spoofer.sock.close()


def test_radio_status_may_come_unsigned(signed_fleet) -> None:
    """ArduPilot's rule, applied by both programs: a radio modem cannot sign its RADIO_STATUS."""
    fleet, port = signed_fleet
    genuine, radio = Vehicle(port, KEY), Vehicle(port, None)
    genuine.send(genuine.heartbeat())
    settle(fleet)
    radio.send(bytes(radio.mav.radio_status_encode(200, 190, 100, 10, 20, 0, 0).pack(radio.mav)))
    settle(fleet)
    stats = fleet.stats()["v0"]
    assert stats["unsigned"] == 0 and stats["received"] == 2
    genuine.sock.close()
    radio.sock.close()
