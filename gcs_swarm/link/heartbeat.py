"""The ground station's presence on one vehicle's link: GCS HEARTBEATs, in vehicle time and wall time, and the
TIMESYNC exchange that measures the link's round trip."""

from __future__ import annotations

import math
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import MAVLinkMessage
from gcs_swarm.link.telemetry import TelemetryState

WALL_HEARTBEAT_S = 1.0  # wall s between the heartbeats (and TIMESYNC requests) sent whatever the vehicle time


class GcsHeartbeat:
    """HEARTBEATs to vehicle `index` through `channel`: one per GCS_HEARTBEAT_MS of its time (the simulator
    times its GCS failsafe in vehicle time; when one is due is link.intake_kernel.heartbeat_due's law, and
    `send` is called then), one per WALL_HEARTBEAT_S of wall time with a TIMESYNC request."""

    def __init__(self, index: int, channel: Channel, state: TelemetryState) -> None:
        self.index = index
        self.channel = channel
        self.state = state
        self._wall = -math.inf  # time.monotonic() of the latest GCS HEARTBEAT
        self._timesync_ns = -1  # ts1 of our latest TIMESYNC request (monotonic ns)

    def send(self) -> None:
        """GCS HEARTBEAT (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)."""
        self.channel.send(
            self.channel.mav.heartbeat_encode(
                mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, mavlink2.MAV_STATE_ACTIVE
            )
        )
        self._wall = time.monotonic()
        self.state.gcs_heartbeat_ms[self.index] = self.state.time_ms[self.index]

    @property
    def last_wall(self) -> float:
        """time.monotonic() of the latest GCS HEARTBEAT (-inf: none yet); it only moves forward."""
        return self._wall

    def send_if_due(self, now: float) -> None:
        """Send the wall-clock heartbeat when due (`now`: time.monotonic()), with a TIMESYNC request whose
        echo measures the link's round-trip time."""
        if now - self._wall >= WALL_HEARTBEAT_S:
            self.send()
            self._timesync_ns = time.monotonic_ns()
            self.channel.send(self.channel.mav.timesync_encode(0, self._timesync_ns))

    def on_timesync(self, m: MAVLinkMessage) -> None:
        """A vehicle's reply (tc1 != 0) to our request echoes our ts1: round trip = now - ts1 (wall ms)."""
        if m.tc1 != 0 and m.ts1 == self._timesync_ns:
            self.state.rtt_ms[self.index] = (time.monotonic_ns() - m.ts1) / 1e6
