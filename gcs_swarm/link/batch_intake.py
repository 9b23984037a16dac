"""A whole fleet's 50 Hz telemetry taken in one compiled call per receive, instead of a Python call chain per
packet: what lets the ground station hold a large fleet at 50 Hz in real time (issue 16).

Network.receive hands every readable endpoint that HotTelemetry serves (udpout, one vehicle, no signing key)
to `BatchIntake.read`, which reads its datagrams with `recv_into` into one byte buffer, and calls `flush`
before it serves any other endpoint and at the end of the receive. `flush` runs link.intake_kernel's
`take_datagrams` over the datagrams in the order they were read; at a datagram the kernel does not take (a
HEARTBEAT, a slow stream, a late or rebooting vehicle, a GCS HEARTBEAT due, anything but the plain case) it
puts that datagram through the per-packet path (`per_packet`, Network's HotTelemetry and general path) and
calls the kernel again from the next one. Every packet is thus applied in the order it was read, as without
the batch, with the same effect; tests/gcs_swarm/link/test_batch_intake.py compares the two over random
datagrams from several vehicles.

Two things differ, both wall-clock stamps: a taken packet's tlog record carries the time of its flush, not
of its own handling (microseconds apart), and VehicleTelemetry's `progress_wall` the time.monotonic() taken
before the kernel call.

Only with numba (extra "fast") on a little-endian machine (`available`); Network falls back to the
per-packet path otherwise, and when the fleet has forwards (they get every packet as it is handled).
"""

from __future__ import annotations

import socket
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from gcs_swarm.link.telemetry import TelemetryState
from gcs_swarm.link.tlog import TlogWriter

if TYPE_CHECKING:
    from gcs_swarm.link.vehicle import VehicleLink

try:
    from gcs_swarm.link import intake_kernel
except ImportError:  # numba not installed
    intake_kernel = None  # type: ignore[assignment]

_UDP_MAX = 65535  # bytes: the largest datagram, room kept free before every read
BUFFER_BYTES = 1 << 20  # datagram bytes gathered before a flush (about 50 frames of 200 vehicles)
MAX_DATAGRAMS = 8192  # datagrams gathered before a flush
MAX_READS_PER_ENDPOINT = 512  # datagrams read from one endpoint per receive (as connection.py)


def available() -> bool:
    """The compiled kernel can run here (numba imported, little-endian byte order)."""
    return intake_kernel is not None and sys.byteorder == "little"


def warm_up() -> None:
    """Compile the kernel, or load it from numba's cache."""
    assert intake_kernel is not None
    intake_kernel.warm_up()


PerPacket = Callable[[int, bytes, float], None]
"""per_packet(vehicle index, datagram, now): put one datagram through the per-packet path."""


class BatchIntake:
    """Gathers the datagrams of the vehicles `links` (their udpout sockets, `add`) and takes them into `state`
    in one kernel call (module doc). `tlog`: a callable returning the fleet's tlog writer (None: no tlog);
    `per_packet`: the path for what the kernel does not take."""

    def __init__(
        self,
        links: list[VehicleLink],
        state: TelemetryState,
        tlog: Callable[[], TlogWriter | None],
        per_packet: PerPacket,
    ) -> None:
        assert intake_kernel is not None
        self.links = links
        self.state = state
        self._tlog = tlog
        self._per_packet = per_packet
        n = len(links)
        self.ids = np.full((2, n), -1, dtype=np.int64)  # bound sysid, component per vehicle (-1: unbound)
        self.received = np.zeros(n, dtype=np.int64)  # packets the kernel took per vehicle, since the flush
        self._buffer = np.empty(BUFFER_BYTES, dtype=np.uint8)
        self._view = memoryview(self._buffer)  # type: ignore[arg-type]
        self._tlog_out = np.empty(
            BUFFER_BYTES * 5 // 3 + 1, dtype=np.uint8
        )  # 8 + 12 bytes per 12-byte packet
        self._no_tlog = np.empty(0, dtype=np.uint8)
        self._starts = np.empty(MAX_DATAGRAMS, dtype=np.int64)
        self._ends = np.empty(MAX_DATAGRAMS, dtype=np.int64)
        self._vehicles = np.empty(MAX_DATAGRAMS, dtype=np.int64)
        self._clock = np.zeros(2)
        self._count = 0  # datagrams gathered
        self._used = 0  # buffer bytes gathered
        self.datagrams_taken = 0  # datagrams the kernel took, since the fleet connected
        self.datagrams_passed = 0  # datagrams put through the per-packet path
        for link in links:
            self.refresh_identity(link.index)

    def refresh_identity(self, index: int) -> None:
        """Vehicle `index`'s bound sysid and component, as its channel has them (Network._bind calls this
        when it binds the vehicle)."""
        channel = self.links[index].channel
        self.ids[0, index] = -1 if channel.sysid is None else channel.sysid
        self.ids[1, index] = channel.compid

    def read(self, sock: socket.socket, index: int, now: float) -> None:
        """Read every datagram waiting on vehicle `index`'s socket (up to MAX_READS_PER_ENDPOINT);
        `now`: time.monotonic() of this receive."""
        for _ in range(MAX_READS_PER_ENDPOINT):
            if self._used + _UDP_MAX > BUFFER_BYTES or self._count == MAX_DATAGRAMS:
                self.flush(now)
            try:
                size = sock.recv_into(self._view[self._used :], _UDP_MAX)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # ECONNREFUSED: nothing listens at the destination (yet)
                continue
            k = self._count
            self._starts[k] = self._used
            self._used += size
            self._ends[k] = self._used
            self._vehicles[k] = index
            self._count = k + 1

    def flush(self, now: float) -> None:
        """Take every datagram gathered (module doc), in order, and empty the buffer."""
        assert intake_kernel is not None
        count = self._count
        if count == 0:
            return
        st = self.state
        tlog = self._tlog()
        first = 0
        while first < count:
            stamp = np.frombuffer(int(time.time() * 1e6).to_bytes(8, "big"), dtype=np.uint8)
            self._clock[0], self._clock[1] = st.clock_ms, st.clock_wall
            stop, written, taken, position_taken = intake_kernel.take_datagrams(
                self._buffer,
                self._starts,
                self._ends,
                self._vehicles,
                first,
                count,
                self.ids,
                st.alive,
                st.times,
                st.latest_ms,
                st.geodetic,
                st.vel,
                st.att,
                st.walls,
                self._clock,
                self.received,
                self._no_tlog if tlog is None else self._tlog_out,
                stamp,
                now,
                time.monotonic(),
            )
            st.clock_ms, st.clock_wall = int(self._clock[0]), float(self._clock[1])
            if taken:
                if position_taken:
                    st.pos_stale = True
                if tlog is not None:
                    tlog.write_records(self._tlog_out[:written].tobytes(), taken)
                for vehicle in np.flatnonzero(self.received):
                    self.links[vehicle].channel.stats.received += int(self.received[vehicle])
                self.received[:] = 0
            self.datagrams_taken += stop - first
            if stop == count:
                break
            index = int(self._vehicles[stop])
            self._per_packet(index, bytes(self._view[self._starts[stop] : self._ends[stop]]), now)
            self.datagrams_passed += 1
            first = stop + 1
        self._count = 0
        self._used = 0
