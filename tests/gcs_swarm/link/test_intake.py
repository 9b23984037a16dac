"""The ground station's one way in for telemetry (link.intake, the law in link.intake_kernel), on real
loopback sockets, against independent expectations: packets built with pymavlink's encoder from known field
values, the state they must give worked out by hand or by pymap3d, pymavlink as the reference decoder of
what a datagram holds. Every endpoint kind, signing and forwards go through the same path."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from tests.gcs_swarm.link.loopback_fleet import (
    COMPID,
    KEY,
    ORIGIN,
    SYSID,
    LoopbackFleet,
    encoder,
    heartbeat,
)

LAT, LON, ALT = 473977420, 85455940, 512345  # degE7, degE7, mm AMSL: about 200 m north-east of ORIGIN


def f32(x: float) -> float:
    """x as the float32 on the wire."""
    return float(struct.unpack("<f", struct.pack("<f", x))[0])


def position(mav: mavlink2.MAVLink, t_ms: int, lat: int = LAT, lon: int = LON, vel=(100, 200, -300)) -> bytes:
    return mav.global_position_int_encode(t_ms, lat, lon, ALT, 0, *vel, 0).pack(mav)


def attitude(
    mav: mavlink2.MAVLink, t_ms: int, roll: float = 0.1, pitch: float = 0.2, yaw: float = 0.3
) -> bytes:
    return mav.attitude_encode(t_ms, roll, pitch, yaw, 0.0, 0.0, 0.0).pack(mav)


@pytest.fixture
def fleet(tmp_path: Path):
    f = LoopbackFleet(tmp_path)
    f.mav = encoder()
    f.feed([heartbeat(f.mav)])
    yield f
    f.close()


def test_a_position_and_an_attitude_become_the_state(fleet) -> None:
    """GLOBAL_POSITION_INT: degE7 -> deg, mm -> m, NED cm/s -> ENU m/s (vy, vx, -vz); ATTITUDE: FRD/NED ->
    FLU/ENU (roll, -pitch, pi/2 - yaw); the ENU position is pymap3d's."""
    fleet.feed([position(fleet.mav, 1000) + attitude(fleet.mav, 1000)])
    st_ = fleet.state
    assert st_.geodetic[0].tolist() == pytest.approx([47.397742, 8.545594, 512.345], abs=1e-12)
    assert st_.vel[0].tolist() == pytest.approx([2.0, 1.0, 3.0], abs=1e-12)
    assert st_.att[0].tolist() == [f32(0.1), -f32(0.2), math.pi / 2 - f32(0.3)]
    expected = pymap3d.geodetic2enu(LAT * 1e-7, LON * 1e-7, ALT * 1e-3, *ORIGIN)
    np.testing.assert_allclose(st_.pos[0], expected, atol=1e-6)
    assert st_.time_ms[0] == 1000 and st_.position_count[0] == 1 and st_.alive[0]
    assert fleet.stats().received == 3  # the HEARTBEAT and the two


def test_the_yaw_wraps_into_minus_pi_to_pi(fleet) -> None:
    """NED yaw -2 rad (clockwise from North past West) is ENU pi/2 + 2 rad, i.e. that minus 2 pi."""
    fleet.feed([attitude(fleet.mav, 1000, yaw=-2.0)])
    assert fleet.state.att[0, 2] == pytest.approx(math.pi / 2 - f32(-2.0) - 2 * math.pi, abs=1e-12)


def test_a_late_packet_is_counted_and_left_out_per_kind(fleet) -> None:
    """A position older than the newest position is late; an attitude of that same older stamp is not (its
    kind's newest is older)."""
    fleet.feed(
        [position(fleet.mav, 2000), position(fleet.mav, 1900, lat=LAT + 1000), attitude(fleet.mav, 1900)]
    )
    assert fleet.stats().late == 1
    assert fleet.state.geodetic[0, 0] == pytest.approx(LAT * 1e-7, abs=1e-12)
    assert fleet.state.att[0, 0] == f32(0.1)
    assert fleet.state.time_ms[0] == 2000 and fleet.state.position_ms[0] == 2000


