"""One vehicle's channel: who it is on the wire (sysid, compid, autopilot dialect), the ground station's
MAVLink 2 encoder for it (GCS sysid/compid, sequence, signing), the endpoint and tlog its packets go through,
and its packet statistics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import signing
from gcs_swarm.link.autopilots import DEFAULT_DIALECT, AutopilotDialect
from gcs_swarm.link.connection import Endpoint, LinkError, MAVLinkMessage
from gcs_swarm.link.tlog import TlogWriter
from swarm_common.mavlink_codec import Packer


@dataclass
class LinkStats:
    """Packets received / sent; garbage (bad); from other systems or components (ignored); losses; unsent;
    refused by the signature check (unsigned, bad_signature)."""

    received: int = 0
    sent: int = 0
    bad: int = 0
    ignored: int = 0
    lost: int = 0
    unsent: int = 0
    late: int = 0  # stamped telemetry older than what was already received (delayed or reordered): ignored
    invalid: int = 0  # well-formed packets with non-finite or impossible values (hostile or broken): ignored
    stream_requests: int = 0  # times the stream watchdog asked a quiet vehicle for its telemetry again
    unsigned: int = 0  # with a signing key: unsigned packets refused (never decoded)
    bad_signature: int = 0  # with a signing key: forged, replayed or too old signed packets refused
    # MAVLink bytes on this vehicle's connection (framing and signature included): of the packets counted in
    # `sent` (the ground station's and those a read-write forward routed to it) and in `received`
    bytes_sent: int = 0
    bytes_received: int = 0


class Channel:
    """Sends the ground station's packets to one vehicle (`name`) and counts them in `stats`.

    `sysid` / `compid` address the vehicle and `autopilot` is its dialect: bound at its first HEARTBEAT
    (gcs_swarm.link.network); before that packets go towards `expected_sysid` (the mission's, or None).
    """

    def __init__(
        self,
        name: str,
        expected_sysid: int | None,
        gcs_sysid: int = 255,
        gcs_compid: int = 190,
        signing_key: bytes | None = None,
    ) -> None:
        self.name = name
        self.expected_sysid = expected_sysid
        self.gcs_sysid = gcs_sysid
        self.endpoint: Endpoint | None = None
        self.tlog: TlogWriter | None = None
        self.sysid: int | None = None
        self.compid = mavlink2.MAV_COMP_ID_AUTOPILOT1
        self.autopilot: AutopilotDialect = DEFAULT_DIALECT
        self.stats = LinkStats()
        self.mav = mavlink2.MAVLink(None, gcs_sysid, gcs_compid)
        """The encoder (GCS sysid/compid, signing): messages built with it go out with `send`."""
        if signing_key is not None:
            signing.sign_outgoing(self.mav, signing_key)

    @property
    def target_sysid(self) -> int:
        """target_system of the vehicle's commands (0 = broadcast before it is bound)."""
        return self.sysid or 0

    def send(self, msg: MAVLinkMessage) -> None:
        """Pack (GCS sysid/compid, this link's sequence) and send one message; it goes to the tlog too."""
        if self.endpoint is None:
            raise LinkError(f"{self.name} is not connected")
        self._transmit(self.endpoint, msg.pack(self.mav))

    def send_packed(self, packer: Packer, *values: Any) -> None:
        """`send` of a message of `packer`'s class with field `values` in wire order (ordered_fieldnames,
        arrays flattened): the same bytes and encoder state, packed at a fraction of pymavlink's cost."""
        if self.endpoint is None:
            raise LinkError(f"{self.name} is not connected")
        self._transmit(self.endpoint, packer.pack(self.mav, *values))

    def _transmit(self, endpoint: Endpoint, packet: bytes) -> None:
        """Advance the sequence past `packet` and send it (to the tlog too), counting it sent or unsent."""
        self.mav.seq = (self.mav.seq + 1) % 256
        if endpoint.send(packet, self.sysid if self.sysid is not None else self.expected_sysid):
            self.stats.sent += 1
            self.stats.bytes_sent += len(packet)
            if self.tlog is not None:
                self.tlog.write(packet)
        else:
            self.stats.unsent += 1

    def send_command(self, command: int, confirmation: int, params: list[float]) -> None:
        """COMMAND_LONG `command` with its 7 `params`, not waiting for the ACK (link.operations waits)."""
        self.send(
            self.mav.command_long_encode(
                self.target_sysid, self.compid, command, min(confirmation, 255), *params
            )
        )
