"""One UDP MAVLink endpoint per simulated vehicle: peers, parsing, commands, params, targets, telemetry out.

Clients speak first; every peer heard from in the last PEER_TIMEOUT_S wall seconds receives the vehicle's
traffic (streams, acks, params, texts), several clients at once. MAVLink 2 out, MAVLink 1 or 2 in. This is the
frame boundary for commands: NED/FRD in, ENU/FLU to the autopilot (spec 1.1). Bad input never raises: it is
ignored or refused and counted in `counters`.
"""

from __future__ import annotations

import math
import socket
import sys
import traceback
from collections import deque
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl_sim import autopilot as ap
from sitl_sim import signing
from sitl_sim.attitude_control import yaw_from_quat
from sitl_sim.link_faults import DOWN, UP, FaultChannel
from sitl_sim.mission_protocol import FenceProtocol
from sitl_sim.streams import DATA_STREAM_GROUPS, STREAM_IDS, Framer, swap_quat_enu_ned

if TYPE_CHECKING:
    from sitl_sim.simulator import Simulator

M = mavlink
PEER_TIMEOUT_S = 5.0  # wall seconds a silent peer keeps receiving traffic
MAX_DATAGRAM = 1400  # bytes; messages are batched per datagram up to this size
MAX_POSITION_M = 1e6  # target position offsets beyond this (m) are absurd
MAX_SPEED = 100.0  # m/s, velocity targets beyond are absurd
MAX_ACCEL = 100.0  # m/s^2
MAX_RATE = 50.0  # rad/s, body/yaw rates beyond are absurd
FLIGHT_SW_VERSION = (4 << 24) | (7 << 16) | (0 << 8) | M.FIRMWARE_VERSION_TYPE_DEV  # "4.7.0-dev", as master
CAPABILITIES = (
    M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | M.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
)
LOCAL_FRAMES = (
    M.MAV_FRAME_LOCAL_NED,
    M.MAV_FRAME_LOCAL_OFFSET_NED,
    M.MAV_FRAME_BODY_NED,
    M.MAV_FRAME_BODY_OFFSET_NED,
)
BODY_FRAMES = (M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_OFFSET_NED)
AMSL_FRAMES = (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT)
ABOVE_HOME_FRAMES = (
    M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    M.MAV_FRAME_GLOBAL_TERRAIN_ALT,  # flat terrain at home altitude
    M.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
)
LOCKSTEP_ANSWERS = (
    M.MAVLINK_MSG_ID_SYSTEM_TIME,
    M.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET,
    M.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED,
    M.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT,
)
# SET_POSITION_TARGET_* type_mask groups (ArduCopter: any bit of a group set ignores the whole group)
POS_IGNORE, VEL_IGNORE, ACC_IGNORE = 0b111, 0b111 << 3, 0b111 << 6
YAW_IGNORE, YAW_RATE_IGNORE = 1 << 10, 1 << 11
RATES_IGNORE = 0b111
THROTTLE_IGNORE = M.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
ATTITUDE_IGNORE = M.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE


@dataclass
class LinkCounters:
    """What one endpoint received and what it threw away."""

    received: int = 0  # valid MAVLink messages addressed to this vehicle
    bad_frames: int = 0  # garbage bytes, bad CRC, unknown ids, truncated frames
    foreign: int = 0  # messages for another system/component
    invalid: int = 0  # NaN/inf/absurd fields, unsupported frames, malformed requests
    refused: int = 0  # well-formed commands/targets the autopilot refused (ArduCopter rules)
    unsigned: int = 0  # with a signing key: unsigned, wrongly signed or replayed messages dropped

    def summary(self) -> str:
        """One line "name=value ..." of all counters."""
        return " ".join(f"{f.name}={getattr(self, f.name)}" for f in fields(self))


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


def _ned_to_enu(v: tuple[float, float, float] | list[float]) -> np.ndarray:
    return np.array([v[1], v[0], -v[2]], dtype=float)


