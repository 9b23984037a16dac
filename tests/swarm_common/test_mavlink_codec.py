"""swarm_common.mavlink_codec against pymavlink, its reference: over randomised fields (every float class:
NaN, inf, -0.0, subnormals, doubles beyond float32), headers (sysid, compid, sequence wrap) and signing state
(random keys, link ids, timestamps), Packer must give pymavlink's bytes and leave the encoder as pymavlink
leaves it, also interleaved with pymavlink packs on one encoder; decode must give pymavlink's message (type,
every field bit for bit, header, msgbuf, payload, crc) or None, never a different message, for valid,
extended, truncated, corrupted and random input."""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common import mavlink_codec
from swarm_common.mavlink_codec import HOT_MESSAGES, Packer

MessageClass = type[mavlink2.MAVLink_message]
OUTGOING = (mavlink2.MAVLink_set_attitude_target_message, mavlink2.MAVLink_system_time_message)
HOT_CLASSES = tuple(mavlink2.mavlink_map[i] for i in HOT_MESSAGES)
SETTINGS = settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])

_INTEGER_RANGES = {
    "uint8_t": (0, 2**8 - 1),
    "int8_t": (-(2**7), 2**7 - 1),
    "uint16_t": (0, 2**16 - 1),
    "int16_t": (-(2**15), 2**15 - 1),
    "uint32_t": (0, 2**32 - 1),
    "int32_t": (-(2**31), 2**31 - 1),
    "uint64_t": (0, 2**64 - 1),
    "int64_t": (-(2**63), 2**63 - 1),
}
_SPECIAL_FLOATS = [0.0, -0.0, math.inf, -math.inf, math.nan, 1e-45, -1e-45, 1.1754942e-38, 3.4028235e38]


def scalar(fieldtype: str, packable: bool) -> st.SearchStrategy[Any]:
    """One field value. packable=False also draws doubles float32 cannot hold (struct refuses them)."""
    if fieldtype in _INTEGER_RANGES:
        low, high = _INTEGER_RANGES[fieldtype]
        return st.integers(low, high) | st.sampled_from([low, high, 0])
    assert fieldtype in ("float", "double"), fieldtype
    floats = st.floats(width=32) | st.sampled_from(_SPECIAL_FLOATS)
    if fieldtype == "double" or not packable:
        floats |= st.floats()
    return floats


@st.composite
def fields(draw: st.DrawFn, cls: MessageClass, packable: bool = True) -> dict[str, Any]:
    """Random values of every field of `cls` (by name; arrays as lists)."""
    values: dict[str, Any] = {}
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))  # wire order, as pymavlink
    for name, fieldtype in zip(cls.fieldnames, cls.fieldtypes, strict=True):
        length = lengths[name]
        value = scalar(fieldtype, packable)
        values[name] = draw(st.lists(value, min_size=length, max_size=length) if length else value)
        if draw(st.integers(0, 3)) == 0:  # zeros: MAVLink 2 truncates trailing zero bytes
            values[name] = [0] * length if length else 0
    return values


def wire_values(cls: MessageClass, values: dict[str, Any]) -> list[Any]:
    """Field values in wire order, arrays flattened (what Packer.pack takes)."""
    out: list[Any] = []
    for name in cls.ordered_fieldnames:
        value = values[name]
        out.extend(value if isinstance(value, list) else [value])
    return out


@st.composite
def encoders(draw: st.DrawFn) -> tuple[mavlink2.MAVLink, mavlink2.MAVLink]:
    """Two pymavlink encoders in the same random state (sysid, compid, sequence, maybe signing)."""
    sysid, compid = draw(st.integers(0, 255)), draw(st.integers(0, 255))
    seq = draw(st.integers(0, 255) | st.sampled_from([254, 255]))
    signed = draw(st.booleans())
    key = draw(st.binary(min_size=32, max_size=32))
    link_id = draw(st.integers(0, 255))
    timestamp = draw(st.integers(0, 2**48 - 1) | st.sampled_from([0, 2**48 - 1]))
    pair = []
    for _ in range(2):
        mav = mavlink2.MAVLink(None, sysid, compid)
        mav.seq = seq
        if signed:
            mav.signing.secret_key = key
            mav.signing.link_id = link_id
            mav.signing.timestamp = timestamp
            mav.signing.sign_outgoing = True
        pair.append(mav)
    return pair[0], pair[1]


def encoder_state(mav: mavlink2.MAVLink) -> tuple[Any, ...]:
    s = mav.signing
    return (mav.seq, mav.srcSystem, mav.srcComponent, s.secret_key, s.link_id, s.timestamp, s.sign_outgoing)


def outcome(pack: Callable[[], bytes]) -> tuple[str, Any]:
    """('bytes', packet) or ('error', (type, message)) of one pack."""
    try:
        return "bytes", pack()
    except (struct.error, OverflowError) as err:
        return "error", (type(err), str(err))


# ------------------------------------------------------------------ packing


