"""The radio under each vehicle's link: capacity, air time, transmit buffers, half duplex (docs/radio.md).

A packet entering a vehicle's FaultChannel (sitl_sim.network.link_faults) with a radio first goes through
its `RadioLink`: the transmitting radio's buffer takes it or drops it when full (`TxBuffer`), then it waits
for the air (`Medium`, one FIFO time line per medium and direction, or one for both directions when half
duplex) and occupies it for its air time (swarm_common.radio_presets.RadioSpec.air_time_ns). The channel
delivers it at the first simulated ms at or after its last bit, plus whatever its faults add. Times are
integer simulated ns: the model is a function of simulated time, packet sizes and their order only.

Order of packets entering a medium in the same simulated ms: downlink packets as the simulator sends them
(vehicle by vehicle); the uplink datagrams that reached the sockets in that ms are staged and take the air
after them, sorted by vehicle and arrival (`Medium.settle`), so that the wall-clock order in which sockets are
read never changes the result. An uplink datagram arriving at ms m is due after m in any case (air time > 0),
so staging it until time moves on delays nothing.

A radio's capacity may change in flight (`CapacityChange`, sitl-sim --link-capacity-change): a packet is
timed at the capacity in force when it starts on the air; the buffers keep their size.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

from swarm_common.radio_presets import RadioSpec

UP, DOWN = 0, 1  # directions, as in link_faults: ground station -> vehicle, vehicle -> ground station
NS_PER_MS = 1_000_000


@dataclass(frozen=True)
class CapacityChange:
    """From simulated second start_s on, every radio's capacity is capacity_bps bit/s (the air time of a
    packet that starts then or later, eq. 1 of docs/radio.md)."""

    start_s: float
    capacity_bps: float


def parse_capacity_change(text: str) -> CapacityChange:
    """--link-capacity-change START:BPS (simulated s >= 0, bit/s > 0); ValueError with one sentence."""
    try:
        start_text, bps_text = text.split(":")
        start_s, bps = float(start_text), float(bps_text)
    except ValueError:
        raise ValueError(f"--link-capacity-change must be START:BPS (s, bit/s), not {text!r}") from None
    if not 0.0 <= start_s < math.inf:
        raise ValueError(f"--link-capacity-change start must be >= 0 s, not {start_text!r}")
    if not 0.0 < bps < math.inf:
        raise ValueError(f"--link-capacity-change capacity must be > 0 bit/s, not {bps_text!r}")
    return CapacityChange(start_s, bps)


class TxBuffer:
    """A transmitting radio's buffer: the bytes of packets it accepted that have not started on the air."""

    def __init__(self, limit: int) -> None:
        self.limit = limit  # bytes
        self.used = 0  # bytes held at the last `release`
        self._held: deque[tuple[int, int]] = deque()  # (start on the air ns, bytes), in start order

    def release(self, now_ns: int) -> int:
        """Let go of the packets on the air by now_ns; returns the bytes still held."""
        held = self._held
        while held and held[0][0] <= now_ns:
            self.used -= held.popleft()[1]
        return self.used

    def hold(self, start_ns: int, size: int) -> None:
        """Keep `size` bytes until start_ns (starts never decrease: one FIFO medium)."""
        self._held.append((start_ns, size))
        self.used += size

    def free_percent(self, now_ns: int) -> int:
        """Free share of the buffer as SiK reports it in RADIO_STATUS.txbuf: serial.c serial_read_space,
        (100 * (free / 8)) / (size / 8) in integer arithmetic."""
        free = self.limit - self.release(now_ns)
        return (100 * (free // 8)) // max(1, self.limit // 8)


@dataclass
class RadioCounts:
    """What one direction of one vehicle's radio did."""

    packets: int = 0  # packets put on the air
    bytes: int = 0  # their bytes (MAVLink bytes as sent, before the radio's own overhead)
    dropped: int = 0  # packets dropped because the transmitting radio's buffer was full
    delay_ns_sum: int = 0  # time the packets put on the air waited for it, summed
    delay_ns_max: int = 0

    def summary(self, prefix: str) -> str:
        """One "prefix_name=value ..." line; the delays as mean and max in ms."""
        mean = self.delay_ns_sum / self.packets / NS_PER_MS if self.packets else 0.0
        return (
            f"{prefix}_packets={self.packets} {prefix}_bytes={self.bytes} {prefix}_dropped={self.dropped} "
            f"{prefix}_delay_mean_ms={mean:.2f} {prefix}_delay_max_ms={self.delay_ns_max / NS_PER_MS:.2f}"
        )


# a staged uplink arrival: (simulated ms, vehicle, arrival number, its channel's transmit of the packet)
Staged = tuple[int, int, int, Callable[[], None]]


class Medium:
    """The air one or more radio links share: its FIFO time lines and the uplink arrivals not yet timed;
    `changes`: the capacity changes in flight (any order)."""

    def __init__(self, spec: RadioSpec, changes: Sequence[CapacityChange] = ()) -> None:
        self.spec = spec
        # (from ns, the radio from then on), in time order: air_time_ns of the last one started at or before
        self._specs = [(0, spec)] + [
            (round(c.start_s * 1e9), replace(spec, capacity_bps=c.capacity_bps))
            for c in sorted(changes, key=lambda c: c.start_s)
        ]
        self._free_at = [0, 0]  # ns at which each time line is free (half duplex: only [0])
        self._staged: list[Staged] = []
        self._arrivals = 0

    def send(
        self, direction: int, size: int, now_ms: int, buffer: TxBuffer, counts: RadioCounts
    ) -> int | None:
        """A packet of `size` bytes handed to the transmitting radio (whose buffer is `buffer`) at now_ms:
        the ns its last bit leaves the air, or None when the buffer had no room (counted in `counts`)."""
        now_ns = now_ms * NS_PER_MS
        if buffer.release(now_ns) + size > buffer.limit:
            counts.dropped += 1
            return None
        line = 0 if self.spec.half_duplex else direction
        start = max(now_ns, self._free_at[line])
        end = start + self._spec_at(start).air_time_ns(size)
        self._free_at[line] = end
        buffer.hold(start, size)
        wait = start - now_ns
        counts.packets += 1
        counts.bytes += size
        counts.delay_ns_sum += wait
        counts.delay_ns_max = max(counts.delay_ns_max, wait)
        return end

    def _spec_at(self, t_ns: int) -> RadioSpec:
        """The radio in force at simulated time t_ns (the latest capacity change at or before it)."""
        current = self.spec
        for start_ns, spec in self._specs:
            if start_ns > t_ns:
                break
            current = spec
        return current

    def stage(self, now_ms: int, vehicle: int, transmit: Callable[[], None]) -> None:
        """An uplink datagram of `vehicle` reached its socket at now_ms: `transmit` times it at `settle`."""
        self._arrivals += 1
        self._staged.append((now_ms, vehicle, self._arrivals, transmit))

    def settle(self, now_ms: int) -> None:
        """Time the staged uplink arrivals of every ms before now_ms, by ms, vehicle and arrival."""
        staged = self._staged
        if not staged or staged[0][0] >= now_ms:  # staged in arrival order: the oldest first
            return
        ready = sorted((s for s in staged if s[0] < now_ms), key=lambda s: s[:3])
        self._staged = [s for s in staged if s[0] >= now_ms]
        for *_, transmit in ready:
            transmit()


class RadioLink:
    """One vehicle's radio link: the medium it uses, the two transmitting buffers (UP: the ground radio's,
    which all vehicles share on a shared medium; DOWN: the vehicle's own) and its counts each way."""

    def __init__(self, medium: Medium, ground: TxBuffer) -> None:
        self.medium = medium
        self.spec = medium.spec
        self.buffers = (ground, TxBuffer(medium.spec.buffer_limit))
        self.counts = (RadioCounts(), RadioCounts())

    def send(self, direction: int, size: int, now_ms: int) -> int | None:
        """Medium.send of a packet in `direction` through this link's transmitting radio."""
        return self.medium.send(direction, size, now_ms, self.buffers[direction], self.counts[direction])

    def summary(self) -> str:
        """The counts of both directions, "radio_up_packets=... radio_down_delay_max_ms=..."."""
        return f"{self.counts[UP].summary('radio_up')} {self.counts[DOWN].summary('radio_down')}"


def fleet_radios(
    spec: RadioSpec | None, vehicles: int, changes: Sequence[CapacityChange] = ()
) -> list[RadioLink | None]:
    """Each vehicle's RadioLink for `spec` (None: no radio model), its capacity changing in flight as
    `changes` say: one medium and one ground radio for all when spec.shared, else one pair of radios each."""
    if spec is None:
        return [None] * vehicles
    if spec.shared:
        medium, ground = Medium(spec, changes), TxBuffer(spec.buffer_limit)
        return [RadioLink(medium, ground) for _ in range(vehicles)]
    return [RadioLink(Medium(spec, changes), TxBuffer(spec.buffer_limit)) for _ in range(vehicles)]
