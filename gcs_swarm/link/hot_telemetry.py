"""The ground station's intake of one vehicle's 50 Hz telemetry (GLOBAL_POSITION_INT, ATTITUDE) straight from
the datagram's bytes, without building pymavlink message objects.

A fleet of N vehicles sends 2 N of these packets every 20 ms frame; through pymavlink objects and the
network's routing each costs about 13 us of the ground station's tick (benchmarks/bench_intake.py). This
path does for them exactly what the general path does (gcs_swarm.link.network: tlog and forwards, `received`
count, the link's telemetry handler, `heard`), with the same checks, and leaves every packet it cannot take
whole to the general path, which then decodes it as before:

- a signed packet or one with an unknown incompatibility flag (pymavlink checks signatures);
- another message type;
- a packet whose sysid or component is not the bound vehicle's autopilot (binding, `ignored`, STATUSTEXT
  from other components: Network.accept and VehicleLink.handle decide);
- a packet whose CRC fails (pymavlink makes it BAD_DATA).

Fields are unpacked with pymavlink's own struct of the message (`cls.unpacker`), MAVLink 2 trailing-zero
truncation undone as pymavlink does (swarm_common.mavlink_codec.decode). Only for endpoints that check no
signatures (Network builds it for a udpout endpoint of one vehicle when the fleet has no signing key).
tests/gcs_swarm/link/test_hot_telemetry.py flies random datagrams through both paths and compares every
state array, counter, event and tlog record.
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

from fastcrc import crc16
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

if TYPE_CHECKING:
    from gcs_swarm.link.vehicle import VehicleLink

_mcrf4xx: Callable[[bytes, int], int] = crc16.mcrf4xx
_HEADER_LEN = mavlink2.HEADER_LEN_V2  # 10 bytes: magic, len, incompat, compat, seq, sysid, compid, msgid x3


class _Fields:
    """How to turn one message type's payload into its handler's arguments: the fields named `names`, in
    that order, from the payload unpacked in wire order (messages without array fields)."""

    def __init__(self, cls: type[mavlink2.MAVLink_message], names: tuple[str, ...]) -> None:
        if sum(cls.lengths) != len(cls.lengths):
            raise ValueError(f"{cls.msgname} has array fields")
        self.unpacker = cls.unpacker
        self.size = cls.unpacker.size
        self.crc_extra = bytes((cls.crc_extra,))
        self.pick = operator.itemgetter(*(cls.ordered_fieldnames.index(name) for name in names))


POSITION_FIELDS = _Fields(
    mavlink2.MAVLink_global_position_int_message, ("time_boot_ms", "lat", "lon", "alt", "vx", "vy", "vz")
)
"""The arguments of VehicleTelemetry.on_global_position."""
ATTITUDE_FIELDS = _Fields(mavlink2.MAVLink_attitude_message, ("time_boot_ms", "roll", "pitch", "yaw"))
"""The arguments of VehicleTelemetry.on_attitude."""


class TakenPacket(NamedTuple):
    """A packet HotTelemetry took: its bytes, the telemetry handler and that handler's arguments."""

    packet: bytes
    handler: Callable[..., Any]
    values: tuple[Any, ...]


class HotTelemetry:
    """Takes `link`'s GLOBAL_POSITION_INT and ATTITUDE packets from datagram bytes (see the module doc).
    `record(packet)`: what the network does with every packet a vehicle sends (tlog, forwards).

    `take` only reads a packet; `apply` acts on it, when the network reaches it in the order of the packets
    received (a late or rebooting vehicle's clock depends on that order)."""

    def __init__(self, link: VehicleLink, record: Callable[[bytes], None]) -> None:
        self.link = link
        self.record = record
        telemetry = link.telemetry
        self._routes: dict[int, tuple[_Fields, Callable[..., Any]]] = {
            mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: (POSITION_FIELDS, telemetry.on_global_position),
            mavlink2.MAVLINK_MSG_ID_ATTITUDE: (ATTITUDE_FIELDS, telemetry.on_attitude),
        }

    def take(self, data: bytes, start: int, end: int) -> TakenPacket | None:
        """The whole MAVLink 2 packet data[start:end] as a TakenPacket when this path takes it, else None
        (the general path decodes it)."""
        if data[start + 2]:
            return None  # signed (or a flag pymavlink refuses)
        route = self._routes.get(data[start + 7] | data[start + 8] << 8 | data[start + 9] << 16)
        if route is None:
            return None
        channel = self.link.channel
        if data[start + 5] != channel.sysid or data[start + 6] != channel.compid:
            return None
        fields, handler = route
        crc_at = end - 2
        crc = _mcrf4xx(fields.crc_extra, _mcrf4xx(data[start + 1 : crc_at], 0xFFFF))
        if crc != data[crc_at] | data[crc_at + 1] << 8:
            return None
        payload = data[start + _HEADER_LEN : crc_at]
        if len(payload) < fields.size:  # MAVLink 2 trailing zeros were cut
            payload += bytes(fields.size - len(payload))
        return TakenPacket(data[start:end], handler, fields.pick(fields.unpacker.unpack_from(payload)))

    def apply(self, taken: TakenPacket, now: float) -> None:
        """What the general path does with such a packet received at `now` (time.monotonic()): record it,
        count it, hand its fields to the telemetry, mark the link alive."""
        self.record(taken.packet)
        self.link.channel.stats.received += 1
        taken.handler(*taken.values)
        self.link.telemetry.heard(now)
