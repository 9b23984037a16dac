"""swarm_common.mavlink_datagrams: where a MAVLink 2 packet ends, and the leading whole packets of a datagram.
(Equality with parse_buffer over random datagrams: tests/sitl_sim/network/test_datagram_intake.py.)"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.mavlink_datagrams import decode_leading_packets, v2_packet_end

# SYSTEM_TIME (id 2): payload uint64 + uint32 = 12 bytes, none zero here -> 10 header + 12 + 2 CRC = 24 bytes
SYSTEM_TIME = mavlink2.MAVLink_system_time_message(0x0102030405060708, 0x01020304)


def packet(signed: bool = False) -> bytes:
    mav = mavlink2.MAVLink(None, 1, 1)
    if signed:
        mav.signing.secret_key = bytes(32)
        mav.signing.sign_outgoing = True
    return bytes(SYSTEM_TIME.pack(mav))


def test_packet_end_from_its_own_header() -> None:
    assert v2_packet_end(packet(), 0) == 24
    assert v2_packet_end(b"xx" + packet(), 2) == 26
    assert v2_packet_end(packet(signed=True), 0) == 24 + 13  # the signature block


def test_no_end_for_what_is_not_a_whole_plain_or_signed_v2_packet() -> None:
    assert v2_packet_end(packet()[:-1], 0) is None  # truncated
    assert v2_packet_end(b"\xfe" + packet()[1:], 0) is None  # MAVLink 1 marker
    assert v2_packet_end(b"\xfd\x0c", 0) is None  # header cut before the flags
    flagged = bytearray(packet())
    flagged[2] = 0x02  # an incompatibility flag pymavlink refuses before decoding
    assert v2_packet_end(bytes(flagged), 0) is None


def test_leading_packets_decoded_up_to_the_first_other_bytes() -> None:
    bad_crc = bytearray(packet())
    bad_crc[-1] ^= 0xFF
    data = packet() + bytes(bad_crc) + b"\x00junk" + packet()
    messages, offset = decode_leading_packets(mavlink2.MAVLink(None), data)
    assert offset == 48  # two 24-byte packets; the junk and what follows it are the caller's
    assert messages[0].get_type() == "SYSTEM_TIME"
    assert (messages[0].time_unix_usec, messages[0].time_boot_ms) == (0x0102030405060708, 0x01020304)
    assert messages[1].get_type() == "BAD_DATA" and "CRC" in messages[1].reason
