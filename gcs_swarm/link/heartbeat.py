"""The ground station's presence on one vehicle's link: GCS HEARTBEATs, in vehicle time and wall time, and the
TIMESYNC exchange that measures the link's round trip."""

from __future__ import annotations

import math
import time

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import MAVLinkMessage
from gcs_swarm.link.telemetry import TelemetryState

GCS_HEARTBEAT_MS = 500  # [add] vehicle ms between GCS HEARTBEATs: under 10 % loss a 5 s FS_GCS_TIMEOUT
# then needs ~10 lost in a row, not 5
HEARTBEAT_STAGGER_MS = 7  # [add] offset between consecutive vehicles' heartbeat periods, so that a fleet's
# vehicle-time heartbeats (clocks in step) spread over the frames of a period instead of all leaving in one
WALL_HEARTBEAT_S = 1.0  # wall s between the heartbeats (and TIMESYNC requests) sent whatever the vehicle time


class GcsHeartbeat:
    """HEARTBEATs to vehicle `index` through `channel`: one per GCS_HEARTBEAT_MS of its time (the simulator
    times its GCS failsafe in vehicle time), one per WALL_HEARTBEAT_S of wall time with a TIMESYNC request."""

    def __init__(self, index: int, channel: Channel, state: TelemetryState) -> None:
        self.index = index
        self.channel = channel
        self.state = state
        self._wall = -math.inf  # time.monotonic() of the latest GCS HEARTBEAT
        self._phase_ms = index * HEARTBEAT_STAGGER_MS % GCS_HEARTBEAT_MS
        self._timesync_ns = -1  # ts1 of our latest TIMESYNC request (monotonic ns)

    def due(self, t_ms: int) -> bool:
        """A GCS HEARTBEAT is due at time_boot_ms `t_ms`: the first one, then one per GCS_HEARTBEAT_MS period
        of vehicle time (vehicle i's periods start HEARTBEAT_STAGGER_MS * i ms later, modulo the period), and
        one after a reboot."""
        last = int(self.state.gcs_heartbeat_ms[self.index])
        if last < 0 or t_ms < last:
            return True
        shift = GCS_HEARTBEAT_MS - self._phase_ms
        return (t_ms + shift) // GCS_HEARTBEAT_MS > (last + shift) // GCS_HEARTBEAT_MS

    def on_vehicle_time(self, t_ms: int) -> None:
        """The vehicle's time_boot_ms moved to `t_ms`: send the vehicle-time heartbeat if it is due."""
        if self.due(t_ms):
            self.send()

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
