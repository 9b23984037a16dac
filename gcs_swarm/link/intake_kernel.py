"""The law of a vehicle's stamped telemetry, written once and compiled, and the walk that applies it to every
plain 50 Hz packet (GLOBAL_POSITION_INT, ATTITUDE) of one receive's datagrams.

The law (spec 1.1), on the arrays of telemetry.TelemetryState, row or column i = vehicle i:

- `on_time`: a packet stamped with time_boot_ms t advances the vehicle's clock and the fleet clock, reveals a
  reboot (t older than the newest by more than REBOOT_BACKSTEP_MS: its frames start again) and a late
  packet of its kind (older than the newest of that kind: its data must not overwrite newer data), and says
  whether a GCS HEARTBEAT is due in vehicle time (`heartbeat_due`);
- `position_packet`: GLOBAL_POSITION_INT (lat/lon out of bounds: invalid) -> geodetic row, ENU velocity,
  position count, missed frames;
- `attitude_packet`: ATTITUDE (non-finite angles: invalid) -> FLU/ENU Euler angles;
- `heard`: a packet from the vehicle arrived: its link is alive.

Each returns outcome bits (HEARTBEAT_DUE, REBOOTED, LATE, INVALID, REGAINED, POSITION_STORED) for what only
Python can do (send the heartbeat, reset the streams, count, log an event): telemetry.VehicleTelemetry does
it, for the packets pymavlink decodes and for those `take_packets` takes alike.

`take_packets` walks datagrams gathered in one byte buffer (link.intake) in the order they were read, packet
by packet, and takes a packet when it is a whole MAVLink 2 GLOBAL_POSITION_INT or ATTITUDE from the bound
autopilot (sysid -> vehicle by the endpoint's route table, component) with a good CRC; with signing, only a
signed one whose signature the caller has checked (it stops before an unchecked one and says so). It stops
before anything else (left to pymavlink, the general path), and after a taken packet whose outcome needs
Python. Payload fields are read in MAVLink's byte order (little-endian), whatever the machine's.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.jit import kernel
from swarm_common.rotations import yaw_ned_enu

REBOOT_BACKSTEP_MS = 5000  # a time_boot_ms this much older than the latest means a reboot, not a late packet
POSITION_KIND, ATTITUDE_KIND, CLOCK_KIND = 0, 1, 2  # kinds of stamped packets whose lateness is judged apart
# (columns of TelemetryState.latest_ms; CLOCK_KIND: the lockstep clock ticks, link.lockstep); -1: no kind
GCS_HEARTBEAT_MS = 500  # [add] vehicle ms between GCS HEARTBEATs: under 10 % loss a 5 s FS_GCS_TIMEOUT
# then needs ~10 lost in a row, not 5
HEARTBEAT_STAGGER_MS = 7  # [add] offset between consecutive vehicles' heartbeat periods, so that a fleet's
# vehicle-time heartbeats (clocks in step) spread over the frames of a period instead of all leaving in one

TIMES_ROWS = (
    "time_ms",
    "position_ms",
    "tick_ms",
    "position_count",
    "frames_missed",
    "progress_ms",
    "heard_clock_ms",
    "gcs_heartbeat_ms",
    "frame_ms",
)  # TelemetryState.times (9, N) int64, row by row
(_TIME, _POSITION, _TICK, _COUNT, _MISSED, _PROGRESS, _HEARD_CLOCK, _GCS_HEARTBEAT, _FRAME) = range(9)
_PROGRESS_WALL, _LAST_RX_WALL = 0, 1  # rows of TelemetryState.walls (2, N) float64, time.monotonic() s


class LawArrays(NamedTuple):
    """The arrays of telemetry.TelemetryState the law reads and writes (row or column i = vehicle i)."""

    times: np.ndarray  # (9, N) int64, the rows of TIMES_ROWS
    latest_ms: np.ndarray  # (N, 3) int64: newest time_boot_ms per lateness kind (-1: none yet)
    walls: np.ndarray  # (2, N) float64 time.monotonic() s: progress_wall, last_rx_wall
    clock: np.ndarray  # (2,) float64: the fleet clock's ms (largest progress) and its last advance's wall s
    alive: np.ndarray  # (N,) bool
    geodetic: np.ndarray  # (N, 3) lat deg, lon deg, alt m AMSL
    vel: np.ndarray  # (N, 3) ENU m/s
    att: np.ndarray  # (N, 3) roll, pitch, yaw rad, body FLU in world ENU


# outcome bits
HEARTBEAT_DUE = 1  # the vehicle's time moved and a vehicle-time GCS HEARTBEAT is due
REBOOTED = 2  # the vehicle rebooted: its stream rates are gone
LATE = 4  # older than the newest packet of its kind: not applied
INVALID = 8  # values out of range: not applied
REGAINED = 16  # the link was lost and is alive again
POSITION_STORED = 32  # a GLOBAL_POSITION_INT was stored: TelemetryState.pos must be recomputed
FOLLOW_UP = HEARTBEAT_DUE | REBOOTED | LATE | INVALID | REGAINED  # what only Python can finish

# take_packets' stops before a packet
NOT_TAKEN = -1  # for the general path (pymavlink)
UNVERIFIED = -2  # signed, its signature not yet checked

_MARKER_V2 = mavlink2.PROTOCOL_MARKER_V2
_SIGNED = mavlink2.MAVLINK_IFLAG_SIGNED
_SIGNATURE_LEN = mavlink2.MAVLINK_SIGNATURE_BLOCK_LEN
_HEADER_LEN = mavlink2.HEADER_LEN_V2  # 10: magic, len, incompat, compat, seq, sysid, compid, msgid x3
_POSITION_ID = mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
_ATTITUDE_ID = mavlink2.MAVLINK_MSG_ID_ATTITUDE
_POSITION_CRC_EXTRA = mavlink2.MAVLink_global_position_int_message.crc_extra
_ATTITUDE_CRC_EXTRA = mavlink2.MAVLink_attitude_message.crc_extra
_PAYLOAD = max(
    mavlink2.MAVLink_global_position_int_message.unpacker.size,
    mavlink2.MAVLink_attitude_message.unpacker.size,
)  # 28 bytes: the longer payload; MAVLink 2 cuts trailing zeros, and longer payloads' extra bytes are ignored
MIN_PACKET = _HEADER_LEN + 2 + 1  # bytes of the shortest MAVLink 2 packet (one payload byte)
# GLOBAL_POSITION_INT wire offsets (pymavlink's unpacker): time_boot_ms u32 0, lat 4, lon 8, alt 12,
# relative_alt 16 (i32), vx 20, vy 22, vz 24 (i16), hdg 26 (u16). ATTITUDE: time_boot_ms u32 0, roll 4,
# pitch 8, yaw 12, then three rates (f32).


@kernel
def heartbeat_due(i: int, t_ms: int, last_ms: int) -> bool:
    """A GCS HEARTBEAT is due for vehicle `i` at time_boot_ms `t_ms`, the latest having gone at `last_ms`
    (-1: none yet): the first one, one after a reboot, then one per GCS_HEARTBEAT_MS period of vehicle time,
    vehicle i's periods starting HEARTBEAT_STAGGER_MS * i ms later (modulo the period)."""
    if last_ms < 0 or t_ms < last_ms:
        return True
    shift = GCS_HEARTBEAT_MS - i * HEARTBEAT_STAGGER_MS % GCS_HEARTBEAT_MS
    return (t_ms + shift) // GCS_HEARTBEAT_MS > (last_ms + shift) // GCS_HEARTBEAT_MS