@SETTINGS
@given(data=st.data(), cls=st.sampled_from(OUTGOING + HOT_CLASSES))
def test_packer_gives_pymavlinks_bytes_and_encoder_state(data: st.DataObject, cls: MessageClass) -> None:
    reference, lean = data.draw(encoders())
    values = data.draw(fields(cls, packable=data.draw(st.booleans())))
    expected = outcome(lambda: cls(**values).pack(reference))
    got = outcome(lambda: Packer(cls).pack(lean, *wire_values(cls, values)))
    assert got == expected
    assert encoder_state(lean) == encoder_state(reference)


@st.composite
def traffic(draw: st.DrawFn) -> list[tuple[MessageClass, dict[str, Any], bool]]:
    """A sequence of (message class, fields, packed by a Packer on the lean encoder?) to send in turn."""
    other = st.sampled_from(
        [mavlink2.MAVLink_heartbeat_message, mavlink2.MAVLink_command_long_message, *HOT_CLASSES]
    )
    steps = []
    for _ in range(draw(st.integers(1, 40))):
        if draw(st.booleans()):
            cls = draw(st.sampled_from(OUTGOING))
            steps.append((cls, draw(fields(cls)), True))
        else:
            cls = draw(other)
            steps.append((cls, draw(fields(cls)), False))
    return steps


@SETTINGS
@given(pair=encoders(), steps=traffic())
def test_packer_interleaves_with_pymavlink_on_one_encoder(
    pair: tuple[mavlink2.MAVLink, mavlink2.MAVLink], steps: list[tuple[MessageClass, dict[str, Any], bool]]
) -> None:
    """As gcs_swarm.link.channel sends: pack, then advance the sequence (wrapping at 256)."""
    reference, lean = pair
    packers = {cls: Packer(cls) for cls in OUTGOING}
    for cls, values, fast in steps:
        expected = cls(**values).pack(reference)
        reference.seq = (reference.seq + 1) % 256
        if fast:
            got = packers[cls].pack(lean, *wire_values(cls, values))
        else:
            got = cls(**values).pack(lean)
        lean.seq = (lean.seq + 1) % 256
        assert got == expected
    assert encoder_state(lean) == encoder_state(reference)


def test_a_packet_is_header_payload_crc_and_signature() -> None:
    """Reasoned without pymavlink: SYSTEM_TIME(0, 1240) from 7/1 at seq 5, its payload (uint64 0, uint32 1240
    = 0xD8 0x04) cut after the last non-zero byte; CRC-16/MCRF4XX over bytes 1.. and CRC_EXTRA 137."""
    mav = mavlink2.MAVLink(None, 7, 1)
    mav.seq = 5
    packet = Packer(mavlink2.MAVLink_system_time_message).pack(mav, 0, 1240)
    body = bytes([0xFD, 10, 0, 0, 5, 7, 1, 2, 0, 0]) + bytes(8) + bytes([0xD8, 0x04])
    assert packet[:-2] == body
    crc = 0xFFFF
    for byte in body[1:] + bytes([137]):  # the X.25 accumulate step of the MAVLink C library's checksum.h
        tmp = byte ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = (crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)
    assert packet[-2:] == struct.pack("<H", crc)
    assert mav.seq == 5  # the caller advances it


def test_signing_without_a_key_fails_as_in_pymavlink() -> None:
    mav = mavlink2.MAVLink(None, 7, 1)
    mav.signing.sign_outgoing = True
    with pytest.raises(AssertionError):
        mav.system_time_encode(0, 1).pack(mav)
    with pytest.raises(AssertionError):
        Packer(mavlink2.MAVLink_system_time_message).pack(mav, 0, 1)


# ------------------------------------------------------------------ parsing


def bits(value: Any) -> Any:
    """A field value compared bit for bit (floats by their IEEE bytes: NaN equals NaN, -0.0 is not 0.0)."""
    if isinstance(value, float):
        return ("float", struct.pack("<d", value))
    if isinstance(value, list):
        return [bits(v) for v in value]
    return (type(value).__name__, value)


def anatomy(msg: mavlink2.MAVLink_message) -> dict[str, Any]:
    """Everything a consumer can read from a message: its class, every attribute (fields bit for bit),
    its header's attributes, and what the accessors return."""
    attributes = {k: vars(v) if k == "_header" else bits(v) for k, v in vars(msg).items()}
    attributes["_msgbuf type"] = type(msg.get_msgbuf()).__name__
    attributes["_payload type"] = type(msg.get_payload()).__name__
    return {
        "class": type(msg),
        "attributes": attributes,
        "accessors": (
            msg.get_type(),
            msg.get_msgId(),
            msg.get_srcSystem(),
            msg.get_srcComponent(),
            msg.get_seq(),
            msg.get_signed(),
            msg.get_link_id(),
            msg.get_crc(),
            bytes(msg.get_msgbuf()),
            bytes(msg.get_payload() or b""),
        ),
        "dict": repr(msg.to_dict()),
    }


def pymavlink_decode(packet: bytes) -> mavlink2.MAVLink_message | str:
    """pymavlink's decode without a key, as gcs_swarm's parser calls it: the message or the error."""
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    try:
        return parser.decode(bytearray(packet))
    except mavlink2.MAVError as err:
        return f"MAVError: {err.message}"


