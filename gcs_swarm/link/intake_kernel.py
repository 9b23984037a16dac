"""The compiled half of link.batch_intake: a whole fleet's 50 Hz telemetry datagrams (GLOBAL_POSITION_INT and
ATTITUDE) into the state arrays in one call, instead of about 6 us of Python per packet (HotTelemetry).

`take_datagrams` walks the datagrams gathered in one byte buffer, in the order they were read, and takes each
one whole or stops before it. It takes a datagram only when every packet in it is what HotTelemetry.take
would take and HotTelemetry.apply would apply without anything but the plain case:

- nothing but whole, unsigned MAVLink 2 packets (no incompatibility flag), each a GLOBAL_POSITION_INT or an
  ATTITUDE from the bound vehicle's sysid and component, with a good CRC (trailing-zero truncation undone);
- values in range (|lat| <= 90 deg, |lon| <= 180 deg; finite angles: else `invalid` is counted);
- a time_boot_ms that is not late for its kind (`late`), not a reboot, and whose advance makes no GCS
  HEARTBEAT due (the heartbeat is sent by Python, in the middle of the datagram);
- a vehicle whose link is alive (else `heard` may add "link regained").

Every other datagram is left to the caller, which puts it through the per-packet path (HotTelemetry and
Network's general path) and calls again from the next one, so the packets of all vehicles are applied in
the order they were read, as Network.receive applies them. What a taken packet does is
VehicleTelemetry.on_global_position / on_attitude, on_time and heard, statement for statement, on the
arrays of TelemetryState; its tlog record (8-byte big-endian unix us, then the packet) goes to an output
buffer, and `received` is counted per vehicle.

Field decoding reads the payload in the machine's byte order, so link.batch_intake uses this only on
little-endian machines (MAVLink's own order). No fastmath; error_model "numpy". tests/gcs_swarm/link/
test_batch_intake.py compares it with the per-packet path over random datagrams.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.heartbeat import GCS_HEARTBEAT_MS, HEARTBEAT_STAGGER_MS
from gcs_swarm.link.telemetry import ATTITUDE_KIND, POSITION_KIND, REBOOT_BACKSTEP_MS

_kernel = njit(cache=True, error_model="numpy")

_MARKER_V2 = mavlink2.PROTOCOL_MARKER_V2
_HEADER_LEN = mavlink2.HEADER_LEN_V2  # 10: magic, len, incompat, compat, seq, sysid, compid, msgid x3
_POSITION_ID = mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
_ATTITUDE_ID = mavlink2.MAVLINK_MSG_ID_ATTITUDE
_POSITION_CRC_EXTRA = mavlink2.MAVLink_global_position_int_message.crc_extra
_ATTITUDE_CRC_EXTRA = mavlink2.MAVLink_attitude_message.crc_extra
_POSITION_SIZE = mavlink2.MAVLink_global_position_int_message.unpacker.size  # 28 payload bytes
_ATTITUDE_SIZE = mavlink2.MAVLink_attitude_message.unpacker.size  # 28 payload bytes
_SCRATCH = -(-max(_POSITION_SIZE, _ATTITUDE_SIZE) // 4) * 4  # bytes: the longer payload in whole 4-byte words
# GLOBAL_POSITION_INT wire order (pymavlink's unpacker): time_boot_ms u32, lat, lon, alt, relative_alt i32,
# vx, vy, vz i16, hdg u16. ATTITUDE: time_boot_ms u32, roll, pitch, yaw, and three rates f32.
_LAT, _LON, _ALT = 1, 2, 3  # int32 words
_VX, _VY, _VZ = 10, 11, 12  # int16 halves
_ROLL, _PITCH, _YAW = 1, 2, 3  # float32 words


@_kernel
def _crc_ok(buf: np.ndarray, start: int, end: int, crc_extra: int) -> bool:
    """The MAVLink CRC (X.25 / MCRF4XX) over buf[start + 1 : end - 2] and crc_extra equals the packet's."""
    crc = 0xFFFF
    for k in range(start + 1, end - 2 + 1):
        byte = crc_extra if k == end - 2 else int(buf[k])
        tmp = (byte ^ (crc & 0xFF)) & 0xFF
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = ((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)) & 0xFFFF
    return crc == (int(buf[end - 2]) | (int(buf[end - 1]) << 8))


@_kernel
def _heartbeat_due(index: int, t_ms: int, last_ms: int) -> bool:
    """heartbeat.GcsHeartbeat.due for vehicle `index` whose latest GCS HEARTBEAT went at `last_ms`."""
    if last_ms < 0 or t_ms < last_ms:
        return True
    shift = GCS_HEARTBEAT_MS - index * HEARTBEAT_STAGGER_MS % GCS_HEARTBEAT_MS
    return (t_ms + shift) // GCS_HEARTBEAT_MS > (last_ms + shift) // GCS_HEARTBEAT_MS


