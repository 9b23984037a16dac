"""Degraded radio links between each simulated vehicle and its ground station (docs/sitl.md "Link faults").

Every MAVLink packet crossing a vehicle's endpoint, in either direction, goes through that vehicle's channel:
it may be lost, corrupted (one byte flipped, so the receiver's CRC rejects it), duplicated, delayed by
`delay_ms` plus a uniform jitter in [0, jitter_ms], held back further (reordered), or dropped during an
outage. Times are simulated milliseconds, so a lockstep run stays deterministic: each packet's fate is a hash
of (seed, vehicle, direction, simulated ms, message id, occurrence of that id in that ms), never a shared
random stream, so extra packets timed by the wall clock (e.g. keep-alive heartbeats) do not shift the fate
of the others.

The lockstep clock is simulation machinery, not radio: the simulator registers lockstep answers when a
datagram reaches its socket (before the channel), and at every frame end of a faulty vehicle appends a
fault-exempt clock tick, SYSTEM_TIME(time_unix_usec=0, time_boot_ms=frame), after the channel's output.

With a radio (`LinkFaults.radio`, sitl_sim.network.radio), a packet first crosses the radio (buffered, timed
on the air, or dropped for a full buffer); an outage silences it before, the faults act on what left the air.
"""

from __future__ import annotations

import hashlib
import heapq
import math
import struct
from dataclasses import dataclass, fields

from sitl_sim.network.radio import DOWN as DOWN  # directions: ground station -> vehicle, vehicle -> ground
from sitl_sim.network.radio import NS_PER_MS, CapacityChange, RadioLink
from sitl_sim.network.radio import UP as UP
from swarm_common.radio_presets import RadioSpec

REORDER_HOLD_MS = 60  # extra simulated ms a reordered packet is held back (3 frames at 50 Hz)


@dataclass(frozen=True)
class Outage:
    """No packet crosses vehicle `vehicle`'s link (None: every vehicle) from start_s for duration_s
    simulated seconds (inf: for good)."""

    vehicle: int | None
    start_s: float
    duration_s: float

    def covers(self, vehicle: int, t_s: float) -> bool:
        """The outage silences `vehicle` at simulated time t_s."""
        return self.vehicle in (None, vehicle) and self.start_s <= t_s < self.start_s + self.duration_s


@dataclass(frozen=True)
class LinkFaults:
    """Fault settings applied to every vehicle's link (run-time changes go through SIM_LINK_* params).

    Probabilities in [0, 1] per packet; delays in ms of simulated time."""

    loss: float = 0.0
    delay_ms: float = 0.0
    jitter_ms: float = 0.0
    dup: float = 0.0
    corrupt: float = 0.0
    reorder: float = 0.0
    outages: tuple[Outage, ...] = ()
    start_s: float = 0.0  # loss/delay/jitter/dup/corrupt/reorder act from this simulated time on
    radio: RadioSpec | None = None  # the radio under every link (None: unlimited capacity)
    capacity_changes: tuple[CapacityChange, ...] = ()  # the radio's capacity changing in flight

    def params(self) -> dict[str, float]:
        """The SIM_LINK_* parameter defaults these settings give, in FaultChannel.push's order of rates."""
        return {
            "SIM_LINK_LOSS": self.loss,
            "SIM_LINK_DUP": self.dup,
            "SIM_LINK_CORRUPT": self.corrupt,
            "SIM_LINK_REORDER": self.reorder,
            "SIM_LINK_DELAY": self.delay_ms,
            "SIM_LINK_JITTER": self.jitter_ms,
        }


def parse_outage(text: str, vehicles: int) -> Outage:
    """`[I@]START:DURATION` (simulated s; DURATION may be `inf`) -> Outage; ValueError (one sentence)."""
    vehicle: int | None = None
    spec = text.strip()
    if "@" in spec:
        index, spec = spec.split("@", 1)
        if not index.strip().isdigit():
            raise ValueError(f"--link-outage vehicle index must be a whole number, not {index!r}")
        vehicle = int(index)
        if vehicle >= vehicles:
            raise ValueError(f"--link-outage vehicle {vehicle} does not exist (vehicles 0..{vehicles - 1})")
    try:
        start_text, duration_text = spec.split(":")
        start, duration = float(start_text), float(duration_text)
    except ValueError:
        raise ValueError(f"--link-outage must be [I@]START:DURATION in seconds, not {text!r}") from None
    if not (math.isfinite(start) and start >= 0):
        raise ValueError(f"--link-outage start must be >= 0 s, not {start_text!r}")
    if math.isnan(duration) or duration <= 0:
        raise ValueError(f"--link-outage duration must be > 0 s (or inf), not {duration_text!r}")
    return Outage(vehicle, start, duration)


def message_id(packet: bytes) -> int:
    """MAVLink message id from a packet's header (-1 when it is not a MAVLink 1/2 frame start)."""
    if len(packet) >= 10 and packet[0] == 0xFD:
        return packet[7] | packet[8] << 8 | packet[9] << 16
    if len(packet) >= 6 and packet[0] == 0xFE:
        return packet[5]
    return -1


