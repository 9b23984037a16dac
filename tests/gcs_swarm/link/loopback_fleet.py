"""A fleet on real loopback sockets, fed datagrams by sockets playing its vehicles, for the intake tests.

Every datagram goes through the ground station's one way in (Network.receive -> link.intake), whatever the
endpoint: each vehicle on its own udpout endpoint (the simulator's form), or all of them sharing one udpin
endpoint (told apart by sysid); optionally with a signing key and with a forward whose receiving socket
the test reads.
"""

from __future__ import annotations

import socket
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.forward import ForwardConfig
from gcs_swarm.link.vehicle import VehicleConfig

ORIGIN = (47.397742, 8.545594, 488.0)
SYSID, COMPID = 7, 1
KEY = bytes(range(32))


def encoder(sysid: int = SYSID, compid: int = COMPID, key: bytes | None = None) -> mavlink2.MAVLink:
    """A vehicle's MAVLink 2 encoder (signing with `key` when given)."""
    mav = mavlink2.MAVLink(None, sysid, compid)
    if key is not None:
        signing.sign_outgoing(mav, key)
    return mav


def heartbeat(mav: mavlink2.MAVLink) -> bytes:
    """An ArduCopter HEARTBEAT (binds the vehicle at the ground station)."""
    return mav.heartbeat_encode(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 89, 4, 4, 3
    ).pack(mav)


def _socket() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    return sock


class LoopbackFleet:
    """A fleet of `vehicles` vehicles (sysids SYSID, SYSID + 1, ...), each played by a loopback socket;
    `shared`: they share one udpin endpoint (else one udpout endpoint each); `key`: the fleet's signing key;
    `forward`: a forward to a socket (`forward_socket`) the test reads."""

    def __init__(
        self,
        tmp: Path,
        vehicles: int = 1,
        shared: bool = False,
        key: bytes | None = None,
        forward: bool = False,
    ) -> None:
        self.sockets = [_socket() for _ in range(vehicles)]
        if shared:
            port_holder = _socket()
            port = port_holder.getsockname()[1]
            port_holder.close()
            connections = [f"udpin:127.0.0.1:{port}"] * vehicles
        else:
            connections = [f"udpout:127.0.0.1:{s.getsockname()[1]}" for s in self.sockets]
        configs = [VehicleConfig(f"v{i}", c, sysid=SYSID + i) for i, c in enumerate(connections)]
        self.forward_socket = _socket() if forward else None
        forwards = (
            [ForwardConfig(f"udpout:127.0.0.1:{self.forward_socket.getsockname()[1]}")]
            if self.forward_socket is not None
            else []
        )
        self.tlog = tmp / "fleet.tlog"
        self.fleet = Fleet(configs, ORIGIN, tlog_path=self.tlog, signing_key=key, forwards=forwards)
        self.fleet.network.open(5.0, self.tlog)
        self.state = self.fleet.state
        self.gcs: list[tuple[str, int]] = []
        for i, (link, sock) in enumerate(zip(self.fleet.links, self.sockets, strict=True)):
            if shared:
                self.gcs.append(("127.0.0.1", int(connections[i].rsplit(":", 1)[1])))
            else:
                link.heartbeat.send()  # the udpout socket gets its local port; the vehicle learns it
                self.gcs.append(sock.recvfrom(2048)[1])
            sock.setblocking(False)
        if self.forward_socket is not None:
            self.forward_socket.setblocking(False)
        self.from_gcs: list[list[bytes]] = [[] for _ in self.sockets]
        self.forwarded: list[bytes] = []

    def stats(self, i: int = 0):  # noqa: ANN201 - LinkStats
        return self.fleet.links[i].channel.stats

    def feed(self, datagrams: list[bytes], senders: list[int] | None = None) -> None:
        """Send the datagrams (datagram k by vehicle senders[k], default vehicle 0) and let the ground station
        read them all, then collect what it sent back and what it forwarded."""
        for k, datagram in enumerate(datagrams):
            i = 0 if senders is None else senders[k]
            self.sockets[i].sendto(datagram, self.gcs[i])
        seen = -1
        while seen != self._seen():  # until a wait of 10 ms reads nothing more
            seen = self._seen()
            self.fleet.network.receive(0.01)
        for i, sock in enumerate(self.sockets):
            self.from_gcs[i] += _drain(sock)
        if self.forward_socket is not None:
            self.forwarded += _drain(self.forward_socket)

    def _seen(self) -> int:
        return sum(link.channel.stats.received for link in self.fleet.links) + self.fleet.network.unrouted

    def vehicle_records(self) -> list[bytes]:
        """The packets of the tlog's records that came from the vehicles (sysids SYSID...), in order."""
        network = self.fleet.network
        assert network._tlog is not None
        network._tlog.flush()
        data = self.tlog.read_bytes()
        sysids = range(SYSID, SYSID + len(self.sockets))
        packets, k = [], 0
        while k < len(data):
            k += 8  # big-endian us timestamp
            size = 12 + data[k + 1] + (13 if data[k + 2] & mavlink2.MAVLINK_IFLAG_SIGNED else 0)
            if data[k + 5] in sysids:
                packets.append(data[k : k + size])
            k += size
        return packets

    def close(self) -> None:
        self.fleet.network.close()
        for sock in self.sockets:
            sock.close()
        if self.forward_socket is not None:
            self.forward_socket.close()


def _drain(sock: socket.socket) -> list[bytes]:
    out = []
    while True:
        try:
            out.append(sock.recv(65535))
        except BlockingIOError:
            return out
