"""The byte-level intake of the 50 Hz telemetry (gcs_swarm.link.hot_telemetry) against the general path
(every packet a pymavlink message through Network.accept and VehicleLink.handle, `hot_intake=False`): two
fleets of one vehicle each, on real loopback sockets, receive the same random datagrams (valid, late,
rebooting, invalid values, other systems and components, corrupted, truncated, signed, garbage), and end with
the same state, counters, events and tlog records of the vehicle's packets."""

from __future__ import annotations

import dataclasses
import math
import socket
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig

ORIGIN = (47.397742, 8.545594, 488.0)
SYSID, COMPID = 7, 1
KEY = bytes(range(32))
WALL_FIELDS = ("clock_wall",)  # wall-clock stamps: when a packet was read, not what it said


class FleetUnderTest:
    """A fleet of one vehicle on a udpout endpoint, fed by a loopback socket playing the vehicle."""

    def __init__(self, tmp: Path, hot: bool) -> None:
        self.vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.vehicle.bind(("127.0.0.1", 0))
        port = self.vehicle.getsockname()[1]
        self.tlog = tmp / f"{'hot' if hot else 'general'}.tlog"
        config = VehicleConfig("v0", f"udpout:127.0.0.1:{port}", sysid=SYSID)
        self.fleet = Fleet([config], ORIGIN, tlog_path=self.tlog)
        self.fleet.network.hot_intake = hot
        self.fleet.network.open(5.0, self.tlog)
        self.link = self.fleet.links[0]
        self.link.heartbeat.send()  # binds the udpout socket to a local port
        self.gcs = self.vehicle.recvfrom(2048)[1]
        self.taken = 0
        hot_path = self.fleet.network._hot.get(self.link.channel.endpoint)  # type: ignore[arg-type]
        if hot_path is not None:
            take = hot_path.take

            def counting_take(data: bytes, start: int, end: int) -> object:
                taken = take(data, start, end)
                self.taken += taken is not None
                return taken

            hot_path.take = counting_take  # type: ignore[method-assign]

    def feed(self, datagrams: list[bytes]) -> None:
        """Send the datagrams and read them all (the loopback has them once sendto returns)."""
        for datagram in datagrams:
            self.vehicle.sendto(datagram, self.gcs)
        received = -1
        while received != self._received():  # until a wait of 10 ms reads nothing more
            received = self._received()
            self.fleet.network.receive(0.01)

    def _received(self) -> int:
        stats = self.link.channel.stats
        return stats.received + self.fleet.network.unrouted

    def observed(self) -> dict[str, Any]:
        """Everything the intake decides, without wall-clock stamps."""
        st_vars = {
            k: v for k, v in vars(self.fleet.state).items() if k not in WALL_FIELDS and not k.startswith("_")
        }
        telemetry = self.link.telemetry
        return {
            "state": st_vars,
            "pos": self.fleet.state.pos,
            "stats": dataclasses.asdict(self.link.channel.stats),
            "events": [(e.vehicle, e.text, e.severity, e.time_s) for e in self.fleet.events],
            "latest_ms": dict(telemetry._latest_ms),
            "progress_ms": telemetry._progress_ms,
            "sysid": self.link.sysid,
            "vehicle_packets": self.vehicle_packets(),
        }

    def vehicle_packets(self) -> list[bytes]:
        """The tlog's records of packets from the vehicle (its sysid), timestamps left out."""
        self.fleet.network._tlog.flush()  # type: ignore[union-attr]
        data = self.tlog.read_bytes()
        packets, k = [], 0
        while k < len(data):
            k += 8  # big-endian us timestamp
            if data[k] == mavlink2.PROTOCOL_MARKER_V2:
                size = 12 + data[k + 1] + (13 if data[k + 2] & mavlink2.MAVLINK_IFLAG_SIGNED else 0)
            else:
                size = 8 + data[k + 1]
            if data[k + 5 if data[k] == mavlink2.PROTOCOL_MARKER_V2 else k + 3] == SYSID:
                packets.append(data[k : k + size])
            k += size
        return packets

    def close(self) -> None:
        self.fleet.network.close()
        self.vehicle.close()


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
def packet(draw: st.DrawFn) -> bytes:
    """One packet of the kinds a vehicle link carries, sometimes from another system or component, signed
    or damaged."""
    kind = draw(
        st.sampled_from(["position", "position", "attitude", "attitude", "heartbeat", "text", "tick"])
    )
    sender = draw(st.sampled_from([(SYSID, COMPID)] * 6 + [(SYSID + 1, COMPID), (SYSID, 2)]))
    mav = encoder(*sender, signed=draw(st.booleans().filter(lambda _: True)) and draw(st.integers(0, 9)) == 0)
    t_ms = draw(TIME_MS)
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
def datagram(draw: st.DrawFn) -> bytes:
    """1-4 packets, sometimes cut short or followed by garbage."""
    data = b"".join(draw(st.lists(packet(), min_size=1, max_size=4)))
    tail = draw(st.sampled_from(["none"] * 6 + ["cut", "garbage"]))
    if tail == "cut":
        data = data[: draw(st.integers(1, len(data)))]
    elif tail == "garbage":
        data += draw(st.binary(min_size=1, max_size=20))
    return data


