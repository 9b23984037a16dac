"""The one way in for what the vehicles send: every vehicle endpoint's datagrams (or stream chunks) of one
receive gathered in one byte buffer, their plain 50 Hz telemetry taken by one compiled walk, everything else
decoded by pymavlink, all in the order it was read.

Network.receive hands every readable vehicle endpoint to `Intake.read`, which reads it with `read_into`, and
calls `flush` before it serves a forward and at the end of the receive. `flush` runs link.intake_kernel's
`take_packets` from where it stopped:

- it takes the whole MAVLink 2 GLOBAL_POSITION_INT and ATTITUDE packets of bound vehicles (routes: per
  endpoint, sysid -> vehicle, set by `bind`; a shared udpin endpoint routes several) and applies the law
  of link.intake_kernel to them; their tlog records are written and their bytes, unchanged, queued for the
  forwards, as the general path does for what it decodes;
- after a packet whose outcome needs Python (a GCS HEARTBEAT due, a reboot, a late or invalid packet, a
  link regained), the vehicle's VehicleTelemetry.follow_up runs before the next packet is taken;
- before a signed packet (with a signing key only signed packets are taken), the endpoint's own signature
  check (swarm_common.signing.VerifyingParser, as pymavlink's decode calls it) runs; a packet that passes
  is taken, one that fails goes to the general path, which refuses it as before;
- anything else goes to the general path (`deliver`: pymavlink's decoding through the endpoint's parser,
  then Network's routing): one whole packet, or the rest of the datagram when what follows is not one; a
  stream chunk whose parser holds the start of a packet goes there whole.

Two things are stamped per run of the walk rather than per packet, both wall clocks: a taken packet's tlog
record (the unix time the run started) and the telemetry's wall stamps (time.monotonic() at the flush).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from gcs_swarm.link import intake_kernel
from gcs_swarm.link.connection import Endpoint, MAVLinkMessage, UdpRouter
from gcs_swarm.link.telemetry import TelemetryState
from gcs_swarm.link.tlog import TlogWriter
from swarm_common.mavlink_datagrams import v2_packet_end

if TYPE_CHECKING:
    from gcs_swarm.link.vehicle import VehicleLink

_UDP_MAX = 65535  # bytes: the largest datagram, room kept free before every read
BUFFER_BYTES = 1 << 20  # datagram bytes gathered before a flush
MAX_DATAGRAMS = 8192  # datagrams gathered before a flush
_RECORDS_BYTES = BUFFER_BYTES * (8 + intake_kernel.MIN_PACKET) // intake_kernel.MIN_PACKET + 1
_MAX_RECORDS = BUFFER_BYTES // intake_kernel.MIN_PACKET + 1

Deliver = Callable[[Endpoint, MAVLinkMessage, Any, float], None]
"""deliver(endpoint, message, peer, now): the general path for a message pymavlink decoded."""


class Intake:
    """Gathers the vehicle endpoints' bytes and takes them in (module doc). `links`: the fleet's vehicles
    (row i = links[i].index); `signing`: a signing key is set; `tlog()`: the tlog writer (None: none);
    `outgoing`: the frames queued for the forwards (None: no forwards); `deliver`: the general path."""

    def __init__(
        self,
        links: list[VehicleLink],
        state: TelemetryState,
        signing: bool,
        tlog: Callable[[], TlogWriter | None],
        outgoing: list[bytes | bytearray] | None,
        deliver: Deliver,
    ) -> None:
        self.links = links
        self.state = state
        self.signing = signing
        self._tlog = tlog
        self._outgoing = outgoing
        self._deliver = deliver
        self.endpoints: list[Endpoint] = []
        self._routers = False  # a shared udpin endpoint is served: it learns its vehicles' addresses
        self._index: dict[Endpoint, int] = {}
        self.routes = np.full((0, 256), -1, dtype=np.int64)  # (E, 256): endpoint, sysid -> vehicle
        self._buffer = np.empty(BUFFER_BYTES, dtype=np.uint8)
        self._view = memoryview(self._buffer)  # type: ignore[arg-type]
        self.gathered = intake_kernel.Gathered(
            self._buffer,
            np.empty(MAX_DATAGRAMS, dtype=np.int64),
            np.empty(MAX_DATAGRAMS, dtype=np.int64),
            np.empty(MAX_DATAGRAMS, dtype=np.int64),
            np.zeros(len(links), dtype=np.int64),
            np.zeros(len(links), dtype=np.int64),
            np.zeros(len(links), dtype=np.int64),
            np.full(MAX_DATAGRAMS, -1, dtype=np.int64),
            np.empty(_RECORDS_BYTES, dtype=np.uint8),
            np.empty(_MAX_RECORDS, dtype=np.int64),
            np.empty(8, dtype=np.uint8),
        )
        self._peers: list[Any] = [None] * MAX_DATAGRAMS
        self._endpoint_of: list[Endpoint | None] = [None] * MAX_DATAGRAMS
        self._count = 0  # datagrams gathered
        self._used = 0  # buffer bytes gathered

    def add(self, endpoint: Endpoint) -> None:
        """Serve `endpoint` (a vehicle endpoint, once)."""
        self._index[endpoint] = len(self.endpoints)
        self.endpoints.append(endpoint)
        self._routers = self._routers or isinstance(endpoint, UdpRouter)
        self.routes = np.vstack((self.routes, np.full((1, 256), -1, dtype=np.int64)))

    def bind(self, link: VehicleLink) -> None:
        """`link` is bound to its sysid and component (Network._bind): take its packets from now on (when
        its endpoint is one this intake serves)."""
        channel = link.channel
        source = self._index.get(channel.endpoint) if channel.endpoint is not None else None
        if source is None or channel.sysid is None:
            return
        self.routes[source, channel.sysid] = link.index
        self.gathered.compid[link.index] = channel.compid

    def read(self, endpoint: Endpoint, now: float) -> None:
        """Read what `endpoint` has now (up to its reads_per_poll) into the buffer; `now`: time.monotonic()
        of this receive."""
        source, g = self._index[endpoint], self.gathered
        for _ in range(endpoint.reads_per_poll):
            if self._used + _UDP_MAX > BUFFER_BYTES or self._count == MAX_DATAGRAMS:
                self.flush(now)
            busy = endpoint.busy
            got = endpoint.read_into(self._view[self._used :])
            if got is None:
                return
            k = self._count
            g.starts[k] = self._used
            self._used += got[0]
            g.ends[k] = self._used
            g.sources[k] = -1 if busy else source
            self._peers[k] = got[1]
            self._endpoint_of[k] = endpoint
            self._count = k + 1

    def flush(self, now: float) -> None:
        """Take in every datagram gathered (module doc), in order, and empty the buffer."""
        count = self._count
        if count == 0:
            return
        st, g = self.state, self.gathered
        tlog = self._tlog()
        keep = tlog is not None or self._outgoing is not None
        wall_now = time.monotonic()
        d, p = 0, int(g.starts[0])
        verified = (-1, -1)
        learned = 0  # datagrams before this one have taught their udpin endpoints their vehicles' addresses
        while True:
            g.stamp[:] = np.frombuffer(int(time.time() * 1e6).to_bytes(8, "big"), dtype=np.uint8)
            d, p, outcome, vehicle, written, recorded, stored = intake_kernel.take_packets(
                g, d, p, count, self.routes, self.signing, *verified, keep, st.law, now, wall_now
            )
            if stored:
                st.pos_stale = True
            if recorded:
                self._keep(tlog, written, recorded)
            learned = self._learn(learned, min(d, count - 1))
            if d == count:
                break
            if outcome >= 0:  # a taken packet's follow-up
                self.links[vehicle].telemetry.follow_up(outcome)
                continue
            start, end = int(g.starts[d]), int(g.ends[d])
            data = self._view[start:end].tobytes()
            endpoint = self._endpoint_of[d]
            assert endpoint is not None
            offset = p - start
            packet_end = v2_packet_end(data, offset)
            if outcome == intake_kernel.UNVERIFIED and packet_end is not None:
                packet = bytearray(data[offset:packet_end])
                if endpoint.check_signature(packet, packet[5], packet[6]):
                    verified = (d, p)
                    continue
            if packet_end is None or g.sources[d] < 0:
                self._general(endpoint, data[offset:], d, now)
                d += 1
                if d == count:
                    break
                p = int(g.starts[d])
            else:
                self._general(endpoint, data[offset:packet_end], d, now)
                p = start + packet_end
        for row in np.flatnonzero(g.received):
            stats = self.links[row].channel.stats
            stats.received += int(g.received[row])
            stats.bytes_received += int(g.received_bytes[row])
        g.received[:] = 0
        g.received_bytes[:] = 0
        self._count = 0
        self._used = 0

    def _general(self, endpoint: Endpoint, data: bytes, d: int, now: float) -> None:
        """`data` of datagram d through the general path."""
        peer = self._peers[d]
        for msg in endpoint.parse(data, peer):
            self._deliver(endpoint, msg, peer, now)

    def _keep(self, tlog: TlogWriter | None, written: int, recorded: int) -> None:
        """The tlog records the kernel wrote (`written` bytes, `recorded` records) to the tlog, and their
        packets to the forwards."""
        records = self.gathered.records[:written].tobytes()
        if tlog is not None:
            tlog.write_records(records, recorded)
        if self._outgoing is not None:
            starts = self.gathered.record_starts[:recorded].tolist() + [written]
            self._outgoing.extend(records[a + 8 : b] for a, b in zip(starts, starts[1:], strict=False))

    def _learn(self, first: int, last: int) -> int:
        """Datagrams first..last with taken packets teach their endpoint (a udpin one) where the vehicle
        is, as the general path's `parse` does; returns the datagram to start from next time."""
        if not self._routers:
            return last
        taken = self.gathered.taken_sysid
        for k in np.flatnonzero(taken[first : last + 1] >= 0) + first:
            endpoint = self._endpoint_of[k]
            assert endpoint is not None
            endpoint.learn(int(taken[k]), self._peers[k])
        taken[first : last + 1] = -1
        return last
