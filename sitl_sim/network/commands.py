"""Handlers of one vehicle's commands, mode changes, parameters and stream requests (HEARTBEAT, TIMESYNC,
SET_MODE, COMMAND_LONG/INT, PARAM_*, REQUEST_DATA_STREAM), answering as ArduCopter does: the ArduCopter
persona's MAVLink surface, which the PX4 one (px4_commands) extends (sitl_sim.network.surfaces).

Input that ArduCopter refuses is refused here explicitly: `counters.invalid` for NaN/inf/absurd fields and
malformed requests, `counters.refused` for well-formed commands the autopilot declines. No handler raises on
input; an exception escaping one is a simulator bug (the endpoint counts it in `handler_errors`).
"""

from __future__ import annotations

from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot import modes
from sitl_sim.network.counters import LinkCounters
from sitl_sim.network.message_fields import finite, param_name
from sitl_sim.network.outbox import Outbox
from sitl_sim.network.services import SimulatorServices
from sitl_sim.network.streams import DATA_STREAM_GROUPS, STREAM_IDS

FLIGHT_SW_VERSION = (
    (4 << 24) | (7 << 16) | (0 << 8) | mavlink2.FIRMWARE_VERSION_TYPE_DEV
)  # "4.7.0-dev", as master
MAX_INTERVAL_US = 2**31 - 1  # MESSAGE_INTERVAL.interval_us is an int32: a longer interval is malformed
CAPABILITIES = (
    mavlink2.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink2.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | mavlink2.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
)