def assert_same_or_none(packet: bytes) -> mavlink2.MAVLink_message | None:
    """decode(packet) is None or exactly pymavlink's message; returns it."""
    buffer = bytearray(packet)
    lean = mavlink_codec.decode(buffer)
    if lean is not None:
        reference = pymavlink_decode(packet)
        assert not isinstance(reference, str), reference
        assert anatomy(lean) == anatomy(reference)
        assert lean.get_msgbuf() is buffer  # the packet itself, as pymavlink keeps it
    return lean


@SETTINGS
@given(data=st.data(), cls=st.sampled_from(HOT_CLASSES))
def test_decode_gives_pymavlinks_message(data: st.DataObject, cls: MessageClass) -> None:
    sender, _ = data.draw(encoders())
    sender.signing.sign_outgoing = False
    packet = cls(**data.draw(fields(cls))).pack(sender)
    assert assert_same_or_none(packet) is not None


@SETTINGS
@given(data=st.data(), cls=st.sampled_from(HOT_CLASSES))
def test_signed_packets_are_left_to_pymavlink(data: st.DataObject, cls: MessageClass) -> None:
    sender, _ = data.draw(encoders())
    sender.signing.secret_key = data.draw(st.binary(min_size=32, max_size=32))
    sender.signing.sign_outgoing = True
    packet = cls(**data.draw(fields(cls))).pack(sender)
    assert mavlink_codec.decode(bytearray(packet)) is None


def repacked(packet: bytes, payload: bytes, crc_extra: int) -> bytes:
    """`packet`'s header with another payload (and length), and a correct CRC."""
    body = bytes([packet[0], len(payload)]) + packet[2:10] + payload
    crc = mavlink2.x25crc(body[1:] + bytes([crc_extra])).crc
    return body + struct.pack("<H", crc)


@SETTINGS
@given(
    data=st.data(),
    cls=st.sampled_from(HOT_CLASSES),
    extra=st.binary(min_size=1, max_size=30),
    compat=st.integers(0, 255),
)
def test_decode_of_longer_shorter_and_flagged_payloads(
    data: st.DataObject, cls: MessageClass, extra: bytes, compat: int
) -> None:
    """A payload longer than this dialect knows (a newer sender's extensions) is cut, a shorter one padded
    with zeros, compatibility flags are kept: as pymavlink does; a length of zero too."""
    sender, _ = data.draw(encoders())
    sender.signing.sign_outgoing = False
    packet = bytearray(cls(**data.draw(fields(cls))).pack(sender))
    packet[3] = compat
    full = cls.unpacker.pack(*wire_values(cls, data.draw(fields(cls))))
    cut = data.draw(st.integers(0, len(full)))
    for payload in (full + extra, full[:cut]):
        assert assert_same_or_none(repacked(bytes(packet), payload, cls.crc_extra)) is not None


@SETTINGS
@given(data=st.data(), cls=st.sampled_from(HOT_CLASSES))
def test_damaged_packets_are_never_a_different_message(data: st.DataObject, cls: MessageClass) -> None:
    """Flipped bits (header, payload, CRC), truncation, junk after: None, or pymavlink's own message (a flip
    that pymavlink accepts too, e.g. in the sequence byte is a valid packet)."""
    sender, _ = data.draw(encoders())
    sender.signing.sign_outgoing = False
    packet = bytearray(cls(**data.draw(fields(cls))).pack(sender))
    damage = data.draw(st.sampled_from(["flip", "truncate", "append"]))
    if damage == "flip":
        packet[data.draw(st.integers(0, len(packet) - 1))] ^= data.draw(st.integers(1, 255))
    elif damage == "truncate":
        del packet[data.draw(st.integers(0, len(packet) - 1)) :]
    else:
        packet += data.draw(st.binary(min_size=1, max_size=20))
    lean = assert_same_or_none(bytes(packet))
    if damage != "flip":
        assert lean is None


@SETTINGS
@given(garbage=st.binary(max_size=60) | st.binary(max_size=60).map(lambda b: b"\xfd" + b))
def test_garbage_is_never_a_message(garbage: bytes) -> None:
    assert_same_or_none(garbage)


def test_other_messages_and_mavlink1_are_left_to_pymavlink() -> None:
    mav = mavlink2.MAVLink(None, 7, 1)
    statustext = mav.statustext_encode(4, b"PreArm: check").pack(mav)
    heartbeat_v1 = mav.heartbeat_encode(2, 3, 81, 4, 4, 3).pack(mav, force_mavlink1=True)
    mav.seq = 2
    heartbeat_v2 = mav.heartbeat_encode(2, 3, 81, 4, 4, 3).pack(mav)
    assert mavlink_codec.decode(bytearray(statustext)) is None
    assert mavlink_codec.decode(bytearray(heartbeat_v1)) is None
    msg = mavlink_codec.decode(bytearray(heartbeat_v2))
    assert msg is not None and msg.get_type() == "HEARTBEAT" and msg.custom_mode == 4 and msg.get_seq() == 2
