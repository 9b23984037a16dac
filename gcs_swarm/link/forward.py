"""Forwarding: another ground station (QGroundControl, MAVProxy, mavlink-router...) watching the swarm through
the ground station, and what of its traffic may reach the vehicles.

Out: every frame received from every vehicle goes to every forward unchanged (the bytes as received,
signature included, sysid preserved), packed several to a datagram (at most FORWARD_DATAGRAM_BYTES) after
each read of the vehicles' endpoints. In: a frame from a forward is routed like mavlink-router does it, to
the vehicle its target_system names (0 or no target: every vehicle), unchanged, and only if `verdict` lets it
through:

- from a reserved source: the ground station's own (sysid, compid), or a vehicle's sysid -> dropped;
- never forwarded (either mode): what belongs to the ground station flying the vehicles: the lockstep clock
  and link timing (SYSTEM_TIME, TIMESYNC), guided targets (SET_ATTITUDE_TARGET, SET_POSITION_TARGET_*),
  telemetry rates (REQUEST_DATA_STREAM, MAV_CMD_SET_MESSAGE_INTERVAL in COMMAND_LONG/COMMAND_INT), which
  would starve the control loop on the vehicle's shared link, and the signing key (SETUP_SIGNING);
- read-only (the default): only WATCH_MESSAGES (PARAM_REQUEST_READ, PARAM_REQUEST_LIST: reading parameters
  changes nothing on a vehicle); everything else is a command and is dropped;
- read-write (`--forward-rw`): everything else passes (modes, arming, commands, parameter writes, missions).

With a signing key a forward's frames are checked like the vehicles' (swarm_common.signing): unsigned,
forged or replayed ones are dropped, so a forward commands a signed fleet only with the fleet's key; the
ground station never signs on its behalf. Every drop is counted in `ForwardStats`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import Endpoint, MAVLinkMessage, UdpRouter
from swarm_common.signing import is_signature_rejection, was_signed

FORWARD_DATAGRAM_BYTES = 1400  # below a 1500-byte Ethernet MTU after IP/UDP headers
WATCH_MESSAGES = frozenset({"PARAM_REQUEST_READ", "PARAM_REQUEST_LIST"})
NEVER_FORWARDED = frozenset(
    {
        "SYSTEM_TIME",
        "TIMESYNC",
        "SET_ATTITUDE_TARGET",
        "SET_POSITION_TARGET_LOCAL_NED",
        "SET_POSITION_TARGET_GLOBAL_INT",
        "REQUEST_DATA_STREAM",
        "SETUP_SIGNING",
    }
)
NEVER_FORWARDED_COMMANDS = frozenset({mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL})


@dataclass(frozen=True)
class ForwardConfig:
    """A forward: its pymavlink connection string (e.g. udpout:127.0.0.1:14550) and whether its commands may
    reach the vehicles."""

    connection: str
    read_write: bool = False


@dataclass
class ForwardStats:
    """Frames sent to the forward (`sent`, `unsent` when the socket refused), and of the frames received from
    it: garbage (`bad`), refused by signing (`unsigned`, `bad_signature`: forged or replayed), passed to the
    vehicles (`routed`, once per frame), dropped as commands of a read-only forward (`commands_refused`), as
    never forwarded or from a reserved source (`reserved`), or aimed at no vehicle of the fleet
    (`unrouted`)."""

    sent: int = 0
    unsent: int = 0
    received: int = 0
    bad: int = 0
    unsigned: int = 0
    bad_signature: int = 0
    routed: int = 0
    commands_refused: int = 0
    reserved: int = 0
    unrouted: int = 0


def verdict(
    msg: MAVLinkMessage, read_write: bool, gcs_source: tuple[int, int], vehicle_sysids: set[int]
) -> str | None:
    """Why a (well-formed, signature-checked) frame from a forward must not reach the vehicles: "reserved" or
    "command"; None when it may."""
    mtype = msg.get_type()
    source = (msg.get_srcSystem(), msg.get_srcComponent())
    if source == gcs_source or source[0] in vehicle_sysids or mtype in NEVER_FORWARDED:
        return "reserved"
    if mtype in ("COMMAND_LONG", "COMMAND_INT") and msg.command in NEVER_FORWARDED_COMMANDS:
        return "reserved"
    if not read_write and mtype not in WATCH_MESSAGES:
        return "command"
    return None


class Forward:
    """One forward endpoint: batches the vehicles' frames out to it, sorts what it sends (see `verdict`)."""

    def __init__(self, config: ForwardConfig, endpoint: Endpoint) -> None:
        self.config = config
        self.endpoint = endpoint
        self.stats = ForwardStats()

    @property
    def name(self) -> str:
        return self.config.connection

    def send_frames(self, frames: Sequence[bytes | bytearray]) -> None:
        """Send `frames` (whole MAVLink packets, unchanged) packed into datagrams of at most
        FORWARD_DATAGRAM_BYTES; a frame is never split."""
        batch = bytearray()
        count = 0
        for frame in frames:
            if batch and len(batch) + len(frame) > FORWARD_DATAGRAM_BYTES:
                self._send(batch, count)
                batch, count = bytearray(), 0
            batch += frame
            count += 1
        if batch:
            self._send(batch, count)

    def _send(self, datagram: bytearray, frames: int) -> None:
        endpoint = self.endpoint
        sent = (
            endpoint.send_to_all(datagram)
            if isinstance(endpoint, UdpRouter)
            else endpoint.send(datagram, None)
        )
        if sent:
            self.stats.sent += frames
        else:
            self.stats.unsent += frames

    def admit(self, msg: MAVLinkMessage, gcs_source: tuple[int, int], vehicle_sysids: set[int]) -> bool:
        """Count one frame from the forward; True when it may go to the vehicles (routing is the caller's)."""
        stats = self.stats
        stats.received += 1
        if msg.get_type() == "BAD_DATA":
            if not is_signature_rejection(msg):
                stats.bad += 1
            elif was_signed(msg):
                stats.bad_signature += 1
            else:
                stats.unsigned += 1
            return False
        why = verdict(msg, self.config.read_write, gcs_source, vehicle_sysids)
        if why == "reserved":
            stats.reserved += 1
        elif why == "command":
            stats.commands_refused += 1
        return why is None
