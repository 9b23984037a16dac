"""One vehicle's link: the object that ties its channel, telemetry, heartbeat, lockstep answers, setpoints,
commands, streams and parameters together, and hands each incoming packet to the part whose job it is.

Packets reach `VehicleLink.handle` through the network (gcs_swarm.link.network), which has already routed
them to this vehicle by sysid; the fleet (gcs_swarm.link.fleet) drives the link's `Operation`s.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots import formation_mode
from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import LinkError, MAVLinkMessage
from gcs_swarm.link.heartbeat import GcsHeartbeat
from gcs_swarm.link.lockstep import LockstepAnswer, is_clock_tick
from gcs_swarm.link.operations import Commands, Operation, Timeout
from gcs_swarm.link.parameters import Parameters
from gcs_swarm.link.radio_status import RadioStatus
from gcs_swarm.link.setpoints import Setpoints
from gcs_swarm.link.streams import Streams
from gcs_swarm.link.telemetry import Event, TelemetryState, VehicleTelemetry


@dataclass(frozen=True)
class VehicleConfig:
    """A vehicle to connect to: its name, connection string and (optionally) the sysid it must report."""

    name: str
    connection: str
    sysid: int | None = None
    autopilot: str = "auto"  # "auto": the dialect of its HEARTBEAT.autopilot; "ardupilot" | "px4": that one


class VehicleLink:
    """The link to one vehicle: decodes its packets into `state` row `index`, sends its commands.

    Its parts, each with one job: `channel` (identity, encoder, sending, stats), `telemetry` (packets ->
    state), `heartbeat` (GCS HEARTBEAT, TIMESYNC), `lockstep` (frame answers), `setpoints` (guided targets),
    `commands` (COMMAND_LONG operations), `streams` (telemetry rates, watchdog), `parameters`. Created by
    `Fleet`, whose loop drives the operations so that every other link keeps being served while one waits.
    """

    def __init__(
        self,
        index: int,
        config: VehicleConfig,
        state: TelemetryState,
        events: deque[Event],
        gcs_sysid: int = 255,
        gcs_compid: int = 190,
        signing_key: bytes | None = None,
    ) -> None:
        self.index = index
        self.config = config
        self.name = config.name
        self.state = state
        self.channel = Channel(config.name, config.sysid, gcs_sysid, gcs_compid, signing_key)
        self.heartbeat = GcsHeartbeat(index, self.channel, state)
        self.telemetry = VehicleTelemetry(
            index,
            config.name,
            state,
            events,
            self.channel.stats,
            self.heartbeat.send,
            self._rebooted,
        )
        self.lockstep = LockstepAnswer(index, self.channel, self.telemetry)
        self.setpoints = Setpoints(self.channel, self.lockstep)
        self.commands = Commands(self.channel, self.telemetry)
        self.streams = Streams(self.channel, self.telemetry, self.commands)
        self.parameters = Parameters(self.channel, self.telemetry)
        self.radio = RadioStatus()  # RADIO_STATUS reports heard on this connection (link.radio_status)
        # MISSION_* messages from the vehicle, read by the mission-protocol operations (flight.geofence)
        self.mission_messages: deque[MAVLinkMessage] = deque(maxlen=512)
        self.statustext_hooks: list[Callable[[VehicleLink, str], None]] = []  # called with every STATUSTEXT
        self._handlers: dict[str, Callable[[MAVLinkMessage], None]] = {
            **self.telemetry.handlers,
            "COMMAND_ACK": self.commands.on_command_ack,
            "PARAM_VALUE": self.parameters.on_param_value,
            "TIMESYNC": self.heartbeat.on_timesync,
            "MISSION_COUNT": self._on_mission,
            "MISSION_REQUEST": self._on_mission,
            "MISSION_REQUEST_INT": self._on_mission,
            "MISSION_ITEM_INT": self._on_mission,
            "MISSION_ACK": self._on_mission,
        }

    # ------------------------------------------------------------------ identity and sending

    @property
    def sysid(self) -> int | None:
        """The vehicle's sysid, bound at its first HEARTBEAT (config.sysid if given); None before."""
        return self.channel.sysid

    @property
    def compid(self) -> int:
        """The autopilot's component id (from its first HEARTBEAT)."""
        return self.channel.compid

    @property
    def mav(self) -> mavlink2.MAVLink:
        """This link's encoder (GCS sysid/compid, signing): messages built with it go out with `send`."""
        return self.channel.mav

    def send(self, msg: MAVLinkMessage) -> None:
        """Send one message to the vehicle (Channel.send)."""
        self.channel.send(msg)

    def vehicle_clock(self) -> tuple[int, float]:
        """This vehicle's clock for a `Timeout` (VehicleTelemetry.vehicle_clock)."""
        return self.telemetry.vehicle_clock()

    def add_event(self, text: str, severity: int = mavlink2.MAV_SEVERITY_WARNING) -> None:
        """Append an event for this vehicle, stamped with its latest time since boot."""
        self.telemetry.add_event(text, severity)

    def mode_name(self) -> str:
        """The vehicle's flight mode, named in its autopilot's dialect ("UNKNOWN" before a HEARTBEAT)."""
        return self.channel.autopilot.mode_name(int(self.state.mode[self.index]))

    def op_take_control(self, period_ms: int = 0) -> Operation[None]:
        """Into the dialect's formation mode, confirmed by HEARTBEAT. An autopilot that accepts it only over a
        flowing setpoint stream (PX4's OFFBOARD: `setpoint_proof_s`) first gets position holds where the
        vehicle is, one per new frame of its clock at least period_ms of its time after the previous one
        (the command mode's setpoint period; 0: every frame), for that long, and on until the mode shows."""
        dialect = self.channel.autopilot
        st, i = self.state, self.index
        if dialect.setpoint_proof_s <= 0 or st.mode[i] == dialect.mode_number(dialect.formation_mode):
            return (yield from self.commands.op_set_mode(formation_mode))
        if st.position_count[i] == 0:
            raise LinkError(f"{self.name} cannot enter {dialect.formation_mode}: no position received yet")
        point = st.pos[i].copy()
        yaw = float(st.att[i, 2]) if np.isfinite(st.att[i, 2]) else None
        sent_ms = -1

        def stream() -> None:
            nonlocal sent_ms
            if st.time_ms[i] != sent_ms and (sent_ms < 0 or st.time_ms[i] - sent_ms >= period_ms):
                sent_ms = int(st.time_ms[i])
                self.setpoints.send_position_target(point, yaw, stream=True)

        proof = Timeout(dialect.setpoint_proof_s, self.telemetry.vehicle_clock)
        while not proof.expired():
            stream()
            yield
        switch = self.commands.op_set_mode(formation_mode)
        while True:
            stream()
            try:
                next(switch)
            except StopIteration:
                return
            yield

    def not_ready_reason(self) -> str | None:
        """Why the vehicle is not ready to arm (None when it is), as a clause for an error sentence."""
        return self.telemetry.not_ready_reason(self.channel.autopilot, bool(self.streams.rates))

    # ------------------------------------------------------------------ receiving

    def handle(self, msg: MAVLinkMessage, now: float, mtype: str | None = None) -> None:
        """Decode one packet from this vehicle's sysid (routed by the network; `now` = time.monotonic();
        `mtype`: its msg.get_type(), when the caller has it).

        A STATUSTEXT is taken from any of the vehicle's components; anything else only from the autopilot.
        """
        if mtype is None:
            mtype = msg.get_type()
        if mtype == "STATUSTEXT":
            text = self.telemetry.on_statustext(msg)
            for hook in self.statustext_hooks:
                hook(self, text)
        elif msg.get_srcComponent() != self.channel.compid:
            self.channel.stats.ignored += 1
            return
        elif mtype == "SYSTEM_TIME" and is_clock_tick(msg):
            self.lockstep.on_clock_tick(msg)
            return  # a clock tick is no evidence that the radio link works
        else:
            handler = self._handlers.get(mtype)
            if handler is not None:
                handler(msg)
            if mtype == "SYSTEM_TIME":
                self.lockstep.on_system_time(msg)  # a frame of a lockstep simulator
        self.telemetry.heard(now)

    def _rebooted(self) -> None:
        self.streams.on_reboot()

    def _on_mission(self, m: MAVLinkMessage) -> None:
        if m.target_system in (0, self.channel.gcs_sysid):
            self.mission_messages.append(m)