def test_a_reboot_starts_the_frames_again(fleet) -> None:
    """A stamp more than 5 s older than the newest is a reboot, not a late packet: applied, the frames start
    again, and a GCS HEARTBEAT goes at once (the vehicle's new session needs one)."""
    fleet.feed([position(fleet.mav, 20_000)])
    heartbeats_before = len(fleet.from_gcs[0])
    fleet.feed([position(fleet.mav, 100, lat=LAT + 5000)])
    st_ = fleet.state
    assert st_.time_ms[0] == 100 and st_.position_ms[0] == 100 and fleet.stats().late == 0
    assert st_.geodetic[0, 0] == pytest.approx((LAT + 5000) * 1e-7, abs=1e-12)
    assert st_.progress_ms[0] == 0  # the clock does not count back
    assert len(fleet.from_gcs[0]) == heartbeats_before + 1


def test_a_clock_jump_forward_advances_the_fleet_clock(fleet) -> None:
    fleet.feed([position(fleet.mav, 1000), position(fleet.mav, 501_000)])
    assert fleet.state.progress_ms[0] == 500_000 and fleet.state.clock_ms == 500_000
    assert fleet.state.heard_clock_ms[0] == 500_000


@pytest.mark.parametrize(
    ("roll", "pitch", "yaw"), [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, -math.inf)]
)
def test_non_finite_angles_are_invalid(fleet, roll: float, pitch: float, yaw: float) -> None:
    fleet.feed([attitude(fleet.mav, 1000), attitude(fleet.mav, 1020, roll, pitch, yaw)])
    assert fleet.stats().invalid == 1 and fleet.state.att[0, 0] == f32(0.1)
    assert fleet.state.time_ms[0] == 1000  # an invalid packet does not move the clock


@pytest.mark.parametrize(("lat", "lon"), [(900_000_001, LON), (-900_000_001, LON), (LAT, 1_800_000_001)])
def test_positions_out_of_bounds_are_invalid(fleet, lat: int, lon: int) -> None:
    fleet.feed([position(fleet.mav, 1000, lat=lat, lon=lon)])
    assert fleet.stats().invalid == 1 and fleet.state.position_count[0] == 0
    fleet.feed([position(fleet.mav, 1020, lat=900_000_000, lon=-1_800_000_000)])  # the bounds themselves
    assert fleet.state.position_count[0] == 1 and fleet.state.geodetic[0, :2].tolist() == [90.0, -180.0]


def test_the_extreme_climb_rate(fleet) -> None:
    """vz = -32768 cm/s (NED, climbing) is +327.68 m/s up."""
    fleet.feed([position(fleet.mav, 1000, vel=(0, 0, -32768))])
    assert fleet.state.vel[0, 2] == pytest.approx(327.68, abs=1e-12)


def test_trailing_zeros_cut_by_mavlink2_are_restored(fleet) -> None:
    """A position whose last fields are zero is sent shorter (MAVLink 2 truncation): the zeros come back."""
    packet = position(fleet.mav, 1000, vel=(0, 0, 0))
    assert packet[1] < mavlink2.MAVLink_global_position_int_message.unpacker.size
    fleet.feed([packet])
    assert fleet.state.vel[0].tolist() == [0.0, 0.0, 0.0] and fleet.state.position_count[0] == 1


@pytest.mark.parametrize("sender", [(SYSID + 1, COMPID), (SYSID, COMPID + 1)])
def test_other_systems_and_components_are_ignored(fleet, sender: tuple[int, int]) -> None:
    other = encoder(*sender)
    fleet.feed([position(other, 1000) + attitude(other, 1000)])
    assert fleet.state.position_count[0] == 0 and math.isnan(fleet.state.att[0, 0])
    assert fleet.stats().ignored == 2


def test_damaged_truncated_and_garbage_datagrams(fleet) -> None:
    """A bad CRC, a packet cut short at the end of a datagram and garbage are counted bad (BAD_DATA, as
    pymavlink makes them); the whole packets before them in the same datagram are taken, and so are the
    packets of the next datagram."""
    bad_crc = bytearray(position(fleet.mav, 1020))
    bad_crc[-1] ^= 0xFF
    cut = position(fleet.mav, 1040)[:20]
    fleet.feed(
        [attitude(fleet.mav, 1000) + bytes(bad_crc), position(fleet.mav, 1010) + cut, b"\x00\x01garbage"]
    )
    assert fleet.state.time_ms[0] == 1010 and fleet.state.position_count[0] == 1
    assert fleet.stats().bad >= 3
    fleet.feed([position(fleet.mav, 1060)])
    assert fleet.state.position_count[0] == 2