@_kernel
def _load_payload(buf: np.ndarray, start: int, end: int, scratch: np.ndarray) -> None:
    """The packet's payload into `scratch`, zeros after it (MAVLink 2 trailing-zero truncation undone)."""
    payload_start, payload_end = start + _HEADER_LEN, end - 2
    for k in range(_SCRATCH):
        scratch[k] = buf[payload_start + k] if payload_start + k < payload_end else 0


@_kernel
def _takeable(
    buf: np.ndarray,
    start: int,
    end: int,
    i: int,
    sysid: np.ndarray,
    compid: np.ndarray,
    alive: np.ndarray,
    time_ms: np.ndarray,
    latest_ms: np.ndarray,
    gcs_heartbeat_ms: np.ndarray,
    scratch: np.ndarray,
) -> bool:
    """Datagram buf[start:end] of vehicle `i` is one `take_datagrams` takes (module doc); reads only."""
    if start == end:
        return True  # an empty datagram: nothing to do
    if not alive[i] or sysid[i] < 0:
        return False
    words, floats = scratch.view(np.int32), scratch.view(np.float32)
    prev = time_ms[i]
    latest_position, latest_attitude = latest_ms[i, POSITION_KIND], latest_ms[i, ATTITUDE_KIND]
    p = start
    while p < end:
        if end - p < 3 or buf[p] != _MARKER_V2 or buf[p + 2] != 0:
            return False
        packet_end = p + _HEADER_LEN + 2 + np.int64(buf[p + 1])
        if packet_end > end or buf[p + 5] != sysid[i] or buf[p + 6] != compid[i]:
            return False
        msgid = np.int64(buf[p + 7]) | (np.int64(buf[p + 8]) << 8) | (np.int64(buf[p + 9]) << 16)
        if msgid == _POSITION_ID:
            if not _crc_ok(buf, p, packet_end, _POSITION_CRC_EXTRA):
                return False
            _load_payload(buf, p, packet_end, scratch)
            if abs(np.int64(words[_LAT])) > 900_000_000 or abs(np.int64(words[_LON])) > 1_800_000_000:
                return False
        elif msgid == _ATTITUDE_ID:
            if not _crc_ok(buf, p, packet_end, _ATTITUDE_CRC_EXTRA):
                return False
            _load_payload(buf, p, packet_end, scratch)
            roll, pitch, yaw = floats[_ROLL], floats[_PITCH], floats[_YAW]
            if not (math.isfinite(roll) and math.isfinite(pitch) and math.isfinite(yaw)):
                return False
        else:
            return False
        t_ms = int(scratch.view(np.uint32)[0])
        if t_ms > prev:
            if _heartbeat_due(i, t_ms, int(gcs_heartbeat_ms[i])):
                return False
            prev = t_ms
        elif t_ms < prev - REBOOT_BACKSTEP_MS:
            return False
        if msgid == _POSITION_ID:
            if t_ms < latest_position:
                return False
            latest_position = t_ms
        else:
            if t_ms < latest_attitude:
                return False
            latest_attitude = t_ms
        p = packet_end
    return True


