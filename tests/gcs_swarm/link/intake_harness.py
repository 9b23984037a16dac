"""A fleet on real loopback sockets, fed datagrams by sockets playing its vehicles, and the random datagrams
a vehicle link carries: the harness of the intake comparisons (test_hot_telemetry.py, test_batch_intake.py).

A fleet's intake runs in one of three modes: "general" (every packet a pymavlink message through
Network.accept and VehicleLink.handle, the reference), "hot" (HotTelemetry takes the 50 Hz telemetry from
the bytes, packet by packet) and "batch" (BatchIntake takes whole datagrams in one compiled call and hands
the rest to the hot path)."""

from __future__ import annotations

import dataclasses
import math
import socket
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig

ORIGIN = (47.397742, 8.545594, 488.0)
SYSID, COMPID = 7, 1
KEY = bytes(range(32))


WALL_FIELDS = ("clock_wall", "walls", "progress_wall", "last_rx_wall")  # wall-clock stamps, not packet data
MODES = ("general", "hot", "batch")


class FleetUnderTest:
    """A fleet of `vehicles` vehicles on udpout endpoints, each fed by a loopback socket playing it (sysid
    SYSID + i), its intake in `mode` (module doc)."""

    def __init__(self, tmp: Path, mode: str, vehicles: int = 1) -> None:
        assert mode in MODES
        self.mode = mode
        self.sockets = []
        configs = []
        for i in range(vehicles):
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.bind(("127.0.0.1", 0))
            self.sockets.append(sock)
            configs.append(
                VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{sock.getsockname()[1]}", sysid=SYSID + i)
            )
        self.vehicle = self.sockets[0]
        self.tlog = tmp / f"{mode}.tlog"
        self.fleet = Fleet(configs, ORIGIN, tlog_path=self.tlog)
        self.fleet.network.hot_intake = mode != "general"
        self.fleet.network.batch = mode == "batch"
        self.fleet.network.open(5.0, self.tlog)
        self.link = self.fleet.links[0]
        self.gcs = []
        for link, sock in zip(self.fleet.links, self.sockets, strict=True):
            link.heartbeat.send()  # binds the udpout socket to a local port
            self.gcs.append(sock.recvfrom(2048)[1])
            sock.setblocking(False)
        self.taken = 0
        hot_path = self.fleet.network._hot.get(self.link.channel.endpoint)  # type: ignore[arg-type]
        if hot_path is not None:
            take = hot_path.take

            def counting_take(data: bytes, start: int, end: int) -> object:
                taken = take(data, start, end)
                self.taken += taken is not None
                return taken

            hot_path.take = counting_take  # type: ignore[method-assign]
        self.from_gcs: list[list[bytes]] = [[] for _ in self.sockets]

    @property
    def batch(self) -> Any:
        """The fleet's BatchIntake (None: the mode does not use it)."""
        return self.fleet.network._batch

    def feed(self, datagrams: list[bytes], senders: list[int] | None = None) -> None:
        """Send the datagrams (datagram k by vehicle senders[k], default vehicle 0) and read them all (the
        loopback has them once sendto returns)."""
        for k, datagram in enumerate(datagrams):
            i = 0 if senders is None else senders[k]
            self.sockets[i].sendto(datagram, self.gcs[i])
        received = -1
        while received != self._received():  # until a wait of 10 ms reads nothing more
            received = self._received()
            self.fleet.network.receive(0.01)
        for i, sock in enumerate(self.sockets):  # what the ground station sent back (GCS HEARTBEATs)
            while True:
                try:
                    self.from_gcs[i].append(sock.recv(2048))
                except BlockingIOError:
                    break

    def _received(self) -> int:
        return sum(link.channel.stats.received for link in self.fleet.links) + self.fleet.network.unrouted

    def observed(self) -> dict[str, Any]:
        """Everything the intake decides, without wall-clock stamps."""
        st_vars = {
            k: v for k, v in vars(self.fleet.state).items() if k not in WALL_FIELDS and not k.startswith("_")
        }
        return {
            "state": st_vars,
            "pos": self.fleet.state.pos,
            "stats": [dataclasses.asdict(link.channel.stats) for link in self.fleet.links],
            "events": [(e.vehicle, e.text, e.severity, e.time_s) for e in self.fleet.events],
            "sysid": [link.sysid for link in self.fleet.links],
            "vehicle_packets": self.vehicle_packets(),
            "from_gcs": self.from_gcs,
        }

    def vehicle_packets(self) -> list[bytes]:
        """The tlog's records of packets from the vehicles (their sysids), timestamps left out."""
        self.fleet.network._tlog.flush()  # type: ignore[union-attr]
        data = self.tlog.read_bytes()
        sysids = range(SYSID, SYSID + len(self.sockets))
        packets, k = [], 0
        while k < len(data):
            k += 8  # big-endian us timestamp
            if data[k] == mavlink2.PROTOCOL_MARKER_V2:
                size = 12 + data[k + 1] + (13 if data[k + 2] & mavlink2.MAVLINK_IFLAG_SIGNED else 0)
            else:
                size = 8 + data[k + 1]
            if data[k + 5 if data[k] == mavlink2.PROTOCOL_MARKER_V2 else k + 3] in sysids:
                packets.append(data[k : k + size])
            k += size
        return packets

    def close(self) -> None:
        self.fleet.network.close()
        for sock in self.sockets:
            sock.close()


