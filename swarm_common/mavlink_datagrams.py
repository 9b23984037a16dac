"""Fast intake of MAVLink datagrams: whole MAVLink 2 packets go straight to pymavlink's `decode`.

pymavlink's `parse_buffer` feeds a datagram through `parse_char` / `__parse_char_legacy`, which copies and
re-slices its byte buffer once per packet; for a datagram that holds nothing but whole MAVLink 2 packets
(every datagram a well-behaved peer sends) that bookkeeping costs more than decoding. `decode_leading_packets`
cuts those packets out by the length in their own header and hands each to the parser's `decode`, exactly
the call `parse_buffer` would make on exactly the same bytes (a `bytearray` slice from the packet's start to
its end): the CRC, the signature (with a signing key, e.g. swarm_common.signing.VerifyingParser) and the
payload are checked by pymavlink as before, and a `MAVError` becomes the same `MAVLink_bad_data(packet,
reason)` that robust parsing makes. At the first thing that is not such a packet (garbage, MAVLink 1, a
packet with an unknown incompatibility flag, a truncated packet) it stops and returns the offset, and the
caller hands the rest to `parse_buffer` with its own policy for a truncated packet ending the datagram.

Equality with `parse_buffer` holds for a parser whose buffer is empty when the datagram starts (callers parse
whole datagrams and drop a truncated tail) and that parses robustly (`robust_parsing = True`); pymavlink's
byte and packet totals (`total_bytes_received`, `total_packets_received`) are not advanced for the packets
decoded here.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common import mavlink_codec

_MARKER_V2 = mavlink2.PROTOCOL_MARKER_V2
_SIGNED = mavlink2.MAVLINK_IFLAG_SIGNED
_OVERHEAD = mavlink2.HEADER_LEN_V2 + 2  # header and CRC bytes around the payload
_SIGNATURE_LEN = mavlink2.MAVLINK_SIGNATURE_BLOCK_LEN


def v2_packet_end(data: bytes, start: int) -> int | None:
    """End offset of the MAVLink 2 packet at data[start:] when it is whole (length from its own header) and
    has no incompatibility flag but signing, i.e. a packet pymavlink's parse_buffer would cut out unchanged
    and hand to its `decode`; None for anything else (garbage, MAVLink 1, a truncated packet)."""
    if len(data) - start < 3 or data[start] != _MARKER_V2:
        return None
    flags = data[start + 2]
    if flags & ~_SIGNED:
        return None
    end = start + _OVERHEAD + data[start + 1] + (_SIGNATURE_LEN if flags else 0)
    return end if end <= len(data) else None


def decode_leading_packets(
    parser: mavlink2.MAVLink, data: bytes
) -> tuple[list[mavlink2.MAVLink_message], int]:
    """Decode the whole MAVLink 2 packets `data` starts with (usually all of it) with `parser.decode`; returns
    the messages (BAD_DATA for a packet pymavlink refuses: CRC, signature, length) and the offset of the first
    byte not consumed (len(data) when the datagram was nothing but such packets). When the parser checks no
    signatures, swarm_common.mavlink_codec.decode builds the hot messages first (the same objects,
    cheaper)."""
    messages: list[mavlink2.MAVLink_message] = []
    start = 0
    lean = getattr(parser.signing, "secret_key", None) is None  # with a key: pymavlink checks every signature
    while (end := v2_packet_end(data, start)) is not None:
        packet = bytearray(data[start:end])
        msg = mavlink_codec.decode(packet) if lean else None
        if msg is None:
            try:
                msg = parser.decode(packet)
            except mavlink2.MAVError as err:
                msg = mavlink2.MAVLink_bad_data(packet, err.message)
        messages.append(msg)
        start = end
    return messages, start
