"""MAVLink 2 message signing of the simulated vehicles, as ArduPilot's GCS_Signing.cpp does it.

With a key, a vehicle accepts a message only when it carries a valid signature whose timestamp is newer
than the last one accepted from the same stream (link_id, sysid, compid), and a new stream only when its
timestamp is at most one minute older than the vehicle's clock; unsigned messages are dropped, except
RADIO_STATUS (ArduPilot's accept_unsigned_callback list: a radio modem cannot sign). HEARTBEAT is not on
that list, so an unsigned GCS HEARTBEAT does not keep the GCS failsafe from triggering. The vehicle signs
everything it sends. Keys and timestamps come from swarm_common.signing_keys (timestamps from the wall clock:
replaying a recorded packet later is refused); the check itself is swarm_common.signing's, which the ground
station applies too. The key itself is never printed or logged.
"""

from __future__ import annotations

import hashlib
import struct

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.signing import SIGNATURE
from swarm_common.signing_keys import timestamp_now

_CRC = struct.Struct("<H")


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
        body += SIGNATURE.pack(self.link_id, self.timestamp & 0xFFFFFFFF, self.timestamp >> 32)
        body += hashlib.sha256(self._key + bytes(body)).digest()[:6]
        return bytes(body)
