"""The MAVLink 2 signature check both programs apply to what they receive, as ArduPilot's
mavlink_signature_check (GCS_Signing.cpp) does it.

With a key, a message is accepted only when it carries a valid signature whose timestamp is newer than the
last one accepted from the same stream (link_id, sysid, compid), and a new stream only when its timestamp is
at most one minute older than the receiver's signing clock (the wall clock at start, advanced by every
accepted timestamp); unsigned messages are dropped, except RADIO_STATUS (ArduPilot's accept_unsigned_callback
list: a radio modem cannot sign). Rejected messages come out of the parser as BAD_DATA whose reason is
SIGNATURE_REJECTED. Timestamps are 10 us units since 2015-01-01 (swarm_common.signing_keys). The key itself
is never printed or logged.
"""

from __future__ import annotations

import hashlib
import hmac
import struct

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.signing_keys import timestamp_now

NEW_STREAM_MAX_AGE = 6_000_000  # 1 min in 10 us units (pymavlink / MAVLink C library)
UNSIGNED_ACCEPTED = frozenset({mavlink2.MAVLINK_MSG_ID_RADIO_STATUS})
SIGNATURE = struct.Struct("<BIH")  # link_id, timestamp (48 bits as low 32 + high 16)
SIGNATURE_REJECTED = "Invalid signature"  # pymavlink's BAD_DATA reason


class VerifyingParser(mavlink2.MAVLink):
    """Robust pymavlink parser that checks signatures like ArduPilot's mavlink_signature_check: the signature
    is verified *before* the stream's timestamp is advanced (pymavlink advances it first, so one forged packet
    with a huge timestamp would lock the genuine sender out)."""

    def __init__(self, key: bytes) -> None:
        super().__init__(None)
        self.robust_parsing = True
        self.signing.secret_key = key
        self.signing.timestamp = timestamp_now()
        self.signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id in UNSIGNED_ACCEPTED

    def __repr__(self) -> str:
        return "VerifyingParser()"  # never the key

    def check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:  # noqa: N803
        """True for a correctly signed, fresh packet (then its stream's timestamp advances)."""
        link_id, low, high = SIGNATURE.unpack(bytes(msgbuf[-13:-6]))
        timestamp = low | (high << 32)
        expected = hashlib.sha256(self.signing.secret_key + bytes(msgbuf[:-6])).digest()[:6]
        if not hmac.compare_digest(expected, bytes(msgbuf[-6:])):
            return False
        stream = (link_id, srcSystem, srcComponent)
        last = self.signing.stream_timestamps.get(stream)
        if last is not None and timestamp <= last:
            return False  # replayed or reordered
        if last is None and timestamp + NEW_STREAM_MAX_AGE < self.signing.timestamp:
            return False  # a new stream from the past: a recording
        self.signing.stream_timestamps[stream] = timestamp
        self.signing.timestamp = max(self.signing.timestamp, timestamp)
        return True


def new_parser(key: bytes | None = None) -> mavlink2.MAVLink:
    """A MAVLink 2 (reads MAVLink 1 too) ardupilotmega parser that turns garbage into BAD_DATA messages; with
    a signing `key` it also refuses what fails the signature check (VerifyingParser): BAD_DATA whose reason is
    SIGNATURE_REJECTED."""
    if key is not None:
        return VerifyingParser(key)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    return parser


def is_signature_rejection(msg: mavlink2.MAVLink_message) -> bool:
    """`msg` is the BAD_DATA of a packet the signature check refused (unsigned, forged, replayed)."""
    return msg.get_type() == "BAD_DATA" and getattr(msg, "reason", "") == SIGNATURE_REJECTED


def was_signed(msg: mavlink2.MAVLink_message) -> bool:
    """A refused packet (BAD_DATA) carried a signature (forged or replayed) rather than none (unsigned)."""
    data = bytes(getattr(msg, "data", b""))
    return (
        len(data) > 2
        and data[0] == mavlink2.PROTOCOL_MARKER_V2
        and bool(data[2] & mavlink2.MAVLINK_IFLAG_SIGNED)
    )