@kernel
def on_time(i: int, t_ms: int, kind: int, s: LawArrays, wall_now: float) -> int:
    """Vehicle i sent a packet stamped with time_boot_ms `t_ms`, of lateness `kind` (POSITION_KIND,
    ATTITUDE_KIND, CLOCK_KIND; -1: none); `wall_now`: time.monotonic() now. Returns HEARTBEAT_DUE |
    REBOOTED | LATE.

    A stamp newer than the vehicle's newest advances its progress (and the fleet clock); one older by more
    than REBOOT_BACKSTEP_MS is a reboot, after which its frames start again from none. Lateness is per kind:
    a delayed position report older than the latest attitude is still the newest position."""
    times, latest_ms, clock = s.times, s.latest_ms, s.clock
    prev = times[_TIME, i]
    outcome = 0
    if t_ms > prev or t_ms < prev - REBOOT_BACKSTEP_MS:
        if t_ms > prev and prev >= 0:
            progress = times[_PROGRESS, i] + t_ms - prev
            times[_PROGRESS, i] = progress
            s.walls[_PROGRESS_WALL, i] = wall_now
            if progress > clock[0]:
                clock[0], clock[1] = progress, wall_now
        elif t_ms < prev:
            times[_TICK, i] = -1
            times[_FRAME, i] = -1
            times[_POSITION, i] = -1
            latest_ms[i, :] = -1
            outcome |= REBOOTED
        times[_TIME, i] = t_ms
        if heartbeat_due(i, t_ms, times[_GCS_HEARTBEAT, i]):
            outcome |= HEARTBEAT_DUE
    if kind < 0:
        return outcome
    if t_ms < latest_ms[i, kind]:
        return outcome | LATE
    latest_ms[i, kind] = t_ms
    return outcome


