"""Lean MAVLink 2 packing and parsing of the few messages that cross a link every frame, byte for byte and
object for object what pymavlink (the ardupilotmega v2.0 dialect) makes of them, at a fraction of its cost.

pymavlink stays the reference and the default: this module only takes the happy path of a few message types
and hands everything else back to it.

- `Packer(cls).pack(mav, *values)` returns the bytes of `cls(*fields).pack(mav)` from the field values in
  wire order (`cls.ordered_fieldnames`, arrays flattened), with the same effect on `mav`: with signing
  (`mav.signing.sign_outgoing`) the packet is signed and `mav.signing.timestamp` advances by one; `mav.seq`
  is left alone, as pymavlink's pack leaves it (the caller advances it after each packet, whichever packed
  it, so pymavlink and a Packer interleave on one encoder). Values pymavlink cannot pack raise the same error,
  before `mav` changes.
- `decode(packet)` returns the message pymavlink's `MAVLink.decode(packet)` returns for an unsigned MAVLink 2
  packet of one of the HOT_MESSAGES types whose length and CRC check (a real pymavlink message object: same
  class, fields, header, msgbuf, payload, crc), and None for every other packet: the caller then decodes it
  with pymavlink, which gives the same message, or the same MAVError for garbage. Only for a parser without
  a signing key: with one, pymavlink refuses unsigned packets, and signed ones need its signature check.

The CRC is pymavlink's own CRC-16/MCRF4XX (the fastcrc extension it depends on from 2.4.48) over the header
after the start byte, the payload and the message's CRC_EXTRA.
"""

from __future__ import annotations

import hashlib
import operator
import struct
from collections.abc import Callable
from typing import Any

from fastcrc import crc16
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

_HEADER = struct.Struct("<BBBBBBBHB")  # magic, len, incompat, compat, seq, sysid, compid, msgid (16 + 8 bits)
_CRC = struct.Struct("<H")
_SIGNATURE_START = struct.Struct("<BQ")  # link_id, timestamp: the first 7 bytes go on the wire (48-bit stamp)
_HEADER_LEN = mavlink2.HEADER_LEN_V2  # 10 bytes
_MARKER = mavlink2.PROTOCOL_MARKER_V2
_mcrf4xx: Callable[[bytes, int], int] = crc16.mcrf4xx

HOT_MESSAGES = (
    mavlink2.MAVLINK_MSG_ID_HEARTBEAT,
    mavlink2.MAVLINK_MSG_ID_SYS_STATUS,
    mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,
    mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT,
    mavlink2.MAVLINK_MSG_ID_ATTITUDE,
    mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
    mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
    mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
    mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    mavlink2.MAVLINK_MSG_ID_TIMESYNC,
    mavlink2.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET,
)
"""Message ids `decode` parses itself (none has a text field): what a vehicle streams every frame or every
second, and the ground station's answer to every frame (SET_ATTITUDE_TARGET, SYSTEM_TIME)."""


class Packer:
    """Packs messages of one pymavlink class `cls` as `cls(...).pack(mav)` does (see the module doc)."""

    def __init__(self, cls: type[mavlink2.MAVLink_message]) -> None:
        self.cls = cls
        self._payload = cls.unpacker
        self._crc_extra = bytes((cls.crc_extra,))
        self._id_low, self._id_high = cls.id & 0xFFFF, cls.id >> 16

    def pack(self, mav: mavlink2.MAVLink, *values: Any) -> bytes:
        """The packet of `cls` with field `values` in wire order, from `mav`'s sysid, compid and sequence,
        signed when `mav` signs (its signing timestamp then advances by one)."""
        # MAVLink 2 trailing-zero truncation: at least one payload byte stays
        payload = self._payload.pack(*values).rstrip(b"\0") or b"\0"
        signing = mav.signing
        signed = bool(signing.sign_outgoing)
        packet = (
            _HEADER.pack(
                _MARKER,
                len(payload),
                mavlink2.MAVLINK_IFLAG_SIGNED if signed else 0,
                0,
                mav.seq,
                mav.srcSystem,
                mav.srcComponent,
                self._id_low,
                self._id_high,
            )
            + payload
        )
        packet += _CRC.pack(_mcrf4xx(packet[1:] + self._crc_extra, 0xFFFF))
        if not signed:
            return packet
        if signing.secret_key is None:
            raise AssertionError("signing without a secret key")  # as pymavlink's sign_packet
        packet += _SIGNATURE_START.pack(signing.link_id, signing.timestamp)[:7]
        digest = hashlib.sha256(signing.secret_key)
        digest.update(packet)
        signing.timestamp += 1
        return packet + digest.digest()[:6]


class _Layout:
    """How pymavlink turns one message type's payload into its constructor's arguments (MAVLink.decode):
    unpacked in wire order, fields reordered to `fieldnames` order, arrays as lists."""

    def __init__(self, cls: type[mavlink2.MAVLink_message]) -> None:
        if "s" in cls.unpacker.format or len(cls.orders) < 2:
            raise ValueError(f"{cls.msgname}: text fields and one-field messages are pymavlink's to decode")
        self.cls = cls
        self.unpacker = cls.unpacker
        self.size = cls.unpacker.size
        self.crc_extra = bytes((cls.crc_extra,))
        lengths = cls.lengths
        arrays = sum(lengths) != len(lengths)
        self.reorder = None if arrays else operator.itemgetter(*cls.orders)
        self.spans = [(sum(lengths[:order]), lengths[order]) for order in cls.orders] if arrays else []
        """With arrays: (first unpacked item, item count) of each field in `fieldnames` order."""

    def arguments(self, items: tuple[Any, ...]) -> tuple[Any, ...] | list[Any]:
        """Constructor arguments (fieldnames order) from the unpacked payload items (wire order)."""
        if self.reorder is not None:
            result: tuple[Any, ...] = self.reorder(items)
            return result
        return [items[tip] if n == 1 else list(items[tip : tip + n]) for tip, n in self.spans]


_LAYOUTS = {msg_id: _Layout(mavlink2.mavlink_map[msg_id]) for msg_id in HOT_MESSAGES}


def decode(packet: bytearray) -> mavlink2.MAVLink_message | None:
    """The message pymavlink's `MAVLink.decode(packet)` returns, for a whole unsigned MAVLink 2 `packet` of
    a HOT_MESSAGES type with a correct CRC (the message keeps `packet` as its msgbuf); None for anything
    else."""
    size = len(packet)
    if size < _HEADER_LEN + 2 or packet[0] != _MARKER or packet[2]:
        return None  # too short, MAVLink 1 or not a packet, signed or an unknown incompatibility flag
    length = packet[1]
    end = _HEADER_LEN + length
    if size != end + 2:
        return None
    msg_id = packet[7] | packet[8] << 8 | packet[9] << 16
    layout = _LAYOUTS.get(msg_id)
    if layout is None:
        return None
    crc = packet[end] | packet[end + 1] << 8
    if _mcrf4xx(bytes(packet[1:end]) + layout.crc_extra, 0xFFFF) != crc:
        return None
    payload = packet[_HEADER_LEN:end]
    if length < layout.size:  # MAVLink 2 trailing zeros were cut; longer payloads: fields this dialect lacks
        payload += bytes(layout.size - length)
    msg = layout.cls(*layout.arguments(layout.unpacker.unpack_from(payload)))
    msg._msgbuf = packet
    msg._payload = packet[6:end]  # sic: pymavlink's decode keeps the payload from offset 6 (a v1 header)
    msg._crc = crc
    msg._header = mavlink2.MAVLink_header(msg_id, 0, packet[3], length, packet[4], packet[5], packet[6])
    return msg
