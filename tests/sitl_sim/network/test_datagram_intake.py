"""A vehicle endpoint parses each datagram with `endpoint.parse_datagram`: whole MAVLink 2 packets straight
through pymavlink's `decode`, the rest through `parse_buffer`. It must give exactly what pymavlink's
parse_buffer gives for the same datagrams (messages, BAD_DATA and its reason, raw bytes, what is left in the
buffer for a truncated tail) and leave the signing state (stream timestamps) the same, for valid, signed,
forged, replayed, corrupted, truncated, MAVLink 1, unknown-id and garbage input; and the endpoint's counters
must come out as with parse_buffer."""

from __future__ import annotations

from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.network import endpoint as endpoint_module
from sitl_sim.network.endpoint import parse_datagram
from swarm_common.signing import new_parser

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
START_STAMP = 700_000_000_000  # signing timestamps (10 us units) of the senders and the receivers' clock
GCS = ("127.0.0.1", 1)
FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def sender(key: bytes | None, stamp: int) -> mavlink2.MAVLink:
    mav = mavlink2.MAVLink(None, 255, 190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = stamp
    return mav


def uplink_messages(draw: st.DrawFn) -> mavlink2.MAVLink_message:
    """One of the messages a ground station sends a vehicle, with random fields."""
    f = st.floats(width=32, allow_nan=True, allow_infinity=True)
    u8, u32 = st.integers(0, 255), st.integers(0, 2**32 - 1)
    kind = draw(st.integers(0, 5))
    if kind == 0:
        q = [draw(f) for _ in range(4)]
        return mavlink2.MAVLink_set_attitude_target_message(
            draw(u32), draw(u8), draw(u8), draw(u8), q, draw(f), draw(f), draw(f), draw(f)
        )
    if kind == 1:
        return mavlink2.MAVLink_system_time_message(draw(st.integers(0, 2**64 - 1)), draw(u32))
    if kind == 2:
        return mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)
    if kind == 3:
        params = [draw(f) for _ in range(7)]
        return mavlink2.MAVLink_command_long_message(draw(u8), draw(u8), 400, draw(u8), *params)
    if kind == 4:
        return mavlink2.MAVLink_param_set_message(1, 1, b"WPNAV_SPEED", draw(f), 9)
    return mavlink2.MAVLink_radio_status_message(*(draw(u8) for _ in range(5)), 0, 0)


@st.composite
def chunk(draw: st.DrawFn, senders: dict[str, mavlink2.MAVLink]) -> bytes:
    """A packet as it may reach the vehicle: signed with the key or another, unsigned, MAVLink 1, with an
    unknown id, damaged, replayed, or garbage."""
    msg = uplink_messages(draw)
    origin = draw(st.sampled_from(["signed", "signed", "unsigned", "forged", "mavlink1", "unknown"]))
    if origin == "mavlink1":
        data = bytearray(mavlink1.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(mavlink1.MAVLink(None)))
    elif origin == "unknown":  # a well-formed MAVLink 2 packet of a message id the dialect does not know
        data = bytearray([253, 3, 0, 0, 0, 255, 190, 0x39, 0x30, 0x00, 1, 2, 3, 0x12, 0x34])
    else:
        mav = senders[origin]
        if origin != "unsigned" and draw(st.booleans()):
            mav.signing.timestamp -= draw(st.integers(0, 5))  # replayed or reordered
        data = bytearray(msg.pack(mav))
        mav.seq = (mav.seq + 1) % 256
    damage = draw(st.sampled_from(["none", "none", "none", "flip", "truncate", "flags", "garbage"]))
    if damage == "flip":
        data[draw(st.integers(0, len(data) - 1))] ^= draw(st.integers(1, 255))
    elif damage == "truncate":
        data = data[: draw(st.integers(1, len(data) - 1))]
    elif damage == "flags":
        data[2] |= draw(st.sampled_from([0x02, 0x80]))
    elif damage == "garbage":
        data = bytearray(draw(st.binary(min_size=1, max_size=40)))
    return bytes(data)