@kernel
def position_packet(
    i: int, t_ms: int, lat: int, lon: int, alt: int, vx: int, vy: int, vz: int, s: LawArrays, wall_now: float
) -> int:
    """GLOBAL_POSITION_INT's fields (lat, lon degE7, alt mm AMSL, vx, vy, vz cm/s NED) into the geodetic
    row (deg, deg, m) and the ENU velocity m/s (spec 1.1); the rest as `on_time`. Returns its outcome."""
    if abs(lat) > 900_000_000 or abs(lon) > 1_800_000_000:
        return INVALID
    outcome = on_time(i, t_ms, POSITION_KIND, s, wall_now)
    if outcome & LATE:
        return outcome
    geodetic, vel, times = s.geodetic, s.vel, s.times
    geodetic[i, 0] = lat * 1e-7
    geodetic[i, 1] = lon * 1e-7
    geodetic[i, 2] = alt * 1e-3
    vel[i, 0] = vy * 0.01
    vel[i, 1] = vx * 0.01
    vel[i, 2] = -vz * 0.01
    times[_COUNT, i] += 1
    if t_ms > times[_POSITION, i] and times[_POSITION, i] > times[_TICK, i]:
        times[_MISSED, i] += 1  # a new frame; the one in hand was never used
    times[_POSITION, i] = t_ms
    return outcome | POSITION_STORED


@kernel
def attitude_packet(
    i: int, t_ms: int, roll: float, pitch: float, yaw: float, s: LawArrays, wall_now: float
) -> int:
    """ATTITUDE's roll, pitch, yaw rad (body FRD in world NED) into the attitude row roll, pitch, yaw rad
    (body FLU in world ENU, spec 1.1); the rest as `on_time`. Returns its outcome."""
    if not (math.isfinite(roll) and math.isfinite(pitch) and math.isfinite(yaw)):
        return INVALID
    outcome = on_time(i, t_ms, ATTITUDE_KIND, s, wall_now)
    if outcome & LATE:
        return outcome
    s.att[i, 0] = roll
    s.att[i, 1] = -pitch
    s.att[i, 2] = yaw_ned_enu(yaw)
    return outcome


@kernel
def heard(i: int, now: float, s: LawArrays) -> int:
    """A packet from vehicle i's autopilot arrived at `now` (time.monotonic()): its link is alive. REGAINED
    when it was not."""
    s.walls[_LAST_RX_WALL, i] = now
    s.times[_HEARD_CLOCK, i] = np.int64(s.clock[0])
    if s.alive[i]:
        return 0
    s.alive[i] = True
    return REGAINED