def test_mavlink1_telemetry_goes_through_pymavlink_to_the_same_law(fleet) -> None:
    mav1 = mavlink1.MAVLink(None, SYSID, COMPID)
    packet = mav1.global_position_int_encode(1000, LAT, LON, ALT, 0, 100, 200, -300, 0).pack(mav1)
    assert packet[0] == mavlink2.PROTOCOL_MARKER_V1
    fleet.feed([packet])
    assert fleet.state.position_count[0] == 1 and fleet.state.vel[0].tolist() == pytest.approx(
        [2.0, 1.0, 3.0]
    )


def test_the_tlog_records_every_vehicle_packet_as_received(fleet) -> None:
    datagrams = [position(fleet.mav, 1000) + attitude(fleet.mav, 1000), attitude(fleet.mav, 1020)]
    fleet.feed(datagrams)
    records = fleet.vehicle_records()
    assert records[0][7] == mavlink2.MAVLINK_MSG_ID_HEARTBEAT  # the fixture's
    assert b"".join(records[1:]) == b"".join(datagrams) and len(records) == 4


def test_a_lost_link_is_regained_at_the_next_packet(fleet) -> None:
    fleet.feed([position(fleet.mav, 1000)])
    fleet.state.alive[0] = False
    fleet.stats().lost = 1
    fleet.feed([attitude(fleet.mav, 1020)])
    assert fleet.state.alive[0] and any(e.text == "link regained" for e in fleet.fleet.events)


def test_gcs_heartbeats_follow_vehicle_time(fleet) -> None:
    """Vehicle 0's vehicle-time GCS HEARTBEATs: at its first stamped packet (20 ms), then whenever its time
    crosses a multiple of 500 ms (500, 1000, 1500), whether the packet was taken by the walk or not."""
    fleet.from_gcs[0].clear()
    fleet.feed([position(fleet.mav, t) for t in range(20, 1520, 20)])
    sent = [m for d in fleet.from_gcs[0] for m in mavlink2.MAVLink(None).parse_buffer(d) or []]
    assert [m.get_type() for m in sent] == ["HEARTBEAT"] * 4


# ------------------------------------------------------------------ signing


def test_signed_telemetry_is_taken_when_the_signature_holds(tmp_path: Path) -> None:
    fleet = LoopbackFleet(tmp_path, key=KEY)
    try:
        mav = encoder(key=KEY)
        fleet.feed([heartbeat(mav), position(mav, 1000) + attitude(mav, 1000)])
        assert fleet.state.position_count[0] == 1 and fleet.state.att[0, 0] == f32(0.1)
        assert fleet.stats().bad_signature == 0 and fleet.stats().unsigned == 0
    finally:
        fleet.close()


def test_forged_replayed_and_unsigned_telemetry_is_refused(tmp_path: Path) -> None:
    fleet = LoopbackFleet(tmp_path, key=KEY)
    try:
        mav = encoder(key=KEY)
        fleet.feed([heartbeat(mav)])
        good = position(mav, 1000)
        forged = position(encoder(key=bytes(32)), 1020, lat=LAT + 7)
        unsigned = position(encoder(), 1040, lat=LAT + 9)
        fleet.feed([good, good, forged, unsigned])  # the second `good` is a replay
        assert fleet.state.position_count[0] == 1
        assert fleet.state.geodetic[0, 0] == pytest.approx(LAT * 1e-7, abs=1e-12)
        assert fleet.stats().bad_signature == 2 and fleet.stats().unsigned == 1
        fleet.feed([position(mav, 1060)])  # the genuine sender is not locked out
        assert fleet.state.position_count[0] == 2
    finally:
        fleet.close()


def test_a_signed_packet_without_a_key_is_taken(fleet) -> None:
    """Without a signing key pymavlink accepts signed packets unchecked; so does the intake."""
    fleet.feed([position(encoder(key=KEY), 1000)])
    assert fleet.state.position_count[0] == 1


# ------------------------------------------------------------------ udpin, forwards


