"""The fleet's network: its endpoints, the sysid -> vehicle map, and the routing of every incoming packet.

Each vehicle's connection string is opened once (several vehicles may share one udpin endpoint); a packet
is routed to the vehicle configured on its endpoint (by sysid when the endpoint is shared), and a vehicle is
bound to its sysid, component and autopilot dialect at its first HEARTBEAT. Packets from a sysid the mission
does not give a vehicle are counted (`unrouted` on a shared endpoint, `foreign_heartbeats` on a vehicle's
own one), and the identity checks refuse two vehicles answering to one sysid.

Every vehicle endpoint's bytes come in through gcs_swarm.link.intake, whatever the endpoint, the signing
or the forwards: the plain 50 Hz telemetry taken by its compiled walk, everything else decoded by pymavlink
and routed here (`_deliver`). With a signing key every endpoint checks signatures (connection.py): what
fails is counted per vehicle (`unsigned`, `bad_signature` in its LinkStats) and never reaches it. Forwards
(gcs_swarm.link.forward) get every vehicle frame, unchanged and in order, and their own frames are routed to
the vehicles by target system when they may pass.
"""

from __future__ import annotations

import selectors
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots import dialect_for, dialect_named
from gcs_swarm.link.connection import (
    ConnectionSpec,
    Endpoint,
    LinkError,
    MAVLinkMessage,
    UdpRouter,
    open_endpoint,
    parse_connection,
)
from gcs_swarm.link.forward import Forward, ForwardConfig
from gcs_swarm.link.intake import Intake
from gcs_swarm.link.tlog import TlogWriter
from gcs_swarm.link.vehicle import VehicleLink
from swarm_common.signing import is_signature_rejection, was_signed
from swarm_common.spin_wait import select_spinning

SYSID_CONFLICT_HEARTBEATS = 3  # vehicle HEARTBEATs from a wrong sysid before the connection is refused