def bind(fleet: FleetUnderTest) -> None:
    mav = encoder()
    fleet.feed([mav.heartbeat_encode(2, 3, 89, 4, 4, 3).pack(mav)])
    assert fleet.link.sysid == SYSID


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(datagrams=st.lists(datagram(), min_size=1, max_size=12), bound=st.booleans())
def test_hot_and_general_intake_agree(tmp_path: Path, datagrams: list[bytes], bound: bool) -> None:
    hot, general = FleetUnderTest(tmp_path, hot=True), FleetUnderTest(tmp_path, hot=False)
    try:
        for fleet in (hot, general):
            if bound:
                bind(fleet)
            fleet.feed(datagrams)
        hot_seen, general_seen = hot.observed(), general.observed()
        different = [k for k in general_seen if not same(hot_seen[k], general_seen[k])]
        assert not different, {k: (hot_seen[k], general_seen[k]) for k in different}
        assert general.taken == 0
    finally:
        hot.close()
        general.close()


def test_the_hot_path_takes_the_streamed_telemetry(tmp_path: Path) -> None:
    """Without this, the comparison above could hold because the byte path never takes anything: a bound
    vehicle's valid GLOBAL_POSITION_INT and ATTITUDE are taken, and turn into the state the general path
    makes of them (values worked out by hand from the fields)."""
    fleet = FleetUnderTest(tmp_path, hot=True)
    try:
        bind(fleet)
        mav = encoder()
        position = mav.global_position_int_encode(2000, 473977420, 85455940, 498000, 10000, 120, -40, 3, 9000)
        attitude = mav.attitude_encode(2000, 0.1, -0.2, 0.0, 0.0, 0.0, 0.0)
        fleet.feed([position.pack(mav) + attitude.pack(mav)])
        assert fleet.taken == 2
        state = fleet.fleet.state
        assert state.geodetic[0] == pytest.approx([47.397742, 8.545594, 498.0])
        assert state.vel[0] == pytest.approx([-0.40, 1.20, -0.03])  # ENU from NED cm/s
        roll, pitch, yaw = state.att[0]
        assert (roll, pitch) == pytest.approx((0.1, 0.2), abs=1e-7) and yaw == pytest.approx(math.pi / 2)
        assert state.position_ms[0] == 2000 and fleet.link.channel.stats.received == 3
        assert fleet.vehicle_packets()[-2:] == [bytes(position.get_msgbuf()), bytes(attitude.get_msgbuf())]
    finally:
        fleet.close()


def test_the_field_order_is_pymavlinks() -> None:
    """The byte path picks handler arguments by field name from the wire-order unpack; a message whose
    payload is the struct of known values gives those values back."""
    from gcs_swarm.link.hot_telemetry import ATTITUDE_FIELDS, POSITION_FIELDS

    cls = mavlink2.MAVLink_global_position_int_message
    wire = dict(time_boot_ms=5, lat=6, lon=7, alt=8, relative_alt=9, vx=10, vy=11, vz=12, hdg=13)
    payload = struct.pack(cls.unpacker.format, *(wire[name] for name in cls.ordered_fieldnames))
    assert POSITION_FIELDS.pick(POSITION_FIELDS.unpacker.unpack(payload)) == (5, 6, 7, 8, 10, 11, 12)
    cls_att = mavlink2.MAVLink_attitude_message
    values = dict(time_boot_ms=3, roll=0.5, pitch=0.25, yaw=-0.125, rollspeed=1, pitchspeed=2, yawspeed=4)
    payload = struct.pack(cls_att.unpacker.format, *(values[name] for name in cls_att.ordered_fieldnames))
    assert ATTITUDE_FIELDS.pick(ATTITUDE_FIELDS.unpacker.unpack(payload)) == (3, 0.5, 0.25, -0.125)