@dataclass
class LinkDrops:
    """What one vehicle's channel did to its packets (both directions)."""

    lost: int = 0  # dropped by loss or outage
    corrupted: int = 0
    duplicated: int = 0
    delayed: int = 0  # held back by delay, jitter or reordering


class FaultChannel:
    """One vehicle's two-way faulty link: packets in, (due simulated ms, packet) out, in due order."""

    def __init__(
        self, seed: int, vehicle: int, outages: tuple[Outage, ...], radio: RadioLink | None = None
    ) -> None:
        self.seed = seed
        self.radio = radio
        self.vehicle = vehicle
        self.outages = tuple(o for o in outages if o.vehicle in (None, vehicle))
        self.drops = LinkDrops()
        self._queues: tuple[list[tuple[int, int, bytes, object]], ...] = ([], [])
        self._order = 0
        self._seen: list[dict[int, int]] = [{}, {}]
        self._seen_ms = [-1, -1]

    def summary(self) -> str:
        """One line "link_lost=... link_corrupted=... link_duplicated=... link_delayed=..." (then the radio's
        counts, RadioLink.summary, when there is a radio)."""
        line = " ".join(f"link_{f.name}={getattr(self.drops, f.name)}" for f in fields(self.drops))
        return line if self.radio is None else f"{line} {self.radio.summary()}"

    def active(self, rates: tuple[float, ...]) -> bool:
        """A radio, any fault configured (rates: loss, dup, corrupt, reorder, delay_ms, jitter_ms) or any
        outage."""
        return self.radio is not None or bool(self.outages) or any(r > 0 for r in rates)

    def waiting(self, direction: int) -> list[tuple[int, int, bytes, object]]:
        """The queue of `direction` itself (the same list for the channel's life; read only; empty when no
        packet waits): one C-level any() over many channels' queues finds whether any has packets waiting."""
        return self._queues[direction]

    def push(self, direction: int, packet: bytes, tag: object, now_ms: int, rates: tuple[float, ...]) -> None:
        """One packet enters the channel at simulated ms now_ms; tag travels with it (e.g. the peer). With a
        radio, an uplink packet is staged on its medium until time moves on (sitl_sim.network.radio)."""
        radio = self.radio
        if radio is None:
            self._transmit(direction, packet, tag, now_ms, rates)
        elif direction == UP:
            radio.medium.stage(now_ms, self.vehicle, lambda: self._transmit(UP, packet, tag, now_ms, rates))
        else:
            radio.medium.settle(now_ms)
            self._transmit(direction, packet, tag, now_ms, rates)

    def _transmit(
        self, direction: int, packet: bytes, tag: object, now_ms: int, rates: tuple[float, ...]
    ) -> None:
        """The packet's fate, from its entry at now_ms: outage, radio, then the faults."""
        loss, dup, corrupt, reorder, delay_ms, jitter_ms = rates
        if any(o.covers(self.vehicle, now_ms / 1000.0) for o in self.outages):
            self.drops.lost += 1
            return
        sent_ms = now_ms  # the ms from which the faults' delays count: the last bit off the air with a radio
        if self.radio is not None:
            end_ns = self.radio.send(direction, len(packet), now_ms)
            if end_ns is None:
                return
            sent_ms = -(-end_ns // NS_PER_MS)
        u = self._uniforms(direction, packet, now_ms)
        if u[0] < loss:
            self.drops.lost += 1
            return
        copies = 2 if u[1] < dup else 1
        self.drops.duplicated += copies - 1
        if u[2] < corrupt:
            self.drops.corrupted += 1
            data = bytearray(packet)
            data[int(u[3] * len(data)) % len(data)] ^= 1 + int(u[4] * 255)
            packet = bytes(data)
        for copy in range(copies):
            extra = delay_ms + jitter_ms * u[5 + copy] + (REORDER_HOLD_MS if u[7] < reorder else 0.0)
            if extra > 0:
                self.drops.delayed += 1
            self._order += 1
            heapq.heappush(self._queues[direction], (sent_ms + round(extra), self._order, packet, tag))

    def due(self, direction: int, now_ms: int) -> list[tuple[bytes, object]]:
        """Packets (with their tags) due at or before now_ms, in delivery order."""
        queue = self._queues[direction]
        out = []
        while queue and queue[0][0] <= now_ms:
            _, _, packet, tag = heapq.heappop(queue)
            out.append((packet, tag))
        return out

    def _uniforms(self, direction: int, packet: bytes, now_ms: int) -> tuple[float, ...]:
        """Eight uniforms in [0, 1) that depend only on the seed, the vehicle, the direction, the simulated
        ms, the packet's message id and how many packets of that id this direction saw in that ms."""
        if self._seen_ms[direction] != now_ms:
            self._seen_ms[direction] = now_ms
            self._seen[direction] = {}
        msg_id = message_id(packet)
        seen = self._seen[direction]
        k = seen.get(msg_id, 0)
        seen[msg_id] = k + 1
        key = struct.pack("<qiBqii", self.seed, self.vehicle, direction, now_ms, msg_id, k)
        words = struct.unpack("<8I", hashlib.blake2b(key, digest_size=32).digest())
        return tuple(w / 2**32 for w in words)