@_kernel
def take_datagrams(
    buf: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    vehicles: np.ndarray,
    first: int,
    count: int,
    ids: np.ndarray,
    alive: np.ndarray,
    times: np.ndarray,
    latest_ms: np.ndarray,
    geodetic: np.ndarray,
    vel: np.ndarray,
    att: np.ndarray,
    walls: np.ndarray,
    clock: np.ndarray,
    received: np.ndarray,
    tlog: np.ndarray,
    tlog_stamp: np.ndarray,
    now: float,
    wall_now: float,
) -> tuple[int, int, int, bool]:
    """Take datagrams first, first + 1, ... of the `count` gathered, up to the first one it does not take.

    Datagram d is buf[starts[d]:ends[d]] (uint8) from vehicle vehicles[d]. Per vehicle i:
    ids (2, N) int64: bound sysid, component (-1: not bound);
    alive (N,) bool;
    times (7, N) int64: time_ms, position_ms, tick_ms, position_count, frames_missed, progress_ms,
    heard_clock_ms, then gcs_heartbeat_ms (row 7), as in TelemetryState;
    latest_ms (N, 3) int64; geodetic, vel, att (N, 3) float64 (TelemetryState's units);
    walls (2, N) float64: progress_wall, last_rx_wall (time.monotonic() s);
    clock (2,) float64: the fleet clock's clock_ms and clock_wall, read and written;
    received (N,) int64: packets taken per vehicle, added to;
    tlog: uint8 output for the tlog records (8-byte `tlog_stamp` then the packet), at least
    (ends[count - 1] - starts[first]) * 5 // 3 + 1 bytes long; an empty one writes none.
    `now`: time.monotonic() when the datagrams were read (heard); `wall_now`: time.monotonic() now (the time
    progress stamps, VehicleTelemetry.on_time's time.monotonic()).

    Returns (next datagram: the one it stopped before, or `count`; tlog bytes written; packets taken; any
    GLOBAL_POSITION_INT taken, so that TelemetryState.pos is stale).
    """
    time_ms, position_ms, tick_ms, position_count = times[0], times[1], times[2], times[3]
    frames_missed, progress_ms, heard_clock_ms, gcs_heartbeat_ms = times[4], times[5], times[6], times[7]
    sysid, compid = ids[0], ids[1]
    progress_wall, last_rx_wall = walls[0], walls[1]
    clock_ms, clock_wall = np.int64(clock[0]), clock[1]
    scratch = np.zeros(_SCRATCH, dtype=np.uint8)
    words, halves, floats = scratch.view(np.int32), scratch.view(np.int16), scratch.view(np.float32)
    write_tlog = tlog.shape[0] > 0
    written = 0
    taken = 0
    position_taken = False
    d = first
    while d < count:
        start, end, i = starts[d], ends[d], vehicles[d]
        if not _takeable(
            buf, start, end, i, sysid, compid, alive, time_ms, latest_ms, gcs_heartbeat_ms, scratch
        ):
            break
        p = start
        while p < end:
            packet_end = p + _HEADER_LEN + 2 + np.int64(buf[p + 1])
            _load_payload(buf, p, packet_end, scratch)
            t_ms = int(scratch.view(np.uint32)[0])
            # VehicleTelemetry.on_time (no reboot, no heartbeat due, not late: _takeable)
            prev = time_ms[i]
            if t_ms > prev:
                if prev >= 0:
                    progress_ms[i] += t_ms - prev
                    progress_wall[i] = wall_now
                    if progress_ms[i] > clock_ms:
                        clock_ms, clock_wall = progress_ms[i], wall_now
                time_ms[i] = t_ms
            if buf[p + 7] == _POSITION_ID:  # VehicleTelemetry.on_global_position
                latest_ms[i, POSITION_KIND] = t_ms
                geodetic[i, 0] = np.float64(words[_LAT]) * 1e-7  # degE7, degE7, mm AMSL
                geodetic[i, 1] = np.float64(words[_LON]) * 1e-7
                geodetic[i, 2] = np.float64(words[_ALT]) * 1e-3
                vel[i, 0] = np.float64(halves[_VY]) * 0.01  # cm/s NED -> m/s ENU (spec 1.1)
                vel[i, 1] = np.float64(halves[_VX]) * 0.01
                vel[i, 2] = np.float64(-np.int64(halves[_VZ])) * 0.01
                position_taken = True
                position_count[i] += 1
                if t_ms > position_ms[i] and position_ms[i] > tick_ms[i]:
                    frames_missed[i] += 1
                position_ms[i] = t_ms
            else:  # VehicleTelemetry.on_attitude: FRD/NED -> FLU/ENU (spec 1.1)
                latest_ms[i, ATTITUDE_KIND] = t_ms
                yaw = np.float64(floats[_YAW])
                att[i, 0] = np.float64(floats[_ROLL])
                att[i, 1] = -np.float64(floats[_PITCH])
                att[i, 2] = (0.5 * math.pi - yaw + math.pi) % (2.0 * math.pi) - math.pi
            # VehicleTelemetry.heard (alive already)
            last_rx_wall[i] = now
            heard_clock_ms[i] = clock_ms
            received[i] += 1
            taken += 1
            if write_tlog:
                for k in range(8):
                    tlog[written + k] = tlog_stamp[k]
                written += 8
                for k in range(p, packet_end):
                    tlog[written] = buf[k]
                    written += 1
            p = packet_end
        d += 1
    clock[0], clock[1] = np.float64(clock_ms), clock_wall
    return d, written, taken, position_taken


def warm_up() -> None:
    """Compile the kernel (or load it from numba's cache) before the first tick needs it."""
    n = 1
    take_datagrams(
        np.zeros(16, dtype=np.uint8),
        np.zeros(1, dtype=np.int64),
        np.zeros(1, dtype=np.int64),
        np.zeros(1, dtype=np.int64),
        0,
        1,
        np.full((2, n), -1, dtype=np.int64),
        np.zeros(n, dtype=np.bool_),
        np.zeros((8, n), dtype=np.int64),
        np.zeros((n, 3), dtype=np.int64),
        np.zeros((n, 3)),
        np.zeros((n, 3)),
        np.zeros((n, 3)),
        np.zeros((2, n)),
        np.zeros(2),
        np.zeros(n, dtype=np.int64),
        np.zeros(0, dtype=np.uint8),
        np.zeros(8, dtype=np.uint8),
        0.0,
        0.0,
    )