@kernel
def _crc_ok(buf: np.ndarray, start: int, crc_at: int, crc_extra: int) -> bool:
    """The MAVLink CRC (X.25 / MCRF4XX) over buf[start + 1 : crc_at] and crc_extra equals the two bytes at
    crc_at."""
    crc = 0xFFFF
    for k in range(start + 1, crc_at + 1):
        byte = crc_extra if k == crc_at else int(buf[k])
        tmp = (byte ^ (crc & 0xFF)) & 0xFF
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc == (int(buf[crc_at]) | (int(buf[crc_at + 1]) << 8))


@kernel
def _load_payload(buf: np.ndarray, start: int, stop: int, payload: np.ndarray) -> None:
    """buf[start:stop] into `payload`, zeros after it (MAVLink 2 trailing-zero truncation undone)."""
    for k in range(_PAYLOAD):
        payload[k] = buf[start + k] if start + k < stop else 0


@kernel
def _int(p: np.ndarray, k: int, size: int, signed: bool) -> int:
    """The little-endian integer of `size` bytes at payload byte k (two's complement when `signed`)."""
    u = 0
    for b in range(size):
        u |= int(p[k + b]) << (8 * b)
    return u - (1 << (8 * size)) if signed and u >= 1 << (8 * size - 1) else u


@kernel
def _f32(p: np.ndarray, k: int, word: np.ndarray) -> float:
    """The little-endian IEEE float32 at payload byte k, as float64 (`word`: a (1,) uint32 scratch)."""
    word[0] = _int(p, k, 4, False)
    return np.float64(word.view(np.float32)[0])


class Gathered(NamedTuple):
    """One receive's datagrams, gathered by link.intake, and what `take_packets` writes about them (D: the
    most datagrams one flush holds, N: vehicles)."""

    buf: np.ndarray  # uint8: the datagrams back to back, datagram k = buf[starts[k]:ends[k]]
    starts: np.ndarray  # (D,) int64
    ends: np.ndarray  # (D,) int64
    sources: (
        np.ndarray
    )  # (D,) int64: the endpoint datagram k was read from (-1: all of it to the general path)
    compid: np.ndarray  # (N,) int64: each vehicle's autopilot component
    received: np.ndarray  # (N,) int64: packets taken per vehicle
    received_bytes: np.ndarray  # (N,) int64: their bytes (framing and signature included)
    taken_sysid: np.ndarray  # (D,) int64: the sysid of datagram k's latest taken packet (-1: none)
    records: np.ndarray  # uint8: the tlog records of the packets taken (8-byte `stamp`, then the packet)
    record_starts: np.ndarray  # int64: record k starts at byte record_starts[k]
    stamp: np.ndarray  # (8,) uint8: the tlog stamp of this run of the walk (big-endian unix us)