def test_vehicles_sharing_a_udpin_endpoint_are_told_apart_by_sysid(tmp_path: Path) -> None:
    fleet = LoopbackFleet(tmp_path, vehicles=3, shared=True)
    try:
        mavs = [encoder(SYSID + i) for i in range(3)]
        fleet.feed([heartbeat(m) for m in mavs], senders=[0, 1, 2])
        fleet.feed(
            [
                position(m, 1000, lat=LAT + 100 * i) + attitude(m, 1000, yaw=0.1 * i)
                for i, m in enumerate(mavs)
            ],
            senders=[0, 1, 2],
        )
        st_ = fleet.state
        assert st_.position_count.tolist() == [1, 1, 1]
        for i in range(3):
            assert st_.geodetic[i, 0] == pytest.approx((LAT + 100 * i) * 1e-7, abs=1e-12)
            assert st_.att[i, 2] == math.pi / 2 - f32(0.1 * i)
        # each vehicle's GCS HEARTBEAT went to its own address
        for i in range(3):
            msgs = [m for d in fleet.from_gcs[i] for m in mavlink2.MAVLink(None).parse_buffer(d) or []]
            assert {m.get_type() for m in msgs} >= {"HEARTBEAT"}
        other = encoder(SYSID + 5)  # on the shared endpoint, a sysid of no configured vehicle
        fleet.feed([position(other, 1000)])
        assert fleet.fleet.network.unrouted == 1
    finally:
        fleet.close()


@pytest.mark.parametrize("key", [None, KEY])
def test_a_forward_gets_every_vehicle_packet_unchanged_and_in_order(
    tmp_path: Path, key: bytes | None
) -> None:
    fleet = LoopbackFleet(tmp_path, vehicles=2, key=key, forward=True)
    try:
        mavs = [encoder(SYSID + i, key=key) for i in range(2)]
        datagrams = [heartbeat(mavs[0]), heartbeat(mavs[1])]
        for t in (1000, 1020, 1010):  # the last one late
            datagrams += [position(m, t) + attitude(m, t) + m.system_time_encode(0, t).pack(m) for m in mavs]
        fleet.feed(datagrams, senders=[k % 2 for k in range(len(datagrams))])
        forwarded = b"".join(fleet.forwarded)
        assert forwarded == b"".join(fleet.vehicle_records())  # in the order the ground station read them
        for i in range(2):  # each vehicle's bytes unchanged, in its order
            mine = [p for p in split_packets(forwarded) if p[5] == SYSID + i]
            assert b"".join(mine) == b"".join(datagrams[i::2])
        assert fleet.state.position_count.tolist() == [2, 2]
    finally:
        fleet.close()


def split_packets(data: bytes) -> list[bytes]:
    """Whole MAVLink 2 packets laid end to end -> the packets."""
    out, k = [], 0
    while k < len(data):
        end = k + 12 + data[k + 1] + (13 if data[k + 2] & mavlink2.MAVLINK_IFLAG_SIGNED else 0)
        out.append(data[k:end])
        k = end
    return out


# ------------------------------------------------------------------ fuzzing

FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
ANGLE = st.one_of(st.floats(-4.0, 4.0, width=32), st.sampled_from([math.nan, math.inf, -math.inf]))


@st.composite
def packets(draw: st.DrawFn, key: bytes | None = None) -> bytes:
    """One packet a vehicle link may carry: telemetry of the vehicle (or another system or component), a
    heartbeat, a text, a clock tick; signed with `key` (sometimes not, or with another key); sometimes
    damaged."""
    sender = draw(st.sampled_from([(SYSID, COMPID)] * 6 + [(SYSID + 1, COMPID), (SYSID, 2)]))
    signer = draw(st.sampled_from([key] * 8 + [None, bytes(32)])) if key is not None else None
    mav = encoder(*sender, key=signer)
    t_ms = draw(st.integers(0, 12_000))
    kind = draw(st.sampled_from(["position", "attitude", "heartbeat", "text", "tick"]))
    if kind == "position":
        lat = draw(st.one_of(st.integers(-900_000_000, 900_000_000), st.sampled_from([950_000_000, 0])))
        vel = draw(st.tuples(*[st.integers(-32768, 32767)] * 3))
        data = position(mav, t_ms, lat=lat, lon=draw(st.integers(-1_800_000_001, 1_800_000_001)), vel=vel)
    elif kind == "attitude":
        data = attitude(mav, t_ms, draw(ANGLE), draw(ANGLE), draw(ANGLE))
    elif kind == "heartbeat":
        data = heartbeat(mav)
    elif kind == "text":
        data = mav.statustext_encode(4, b"PreArm: Need Position Estimate").pack(mav)
    else:
        data = mav.system_time_encode(0, t_ms).pack(mav)
    damaged = bytearray(data)
    if draw(st.integers(0, 9)) == 0:
        damaged[draw(st.integers(1, len(damaged) - 1))] ^= draw(st.integers(1, 255))
    return bytes(damaged)