class Network:
    """Endpoints and routing for `links` (row i = links[i]) and `forward_configs`; every packet in and out
    goes to the tlog (a forward's frames when they reach a vehicle). `signing_key`: checked on every frame
    received (vehicles' and forwards'). `spin_s`: wall s `receive` polls before it blocks
    (swarm_common.spin_wait; for a lockstep simulator, which answers at once)."""

    def __init__(
        self,
        links: Sequence[VehicleLink],
        signing_key: bytes | None = None,
        forward_configs: Sequence[ForwardConfig] = (),
        spin_s: float = 0.0,
    ) -> None:
        self.links = list(links)
        self.spin_s = spin_s  # wall s receive polls before it blocks (swarm_common.spin_wait)
        self.signing_key = signing_key
        self.forward_configs = list(forward_configs)
        self.forwards: list[Forward] = []
        self._outgoing: list[bytes | bytearray] = []  # vehicle frames read in this receive, for the forwards
        self._routes: dict[Endpoint, list[VehicleLink]] = {}
        self._selector = selectors.DefaultSelector()
        self._tlog: TlogWriter | None = None
        self.unrouted = 0  # packets on a shared udpin endpoint from no configured vehicle
        self.foreign_heartbeats: list[dict[int, int]] = [{} for _ in self.links]
        """Per vehicle: other vehicles' sysids heard on its connection -> their HEARTBEATs."""
        self.intake = self._new_intake()

    def _new_intake(self) -> Intake:
        """The way in for every vehicle endpoint `open` opens (gcs_swarm.link.intake)."""
        return Intake(
            self.links,
            self.links[0].state,
            self.signing_key is not None,
            lambda: self._tlog,
            self._outgoing if self.forward_configs else None,
            self._deliver,
        )

    @property
    def connected(self) -> bool:
        """The endpoints are open."""
        return bool(self._routes)

    def open(self, connect_timeout_s: float, tlog_path: Path | None) -> None:
        """Open every vehicle's endpoint (shared udpin endpoints once) and the tlog; LinkError on failure."""
        self.intake = self._new_intake()
        groups: dict[tuple[str, str, int], tuple[ConnectionSpec, list[VehicleLink]]] = {}
        for link in self.links:
            try:
                spec = parse_connection(link.config.connection)
            except ValueError as err:
                raise LinkError(f"{link.name}: {err}") from None
            groups.setdefault(spec.key, (spec, []))[1].append(link)
        for spec, members in groups.values():
            names = ", ".join(m.name for m in members)
            if len(members) > 1 and spec.kind != "udpin":
                raise LinkError(
                    f"{names} share the connection {spec.text}; "
                    "only a udpin endpoint can serve several vehicles"
                )
            if len(members) > 1 and any(m.config.sysid is None for m in members):
                raise LinkError(
                    f"{names} share {spec.text}: give each of them its sysid so they can be told apart"
                )
            endpoint = open_endpoint(spec, names, connect_timeout_s, self.signing_key)
            self._routes[endpoint] = members
            self.intake.add(endpoint)
            self._selector.register(endpoint.fileno(), selectors.EVENT_READ, endpoint)
            for member in members:
                member.channel.endpoint = endpoint
        for config in self.forward_configs:
            try:
                spec = parse_connection(config.connection)
            except ValueError as err:
                raise LinkError(f"forward: {err}") from None
            forward = Forward(
                config, open_endpoint(spec, f"forward {spec.text}", connect_timeout_s, self.signing_key)
            )
            self.forwards.append(forward)
            self._selector.register(forward.endpoint.fileno(), selectors.EVENT_READ, forward)
        if tlog_path is not None:
            self._tlog = TlogWriter(tlog_path)
            for link in self.links:
                link.channel.tlog = self._tlog

    def close(self) -> None:
        """Close every endpoint and the tlog (idempotent)."""
        for endpoint in self._routes:
            endpoint.close()
        self._routes.clear()
        for forward in self.forwards:
            forward.endpoint.close()
        self.forwards.clear()
        self._selector.close()
        self._selector = selectors.DefaultSelector()
        if self._tlog is not None:
            self._tlog.close()
            self._tlog = None

    def receive(self, timeout_s: float) -> float:
        """Wait up to `timeout_s` for packets and route all that are readable; returns the time.monotonic() at
        which they were read."""
        if self._selector.get_map():
            ready = select_spinning(self._selector, timeout_s, self.spin_s)
        else:  # every stream endpoint was closed by its peer
            ready = []
            time.sleep(max(timeout_s, 0.0))
        now = time.monotonic()
        intake = self.intake
        for key, _ in ready:
            if isinstance(key.data, Forward):
                intake.flush(now)  # what came before the forward's packets is applied before them
                self._from_forward(key.data)
                if key.data.endpoint.closed:
                    self._selector.unregister(key.fd)
                continue
            endpoint: Endpoint = key.data
            intake.read(endpoint, now)
            if endpoint.closed:
                intake.flush(now)
                self._selector.unregister(key.fd)
                for link in self._routes[endpoint]:
                    link.add_event(f"connection {endpoint.spec.text} closed by the peer")
        intake.flush(now)
        if self._outgoing:
            for forward in self.forwards:
                forward.send_frames(self._outgoing)
            self._outgoing.clear()
        return now

    def _from_forward(self, forward: Forward) -> None:
        """Route what a forward sent to the vehicles its target_system names (0 or none: all), unchanged, when
        `Forward.admit` lets it through."""
        gcs = (self.links[0].channel.mav.srcSystem, self.links[0].channel.mav.srcComponent)
        sysids = {s for link in self.links for s in (link.sysid, link.config.sysid) if s is not None}
        for msg, _ in forward.endpoint.receive():
            if not forward.admit(msg, gcs, sysids):
                continue
            target = getattr(msg, "target_system", 0)
            links = [link for link in self.links if link.sysid is not None and target in (0, link.sysid)]
            if not links:
                forward.stats.unrouted += 1
                continue
            forward.stats.routed += 1
            packet = msg.get_msgbuf()
            for link in links:
                endpoint = link.channel.endpoint
                if endpoint is not None and endpoint.send(packet, link.sysid):
                    link.channel.stats.bytes_sent += len(packet)
                    if self._tlog is not None:
                        self._tlog.write(packet)

    def _deliver(self, endpoint: Endpoint, msg: MAVLinkMessage, peer: Any, now: float) -> None:
        mtype = msg.get_type()
        bad = mtype == "BAD_DATA"
        if not bad:
            self._record(msg.get_msgbuf())
        members = self._routes[endpoint]
        if len(members) == 1:
            self.accept(members[0], msg, now, mtype)
            return
        assert isinstance(endpoint, UdpRouter)
        sysid = msg.get_srcSystem() if not bad else endpoint.sysid_of.get(peer, _claimed_sysid(msg))
        for link in members:
            if link.config.sysid == sysid:
                self.accept(link, msg, now, mtype)
                return
        self.unrouted += 1

    def _record(self, packet: bytes | bytearray) -> None:
        """A vehicle's packet (not garbage): to the tlog, and to the forwards after this receive."""
        if self._tlog is not None:
            self._tlog.write(packet)
        if self.forwards:
            self._outgoing.append(packet)

    def accept(self, link: VehicleLink, msg: MAVLinkMessage, now: float, mtype: str | None = None) -> None:
        """A packet from `link`'s connection (`now` = time.monotonic(); `mtype`: its msg.get_type(), when the
        caller has it): counted, garbage and other systems set aside, the rest handed to the link."""
        stats = link.channel.stats
        stats.received += 1
        stats.bytes_received += len(msg.get_msgbuf())
        if mtype is None:
            mtype = msg.get_type()
        if mtype == "RADIO_STATUS":  # the radio's own report (sysid 51 for SiK): kept, never bound to
            link.radio.update(msg)
        if mtype == "BAD_DATA":
            if not is_signature_rejection(msg):
                stats.bad += 1
            elif was_signed(msg):
                stats.bad_signature += 1
            else:
                stats.unsigned += 1
            return
        sysid = msg.get_srcSystem()
        if sysid != link.sysid and not self._bind(link, msg, mtype, sysid):
            stats.ignored += 1
            return
        link.handle(msg, now, mtype)

    def _bind(self, link: VehicleLink, msg: MAVLinkMessage, mtype: str, sysid: int) -> bool:
        """Bind `link` at the first vehicle HEARTBEAT with the expected sysid (its component and autopilot
        dialect with it); count other vehicles' sysids."""
        if mtype != "HEARTBEAT" or msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
            return False
        if msg.type == mavlink2.MAV_TYPE_GCS:
            return False
        channel = link.channel
        if channel.sysid is None and link.config.sysid in (None, sysid):
            channel.sysid, channel.compid = sysid, msg.get_srcComponent()
            self.intake.bind(link)
            heard = dialect_for(msg.autopilot)
            named = link.config.autopilot
            channel.autopilot = heard if named == "auto" else dialect_named(named)
            if channel.autopilot is not heard:
                link.add_event(
                    f"its HEARTBEAT says autopilot {msg.autopilot}; spoken to as {channel.autopilot.name}, "
                    "as the mission says"
                )
            link.state.ekf_required[link.index] = channel.autopilot.needs_ekf_report
            link.state.prearm_gated[link.index] = channel.autopilot.prearm_bit_in_enabled
            return True
        foreign = self.foreign_heartbeats[link.index]
        foreign[sysid] = foreign.get(sysid, 0) + 1
        if channel.sysid is not None and foreign[sysid] == 1:
            link.add_event(f"its connection also carries sysid {sysid}; those packets are ignored")
        return False

    def check_identities(self, wrong_sysid_heartbeats: int = SYSID_CONFLICT_HEARTBEATS) -> None:
        """LinkError when two vehicles report one sysid, a vehicle keeps reporting a sysid other than its
        configured one (`wrong_sysid_heartbeats` HEARTBEATs), or one sysid is heard from several addresses."""
        by_sysid: dict[int, VehicleLink] = {}
        for link in self.links:
            conn = link.config.connection
            if link.sysid is not None:
                other = by_sysid.setdefault(link.sysid, link)
                if other is not link:
                    hint = link.channel.autopilot.sysid_param_hint()
                    raise LinkError(
                        f"{other.name} ({other.config.connection}) and {link.name} ({conn}) both report "
                        f"sysid {link.sysid}; give each vehicle its own {hint}"
                    )
            elif link.config.sysid is not None:
                foreign = self.foreign_heartbeats[link.index]
                wrong = [s for s, n in foreign.items() if n >= wrong_sysid_heartbeats]
                if wrong:
                    raise LinkError(
                        f"{link.name} ({conn}) reports sysid {wrong[0]}, but the mission gives it sysid "
                        f"{link.config.sysid}"
                    )
            endpoint = link.channel.endpoint
            wanted = link.sysid if link.sysid is not None else link.config.sysid
            if isinstance(endpoint, UdpRouter) and wanted is not None:
                addresses = endpoint.addresses.get(wanted, [])
                if len(addresses) > 1:
                    shown = ", ".join(f"{host}:{port}" for host, port in addresses)
                    raise LinkError(
                        f"{link.name}'s sysid {wanted} is heard from several addresses on {conn} ({shown}); "
                        "two vehicles share that sysid"
                    )


def _claimed_sysid(msg: MAVLinkMessage) -> int | None:
    """The sysid in the header of a refused MAVLink 2 packet (BAD_DATA), None when it has none."""
    data = bytes(getattr(msg, "data", b""))
    return data[5] if len(data) > 5 and data[0] == mavlink2.PROTOCOL_MARKER_V2 else None