def described(msg: mavlink2.MAVLink_message) -> tuple[Any, ...]:
    kind = msg.get_type()
    if kind == "BAD_DATA":
        return (kind, bytes(msg.data), msg.reason)
    fields = repr(sorted(msg.to_dict().items()))
    header = vars(msg.get_header())
    return (kind, bytes(msg.get_msgbuf()), fields, repr(sorted(header.items())), msg._signed, msg.get_crc())


def receivers(key: bytes | None) -> tuple[mavlink2.MAVLink, mavlink2.MAVLink]:
    pair = (new_parser(key), new_parser(key))
    for parser in pair:
        parser.signing.timestamp = START_STAMP
    return pair


def assert_same_as_parse_buffer(key: bytes | None, datagrams: list[bytes]) -> None:
    fast, reference = receivers(key)
    for data in datagrams:
        got = parse_datagram(fast, data)
        expected = reference.parse_buffer(data) or []
        assert [described(m) for m in got] == [described(m) for m in expected]
        assert fast.buf_len() == reference.buf_len()  # a truncated tail is left for the caller to count
        assert fast.signing.stream_timestamps == reference.signing.stream_timestamps
        assert fast.signing.timestamp == reference.signing.timestamp
        for parser in (fast, reference):
            endpoint_module._reset_parser(parser)


def new_senders() -> dict[str, mavlink2.MAVLink]:
    return {
        "signed": sender(KEY, START_STAMP + 100),
        "unsigned": sender(None, 0),
        "forged": sender(OTHER_KEY, START_STAMP + 100),
    }


@FUZZ
@given(data=st.data())
def test_same_messages_as_parse_buffer_signed(data: st.DataObject) -> None:
    senders = new_senders()
    datagrams = data.draw(st.lists(st.lists(chunk(senders), min_size=1, max_size=5), min_size=1, max_size=4))
    assert_same_as_parse_buffer(KEY, [b"".join(parts) for parts in datagrams])


@FUZZ
@given(data=st.data())
def test_same_messages_as_parse_buffer_unsigned(data: st.DataObject) -> None:
    senders = new_senders()
    datagrams = data.draw(st.lists(st.lists(chunk(senders), min_size=1, max_size=5), min_size=1, max_size=4))
    assert_same_as_parse_buffer(None, [b"".join(parts) for parts in datagrams])


@FUZZ
@given(datagrams=st.lists(st.binary(min_size=1, max_size=300), min_size=1, max_size=4))
def test_same_messages_as_parse_buffer_random_bytes(datagrams: list[bytes]) -> None:
    assert_same_as_parse_buffer(None, datagrams)


def reference_counts(datagrams: list[bytes]) -> tuple[int, int]:
    """(messages, bad frames) as the endpoint counted them with parse_buffer: a parser failure or a truncated
    tail is one bad frame each, every BAD_DATA one more."""
    parser = new_parser(None)
    messages = bad = 0
    for data in datagrams:
        parsed = parser.parse_buffer(data) or []
        if parser.buf_len() > 0:
            bad += 1
            endpoint_module._reset_parser(parser)
        messages += sum(1 for m in parsed if m.get_msgId() >= 0)
        bad += sum(1 for m in parsed if m.get_msgId() < 0)
    return messages, bad


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_endpoint_counters_as_with_parse_buffer(sim, data: st.DataObject) -> None:
    senders = new_senders()
    parts = data.draw(st.lists(st.lists(chunk(senders), min_size=1, max_size=5), min_size=1, max_size=4))
    datagrams = [b"".join(p) for p in parts]
    counters = sim.endpoints[0].counters
    before = counters.received + counters.foreign, counters.bad_frames
    for datagram in datagrams:
        sim.endpoints[0].handle_datagram(datagram, GCS, 0.0)
    messages, bad = reference_counts(datagrams)
    assert counters.received + counters.foreign - before[0] == messages
    assert counters.bad_frames - before[1] == bad