def same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool(np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return bool(a == b)


def encoder(sysid: int = SYSID, compid: int = COMPID, signed: bool = False) -> mavlink2.MAVLink:
    mav = mavlink2.MAVLink(None, sysid, compid)
    if signed:
        signing.sign_outgoing(mav, KEY)
    return mav


ANGLE = st.one_of(st.floats(-4.0, 4.0, width=32), st.sampled_from([math.nan, math.inf, -math.inf]))
TIME_MS = st.integers(0, 12_000)  # forward steps, late packets and (a backstep over 5 s) reboots


@st.composite
def packet(draw: st.DrawFn, sysid: int = SYSID, time_ms: st.SearchStrategy[int] = TIME_MS) -> bytes:
    """One packet of the kinds a vehicle link carries (vehicle `sysid`, stamped with a `time_ms`), sometimes
    from another system or component, signed or damaged."""
    kind = draw(
        st.sampled_from(["position", "position", "attitude", "attitude", "heartbeat", "text", "tick"])
    )
    sender = draw(st.sampled_from([(sysid, COMPID)] * 6 + [(sysid + 1, COMPID), (sysid, 2)]))
    mav = encoder(*sender, signed=draw(st.booleans().filter(lambda _: True)) and draw(st.integers(0, 9)) == 0)
    t_ms = draw(time_ms)
    if kind == "position":
        lat = draw(st.one_of(st.integers(-900_000_000, 900_000_000), st.sampled_from([950_000_000, 0])))
        lon = draw(st.integers(-1_800_000_001, 1_800_000_001))
        vel = draw(st.tuples(*[st.integers(-32768, 32767)] * 3))
        msg = mav.global_position_int_encode(
            t_ms, lat, lon, draw(st.integers(-(2**31), 2**31 - 1)), 0, *vel, 0
        )
    elif kind == "attitude":
        msg = mav.attitude_encode(t_ms, draw(ANGLE), draw(ANGLE), draw(ANGLE), 0.0, 0.0, 0.0)
    elif kind == "heartbeat":
        msg = mav.heartbeat_encode(2, 3, 89, draw(st.integers(0, 6)), 4, 3)
    elif kind == "text":
        msg = mav.statustext_encode(4, b"PreArm: Need Position Estimate")
    else:
        msg = mav.system_time_encode(0, t_ms)  # a lockstep clock tick
    data = bytearray(msg.pack(mav))
    damage = draw(st.sampled_from(["none"] * 8 + ["crc", "payload"]))
    if damage == "crc":
        data[-1] ^= 0xFF
    elif damage == "payload" and len(data) > 12:
        data[10] ^= 0x55
    return bytes(data)


@st.composite
def datagram(draw: st.DrawFn, sysid: int = SYSID, time_ms: st.SearchStrategy[int] = TIME_MS) -> bytes:
    """1-4 packets (`packet`), sometimes cut short or followed by garbage."""
    data = b"".join(draw(st.lists(packet(sysid, time_ms), min_size=1, max_size=4)))
    tail = draw(st.sampled_from(["none"] * 6 + ["cut", "garbage"]))
    if tail == "cut":
        data = data[: draw(st.integers(1, len(data)))]
    elif tail == "garbage":
        data += draw(st.binary(min_size=1, max_size=20))
    return data


def bind(fleet: FleetUnderTest) -> None:
    """Every vehicle says HEARTBEAT: the fleet binds their sysids."""
    heartbeats = []
    for i in range(len(fleet.sockets)):
        mav = encoder(SYSID + i)
        heartbeats.append(mav.heartbeat_encode(2, 3, 89, 4, 4, 3).pack(mav))
    fleet.feed(heartbeats, list(range(len(fleet.sockets))))
    assert [link.sysid for link in fleet.fleet.links] == [SYSID + i for i in range(len(fleet.sockets))]
