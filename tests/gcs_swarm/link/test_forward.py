"""Forwarding (gcs_swarm.link.forward through Network): every vehicle frame reaches the forward unchanged;
a forward's frames reach the vehicle their target_system names, only when the forward's mode and the
signing key let them through.

Vehicles and the forwarded ground station are plain UDP sockets speaking pymavlink on loopback; the fleet
(vehicles on udpout, the forward on udpout) is driven through Network.receive only."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.forward import FORWARD_DATAGRAM_BYTES, ForwardConfig
from gcs_swarm.link.vehicle import VehicleConfig
from swarm_common.ports import free_udp_base

KEY = bytes(range(32))
ORIGIN = (47.397742, 8.545594, 488.0)
M = mavlink2


class Peer:
    """A socket bound on loopback `port` that packs as (sysid, compid), signed with `key` if given."""

    def __init__(self, port: int, sysid: int, compid: int, key: bytes | None = None) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", port))
        self.sock.settimeout(0.05)
        self.mav = M.MAVLink(None, sysid, compid)
        if key is not None:
            signing.sign_outgoing(self.mav, key, link_id=3)
        self.address: tuple[str, int] | None = None  # where the ground station's datagrams come from

    def pack(self, msg: M.MAVLink_message) -> bytes:
        return bytes(msg.pack(self.mav))

    def datagrams(self) -> list[bytes]:
        """Everything received so far (waits briefly for loopback)."""
        out = []
        while True:
            try:
                data, self.address = self.sock.recvfrom(65535)
            except TimeoutError:
                return out
            out.append(data)

    def send(self, packet: bytes) -> None:
        assert self.address is not None, "the ground station has not spoken to this peer yet"
        self.sock.sendto(packet, self.address)


def split_frames(datagrams: list[bytes]) -> list[bytes]:
    """The MAVLink packets in datagrams, as bytes (parsed without a key: signatures are not checked)."""
    parser = M.MAVLink(None)
    return [bytes(m.get_msgbuf()) for d in datagrams for m in parser.parse_buffer(d) or []]


def heartbeat(peer: Peer) -> bytes:
    return peer.pack(
        peer.mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3, 3)
    )


def set_mode(peer: Peer, target: int) -> bytes:
    """COMMAND_LONG DO_SET_MODE LOITER (ArduCopter custom mode 5) to `target`."""
    return peer.pack(peer.mav.command_long_encode(target, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 5, 0, 0, 0, 0, 0))


Rig = tuple[Fleet, list[Peer], Peer]


@pytest.fixture
def rig() -> Iterator[Callable[..., Rig]]:
    """Factory: rig(read_write=False, key=None) -> (fleet, [vehicle sysid 1, vehicle sysid 2], forward peer
    of sysid 250), the vehicles bound (they sent a HEARTBEAT) and the forward's address learnt."""
    made: list[Rig] = []

    def make(read_write: bool = False, key: bytes | None = None) -> Rig:
        base = free_udp_base(3)
        vehicles = [Peer(base + i, 1 + i, 1, key) for i in range(2)]
        qgc = Peer(base + 2, 250, 190, key)
        configs = [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{base + i}", sysid=1 + i) for i in range(2)]
        forward = ForwardConfig(f"udpout:127.0.0.1:{base + 2}", read_write)
        fleet = Fleet(configs, ORIGIN, signing_key=key, forwards=[forward])
        fleet.network.open(1.0, None)
        made.append((fleet, vehicles, qgc))
        for link in fleet.links:  # the fleet speaks first (udpout), so that the vehicles learn its address
            link.heartbeat.send_if_due(0.0)
        for v in vehicles:
            v.datagrams()
            v.send(heartbeat(v))
        pump(fleet)
        assert [link.sysid for link in fleet.links] == [1, 2]
        qgc.datagrams()
        return fleet, vehicles, qgc

    yield make
    for fleet, vehicles, qgc in made:
        fleet.close()
        for peer in [*vehicles, qgc]:
            peer.sock.close()


def pump(fleet: Fleet) -> None:
    for _ in range(4):
        fleet.network.receive(0.03)


def test_every_vehicle_frame_reaches_the_forward_unchanged(rig) -> None:
    fleet, (v1, v2), qgc = rig()
    sent = [heartbeat(v1), heartbeat(v2)]
    sent += [v1.pack(v1.mav.global_position_int_encode(1000 + k, 1, 2, 3, 4, 5, 6, 7, 8)) for k in range(60)]
    for packet in sent:
        (v1 if packet[5] == 1 else v2).send(packet)
    pump(fleet)
    datagrams = qgc.datagrams()
    got = split_frames(datagrams)
    for sysid in (1, 2):  # same bytes, in each vehicle's order (the vehicles' sockets are read in any order)
        assert [f for f in got if f[5] == sysid] == [f for f in sent if f[5] == sysid]
    assert len(got) == len(sent)
    assert all(len(d) <= FORWARD_DATAGRAM_BYTES for d in datagrams)
    assert len(datagrams) < len(sent)  # packed several to a datagram
    assert fleet.forward_stats()[qgc_name(fleet)]["sent"] == 2 + len(sent)  # the rig's binding HEARTBEATs too


def qgc_name(fleet: Fleet) -> str:
    return fleet.network.forwards[0].name


def test_read_only_forward_may_read_parameters_but_not_command(rig) -> None:
    fleet, (v1, v2), qgc = rig()
    refused = [
        set_mode(qgc, 1),
        qgc.pack(qgc.mav.param_set_encode(1, 1, b"WPNAV_SPEED", 100.0, M.MAV_PARAM_TYPE_REAL32)),
        qgc.pack(qgc.mav.command_long_encode(0, 0, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)),
        heartbeat(qgc),
    ]
    read = qgc.pack(qgc.mav.param_request_read_encode(2, 1, b"WPNAV_SPEED", -1))
    for packet in [*refused, read]:
        qgc.send(packet)
    pump(fleet)
    assert split_frames(v1.datagrams()) == []
    assert read in split_frames(v2.datagrams())
    stats = fleet.forward_stats()[qgc_name(fleet)]
    assert (stats["commands_refused"], stats["routed"]) == (len(refused), 1)


def test_read_write_forward_is_routed_by_target_system(rig) -> None:
    fleet, (v1, v2), qgc = rig(read_write=True)
    to_v1, to_all, to_nobody = set_mode(qgc, 1), set_mode(qgc, 0), set_mode(qgc, 9)
    for packet in (to_v1, to_all, to_nobody):
        qgc.send(packet)
    pump(fleet)
    assert [f for f in split_frames(v1.datagrams()) if f[5] == 250] == [to_v1, to_all]
    assert [f for f in split_frames(v2.datagrams()) if f[5] == 250] == [to_all]
    stats = fleet.forward_stats()[qgc_name(fleet)]
    assert (stats["routed"], stats["unrouted"]) == (2, 1)


def test_reserved_sources_and_the_ground_stations_own_messages_never_pass(rig) -> None:
    fleet, (v1, v2), qgc = rig(read_write=True)
    posing_as_gcs, posing_as_v2 = M.MAVLink(None, 255, 190), M.MAVLink(None, 2, 1)
    packets = [
        bytes(M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 5, 0, 0, 0, 0, 0).pack(mav))
        for mav in (posing_as_gcs, posing_as_v2)
    ]
    packets += [
        qgc.pack(qgc.mav.system_time_encode(0, 10**9)),  # would answer a lockstep frame
        qgc.pack(qgc.mav.timesync_encode(0, 1)),
        qgc.pack(qgc.mav.set_attitude_target_encode(10**9, 1, 1, 0, [1, 0, 0, 0], 0, 0, 0, 0.5)),
        qgc.pack(qgc.mav.request_data_stream_encode(1, 1, 0, 2, 1)),
        qgc.pack(qgc.mav.setup_signing_encode(1, 1, bytes(32), 0)),  # would change the fleet's key
        qgc.pack(
            qgc.mav.command_long_encode(1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 33, 1e6, 0, 0, 0, 0, 0)
        ),
    ]
    for packet in packets:
        qgc.send(packet)
    pump(fleet)
    assert [f for f in split_frames(v1.datagrams() + v2.datagrams()) if f[5] != 255 or f[6] != 190] == []
    assert fleet.forward_stats()[qgc_name(fleet)]["reserved"] == len(packets)


