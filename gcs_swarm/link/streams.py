"""The telemetry the ground station asks one vehicle for, and the watchdog that asks again when it stops.

ArduCopter streams nothing on a link until a ground station asks (its MAVn_* / SRn_* rates are 0 by default)
and forgets every rate when it reboots, so asking is part of the link's job, not the flight's.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TypeVar

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.operations import Commands, Operation, message_id
from gcs_swarm.link.telemetry import VehicleTelemetry

MessageT = TypeVar("MessageT", bound=str | int)  # a MAVLink message name or id
STREAM_QUIET_S = 2.0  # [add] vehicle s without a position from a heard vehicle before its streams are asked
# again


def telemetry_rates(control_hz: float, status_hz: float = 2.0) -> dict[str, float]:
    """Message rates (Hz) the ground station needs: state at the control rate, health at `status_hz`."""
    return {
        "ATTITUDE": control_hz,
        "GLOBAL_POSITION_INT": control_hz,
        "SYS_STATUS": status_hz,
        "EKF_STATUS_REPORT": status_hz,
        "EXTENDED_SYS_STATE": status_hz,
        "GPS_RAW_INT": status_hz,
    }


class Streams:
    """Asks the vehicle behind `channel` for its telemetry and watches that it keeps coming."""

    def __init__(self, channel: Channel, telemetry: VehicleTelemetry, commands: Commands) -> None:
        self.channel = channel
        self.telemetry = telemetry
        self.commands = commands
        self.rates: dict[str | int, float] = {}  # the telemetry asked for (op_request_streams), Hz
        self.asked_ms = -1  # time_boot_ms of the watchdog's latest request (check), -1: none

    def on_reboot(self) -> None:
        """The vehicle rebooted: its rates are gone, the watchdog may ask again at once."""
        self.asked_ms = -1

    def op_set_message_interval(self, message: str | int, hz: float) -> Operation[int]:
        """MAV_CMD_SET_MESSAGE_INTERVAL: `message` every 1/hz s (hz <= 0 stops it)."""
        try:
            msg_id = message_id(message)
        except ValueError as err:
            raise LinkError(f"{self.channel.name}: {err}") from None
        interval_us = 1e6 / hz if hz > 0 else -1.0
        return self.commands.op_command(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, float(msg_id), interval_us)

    def op_request_streams(self, rates: Mapping[MessageT, float]) -> Operation[None]:
        """Ask for each message at its rate (Hz): SET_MESSAGE_INTERVAL, acknowledged, one after the other; a
        message the vehicle refuses (COMMAND_ACK other than ACCEPTED) is asked for by REQUEST_DATA_STREAM of
        its stream group in the autopilot's dialect instead, unless it is to stop (hz <= 0: that would stop
        the group's other messages) (no ACK exists for that; the stream watchdog, `check`, asks again if the
        telemetry does not come). Messages the autopilot does not have (its
        dialect's `unsupported_streams`, e.g. PX4's EKF_STATUS_REPORT) are not asked for. The rates are
        remembered for `check`."""
        missing = self.channel.autopilot.unsupported_streams
        self.rates = {message: float(hz) for message, hz in rates.items() if message not in missing}
        for message, hz in self.rates.items():
            try:
                yield from self.op_set_message_interval(message, hz)
            except LinkError as err:
                if "refused" not in str(err):
                    raise
                if hz > 0:  # stopping a whole group would stop the other messages in it too
                    self.request_data_stream(message, hz)

    def request_data_stream(self, message: str | int, hz: float) -> None:
        """REQUEST_DATA_STREAM of the stream group that carries `message` (if any), at `hz`."""
        name = message if isinstance(message, str) else mavlink2.mavlink_map[int(message)].msgname
        group = self.channel.autopilot.stream_group(str(name))
        if group is None:
            return
        rate = max(1, min(int(round(hz)), 0xFFFF)) if hz > 0 else 0
        ch = self.channel
        ch.send(ch.mav.request_data_stream_encode(ch.target_sysid, ch.compid, group, rate, 1 if rate else 0))

    def request_message(self, message: str | int) -> None:
        """MAV_CMD_REQUEST_MESSAGE, not waiting for the ACK (used to learn the vehicle's time at connect)."""
        self.channel.send_command(
            mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, [float(message_id(message))] + [0.0] * 6
        )

    def check(self) -> None:
        """Stream watchdog: a vehicle that is heard (HEARTBEATs) but whose positions stopped for
        STREAM_QUIET_S of its own time (after a reboot ArduPilot forgets every rate; a message interval can
        also be lost) is asked again for every stream, by both SET_MESSAGE_INTERVAL and REQUEST_DATA_STREAM
        without waiting for ACKs, at most once per STREAM_QUIET_S. Called by the fleet on every pump."""
        st, i = self.telemetry.state, self.telemetry.index
        if not self.rates or self.channel.sysid is None or not st.alive[i]:
            return
        now_ms = int(st.time_ms[i])
        last_position = int(st.position_ms[i])
        quiet = now_ms - max(last_position, self.asked_ms) > STREAM_QUIET_S * 1000
        if now_ms < 0 or not quiet:
            return
        self.asked_ms = now_ms
        self.channel.stats.stream_requests += 1
        self._send_requests()

    def ask(self, rates: Mapping[MessageT, float]) -> None:
        """Ask for each message at its rate (Hz; <= 0 stops it) in flight, without waiting for ACKs (the
        caller asks again if the telemetry does not change, as command_mode.CommandModeWatch does): each by
        SET_MESSAGE_INTERVAL, and those to go by REQUEST_DATA_STREAM too. Messages the autopilot does not
        have are left out, as in op_request_streams; the rates are remembered for `check`."""
        missing = self.channel.autopilot.unsupported_streams
        self.rates = {message: float(hz) for message, hz in rates.items() if message not in missing}
        self._send_requests()

    def _send_requests(self) -> None:
        """SET_MESSAGE_INTERVAL (and REQUEST_DATA_STREAM for a rate > 0) of every remembered rate, unACKed."""
        for message, hz in self.rates.items():
            try:
                msg_id = message_id(message)
            except ValueError:
                continue
            interval_us = 1e6 / hz if hz > 0 else -1.0
            self.channel.send_command(
                mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, 0, [float(msg_id), interval_us, 0, 0, 0, 0, 0]
            )
            if hz > 0:
                self.request_data_stream(message, hz)