class VehicleEndpoint:
    """UDP endpoint of vehicle `index` (sysid) on bind:port, served by the simulator `sim`."""

    def __init__(self, index: int, sysid: int, bind: str, port: int, sim: Simulator) -> None:
        self.index = index
        self.sysid = sysid
        self.sim = sim
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.setblocking(False)
            self.sock.bind((bind, port))
        except OSError:
            self.sock.close()
            raise
        key = sim.config.signing_key
        self.rx = signing.new_parser(key)
        self.clock_rx = signing.new_parser(key)  # reads lockstep answers before the faulty link (link_faults)
        self.signer = None if key is None else signing.FrameSigner(key)
        self.channel = FaultChannel(sim.config.seed, index, sim.config.link.outages)
        self.framer = Framer(sysid, 1)
        self.tx = self.framer.mav  # pymavlink encoder of this vehicle's messages
        self.peers: dict[tuple[str, int], float] = {}
        self.out: list[bytes] = []
        self.inbox: deque[tuple[bytes, tuple[str, int]]] = deque()
        self.counters = LinkCounters()
        self._handlers = {
            M.MAVLINK_MSG_ID_HEARTBEAT: self._on_heartbeat,
            M.MAVLINK_MSG_ID_SYSTEM_TIME: lambda msg, addr: None,
            M.MAVLINK_MSG_ID_TIMESYNC: self._on_timesync,
            M.MAVLINK_MSG_ID_COMMAND_LONG: self._on_command_long,
            M.MAVLINK_MSG_ID_COMMAND_INT: self._on_command_int,
            M.MAVLINK_MSG_ID_SET_MODE: self._on_set_mode,
            M.MAVLINK_MSG_ID_PARAM_REQUEST_LIST: self._on_param_request_list,
            M.MAVLINK_MSG_ID_PARAM_REQUEST_READ: self._on_param_request_read,
            M.MAVLINK_MSG_ID_PARAM_SET: self._on_param_set,
            M.MAVLINK_MSG_ID_REQUEST_DATA_STREAM: self._on_request_data_stream,
            M.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED: self._on_position_target_local,
            M.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT: self._on_position_target_global,
            M.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET: self._on_attitude_target,
        }
        self.missions = FenceProtocol(self)  # MISSION_* of the fence (sitl_sim.mission_protocol)
        for msg_id in self.missions.handlers:
            self._handlers[msg_id] = lambda msg, addr: self.missions.handle(msg)

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
        while True:
            try:
                self.inbox.append(self.sock.recvfrom(65535))
            except BlockingIOError:
                break
            except OSError:  # e.g. ICMP port unreachable from a peer that went away
                continue
        lockstep = self.sim.lockstep
        handled = 0
        while self.inbox:
            if (
                frame_ms is not None
                and lockstep is not None
                and lockstep.vehicle_answered(self.index, frame_ms)
            ):
                break
            data, addr = self.inbox.popleft()
            handled += 1
            if addr not in self.peers:
                self.peers[addr] = wall_now
                self.sim.on_new_peer(self)
            self.peers[addr] = wall_now
            rates = self.link_rates()
            if not self.channel.active(rates):
                self._handle_datagram(data, addr, wall_now)
                continue
            self._register_lockstep_answers(data, addr, wall_now)
            self.channel.push(UP, data, addr, self.sim.time_us // 1000, rates)
            handled += self._deliver_due(wall_now)
        return handled + self._deliver_due(wall_now)

    def link_rates(self) -> tuple[float, ...]:
        """This vehicle's SIM_LINK_* values: loss, dup, corrupt, reorder, delay_ms, jitter_ms (all zero while
        a lockstep simulator waits at boot for its clients, as delays in simulated time could not elapse, and
        before --link-from)."""
        if (
            self.sim.lockstep is not None
            and not self.sim.lockstep_started
            or self.sim.t < self.sim.config.link.start_s
        ):
            return (0.0,) * 6
        p, i = self.sim.params, self.index
        return tuple(
            p.value(i, name)
            for name in (
                "SIM_LINK_LOSS",
                "SIM_LINK_DUP",
                "SIM_LINK_CORRUPT",
                "SIM_LINK_REORDER",
                "SIM_LINK_DELAY",
                "SIM_LINK_JITTER",
            )
        )

    def _deliver_due(self, wall_now: float) -> int:
        """Hand the uplink packets the faulty link delivers by now to the autopilot; returns how many."""
        if not self.channel.pending(UP):
            return 0
        due = self.channel.due(UP, self.sim.time_us // 1000)
        for data, addr in due:
            self._handle_datagram(data, addr, wall_now)  # type: ignore[arg-type]
        return len(due)

    def _register_lockstep_answers(self, data: bytes, addr: tuple[str, int], wall_now: float) -> None:
        """The lockstep clock hears every answer that reaches the socket, whatever the radio does with it."""
        if self.sim.lockstep is None:
            return
        try:
            messages = self.clock_rx.parse_buffer(data) or []
        except Exception:  # noqa: BLE001 - hostile bytes: the radio path counts them
            messages = []
        _reset_parser(self.clock_rx)
        for msg in messages:
            if msg.get_msgId() in LOCKSTEP_ANSWERS and getattr(msg, "target_system", 0) in (0, self.sysid):
                self.sim.lockstep.answer(self.index, addr, int(msg.time_boot_ms), wall_now)

    def _handle_datagram(self, data: bytes, addr: tuple[str, int], wall_now: float) -> None:
        try:
            messages = self.rx.parse_buffer(data) or []
        except Exception:  # noqa: BLE001 - a parser failure on hostile bytes must not stop the vehicle
            messages = []
            self.counters.bad_frames += 1
        if self.rx.buf_len() > 0:  # a datagram ended inside a frame: drop the fragment, resync on the next
            self.counters.bad_frames += 1
            _reset_parser(self.rx)
        for msg in messages:
            self._handle_message(msg, addr, wall_now)

    def _handle_message(self, msg: mavlink.MAVLink_message, addr: tuple[str, int], wall_now: float) -> None:
        msg_id = msg.get_msgId()
        if msg_id < 0:  # MAVLink_bad_data
            if getattr(msg, "reason", "") == signing.SIGNATURE_REJECTED:
                self.counters.unsigned += 1
            else:
                self.counters.bad_frames += 1
            return
        target_system = getattr(msg, "target_system", 0)
        target_component = getattr(msg, "target_component", 0)
        if target_system not in (0, self.sysid) or target_component not in (0, 1):
            self.counters.foreign += 1
            return
        self.counters.received += 1
        handler = self._handlers.get(msg_id)
        if handler is None:
            return
        try:
            handler(msg, addr)
        except Exception:  # noqa: BLE001 - never let one message crash the simulator; report it
            self.counters.invalid += 1
            print(f"sitl-sim: vehicle {self.index}: error handling {msg.get_type()}:", file=sys.stderr)
            traceback.print_exc(limit=3, file=sys.stderr)
            return
        if msg_id in LOCKSTEP_ANSWERS and self.sim.lockstep is not None:
            time_boot_ms = msg.time_boot_ms
            self.sim.lockstep.answer(self.index, addr, int(time_boot_ms), wall_now)

    # --- output ---------------------------------------------------------------------------------------------

    def send(self, msg: mavlink.MAVLink_message) -> None:
        """Queue a message for every live peer (sent by flush)."""
        self.out.append(self.framer.pack(msg))

    def flush(self, wall_now: float, clock_ms: int | None = None) -> None:
        """Queue pending STATUSTEXTs, pass everything queued through the (faulty) link, send what it lets
        through to the live peers, batched in datagrams. clock_ms: a lockstep frame end (a faulty link then
        ends with the fault-exempt clock tick SYSTEM_TIME(0, clock_ms), see link_faults)."""
        for severity, text in self.sim.autopilot.texts[self.index]:
            self.send(self.tx.statustext_encode(severity, text.encode("ascii", "replace")[:50]))
        self.sim.autopilot.texts[self.index].clear()
        packets, self.out = self.out, []
        if self.signer is not None:
            packets = [self.signer.sign(packet) for packet in packets]
        rates = self.link_rates()
        if self.channel.active(rates):
            now_ms = self.sim.time_us // 1000
            for packet in packets:
                self.channel.push(DOWN, packet, None, now_ms, rates)
            packets = [packet for packet, _ in self.channel.due(DOWN, now_ms)]
            if clock_ms is not None and self.peers:
                tick = self.framer.pack(self.tx.system_time_encode(0, clock_ms))
                packets.append(tick if self.signer is None else self.signer.sign(tick))
        if not packets:
            return
        datagrams: list[bytes] = []
        chunk = bytearray()
        for packet in packets:
            if chunk and len(chunk) + len(packet) > MAX_DATAGRAM:
                datagrams.append(bytes(chunk))
                chunk = bytearray()
            chunk += packet
        datagrams.append(bytes(chunk))
        for addr, heard in list(self.peers.items()):
            if wall_now - heard > PEER_TIMEOUT_S:
                del self.peers[addr]
                continue
            for datagram in datagrams:
                try:
                    self.sock.sendto(datagram, addr)
                except OSError:  # peer gone or buffer full: UDP is lossy, the next stream sample follows
                    break

    def ack(self, command: int, result: int, msg: mavlink.MAVLink_message) -> None:
        """COMMAND_ACK addressed to the sender of msg."""
        self.send(
            self.tx.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        )

    def send_param(self, j: int) -> None:
        """PARAM_VALUE of parameter index j."""
        params = self.sim.params
        spec = params.specs[j]
        value = float(params.values[self.index, j])
        self.send(self.tx.param_value_encode(spec.name.encode(), value, spec.type, len(params), j))

    # --- handlers -------------------------------------------------------------------------------------------

    def _on_heartbeat(self, msg: mavlink.MAVLink_heartbeat_message, addr: tuple[str, int]) -> None:
        self.sim.autopilot.gcs_heartbeat(self.index, msg.get_srcSystem())

    def _on_timesync(self, msg: mavlink.MAVLink_timesync_message, addr: tuple[str, int]) -> None:
        if msg.tc1 == 0:  # a request: answer with our clock (ns since boot), echoing ts1
            self.send(self.tx.timesync_encode(self.sim.time_us * 1000, msg.ts1))

    def _on_set_mode(self, msg: mavlink.MAVLink_set_mode_message, addr: tuple[str, int]) -> None:
        result = self._set_mode(msg.base_mode, msg.custom_mode)
        self.ack(M.MAVLINK_MSG_ID_SET_MODE, result, msg)  # ArduPilot acks SET_MODE with command id 11

    def _set_mode(self, base_mode: float, custom_mode: float) -> int:
        if not _finite(base_mode, custom_mode):
            self.counters.invalid += 1
            return M.MAV_RESULT_DENIED
        if not int(base_mode) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return M.MAV_RESULT_UNSUPPORTED
        return self._refused_if_not_accepted(self.sim.autopilot.set_mode(self.index, int(custom_mode)))

    def _refused_if_not_accepted(self, result: int) -> int:
        if result != M.MAV_RESULT_ACCEPTED:
            self.counters.refused += 1
        return result

    def _on_command_long(self, msg: mavlink.MAVLink_command_long_message, addr: tuple[str, int]) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        self.ack(msg.command, self._command(msg.command, params, None), msg)

    def _on_command_int(self, msg: mavlink.MAVLink_command_int_message, addr: tuple[str, int]) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y), msg.z)
        self.ack(msg.command, self._command(msg.command, params, msg.frame), msg)

    def _command(self, command: int, p: tuple[float, ...], frame: int | None) -> int:
        """Run a COMMAND_LONG/COMMAND_INT (frame None for COMMAND_LONG); returns the MAV_RESULT."""
        i = self.index
        autopilot = self.sim.autopilot
        if command == M.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] == 1:
                return self._refused_if_not_accepted(autopilot.arm(i, force=p[1] == ap.FORCE_ARM))
            if p[0] == 0:
                return self._refused_if_not_accepted(autopilot.disarm(i, force=p[1] == ap.FORCE_DISARM))
            return self._invalid(M.MAV_RESULT_DENIED)
        if command == M.MAV_CMD_DO_SET_MODE:
            return self._set_mode(p[0], p[1])
        if command == M.MAV_CMD_NAV_TAKEOFF:
            if frame is not None and frame not in (
                M.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ):
                return self._invalid(M.MAV_RESULT_DENIED)
            return self._refused_if_not_accepted(autopilot.takeoff(i, p[6]))
        if command == M.MAV_CMD_NAV_LAND:
            return self._refused_if_not_accepted(autopilot.set_mode(i, ap.LAND))
        if command == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._refused_if_not_accepted(autopilot.set_mode(i, ap.RTL))
        if command == M.MAV_CMD_SET_MESSAGE_INTERVAL:
            if not _finite(p[0], p[1]) or not self.sim.streams.set_interval(
                i, int(p[0]), p[1], self.sim.time_us
            ):
                return self._invalid(M.MAV_RESULT_DENIED)
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_GET_MESSAGE_INTERVAL:
            interval = self.sim.streams.interval(i, int(p[0])) if _finite(p[0]) else None
            if interval is None:
                return self._invalid(M.MAV_RESULT_DENIED)
            self.send(self.tx.message_interval_encode(int(p[0]), interval))
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_REQUEST_MESSAGE:
            return self._request_message(int(p[0])) if _finite(p[0]) else self._invalid(M.MAV_RESULT_DENIED)
        if command == M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            return self._request_message(M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        if command == M.MAV_CMD_GET_HOME_POSITION:
            return self._request_message(M.MAVLINK_MSG_ID_HOME_POSITION)
        if command == M.MAV_CMD_DO_FENCE_ENABLE:
            return self._fence_enable(p)
        return M.MAV_RESULT_UNSUPPORTED

    def _fence_enable(self, p: tuple[float, ...]) -> int:
        """MAV_CMD_DO_FENCE_ENABLE (GCS_Fence.cpp handle_command_do_fence_enable): param1 0 off, 1 on (FAILED
        if none of the fences is present), 2 floor off; param2 the fence types (0: all). Not saved."""
        if not _finite(p[0], p[1]):
            return self._invalid(M.MAV_RESULT_DENIED)
        autopilot, i = self.sim.autopilot, self.index
        configured = int(self.sim.params.value(i, "FENCE_TYPE"))
        fences = int(p[1]) & 0xFF or 0xF
        if int(p[0]) == 0:
            autopilot.fence.enable(i, False, fences, configured)
        elif int(p[0]) == 1:
            if not autopilot.fence.present_one(i, configured) & fences:
                return self._refused_if_not_accepted(M.MAV_RESULT_FAILED)
            autopilot.fence.enable(i, True, fences, configured)
        elif int(p[0]) == 2:
            autopilot.fence.enable(i, False, 8, configured)
        else:
            return self._refused_if_not_accepted(M.MAV_RESULT_FAILED)
        return M.MAV_RESULT_ACCEPTED

    def _invalid(self, result: int) -> int:
        self.counters.invalid += 1
        return result

    def _request_message(self, msg_id: int) -> int:
        """Send one message now (REQUEST_MESSAGE); FAILED when it is unknown or not available yet.

        The ACK is queued by the caller after this message; both leave in the same datagram.
        """
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            zeros = [0] * 8
            self.send(
                self.tx.autopilot_version_encode(
                    CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, zeros, zeros, zeros, 0, 0, self.sysid
                )
            )
            return M.MAV_RESULT_ACCEPTED
        if msg_id not in STREAM_IDS:
            self.counters.refused += 1
            return M.MAV_RESULT_FAILED
        data = self.sim.telemetry_view().encode(self.framer, msg_id, self.index)
        if data is None:
            self.counters.refused += 1
            return M.MAV_RESULT_FAILED
        self.out.append(data)
        return M.MAV_RESULT_ACCEPTED

    def _on_request_data_stream(
        self, msg: mavlink.MAVLink_request_data_stream_message, addr: tuple[str, int]
    ) -> None:
        group = DATA_STREAM_GROUPS.get(msg.req_stream_id)
        if group is None:
            return
        rate = msg.req_message_rate if msg.start_stop else 0
        interval = 1e6 / rate if rate > 0 else -1
        for msg_id in group:
            self.sim.streams.set_interval(self.index, msg_id, interval, self.sim.time_us)

    def _on_param_request_list(self, msg: mavlink.MAVLink_message, addr: tuple[str, int]) -> None:
        for j in range(len(self.sim.params)):
            self.send_param(j)

    def _on_param_request_read(
        self, msg: mavlink.MAVLink_param_request_read_message, addr: tuple[str, int]
    ) -> None:
        params = self.sim.params
        if msg.param_index >= 0:
            j = msg.param_index if msg.param_index < len(params) else None
        else:
            j = params.index.get(_param_name(msg.param_id))
        if j is None:
            self.counters.invalid += 1
            return
        self.send_param(j)

    def _on_param_set(self, msg: mavlink.MAVLink_param_set_message, addr: tuple[str, int]) -> None:
        name = _param_name(msg.param_id)
        params = self.sim.params
        value = float(msg.param_value)
        problem = params.check(name, value)
        if problem is not None:
            self.counters.refused += 1
            self.sim.autopilot.say(self.index, M.MAV_SEVERITY_WARNING, f"Param denied: {problem}")
            if name in params.index:
                self.send_param(params.index[name])  # echo the unchanged value, as ArduPilot does
            return
        self.sim.set_param(self.index, name, value)

    def _on_position_target_local(
        self, msg: mavlink.MAVLink_set_position_target_local_ned_message, addr: tuple[str, int]
    ) -> None:
        if msg.coordinate_frame not in LOCAL_FRAMES:
            self.counters.invalid += 1
            return
        mask = msg.type_mask
        state = self.sim.autopilot.state
        yaw_ned = math.pi / 2 - float(yaw_from_quat(state.quat[self.index]))
        body = msg.coordinate_frame in BODY_FRAMES

        def to_north_east(v: list[float]) -> list[float]:
            if not body:
                return v
            c, s = math.cos(yaw_ned), math.sin(yaw_ned)
            return [v[0] * c - v[1] * s, v[0] * s + v[1] * c, v[2]]

        pos = vel = acc = None
        if not mask & POS_IGNORE:
            values = [msg.x, msg.y, msg.z]
            if not _finite(*values) or max(map(abs, values)) > MAX_POSITION_M:
                self.counters.invalid += 1
                return
            offset = _ned_to_enu(to_north_east(values))
            base = (
                self.sim.autopilot.origin[self.index]
                if msg.coordinate_frame == M.MAV_FRAME_LOCAL_NED
                else None
            )
            pos = offset + (state.pos[self.index] if base is None else base)
        vel, acc, ok = self._velocity_accel(msg, mask, to_north_east)
        if not ok:
            return
        self._apply_position_target(msg, mask, pos, vel, acc, yaw_offset=yaw_ned if body else 0.0)

    def _on_position_target_global(
        self, msg: mavlink.MAVLink_set_position_target_global_int_message, addr: tuple[str, int]
    ) -> None:
        frame = msg.coordinate_frame
        if frame not in AMSL_FRAMES and frame not in ABOVE_HOME_FRAMES:
            self.counters.invalid += 1
            return
        mask = msg.type_mask
        pos = None
        if not mask & POS_IGNORE:
            lat, lon, alt = msg.lat_int / 1e7, msg.lon_int / 1e7, msg.alt
            if not (_finite(alt) and abs(lat) <= 90.0 and abs(lon) <= 180.0 and abs(alt) <= MAX_POSITION_M):
                self.counters.invalid += 1
                return
            geodesy = self.sim.geodesy
            home_amsl = geodesy.alt0 + self.sim.autopilot.home[self.index, 2]
            pos = geodesy.to_enu(lat, lon, alt if frame in AMSL_FRAMES else home_amsl + alt)
        vel, acc, ok = self._velocity_accel(msg, mask, lambda v: v)
        if not ok:
            return
        self._apply_position_target(msg, mask, pos, vel, acc, yaw_offset=0.0)

    def _velocity_accel(self, msg: mavlink.MAVLink_message, mask: int, rotate) -> tuple:  # noqa: ANN001
        """Velocity and acceleration (ENU) of a position target, or (None, None, False) if absurd."""
        vel = acc = None
        if not mask & VEL_IGNORE:
            values = [msg.vx, msg.vy, msg.vz]
            if not _finite(*values) or max(map(abs, values)) > MAX_SPEED:
                self.counters.invalid += 1
                return None, None, False
            vel = _ned_to_enu(rotate(values))
        if not mask & ACC_IGNORE:
            values = [msg.afx, msg.afy, msg.afz]
            if not _finite(*values) or max(map(abs, values)) > MAX_ACCEL:
                self.counters.invalid += 1
                return None, None, False
            acc = _ned_to_enu(rotate(values))
        return vel, acc, True

    def _apply_position_target(self, msg, mask: int, pos, vel, acc, yaw_offset: float) -> None:  # noqa: ANN001
        yaw = yaw_rate = None
        if not mask & YAW_IGNORE:
            if not (_finite(msg.yaw) and abs(msg.yaw) <= 4 * math.pi):
                self.counters.invalid += 1
                return
            yaw = math.pi / 2 - (msg.yaw + yaw_offset)  # NED heading -> ENU yaw
        if not mask & YAW_RATE_IGNORE:
            if not (_finite(msg.yaw_rate) and abs(msg.yaw_rate) <= MAX_RATE):
                self.counters.invalid += 1
                return
            yaw_rate = -msg.yaw_rate
        if not self.sim.autopilot.set_position_target(self.index, pos, vel, acc, yaw, yaw_rate):
            self.counters.refused += 1

    def _on_attitude_target(
        self, msg: mavlink.MAVLink_set_attitude_target_message, addr: tuple[str, int]
    ) -> None:
        mask = msg.type_mask
        autopilot = self.sim.autopilot
        values = [*msg.q, msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate, msg.thrust]
        if not _finite(*values) or max(map(abs, values[4:7])) > MAX_RATE:
            self.counters.invalid += 1
            return
        if autopilot.mode[self.index] not in (ap.GUIDED, ap.GUIDED_NOGPS) or mask & THROTTLE_IGNORE:
            self.counters.refused += 1
            return
        quat = None
        if not mask & ATTITUDE_IGNORE:
            q = np.array(msg.q, dtype=float)
            if abs(float(q @ q) - 1.0) >= 1e-3:  # ArduPilot Quaternion::is_unit_length
                self.counters.refused += 1
                return
            quat = swap_quat_enu_ned(q)
        rate_bits = mask & RATES_IGNORE
        if rate_bits not in (0, RATES_IGNORE):  # some but not all rates ignored: ill-defined, stop
            self.counters.refused += 1
            autopilot.guided_stop(self.index)
            return
        rates = (
            None if rate_bits else np.array([msg.body_roll_rate, -msg.body_pitch_rate, -msg.body_yaw_rate])
        )
        autopilot.set_attitude_target(self.index, quat, rates, msg.thrust)


def _reset_parser(parser: mavlink.MAVLink) -> None:
    """Forget a partial frame left in a pymavlink parser's buffer (resync on the next datagram)."""
    parser.buf = bytearray()
    parser.buf_index = 0
    parser.expected_length = mavlink.HEADER_LEN_V1 + 2


def _param_name(raw: bytes | str) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return raw.split("\0", 1)[0].strip()