def test_unsigned_forward_commands_never_reach_a_signing_vehicle(rig) -> None:
    fleet, (v1, v2), qgc = rig(read_write=True, key=KEY)
    stranger = M.MAVLink(None, 250, 190)  # what the forward would send without the fleet's key
    unsigned = bytes(
        M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 5, 0, 0, 0, 0, 0).pack(stranger)
    )
    forged_mav = M.MAVLink(None, 250, 190)
    signing.sign_outgoing(forged_mav, bytes(32), link_id=3)
    forged = bytes(
        M.MAVLink_command_long_message(1, 1, M.MAV_CMD_DO_SET_MODE, 0, 1, 5, 0, 0, 0, 0, 0).pack(forged_mav)
    )
    signed = set_mode(qgc, 1)  # carries a valid signature made with the fleet's key by the forward itself
    for packet in (unsigned, forged, signed, signed):  # the last one replayed
        qgc.send(packet)
    pump(fleet)
    from_forward = [f for f in split_frames(v1.datagrams()) if f[5] == 250]
    assert from_forward == [signed]  # unchanged: the ground station never re-signs a forward's frame
    stats = fleet.forward_stats()[qgc_name(fleet)]
    assert (stats["unsigned"], stats["bad_signature"], stats["routed"]) == (1, 2, 1)