@kernel
def take_packets(
    g: Gathered,
    d: int,
    p: int,
    count: int,
    routes: np.ndarray,
    signing: bool,
    verified_d: int,
    verified_p: int,
    keep: bool,
    s: LawArrays,
    now: float,
    wall_now: float,
) -> tuple[int, int, int, int, int, int, bool]:
    """Take the packets from offset p of datagram d on, up to the `count` gathered in `g` (module doc).

    routes (E, 256) int64: the vehicle a sysid's packets on endpoint e belong to (-1: none bound).
    `signing`: a signing key is set, so only signed packets are taken, and only the one at (verified_d,
    verified_p), whose signature the caller has checked, without stopping first. `keep`: write the tlog
    records. `s`: the state (LawArrays). `now`: time.monotonic() when the datagrams were read; `wall_now`:
    time.monotonic() now.

    Returns (d, p, outcome, vehicle, record bytes written, records written, any position stored): it
    stopped at offset p of datagram d (d == count: all done) with outcome NOT_TAKEN or UNVERIFIED before the
    packet there, or with the FOLLOW_UP outcome of vehicle's packet just before it.
    """
    buf, compid, records = g.buf, g.compid, g.records
    payload = np.zeros(_PAYLOAD, dtype=np.uint8)
    word = np.empty(1, dtype=np.uint32)
    written, recorded = 0, 0
    position_stored = False
    while d < count:
        end = g.ends[d]
        e = g.sources[d]
        while p < end:
            if e < 0 or end - p < MIN_PACKET or buf[p] != _MARKER_V2 or buf[p + 2] & ~_SIGNED:
                return d, p, NOT_TAKEN, -1, written, recorded, position_stored
            signed = buf[p + 2] != 0
            crc_at = p + _HEADER_LEN + np.int64(buf[p + 1])
            packet_end = crc_at + 2 + (_SIGNATURE_LEN if signed else 0)
            i = routes[e, buf[p + 5]]
            if packet_end > end or i < 0 or buf[p + 6] != compid[i]:
                return d, p, NOT_TAKEN, -1, written, recorded, position_stored
            msgid = np.int64(buf[p + 7]) | (np.int64(buf[p + 8]) << 8) | (np.int64(buf[p + 9]) << 16)
            if msgid == _POSITION_ID:
                crc_extra = _POSITION_CRC_EXTRA
            elif msgid == _ATTITUDE_ID:
                crc_extra = _ATTITUDE_CRC_EXTRA
            else:
                return d, p, NOT_TAKEN, -1, written, recorded, position_stored
            if not _crc_ok(buf, p, crc_at, crc_extra) or (signing and not signed):
                return d, p, NOT_TAKEN, -1, written, recorded, position_stored
            if signing and not (d == verified_d and p == verified_p):
                return d, p, UNVERIFIED, i, written, recorded, position_stored
            _load_payload(buf, p + _HEADER_LEN, crc_at, payload)
            t_ms = _int(payload, 0, 4, False)
            if msgid == _POSITION_ID:
                outcome = position_packet(
                    i,
                    t_ms,
                    _int(payload, 4, 4, True),
                    _int(payload, 8, 4, True),
                    _int(payload, 12, 4, True),
                    _int(payload, 20, 2, True),
                    _int(payload, 22, 2, True),
                    _int(payload, 24, 2, True),
                    s,
                    wall_now,
                )
                position_stored = position_stored or outcome & POSITION_STORED != 0
            else:
                outcome = attitude_packet(
                    i,
                    t_ms,
                    _f32(payload, 4, word),
                    _f32(payload, 8, word),
                    _f32(payload, 12, word),
                    s,
                    wall_now,
                )
            outcome |= heard(i, now, s)
            g.received[i] += 1
            g.received_bytes[i] += packet_end - p
            g.taken_sysid[d] = buf[p + 5]
            if keep:
                g.record_starts[recorded] = written
                recorded += 1
                for k in range(8):
                    records[written + k] = g.stamp[k]
                written += 8
                for k in range(p, packet_end):
                    records[written] = buf[k]
                    written += 1
            p = packet_end
            if outcome & FOLLOW_UP:
                return d, p, outcome, i, written, recorded, position_stored
        d += 1
        if d < count:
            p = g.starts[d]
    return d, p, 0, -1, written, recorded, position_stored


def warm_up() -> None:
    """Compile every function of the law for the argument types the link gives them, or load them from
    numba's cache, before the first receive needs them."""
    rows = np.zeros((1, 3))
    s = LawArrays(
        np.full((len(TIMES_ROWS), 1), -1, dtype=np.int64),
        np.full((1, 3), -1, dtype=np.int64),
        np.zeros((2, 1)),
        np.zeros(2),
        np.zeros(1, dtype=np.bool_),
        rows,
        rows,
        rows,
    )
    on_time(0, 1, -1, s, 0.0)
    position_packet(0, 1, 0, 0, 0, 0, 0, 0, s, 0.0)
    attitude_packet(0, 1, 0.0, 0.0, 0.0, s, 0.0)
    heard(0, 0.0, s)
    one = np.zeros(1, dtype=np.int64)
    bytes_ = np.zeros(8, dtype=np.uint8)
    g = Gathered(bytes_, one, one, one, one, one, one, one, bytes_, one, bytes_)
    take_packets(g, 0, 0, 0, np.full((1, 256), -1, dtype=np.int64), False, -1, -1, False, s, 0.0, 0.0)