class CommandHandlers:
    """Commands, modes, parameters and stream requests of vehicle `index` (sysid), served by `sim`; replies go
    to `outbox`, refusals to `counters`."""

    capabilities = CAPABILITIES  # AUTOPILOT_VERSION.capabilities
    flight_sw_version = FLIGHT_SW_VERSION  # AUTOPILOT_VERSION.flight_sw_version
    unavailable_result = mavlink2.MAV_RESULT_FAILED  # REQUEST_MESSAGE of a message not sent (yet)

    def __init__(
        self, index: int, sysid: int, counters: LinkCounters, outbox: Outbox, sim: SimulatorServices
    ) -> None:
        self.index = index
        self.sysid = sysid
        self.counters = counters
        self.outbox = outbox
        self.sim = sim

    def handlers(self) -> dict[int, Callable[[mavlink2.MAVLink_message, tuple[str, int]], None]]:
        """Message id -> handler(msg, sender address)."""
        return {
            mavlink2.MAVLINK_MSG_ID_HEARTBEAT: self._on_heartbeat,
            mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME: lambda msg, addr: None,
            mavlink2.MAVLINK_MSG_ID_TIMESYNC: self._on_timesync,
            mavlink2.MAVLINK_MSG_ID_COMMAND_LONG: self._on_command_long,
            mavlink2.MAVLINK_MSG_ID_COMMAND_INT: self._on_command_int,
            mavlink2.MAVLINK_MSG_ID_SET_MODE: self._on_set_mode,
            mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_LIST: self._on_param_request_list,
            mavlink2.MAVLINK_MSG_ID_PARAM_REQUEST_READ: self._on_param_request_read,
            mavlink2.MAVLINK_MSG_ID_PARAM_SET: self._on_param_set,
            mavlink2.MAVLINK_MSG_ID_REQUEST_DATA_STREAM: self._on_request_data_stream,
        }

    def _on_heartbeat(self, msg: mavlink2.MAVLink_heartbeat_message, addr: tuple[str, int]) -> None:
        self.sim.autopilot.gcs_heartbeat(self.index, msg.get_srcSystem())

    def _on_timesync(self, msg: mavlink2.MAVLink_timesync_message, addr: tuple[str, int]) -> None:
        if msg.tc1 == 0:  # a request: answer with our clock (ns since boot), echoing ts1
            self.outbox.send(self.outbox.tx.timesync_encode(self.sim.time_us * 1000, msg.ts1))

    def _on_set_mode(self, msg: mavlink2.MAVLink_set_mode_message, addr: tuple[str, int]) -> None:
        result = self._set_mode(msg.base_mode, msg.custom_mode)
        self.outbox.ack(mavlink2.MAVLINK_MSG_ID_SET_MODE, result, msg)  # ArduPilot acks with command id 11

    def _set_mode(self, base_mode: float, custom_mode: float) -> int:
        if not finite(base_mode, custom_mode):
            self.counters.invalid += 1
            return mavlink2.MAV_RESULT_DENIED
        if not int(base_mode) & mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return mavlink2.MAV_RESULT_UNSUPPORTED
        return self._refused_if_not_accepted(self.sim.autopilot.set_mode(self.index, int(custom_mode)))

    def _refused_if_not_accepted(self, result: int) -> int:
        if result != mavlink2.MAV_RESULT_ACCEPTED:
            self.counters.refused += 1
        return result

    def _on_command_long(self, msg: mavlink2.MAVLink_command_long_message, addr: tuple[str, int]) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7)
        self.outbox.ack(msg.command, self._command(msg.command, params, None, msg.get_srcComponent()), msg)

    def _on_command_int(self, msg: mavlink2.MAVLink_command_int_message, addr: tuple[str, int]) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, float(msg.x), float(msg.y), msg.z)
        self.outbox.ack(
            msg.command, self._command(msg.command, params, msg.frame, msg.get_srcComponent()), msg
        )

    def _command(self, command: int, p: tuple[float, ...], frame: int | None, source: int) -> int:
        """Run a COMMAND_LONG/COMMAND_INT (frame None for COMMAND_LONG) from component `source` (PX4's rules
        read it); returns the MAV_RESULT."""
        i = self.index
        autopilot = self.sim.autopilot
        if command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] == 1:
                return self._refused_if_not_accepted(autopilot.arm(i, force=p[1] == modes.FORCE_ARM))
            if p[0] == 0:
                return self._refused_if_not_accepted(autopilot.disarm(i, force=p[1] == modes.FORCE_DISARM))
            return self._invalid(mavlink2.MAV_RESULT_DENIED)
        if command == mavlink2.MAV_CMD_DO_SET_MODE:
            return self._set_mode(p[0], p[1])
        if command == mavlink2.MAV_CMD_NAV_TAKEOFF:
            if frame is not None and frame not in (
                mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            ):
                return self._invalid(mavlink2.MAV_RESULT_DENIED)
            return self._refused_if_not_accepted(autopilot.takeoff(i, p[6]))
        if command == mavlink2.MAV_CMD_NAV_LAND:
            return self._refused_if_not_accepted(autopilot.set_mode(i, modes.LAND))
        if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._refused_if_not_accepted(autopilot.set_mode(i, modes.RTL))
        if command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL:
            if not finite(p[0], p[1]) or abs(p[1]) > MAX_INTERVAL_US:
                return self._invalid(mavlink2.MAV_RESULT_DENIED)
            if not self.sim.streams.set_interval(i, int(p[0]), p[1], self.sim.time_us):
                return self._invalid(mavlink2.MAV_RESULT_DENIED)
            return mavlink2.MAV_RESULT_ACCEPTED
        if command == mavlink2.MAV_CMD_GET_MESSAGE_INTERVAL:
            interval = self.sim.streams.interval(i, int(p[0])) if finite(p[0]) else None
            if interval is None:
                return self._invalid(mavlink2.MAV_RESULT_DENIED)
            self.outbox.send(self.outbox.tx.message_interval_encode(int(p[0]), interval))
            return mavlink2.MAV_RESULT_ACCEPTED
        if command == mavlink2.MAV_CMD_REQUEST_MESSAGE:
            if not finite(p[0]):
                return self._invalid(mavlink2.MAV_RESULT_DENIED)
            return self._request_message(int(p[0]))
        if command == mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            return self._request_message(mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        if command == mavlink2.MAV_CMD_GET_HOME_POSITION:
            return self._request_message(mavlink2.MAVLINK_MSG_ID_HOME_POSITION)
        if command == mavlink2.MAV_CMD_DO_FENCE_ENABLE:
            return self._fence_enable(p)
        return mavlink2.MAV_RESULT_UNSUPPORTED

    def _fence_enable(self, p: tuple[float, ...]) -> int:
        """MAV_CMD_DO_FENCE_ENABLE (GCS_Fence.cpp handle_command_do_fence_enable): param1 0 off, 1 on (FAILED
        if none of the fences is present), 2 floor off; param2 the fence types (0: all). Not saved."""
        if not finite(p[0], p[1]):
            return self._invalid(mavlink2.MAV_RESULT_DENIED)
        autopilot, i = self.sim.autopilot, self.index
        configured = int(self.sim.params.value(i, "FENCE_TYPE"))
        fences = int(p[1]) & 0xFF or 0xF
        if int(p[0]) == 0:
            autopilot.fence.enable(i, False, fences, configured)
        elif int(p[0]) == 1:
            if not autopilot.fence.present_one(i, configured) & fences:
                return self._refused_if_not_accepted(mavlink2.MAV_RESULT_FAILED)
            autopilot.fence.enable(i, True, fences, configured)
        elif int(p[0]) == 2:
            autopilot.fence.enable(i, False, 8, configured)
        else:
            return self._refused_if_not_accepted(mavlink2.MAV_RESULT_FAILED)
        return mavlink2.MAV_RESULT_ACCEPTED

    def _invalid(self, result: int) -> int:
        self.counters.invalid += 1
        return result

    def _request_message(self, msg_id: int) -> int:
        """Send one message now (REQUEST_MESSAGE); `unavailable_result` when it is unknown or not available
        yet (ArduPilot: FAILED; PX4's handle_request_message_command: DENIED).

        The ACK is queued by the caller after this message; both leave in the same datagram.
        """
        if msg_id == mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            zeros = [0] * 8
            self.outbox.send(
                self.outbox.tx.autopilot_version_encode(
                    self.capabilities, self.flight_sw_version, 0, 0, 0, zeros, zeros, zeros, 0, 0, self.sysid
                )
            )
            return mavlink2.MAV_RESULT_ACCEPTED
        view = self.sim.telemetry_view()
        data = view.encode(self.outbox.framer, msg_id, self.index) if msg_id in STREAM_IDS else None
        if data is None:
            return self._refused_if_not_accepted(self.unavailable_result)
        self.outbox.append(data)
        return mavlink2.MAV_RESULT_ACCEPTED

    def _on_request_data_stream(
        self, msg: mavlink2.MAVLink_request_data_stream_message, addr: tuple[str, int]
    ) -> None:
        group = DATA_STREAM_GROUPS.get(msg.req_stream_id)
        if group is None:
            return
        rate = msg.req_message_rate if msg.start_stop else 0
        interval = 1e6 / rate if rate > 0 else -1
        for msg_id in group:
            self.sim.streams.set_interval(self.index, msg_id, interval, self.sim.time_us)

    def _send_param(self, j: int) -> None:
        bytewise = self.sim.autopilot.persona(self.index).bytewise_params  # how its integers travel
        self.outbox.send_param(self.sim.params, self.index, j, bytewise=bytewise)

    def _on_param_request_list(self, msg: mavlink2.MAVLink_message, addr: tuple[str, int]) -> None:
        for j in self.sim.params.listing(self.index):
            self._send_param(j)

    def _on_param_request_read(
        self, msg: mavlink2.MAVLink_param_request_read_message, addr: tuple[str, int]
    ) -> None:
        params = self.sim.params
        listing = params.listing(self.index)
        if msg.param_index >= 0:
            j = listing[msg.param_index] if msg.param_index < len(listing) else None
        else:
            j = params.lookup(self.index, param_name(msg.param_id))
        if j is None:
            self.counters.invalid += 1
            return
        self._send_param(j)

    def _on_param_set(self, msg: mavlink2.MAVLink_param_set_message, addr: tuple[str, int]) -> None:
        name = param_name(msg.param_id)
        params = self.sim.params
        value = float(msg.param_value)
        j = params.lookup(self.index, name)
        problem = params.check(name, value) if j is not None else f"unknown parameter {name}"
        if problem is not None:
            self.counters.refused += 1
            self.sim.autopilot.say(self.index, mavlink2.MAV_SEVERITY_WARNING, f"Param denied: {problem}")
            if j is not None:
                self._send_param(j)  # the unchanged value, as ArduPilot
            return
        self.sim.set_param(self.index, name, value)
