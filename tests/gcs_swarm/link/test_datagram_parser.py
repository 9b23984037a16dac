"""connection._DatagramParser hands whole MAVLink 2 packets straight to pymavlink's `decode`: the result must
be exactly what pymavlink's parse_buffer makes of the same datagrams (messages, BAD_DATA and its reason, raw
bytes for the tlog), for valid, signed, corrupted, truncated, MAVLink 1 and garbage input."""

from __future__ import annotations

from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.connection import _DatagramParser, new_parser

KEY = bytes(range(32))


class ReferenceParser:
    """The datagram parser as it was: parse_buffer on the whole datagram, a truncated tail is BAD_DATA."""

    def __init__(self) -> None:
        self._parser = new_parser()

    def parse(self, data: bytes) -> list[mavlink2.MAVLink_message]:
        msgs = self._parser.parse_buffer(data) or []
        if self._parser.buf_len() > 0:
            msgs.append(
                mavlink2.MAVLink_bad_data(bytearray(data[-self._parser.buf_len() :]), "truncated packet")
            )
            self._parser = new_parser()
        return msgs


def sender(signed: bool) -> mavlink2.MAVLink:
    mav = mavlink2.MAVLink(None, 7, 1)
    if signed:
        signing.sign_outgoing(mav, KEY)
    return mav


def packets(mav: mavlink2.MAVLink, mavlink1: bool) -> list[bytes]:
    msgs = [
        mav.global_position_int_encode(1234, -353632610, 1491652300, 594000, 10000, 10, 20, -30, 3700),
        mav.attitude_encode(1234, 0.01, -0.02, 3.0, 0.0, 0.1, 0.0),
        mav.heartbeat_encode(2, 3, 81, 4, 4, 3),
        mav.statustext_encode(4, b"PreArm: check"),
        mav.param_value_encode(b"MOT_THST_HOVER", 0.35, 9, 900, 12),
        mav.system_time_encode(0, 1240),
    ]
    return [bytes(m.pack(mav, force_mavlink1=mavlink1)) for m in msgs]


@st.composite
def chunk(draw: st.DrawFn) -> bytes:
    signed = draw(st.booleans())
    mavlink1 = not signed and draw(st.integers(0, 5)) == 0
    data = bytearray(draw(st.sampled_from(packets(sender(signed), mavlink1))))
    damage = draw(st.sampled_from(["none", "none", "flip", "truncate", "flags", "garbage"]))
    if damage == "flip":
        data[draw(st.integers(0, len(data) - 1))] ^= draw(st.integers(1, 255))
    elif damage == "truncate":
        data = data[: draw(st.integers(1, len(data) - 1))]
    elif damage == "flags":
        data[2] |= 0x02
    elif damage == "garbage":
        data = bytearray(draw(st.binary(min_size=1, max_size=40)))
    return bytes(data)


def described(msg: mavlink2.MAVLink_message) -> tuple[Any, ...]:
    kind = msg.get_type()
    fields = msg.reason if kind == "BAD_DATA" else repr(sorted(msg.to_dict().items()))
    return (kind, bytes(msg.get_msgbuf()), fields, msg.get_srcSystem(), msg.get_srcComponent(), msg.get_seq())


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(datagrams=st.lists(st.lists(chunk(), min_size=1, max_size=5), min_size=1, max_size=4))
def test_same_messages_as_parse_buffer(datagrams: list[list[bytes]]) -> None:
    fast, reference = _DatagramParser(), ReferenceParser()
    for parts in datagrams:
        data = b"".join(parts)
        assert [described(m) for m in fast.parse(data)] == [described(m) for m in reference.parse(data)]


def test_a_datagram_of_valid_packets_is_decoded_whole() -> None:
    data = b"".join(packets(sender(signed=False), mavlink1=False))
    types = [m.get_type() for m in _DatagramParser().parse(data)]
    assert types == [
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "HEARTBEAT",
        "STATUSTEXT",
        "PARAM_VALUE",
        "SYSTEM_TIME",
    ]
