"""The link's housekeeping at every pump: wall-clock heartbeats due, loss checks, the stream watchdog; skipped
as a whole while bounds show that none of it can act.

Each pump used to call, for every vehicle, `GcsHeartbeat.send_if_due`, `VehicleTelemetry.check_loss` and
`Streams.check`, for a large fleet a noticeable share of each pump, although almost every call finds
nothing to do. `Housekeeping.run` makes those calls only when one of
them may act, from three bounds taken at its last full pass over the links and the telemetry arrays:

    heartbeats   any send_if_due acts only if now - last_wall >= WALL_HEARTBEAT_S for some link; last_wall
                 only moves forward, so the oldest one at the last pass bounds them all
    loss         check_loss acts only on an alive vehicle, and only if
                 (clock_ms - heard_clock_ms) / 1000 > loss timeout or now - last_rx_wall > wall loss timeout;
                 both marks only move forward (a packet sets them to the current clock and wall time), so the
                 oldest ones of the vehicles alive at the last pass bound them all: a vehicle lost then is
                 alive again only after a packet, which set its marks to at least the clock and wall time of
                 that pass (the bounds when none was alive). A lost vehicle does not keep the pumps making
                 full passes.
    streams      Streams.check acts only if time_ms - max(position_ms, asked_ms) > STREAM_QUIET_S * 1000 for
                 some vehicle, which needs time_ms - position_ms above it: checked over the state arrays
                 at each pump

Subtraction and division are monotonic in floating point as well, so a bound that says "nothing can act" is
never wrong: a skipped pump sends, marks and asks exactly what the full pass would have (nothing). When a
bound may be crossed the full pass runs, every call checking its own condition, as before.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from gcs_swarm.link.heartbeat import WALL_HEARTBEAT_S
from gcs_swarm.link.streams import STREAM_QUIET_S
from gcs_swarm.link.telemetry import TelemetryState
from gcs_swarm.link.vehicle import VehicleLink

_STREAM_QUIET_MS = STREAM_QUIET_S * 1000


class Housekeeping:
    """The per-pump housekeeping of `links` (rows of `state`), with the fleet's loss timeouts (s)."""

    def __init__(self, links: Sequence[VehicleLink], state: TelemetryState) -> None:
        self.links = links
        self.state = state
        self.full_passes = 0  # pumps that called every link's checks (the rest were skipped by the bounds)
        self._oldest_heartbeat_wall = -np.inf  # min last_wall over the links at the last full pass
        self._oldest_heard_clock_ms = 0  # min heard_clock_ms over the links alive at the last full pass
        self._oldest_rx_wall = -np.inf  # min last_rx_wall over the links alive at the last full pass

    def run(self, now: float, loss_timeout_s: float, loss_wall_timeout_s: float) -> None:
        """Send the wall-clock heartbeats due, mark silent vehicles lost, re-ask quiet streams (`now`:
        time.monotonic() when the pump's select returned)."""
        if not self._may_act(now, loss_timeout_s, loss_wall_timeout_s):
            return
        self.full_passes += 1
        for link in self.links:
            if link.channel.endpoint is not None:
                link.heartbeat.send_if_due(now)
                link.telemetry.check_loss(now, loss_timeout_s, loss_wall_timeout_s)
                link.streams.check()
        self._oldest_heartbeat_wall = min(link.heartbeat.last_wall for link in self.links)
        alive = [link.telemetry for link in self.links if self.state.alive[link.index]]
        self._oldest_heard_clock_ms = min((t.heard_clock_ms for t in alive), default=self.state.clock_ms)
        self._oldest_rx_wall = min((t.last_rx_wall for t in alive), default=now)

    def _may_act(self, now: float, loss_timeout_s: float, loss_wall_timeout_s: float) -> bool:
        """False only when no link's heartbeat, loss check or stream watchdog can act (module doc)."""
        st = self.state
        return bool(
            now - self._oldest_heartbeat_wall >= WALL_HEARTBEAT_S
            or (st.clock_ms - self._oldest_heard_clock_ms) / 1000.0 > loss_timeout_s
            or now - self._oldest_rx_wall > loss_wall_timeout_s
            or (st.time_ms - st.position_ms).max(initial=0) > _STREAM_QUIET_MS
        )
