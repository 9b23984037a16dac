"""One UDP MAVLink endpoint per simulated vehicle: peers, datagrams in, the dispatch to the message handlers,
the (faulty) link, telemetry and replies out.

Clients speak first; every peer heard from in the last PEER_TIMEOUT_S wall seconds receives the vehicle's
traffic (streams, acks, params, texts), several clients at once. MAVLink 2 out, MAVLink 1 or 2 in. The
handlers live in sitl_sim.network.commands, .setpoints and .mission_protocol. Bad input never raises: it is
ignored or refused and counted in `counters`; an exception escaping a handler is a simulator bug, logged with
its traceback and counted in `counters.handler_errors`, and the vehicle goes on serving.

The ground station's answer to every frame, a datagram holding one unsigned SET_ATTITUDE_TARGET, takes a
short cut on a vehicle whose persona allows it (sitl_sim.network.surfaces) and without a signing key: its
fields are unpacked straight from the packet (`lone_attitude_target`) and handed to the setpoint handler's
`attitude_target`, with the checks, counters and lockstep answer of the general path (`parse_datagram`,
`_handle_message`) and no pymavlink message object.
"""

from __future__ import annotations

import logging
import socket
from collections import deque
from collections.abc import Callable
from typing import Any

from fastcrc.crc16 import mcrf4xx
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.network import signing
from sitl_sim.network.counters import LinkCounters
from sitl_sim.network.link_faults import DOWN, UP, FaultChannel, LinkFaults, Outage
from sitl_sim.network.mission_protocol import FenceProtocol
from sitl_sim.network.outbox import Outbox
from sitl_sim.network.radio import NS_PER_MS, RadioLink
from sitl_sim.network.services import SimulatorServices
from sitl_sim.network.streams import Framer
from sitl_sim.network.surfaces import SURFACES
from swarm_common.mavlink_datagrams import decode_leading_packets
from swarm_common.signing import is_signature_rejection, new_parser

logger = logging.getLogger(__name__)
PEER_TIMEOUT_S = 5.0  # wall seconds a silent peer keeps receiving traffic
MAX_DATAGRAM = 1400  # bytes; messages are batched per datagram up to this size
LOCKSTEP_ANSWERS = (
    mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,
    mavlink2.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET,
    mavlink2.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED,
    mavlink2.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT,
)
RADIO_STATUS_SOURCE = (ord("3"), ord("D"))  # SiK mavlink.c RADIO_SOURCE_SYSTEM, RADIO_SOURCE_COMPONENT
LINK_PARAMS = tuple(LinkFaults().params())  # SIM_LINK_*, in the order of link_rates and FaultChannel's rates
NO_LINK_FAULTS = (0.0,) * len(LINK_PARAMS)
Handler = Callable[[mavlink2.MAVLink_message, tuple[str, int]], None]
AttitudeTargetHandler = Callable[[int, tuple[float, ...], float, float, float, float], None]
ATTITUDE_TARGET = mavlink2.MAVLink_set_attitude_target_message
ATTITUDE_TARGET_CRC_EXTRA = bytes((ATTITUDE_TARGET.crc_extra,))
ATTITUDE_TARGET_SIZE = ATTITUDE_TARGET.unpacker.size  # payload bytes before MAVLink 2 truncation (39)