@st.composite
def datagrams(draw: st.DrawFn, key: bytes | None = None) -> bytes:
    data = b"".join(draw(st.lists(packets(key), min_size=1, max_size=4)))
    tail = draw(st.sampled_from(["none"] * 6 + ["cut", "garbage"]))
    if tail == "cut":
        data = data[: draw(st.integers(1, len(data)))]
    elif tail == "garbage":
        data += draw(st.binary(min_size=1, max_size=20))
    return data


def pymavlink_count(datagram: bytes) -> int:
    """How many messages pymavlink makes of one datagram on its own (BAD_DATA included; a truncated tail is
    one more)."""
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    msgs = parser.parse_buffer(datagram) or []
    return len(msgs) + (1 if parser.buf_len() else 0)


@pytest.mark.parametrize(("shared", "key"), [(False, None), (True, None), (False, KEY)])
@FUZZ
@given(data=st.data())
def test_random_datagrams_never_crash_and_every_message_is_counted(
    tmp_path_factory, shared: bool, key: bytes | None, data: st.DataObject
) -> None:
    """On a vehicle's own udpout endpoint, on a shared udpin one, with signing: whatever arrives, nothing
    raises, every message pymavlink makes of the datagrams is counted once (the vehicle's `received`, or
    `unrouted` on a shared endpoint), the state holds no infinity, and a fresh position is still taken."""
    sent = data.draw(st.lists(datagrams(key), min_size=1, max_size=12))
    fleet = LoopbackFleet(tmp_path_factory.mktemp("fuzz"), shared=shared, key=key)
    try:
        mav = encoder(key=key)
        fleet.feed([heartbeat(mav)])
        fleet.feed(sent)
        assert fleet.stats().received + fleet.fleet.network.unrouted == 1 + sum(
            pymavlink_count(d) for d in sent
        )
        st_ = fleet.state
        for rows in (st_.geodetic, st_.vel, st_.att):
            assert not np.isinf(rows).any()
        count = int(st_.position_count[0])
        fleet.feed([heartbeat(mav) + position(mav, 100_000)])
        assert st_.position_count[0] == count + 1
    finally:
        fleet.close()


# ------------------------------------------------------------------ a byte stream (tcp)


@pytest.mark.parametrize("seed", range(4))
def test_a_stream_cut_anywhere_gives_the_same_state(tmp_path: Path, seed: int) -> None:
    """On a TCP link the bytes come in chunks cut anywhere, packets split across reads, garbage between
    them: the fleet takes in what pymavlink decodes from the whole stream at once, every packet once."""
    import socket
    import time

    from gcs_swarm.link.fleet import Fleet
    from gcs_swarm.link.vehicle import VehicleConfig

    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    fleet = Fleet([VehicleConfig("v0", f"tcp:127.0.0.1:{server.getsockname()[1]}", sysid=SYSID)], ORIGIN)
    fleet.network.open(5.0, None)
    vehicle, _ = server.accept()
    try:
        mav = encoder()
        stream = heartbeat(mav)
        for k, t in enumerate(range(1000, 1400, 20)):
            stream += position(mav, t, lat=LAT + t) + attitude(mav, t, yaw=0.001 * t)
            if k == 7:
                stream += b"\x00garbage\xfd"
        rng = np.random.default_rng(seed)
        cuts = np.sort(rng.choice(np.arange(1, len(stream)), size=30, replace=False))
        for chunk in np.split(np.frombuffer(stream, dtype=np.uint8), cuts):
            vehicle.sendall(chunk.tobytes())
            time.sleep(0.002)
            fleet.network.receive(0.0)
        deadline = time.monotonic() + 5.0
        while fleet.state.time_ms[0] < 1380 and time.monotonic() < deadline:
            fleet.network.receive(0.01)
        reference = mavlink2.MAVLink(None)  # pymavlink on the whole stream: what the bytes hold
        reference.robust_parsing = True
        decoded = reference.parse_buffer(stream) or []
        positions = [m for m in decoded if m.get_type() == "GLOBAL_POSITION_INT"]
        attitudes = [m for m in decoded if m.get_type() == "ATTITUDE"]
        assert 0 < len(positions) < 20  # the stray 0xfd after the garbage swallows a few packets
        assert fleet.state.position_count[0] == len(positions)
        assert fleet.state.geodetic[0, 0] == pytest.approx(positions[-1].lat * 1e-7, abs=1e-12)
        assert fleet.state.att[0, 2] == math.pi / 2 - f32(attitudes[-1].yaw)
        stats = fleet.links[0].channel.stats
        assert stats.late == stats.invalid == 0
    finally:
        fleet.network.close()
        vehicle.close()
        server.close()
