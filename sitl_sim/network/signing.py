"""MAVLink 2 message signing of the simulated vehicles, as ArduPilot's GCS_Signing.cpp does it.

With a key, a vehicle accepts a message only when it carries a valid signature whose timestamp is newer
than the last one accepted from the same stream (link_id, sysid, compid), and a new stream only when its
timestamp is at most one minute older than the vehicle's clock; unsigned messages are dropped, except
RADIO_STATUS (ArduPilot's accept_unsigned_callback list: a radio modem cannot sign). HEARTBEAT is not on
that list, so an unsigned GCS HEARTBEAT does not keep the GCS failsafe from triggering. The vehicle signs
everything it sends. Keys and timestamps come from swarm_common.signing_keys (timestamps from the wall clock:
replaying a recorded packet later is refused). The key itself is never printed or logged.
"""

from __future__ import annotations

import hashlib
import hmac
import struct

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.signing_keys import timestamp_now

NEW_STREAM_MAX_AGE = 6_000_000  # 1 min in 10 us units (pymavlink / MAVLink C library)
UNSIGNED_ACCEPTED = frozenset({mavlink2.MAVLINK_MSG_ID_RADIO_STATUS})
_SIGNATURE = struct.Struct("<BIH")  # link_id, timestamp (48 bits as low 32 + high 16)
_CRC = struct.Struct("<H")


class VerifyingParser(mavlink2.MAVLink):
    """pymavlink parser that checks signatures like ArduPilot's mavlink_signature_check: the signature is
    verified *before* the stream's timestamp is advanced (pymavlink advances it first, so one forged packet
    with a huge timestamp would lock the genuine ground station out)."""

    def __init__(self, key: bytes) -> None:
        super().__init__(None)
        self.robust_parsing = True
        self.signing.secret_key = key
        self.signing.timestamp = timestamp_now()
        self.signing.allow_unsigned_callback = lambda _mav, msg_id: msg_id in UNSIGNED_ACCEPTED

    def check_signature(self, msgbuf: bytearray, srcSystem: int, srcComponent: int) -> bool:  # noqa: N803
        """True for a correctly signed, fresh packet (then its stream's timestamp advances)."""
        link_id, low, high = _SIGNATURE.unpack(bytes(msgbuf[-13:-6]))
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


def new_parser(key: bytes | None) -> mavlink2.MAVLink:
    """A robust parser; with a key, messages failing the signature rules come out as BAD_DATA whose reason
    is SIGNATURE_REJECTED."""
    if key is not None:
        return VerifyingParser(key)
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    return parser


SIGNATURE_REJECTED = "Invalid signature"  # pymavlink's BAD_DATA reason


class FrameSigner:
    """Signs already framed MAVLink 2 packets (streams.Framer output) on link `link_id`."""

    def __init__(self, key: bytes, link_id: int = 0) -> None:
        self._key = key
        self.link_id = link_id
        self.timestamp = timestamp_now()

    def __repr__(self) -> str:
        return f"FrameSigner(link_id={self.link_id})"  # never the key

    def sign(self, packet: bytes) -> bytes:
        """The packet with the signed flag, its CRC recomputed and the 13-byte signature appended; MAVLink 1
        packets (which cannot be signed) and already signed ones are returned unchanged."""
        signed = len(packet) >= 12 and packet[2] & mavlink2.MAVLINK_IFLAG_SIGNED
        if len(packet) < 12 or packet[0] != mavlink2.PROTOCOL_MARKER_V2 or signed:
            return packet
        msg_id = packet[7] | (packet[8] << 8) | (packet[9] << 16)
        body = bytearray(packet[:-2])
        body[2] |= mavlink2.MAVLINK_IFLAG_SIGNED
        crc = mavlink2.x25crc(bytes(body[1:]) + bytes((mavlink2.mavlink_map[msg_id].crc_extra,)))
        self.timestamp = max(self.timestamp + 1, timestamp_now())
        body += _CRC.pack(crc.crc)
        body += _SIGNATURE.pack(self.link_id, self.timestamp & 0xFFFFFFFF, self.timestamp >> 32)
        body += hashlib.sha256(self._key + bytes(body)).digest()[:6]
        return bytes(body)