class VehicleEndpoint:
    """UDP endpoint of vehicle `index` (sysid) on bind:port, served by the simulator `sim`.

    signing_key: MAVLink 2 signing key or None; seed, outages: the faulty link's
    (sitl_sim.network.link_faults); link_from_s: simulated s before which the SIM_LINK_* faults do not apply;
    radio: the radio under the link (sitl_sim.network.radio), None for unlimited capacity.
    """

    def __init__(
        self,
        index: int,
        sysid: int,
        bind: str,
        port: int,
        sim: SimulatorServices,
        signing_key: bytes | None,
        seed: int,
        outages: tuple[Outage, ...],
        link_from_s: float,
        radio: RadioLink | None = None,
    ) -> None:
        self.index = index
        self.sysid = sysid
        self.sim = sim
        self.link_from_s = link_from_s
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setblocking(False)
            self.sock.bind((bind, port))
        except OSError:
            self.sock.close()
            raise
        self.rx = new_parser(signing_key)
        self.clock_rx = new_parser(signing_key)  # reads lockstep answers before the faulty link
        self.signer = None if signing_key is None else signing.FrameSigner(signing_key)
        self.channel = FaultChannel(seed, index, outages, radio)
        self._radio_status = Framer(*RADIO_STATUS_SOURCE)  # the ground radio's own MAVLink sender
        self._radio_status_ms = 0  # simulated ms at or after which the ground radio next reports
        self._link_columns = [sim.params.column_index(name) for name in LINK_PARAMS]
        self._link_revision = -1  # sim.params.revision when _link_configured was read
        self._link_configured = False  # some SIM_LINK_* parameter of this vehicle is > 0
        self.outbox = Outbox(Framer(sysid, 1))
        self.peers: dict[tuple[str, int], float] = {}
        self.inbox: deque[tuple[bytes, tuple[str, int]]] = deque()
        self.counters = LinkCounters()
        self.missions = FenceProtocol(index, self.counters, self.outbox, sim)  # MISSION_* of the fence
        surface = SURFACES[type(sim.autopilot.persona(index))]  # its persona's MAVLink surface
        setpoints = surface.setpoints(index, self.counters, sim)
        self.handlers: dict[int, Handler] = {
            **surface.commands(index, sysid, self.counters, self.outbox, sim).handlers(),
            **setpoints.handlers(),
        }
        # the lone SET_ATTITUDE_TARGET short cut (module doc): not with a key (the parser checks signatures)
        self._attitude_target: AttitudeTargetHandler | None = (
            setpoints.attitude_target if surface.attitude_short_cut and signing_key is None else None
        )
        for msg_id in self.missions.handlers:  # the fence's MISSION_* handlers take no sender address
            self.handlers[msg_id] = lambda msg, addr: self.missions.handlers[msg.get_msgId()](msg)

    def fileno(self) -> int:
        """The socket's file descriptor (for selectors)."""
        return self.sock.fileno()

    def close(self) -> None:
        """Release the port."""
        self.sock.close()

    # --- input ----------------------------------------------------------------------------------------------

    def receive(self, wall_now: float, frame_ms: int | None = None) -> int:
        """Read every datagram waiting on the socket and handle them in order; returns how many were handled.

        frame_ms: the simulator is paused at this lockstep frame end. Once this vehicle's lockstep clients
        have all answered it, later datagrams wait in the inbox for the next frame end, so what a client sends
        after its answer never depends on how fast the simulator read it.
        """
        inbox, peers, recvfrom = self.inbox, self.peers, self.sock.recvfrom
        while True:
            try:
                inbox.append(recvfrom(65535))
            except BlockingIOError:
                break
            except OSError:  # e.g. ICMP port unreachable from a peer that went away
                continue
        lockstep = self.sim.lockstep
        handled = 0
        while inbox:
            if (
                frame_ms is not None
                and lockstep is not None
                and lockstep.vehicle_answered(self.index, frame_ms)
            ):
                break
            data, addr = inbox.popleft()
            handled += 1
            if addr not in peers:
                peers[addr] = wall_now
                self.sim.on_new_peer(self.index)
            peers[addr] = wall_now
            rates = self._faulty_link_rates()
            if rates is None:
                self.handle_datagram(data, addr, wall_now)
                continue
            self._register_lockstep_answers(data, addr, wall_now)
            self.channel.push(UP, data, addr, self.sim.time_us // 1000, rates)
            handled += self._deliver_due(wall_now)
        return handled + self._deliver_due(wall_now)

    def link_rates(self) -> tuple[float, ...]:
        """This vehicle's SIM_LINK_* values: loss, dup, corrupt, reorder, delay_ms, jitter_ms (all zero while
        a lockstep simulator waits at boot for its clients, as delays in simulated time could not elapse, and
        before --link-from)."""
        sim = self.sim
        if sim.lockstep is not None and not sim.lockstep_started or sim.t < self.link_from_s:
            return NO_LINK_FAULTS
        return self._configured_link_rates()

    def _configured_link_rates(self) -> tuple[float, ...]:
        """This vehicle's SIM_LINK_* parameter values in link_rates order, whether they apply yet or not."""
        row = self.sim.params.values[self.index]
        return tuple(map(row.item, self._link_columns))

    def _faulty_link_rates(self) -> tuple[float, ...] | None:
        """link_rates() when the faulty link acts on this vehicle's packets now (FaultChannel.active), None
        when they go straight through: always None without a radio, without an outage and with no SIM_LINK_*
        rate > 0, which is found cheaply (the parameters are read again only after one was set,
        ParamTable.revision). A radio acts from the start, but not while a lockstep simulator waits at boot
        for its clients (its simulated time could not elapse)."""
        params = self.sim.params
        if self._link_revision != params.revision:
            self._link_revision = params.revision
            self._link_configured = any(r > 0 for r in self._configured_link_rates())
        radio_on = self.channel.radio is not None and (self.sim.lockstep is None or self.sim.lockstep_started)
        if not self._link_configured and not self.channel.outages and not radio_on:
            return None
        rates = self.link_rates()
        return rates if radio_on or self.channel.active(rates) else None

    def _deliver_due(self, wall_now: float) -> int:
        """Hand the uplink packets the faulty link delivers by now to the autopilot; returns how many."""
        if not self.channel.waiting(UP):
            return 0
        due = self.channel.due(UP, self.sim.time_us // 1000)
        for data, addr in due:
            self.handle_datagram(data, addr, wall_now)  # type: ignore[arg-type]
        return len(due)

    def _register_lockstep_answers(self, data: bytes, addr: tuple[str, int], wall_now: float) -> None:
        """The lockstep clock hears every answer that reaches the socket, whatever the radio does with it."""
        if self.sim.lockstep is None:
            return
        try:
            messages = parse_datagram(self.clock_rx, data)
        except Exception:  # noqa: BLE001 - hostile bytes: the radio path counts them
            messages = []
        _reset_parser(self.clock_rx)
        for msg in messages:
            if msg.get_msgId() in LOCKSTEP_ANSWERS and getattr(msg, "target_system", 0) in (0, self.sysid):
                self.sim.lockstep.answer(self.index, addr, int(msg.time_boot_ms), wall_now)

    def handle_datagram(self, data: bytes, addr: tuple[str, int], wall_now: float) -> None:
        """Handle the messages of one datagram from addr in order (garbage is counted, never raised)."""
        attitude_target = self._attitude_target
        if attitude_target is not None:
            fields = lone_attitude_target(data)
            if fields is not None:
                self._handle_attitude_target(attitude_target, fields, addr, wall_now)
                return
        try:
            messages = parse_datagram(self.rx, data)
        except Exception:  # noqa: BLE001 - a parser failure on hostile bytes must not stop the vehicle
            messages = []
            self.counters.bad_frames += 1
        if self.rx.buf_len() > 0:  # a datagram ended inside a frame: drop the fragment, resync on the next
            self.counters.bad_frames += 1
            _reset_parser(self.rx)
        for msg in messages:
            self._handle_message(msg, addr, wall_now)

    def _handle_message(self, msg: mavlink2.MAVLink_message, addr: tuple[str, int], wall_now: float) -> None:
        msg_id = msg.get_msgId()
        if msg_id < 0:  # MAVLink_bad_data
            if is_signature_rejection(msg):
                self.counters.unsigned += 1
            else:
                self.counters.bad_frames += 1
            return
        if not self._addressed_here(getattr(msg, "target_system", 0), getattr(msg, "target_component", 0)):
            return
        handler = self.handlers.get(msg_id)
        if handler is None:
            return
        try:
            handler(msg, addr)
        except Exception:  # a simulator bug: log it, count it apart from bad input, keep serving
            self._handler_failed(msg.get_type())
            return
        if msg_id in LOCKSTEP_ANSWERS and self.sim.lockstep is not None:
            time_boot_ms = msg.time_boot_ms
            self.sim.lockstep.answer(self.index, addr, int(time_boot_ms), wall_now)

    def _handle_attitude_target(
        self,
        handler: AttitudeTargetHandler,
        fields: tuple[Any, ...],
        addr: tuple[str, int],
        wall_now: float,
    ) -> None:
        """_handle_message of a lone SET_ATTITUDE_TARGET from its fields (lone_attitude_target's, wire
        order) for `handler` (the setpoints' attitude_target): the same addressing check, counters, handler
        error and lockstep answer."""
        time_boot_ms, w, x, y, z, roll_rate, pitch_rate, yaw_rate, thrust, system, component, mask = fields
        if not self._addressed_here(system, component):
            return
        try:
            handler(mask, (w, x, y, z), roll_rate, pitch_rate, yaw_rate, thrust)
        except Exception:  # a simulator bug: log it, count it apart from bad input, keep serving
            self._handler_failed(ATTITUDE_TARGET.msgname)
            return
        if self.sim.lockstep is not None:
            self.sim.lockstep.answer(self.index, addr, time_boot_ms, wall_now)

    def _addressed_here(self, target_system: int, target_component: int) -> bool:
        """A valid message for (target_system, target_component) is this vehicle's (broadcast 0 or its sysid,
        component 0 or the autopilot's 1), counted in `received`; else it is counted `foreign`."""
        if target_system not in (0, self.sysid) or target_component not in (0, 1):
            self.counters.foreign += 1
            return False
        self.counters.received += 1
        return True

    def _handler_failed(self, msg_type: str) -> None:
        """Count and log (with the traceback being handled) an exception a handler raised on a msg_type."""
        self.counters.handler_errors += 1
        logger.exception("vehicle %d: error handling %s", self.index, msg_type)

    # --- output ---------------------------------------------------------------------------------------------

    def flush(self, wall_now: float, clock_ms: int | None = None) -> None:
        """Queue pending STATUSTEXTs, pass everything queued through the (faulty) link, send what it lets
        through to the live peers, batched in datagrams. clock_ms: a lockstep frame end (a faulty link then
        ends with the fault-exempt clock tick SYSTEM_TIME(0, clock_ms), see link_faults)."""
        for severity, text in self.sim.autopilot.texts[self.index]:
            self.outbox.send(self.outbox.tx.statustext_encode(severity, text.encode("ascii", "replace")[:50]))
        self.sim.autopilot.texts[self.index].clear()
        packets = self.outbox.take()
        if self.signer is not None:
            packets = [self.signer.sign(packet) for packet in packets]
        rates = self._faulty_link_rates()
        if rates is not None:
            now_ms = self.sim.time_us // 1000
            for packet in packets:
                self.channel.push(DOWN, packet, None, now_ms, rates)
            packets = [packet for packet, _ in self.channel.due(DOWN, now_ms)]
            if clock_ms is not None and self.peers:
                tick = self.outbox.framer.pack(self.outbox.tx.system_time_encode(0, clock_ms))
                packets.append(tick if self.signer is None else self.signer.sign(tick))
            radio = self.channel.radio
            status_due = now_ms >= self._radio_status_ms and self.peers
            if radio is not None and radio.spec.radio_status and status_due:
                packets.append(self._ground_radio_status(radio, now_ms))
        if not packets:
            return
        datagrams = _batched(packets)
        for addr, heard in list(self.peers.items()):
            if wall_now - heard > PEER_TIMEOUT_S:
                del self.peers[addr]
                continue
            for datagram in datagrams:
                try:
                    self.sock.sendto(datagram, addr)
                except OSError:  # peer gone or buffer full: UDP is lossy, the next stream sample follows
                    break

    def _ground_radio_status(self, radio: RadioLink, now_ms: int) -> bytes:
        """The ground radio's RADIO_STATUS at now_ms, as SiK's mavlink.c MAVLink_report writes it to the
        ground station's serial port (not over the air, unsigned, sysid '3' compid 'D'): txbuf the free share
        of its transmit buffer (TxBuffer.free_percent); rssi, remrssi, noise, remnoise 255 (unknown: no
        propagation model), rxerrors and fixed 0. Once a simulated second."""
        self._radio_status_ms = (now_ms // 1000 + 1) * 1000
        txbuf = radio.buffers[UP].free_percent(now_ms * NS_PER_MS)
        framer = self._radio_status
        return framer.pack(framer.mav.radio_status_encode(255, 255, txbuf, 255, 255, 0, 0))


def _batched(packets: list[bytes]) -> list[bytes]:
    """Packets in order, joined into datagrams of at most MAX_DATAGRAM bytes (a longer packet alone)."""
    if sum(map(len, packets)) <= MAX_DATAGRAM:
        return [b"".join(packets)]
    datagrams: list[bytes] = []
    chunk = bytearray()
    for packet in packets:
        if chunk and len(chunk) + len(packet) > MAX_DATAGRAM:
            datagrams.append(bytes(chunk))
            chunk = bytearray()
        chunk += packet
    datagrams.append(bytes(chunk))
    return datagrams


def parse_datagram(parser: mavlink2.MAVLink, data: bytes) -> list[mavlink2.MAVLink_message]:
    """The messages `parser.parse_buffer(data)` returns for one whole datagram (its buffer empty before): the
    whole MAVLink 2 packets it starts with straight through pymavlink's decode
    (swarm_common.mavlink_datagrams), the rest through parse_buffer, which leaves a truncated packet ending
    the datagram in the parser's buffer; raises what parse_buffer raises."""
    messages, start = decode_leading_packets(parser, data)
    if start < len(data):
        messages += parser.parse_buffer(data[start:]) or []
    return messages


def lone_attitude_target(data: bytes) -> tuple[Any, ...] | None:
    """The fields of SET_ATTITUDE_TARGET in wire order (time_boot_ms ms, q [w,x,y,z] body FRD -> NED, body
    roll, pitch, yaw rates FRD rad/s, thrust, target_system, target_component, type_mask) when `data` is
    exactly one unsigned MAVLink 2 SET_ATTITUDE_TARGET packet with a correct CRC; None for anything else.

    Accepts what parse_datagram decodes with a parser without a signing key into one SET_ATTITUDE_TARGET
    message and nothing else (swarm_common.mavlink_codec.decode's rules: no incompatibility flag, the
    CRC-16/MCRF4XX of all but the magic byte and then CRC_EXTRA), with the same values: the MAVLink 2 trailing
    zeros put back, payload bytes beyond the dialect's fields ignored."""
    size = len(data)
    if size < 12 or data[0] != mavlink2.PROTOCOL_MARKER_V2 or data[2] or size != 12 + data[1]:
        return None
    if data[7] | data[8] << 8 | data[9] << 16 != mavlink2.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET:
        return None
    end = size - 2  # the CRC's first byte
    if mcrf4xx(data[1:end] + ATTITUDE_TARGET_CRC_EXTRA, 0xFFFF) != data[end] | data[end + 1] << 8:
        return None
    if data[1] < ATTITUDE_TARGET_SIZE:
        return ATTITUDE_TARGET.unpacker.unpack(data[10:end] + bytes(ATTITUDE_TARGET_SIZE - data[1]))
    return ATTITUDE_TARGET.unpacker.unpack_from(data, 10)


def _reset_parser(parser: mavlink2.MAVLink) -> None:
    """Forget a partial frame left in a pymavlink parser's buffer (resync on the next datagram)."""
    parser.buf = bytearray()
    parser.buf_index = 0
    parser.expected_length = mavlink2.HEADER_LEN_V1 + 2
