"""Telemetry: which message is due when (per vehicle), and how each is built from the simulated state.

Streams are scheduled at multiples of their interval from boot, checked at every autopilot tick, so a 50 Hz
stream lands on every 20 ms frame end. Intervals shorter than the tick are raised to the tick (the fastest the
autopilot state changes). This module is also the MAVLink frame boundary for telemetry: physics is ENU/FLU,
everything built here is NED/FRD (spec 1.1). The fast streams' payloads are packed for the whole fleet at once
per instant (TelemetryView); each vehicle's packet then only gets its header and CRC.
"""

from __future__ import annotations

import math
import re
import struct
from collections.abc import Sequence
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import pymap3d
from fastcrc.crc16 import mcrf4xx as _mcrf4xx  # pymavlink's x25crc: CRC-16/MCRF4XX from 0xFFFF
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.arducopter import DEFAULT_RATES_HZ
from swarm_common.jit import kernel

if TYPE_CHECKING:
    from sitl_sim.autopilot.copter import Autopilot

# every stream the simulator sends, in its order: the ArduCopter persona's table of default rates lists them
STREAM_IDS = tuple(DEFAULT_RATES_HZ)
# Legacy REQUEST_DATA_STREAM groups (MAVProxy uses them) -> the messages of ours they contain, as ArduPilot
# groups them (libraries/GCS_MAVLink/GCS_MAVLink_Parameters.cpp STREAM_*_msgs); EXTENDED_SYS_STATE is in
# none (only SET_MESSAGE_INTERVAL starts it).
DATA_STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mavlink2.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink2.MAVLINK_MSG_ID_FENCE_STATUS,
    ),
    mavlink2.MAV_DATA_STREAM_POSITION: (
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    mavlink2.MAV_DATA_STREAM_EXTRA1: (mavlink2.MAVLINK_MSG_ID_ATTITUDE,),
    mavlink2.MAV_DATA_STREAM_EXTRA3: (
        mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
        mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,
    ),
}
DATA_STREAM_GROUPS[mavlink2.MAV_DATA_STREAM_ALL] = tuple(
    m for group in DATA_STREAM_GROUPS.values() for m in group
)

SQRT_HALF = math.sqrt(0.5)


def swap_quat_enu_ned(q: Sequence[float]) -> tuple[float, float, float, float]:
    """One body FLU->ENU quaternion (4,) [w,x,y,z] <-> the body FRD->NED one (the map is its own inverse).

    q_ned = q(ENU->NED) * q * q(FRD->FLU), both fixed rotations being half turns (about (1,1,0)/sqrt 2 and x).
    Scalar arithmetic (one setpoint at a time): the same float64 operations as ned_telemetry's.
    """
    w, x, y, z = (float(c) for c in q)
    return SQRT_HALF * (w + z), SQRT_HALF * (x + y), SQRT_HALF * (x - y), SQRT_HALF * (w - z)


@kernel
def ned_telemetry(
    pos: np.ndarray, vel: np.ndarray, quat: np.ndarray, omega: np.ndarray, origin: np.ndarray
) -> np.ndarray:
    """(N,16) per vehicle: quaternion FRD->NED (4), roll, pitch, yaw NED (3), body rates FRD (3), position NED
    from origin (3), velocity NED (3); from ENU/FLU pos, vel, origin (N,3), quat (N,4), omega (N,3)."""
    out = np.empty((pos.shape[0], 16))
    for i in range(pos.shape[0]):
        w, x, y, z = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        qw, qx, qy, qz = SQRT_HALF * (w + z), SQRT_HALF * (x + y), SQRT_HALF * (x - y), SQRT_HALF * (w - z)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = qw, qx, qy, qz
        out[i, 4] = math.atan2(2.0 * (qw * qx + qy * qz), 1.0 - 2.0 * (qx * qx + qy * qy))
        out[i, 5] = math.asin(min(max(2.0 * (qw * qy - qz * qx), -1.0), 1.0))
        out[i, 6] = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        out[i, 7], out[i, 8], out[i, 9] = omega[i, 0], -omega[i, 1], -omega[i, 2]
        out[i, 10], out[i, 11], out[i, 12] = (
            pos[i, 1] - origin[i, 1],
            pos[i, 0] - origin[i, 0],
            origin[i, 2] - pos[i, 2],
        )
        out[i, 13], out[i, 14], out[i, 15] = vel[i, 1], vel[i, 0], -vel[i, 2]
    return out


WGS84_A = 6378137.0  # m, semi-major axis
WGS84_F = 1.0 / 298.257223563
WGS84_B = WGS84_A * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)


@kernel
def enu_to_geodetic(enu: np.ndarray, lat0: float, lon0: float, alt0: float) -> np.ndarray:
    """(N,3) ENU m around (lat0, lon0 deg, alt0 m) -> (N,3) lat, lon (deg), alt (m), WGS84, exact.

    ENU -> ECEF by rotation, ECEF -> geodetic by Heikkinen's closed form (no iteration).
    """
    phi, lam = math.radians(lat0), math.radians(lon0)
    sp, cp, sl, cl = math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)
    a, b, e2 = WGS84_A, WGS84_B, WGS84_E2
    n0 = a / math.sqrt(1.0 - e2 * sp * sp)
    x0, y0, z0 = (n0 + alt0) * cp * cl, (n0 + alt0) * cp * sl, (n0 * (1.0 - e2) + alt0) * sp
    out = np.empty_like(enu)
    for i in range(enu.shape[0]):
        e, n, u = enu[i, 0], enu[i, 1], enu[i, 2]
        x = x0 - sl * e - sp * cl * n + cp * cl * u
        y = y0 + cl * e - sp * sl * n + cp * sl * u
        z = z0 + cp * n + sp * u
        p = math.hypot(x, y)
        f54 = 54.0 * b * b * z * z
        g = p * p + (1.0 - e2) * z * z - e2 * (a * a - b * b)
        c = e2 * e2 * f54 * p * p / (g * g * g)
        s = (1.0 + c + math.sqrt(c * c + 2.0 * c)) ** (1.0 / 3.0)
        k = s + 1.0 + 1.0 / s
        pp = f54 / (3.0 * k * k * g * g)
        q = math.sqrt(1.0 + 2.0 * e2 * e2 * pp)
        r0 = -(pp * e2 * p) / (1.0 + q) + math.sqrt(
            0.5 * a * a * (1.0 + 1.0 / q) - pp * (1.0 - e2) * z * z / (q * (1.0 + q)) - 0.5 * pp * p * p
        )
        t = p - e2 * r0
        uu = math.sqrt(t * t + z * z)
        vv = math.sqrt(t * t + (1.0 - e2) * z * z)
        zz = b * b * z / (a * vv)
        out[i, 0] = math.degrees(math.atan2(z + (e2 / (1.0 - e2)) * zz, p))
        out[i, 1] = math.degrees(math.atan2(y, x))
        out[i, 2] = uu * (1.0 - b * b / (a * vv))
    return out


class Geodesy:
    """Local ENU metres (mission frame) <-> WGS84 around home = the ENU origin (lat, lon deg, alt m AMSL)."""

    def __init__(self, home: tuple[float, float, float]) -> None:
        self.lat0, self.lon0, self.alt0 = home

    def to_geodetic(self, enu: np.ndarray) -> np.ndarray:
        """(N,3) ENU -> (N,3) lat, lon (deg), alt (m AMSL)."""
        return enu_to_geodetic(np.ascontiguousarray(enu, dtype=float), self.lat0, self.lon0, self.alt0)

    def to_enu(self, lat: float, lon: float, alt: float) -> np.ndarray:
        """One WGS84 point (deg, deg, m AMSL) -> (3,) ENU m."""
        e, n, u = pymap3d.geodetic2enu(lat, lon, alt, self.lat0, self.lon0, self.alt0)
        return np.array([float(e), float(n), float(u)])


SPREAD_FROM_US = 100_000  # us: streams this slow or slower are spread over the ticks by vehicle


class StreamSchedule:
    """Per-vehicle stream intervals (N, M) us (0 = off) and next due times, M = len(STREAM_IDS).

    A stream of interval P is due at k P + phase from boot. The phase is 0 for fast streams (the 50 Hz control
    telemetry of every vehicle lands on the same tick, one lockstep frame) and, for streams of P >=
    SPREAD_FROM_US (the 1 Hz HEARTBEAT, status streams), vehicle i's (i x tick) mod P: a fleet's slow streams
    are spread over the ticks instead of leaving in one burst every second (at 200 vehicles: 2 per tick, not
    200 at once), as the autopilots of a real fleet are not phase-locked either.
    """

    def __init__(self, n: int, tick_us: int, default_rates_hz: np.ndarray | None = None) -> None:
        """default_rates_hz (N, M) Hz per vehicle and stream (0 = off), default DEFAULT_RATES_HZ for all."""
        self.tick_us = tick_us
        self.column = {msg_id: j for j, msg_id in enumerate(STREAM_IDS)}
        if default_rates_hz is None:
            default_rates_hz = np.tile([DEFAULT_RATES_HZ[m] for m in STREAM_IDS], (n, 1))
        rates = np.asarray(default_rates_hz, dtype=float)
        safe = np.where(rates > 0, rates, 1.0)
        self.default_us = np.where(rates > 0, np.maximum(tick_us, np.round(1e6 / safe)), 0).astype(np.int64)
        self.interval_us = self.default_us.copy()
        self.vehicle_offset_us = np.arange(n, dtype=np.int64)[:, None] * tick_us  # (N, 1)
        self.phase_us = self._phase(self.vehicle_offset_us, self.interval_us)
        self.next_due_us = self.phase_us.copy()

    @staticmethod
    def _phase(offset_us: np.ndarray, interval_us: np.ndarray) -> np.ndarray:
        """Phase (us) of streams of `interval_us` for vehicles `offset_us` (= index x tick), broadcast."""
        slow = interval_us >= SPREAD_FROM_US
        return np.where(slow, offset_us % np.maximum(interval_us, 1), 0)

    def set_interval(self, i: int, msg_id: int, interval_us: float, now_us: int) -> bool:
        """SET_MESSAGE_INTERVAL semantics: us > 0 period, 0 default, -1 off; False if msg_id is no stream."""
        j = self.column.get(msg_id)
        if j is None:
            return False
        if interval_us < 0:
            value = 0
        elif interval_us == 0:
            value = int(self.default_us[i, j])
        else:
            value = max(self.tick_us, round(interval_us))
        self.interval_us[i, j] = value
        if value:
            phase = int(self._phase(self.vehicle_offset_us[i], np.array([value]))[0])
            self.phase_us[i, j] = phase
            self.next_due_us[i, j] = -(-(now_us - phase) // value) * value + phase  # next k P + phase >= now
        return True

    def interval(self, i: int, msg_id: int) -> int | None:
        """Current interval (us, -1 = off) or None when msg_id is not a stream."""
        j = self.column.get(msg_id)
        if j is None:
            return None
        value = int(self.interval_us[i, j])
        return value if value else -1

    def due(self, now_us: int) -> list[tuple[int, int]]:
        """(vehicle, msg_id) pairs due at now_us (vehicle, then STREAM_IDS order); schedules the next."""
        on = self.interval_us > 0
        mask = on & (self.next_due_us <= now_us)
        if not mask.any():
            return []
        rows, cols = np.nonzero(mask)
        interval, phase = self.interval_us[rows, cols], self.phase_us[rows, cols]
        self.next_due_us[rows, cols] = ((now_us - phase) // interval + 1) * interval + phase
        return [(r, STREAM_IDS[c]) for r, c in zip(rows.tolist(), cols.tolist(), strict=True)]


def truncate(payload: bytes) -> bytes:
    """MAVLink 2 trailing-zero truncation of a packed payload (at least one byte stays)."""
    return payload.rstrip(b"\0") or b"\0"


STRUCT_TO_NUMPY = {  # struct format character -> numpy type (wire_dtype adds the byte order)
    "B": "u1", "b": "i1", "H": "u2", "h": "i2", "I": "u4", "i": "i4", "Q": "u8", "q": "i8",
    "f": "f4", "d": "f8",
}  # fmt: skip


def wire_dtype(cls: type[mavlink2.MAVLink_message]) -> np.dtype:
    """Structured dtype of message class cls's (numeric) payload: its fields named and in wire order
    (ordered_fieldnames), little-endian and unpadded, exactly as cls.unpacker.format packs them."""
    items = re.findall(r"(\d*)([a-zA-Z])", cls.unpacker.format.removeprefix("<"))
    fields = [
        (name, "<" + STRUCT_TO_NUMPY[code], (int(count),) if count else ())
        for name, (count, code) in zip(cls.ordered_fieldnames, items, strict=True)
    ]
    return np.dtype(fields)


# wire_dtype of the messages TelemetryView packs for the whole fleet, by msg_id
FLEET_DTYPES = {
    cls.id: wire_dtype(cls)
    for cls in (
        mavlink2.MAVLink_attitude_message,
        mavlink2.MAVLink_attitude_quaternion_message,
        mavlink2.MAVLink_local_position_ned_message,
        mavlink2.MAVLink_global_position_int_message,
    )
}


class Framer:
    """MAVLink 2 framing of one sender (sysid, compid) with its own sequence number.

    `pack` frames a pymavlink message object; `frame` builds the same bytes straight from a message class and
    its field values in wire order, and `frame_payload` from an already packed payload (the hot telemetry
    path: no per-message objects).
    """

    HEADER = struct.Struct("<BBBBBBBHB")
    CRC = struct.Struct("<H")

    def __init__(self, sysid: int, compid: int) -> None:
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)

    def pack(self, msg: mavlink2.MAVLink_message) -> bytes:
        """Bytes of a pymavlink message (then the sequence number advances)."""
        data = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) % 256
        return data

    def frame(self, cls: type[mavlink2.MAVLink_message], *values: float) -> bytes:
        """Bytes of message class cls from field values in wire order (ordered_fieldnames, flat arrays)."""
        return self.frame_payload(cls, truncate(cls.unpacker.pack(*values)))

    def frame_payload(self, cls: type[mavlink2.MAVLink_message], payload: bytes) -> bytes:
        """Bytes of message class cls around its packed, truncated payload: header (with this sender's
        sequence number, which then advances), payload, CRC-16/MCRF4XX of all but the magic byte and then
        cls.crc_extra."""
        mav = self.mav
        seq = mav.seq
        header = self.HEADER.pack(
            253, len(payload), 0, 0, seq, mav.srcSystem, mav.srcComponent, cls.id & 0xFFFF, cls.id >> 16
        )
        mav.seq = (seq + 1) % 256
        body = header + payload
        return body + self.CRC.pack(_mcrf4xx(body[1:] + cls.crc_extra.to_bytes(), 0xFFFF))


class TelemetryView:
    """The fleet as MAVLink sees it at one instant; arrays computed on first use.

    The messages of the fast streams (ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED, GLOBAL_POSITION_INT)
    are packed for the whole fleet at once (numpy, wire_dtype) on first use; each vehicle's packet then only
    gets its header and CRC (Framer.frame_payload).
    """

    def __init__(self, autopilot: Autopilot, time_us: int, geodesy: Geodesy, unix_epoch_us: int) -> None:
        self.ap = autopilot
        self.time_us = time_us
        self.time_boot_ms = time_us // 1000
        self.geodesy = geodesy
        self.unix_epoch_us = unix_epoch_us

    @cached_property
    def ned(self) -> np.ndarray:
        """(N,16) per vehicle (ned_telemetry): q FRD->NED 0:4, roll pitch yaw 4:7 (rad), rates FRD 7:10
        (rad/s), position NED 10:13 (m, from its EKF origin), velocity NED 13:16 (m/s)."""
        state = self.ap.state
        return ned_telemetry(state.pos, state.vel, state.quat, state.omega, self.ap.origin)

    @cached_property
    def global_position(self) -> np.ndarray:
        """(N,4) int64 per vehicle: lat, lon (1e7 deg), alt (mm AMSL), alt above home (mm), rounded half to
        even."""
        geodetic = self.geodesy.to_geodetic(self.ap.state.pos) * np.array([1e7, 1e7, 1000.0])
        rel = (self.ap.state.pos[:, 2] - self.ap.home[:, 2]) * 1000.0
        return np.round(np.column_stack((geodetic, rel))).astype(np.int64)

    def _fleet_payloads(self, cls: type[mavlink2.MAVLink_message], **fields: np.ndarray) -> list[bytes]:
        """Each vehicle's payload of message class cls, truncated: time_boot_ms now, the named fields from
        their (N,) columns (cast to the field's wire type), the others zero."""
        payload = np.zeros(self.ap.n, dtype=FLEET_DTYPES[cls.id])
        payload["time_boot_ms"] = self.time_boot_ms
        for name, column in fields.items():
            payload[name] = column
        blob, size = payload.tobytes(), payload.dtype.itemsize
        return [truncate(blob[k : k + size]) for k in range(0, len(blob), size)]

    @cached_property
    def attitude_payloads(self) -> list[bytes]:
        """ATTITUDE payload per vehicle: roll, pitch, yaw NED (rad), body rates FRD (rad/s)."""
        ned = self.ned
        return self._fleet_payloads(
            mavlink2.MAVLink_attitude_message,
            roll=ned[:, 4], pitch=ned[:, 5], yaw=ned[:, 6],
            rollspeed=ned[:, 7], pitchspeed=ned[:, 8], yawspeed=ned[:, 9],
        )  # fmt: skip

    @cached_property
    def attitude_quaternion_payloads(self) -> list[bytes]:
        """ATTITUDE_QUATERNION payload per vehicle: q FRD->NED (w, x, y, z), body rates FRD (rad/s),
        repr_offset_q zero."""
        ned = self.ned
        return self._fleet_payloads(
            mavlink2.MAVLink_attitude_quaternion_message,
            q1=ned[:, 0], q2=ned[:, 1], q3=ned[:, 2], q4=ned[:, 3],
            rollspeed=ned[:, 7], pitchspeed=ned[:, 8], yawspeed=ned[:, 9],
        )  # fmt: skip

    @cached_property
    def local_position_payloads(self) -> list[bytes]:
        """LOCAL_POSITION_NED payload per vehicle: position NED from its EKF origin (m), velocity NED
        (m/s)."""
        ned = self.ned
        return self._fleet_payloads(
            mavlink2.MAVLink_local_position_ned_message,
            x=ned[:, 10], y=ned[:, 11], z=ned[:, 12], vx=ned[:, 13], vy=ned[:, 14], vz=ned[:, 15],
        )  # fmt: skip

    @cached_property
    def global_position_int_payloads(self) -> list[bytes]:
        """GLOBAL_POSITION_INT payload per vehicle: global_position; velocity NED v (m/s) as
        clamp(round(100 v), int16) cm/s; heading hdg = round(100 degrees(yaw NED)) mod 36000 cdeg, in
        [0, 36000). round: half to even, as Python's round."""
        lat, lon, alt, relative_alt = self.global_position.T
        vn, ve, vd = np.rint(self.ned[:, 13:16] * 100.0).clip(-32768, 32767).T
        hdg = np.rint(np.degrees(self.ned[:, 6]) * 100.0).astype(np.int64) % 36000
        return self._fleet_payloads(
            mavlink2.MAVLink_global_position_int_message,
            lat=lat, lon=lon, alt=alt, relative_alt=relative_alt, vx=vn, vy=ve, vz=vd, hdg=hdg,
        )  # fmt: skip

    def encode(self, framer: Framer, msg_id: int, i: int) -> bytes | None:
        """The framed message msg_id of vehicle i now, or None when the vehicle has nothing to say yet."""
        return _ENCODERS[msg_id](self, framer, i)


def _heartbeat(v: TelemetryView, f: Framer, i: int) -> bytes:
    autopilot, base_mode, custom_mode, system_status = v.ap.persona(i).heartbeat(i)
    return f.pack(
        f.mav.heartbeat_encode(
            mavlink2.MAV_TYPE_QUADROTOR, autopilot, base_mode, custom_mode, system_status, 3
        )
    )


def _sys_status(v: TelemetryView, f: Framer, i: int) -> bytes:
    present, enabled, health = v.ap.sensor_bits(i)
    return f.pack(f.mav.sys_status_encode(present, enabled, health, 120, 12600, 100, 100, 0, 0, 0, 0, 0, 0))


def _ekf_status(v: TelemetryView, f: Framer, i: int) -> bytes | None:
    if not v.ap.persona(i).reports_ekf_status:
        return None  # an ardupilotmega message, which not every persona sends
    return f.pack(f.mav.ekf_status_report_encode(v.ap.ekf_flags(i), 0.02, 0.02, 0.02, 0.02, 0.0, 0.0))


def _attitude(v: TelemetryView, f: Framer, i: int) -> bytes:
    return f.frame_payload(mavlink2.MAVLink_attitude_message, v.attitude_payloads[i])


def _attitude_quaternion(v: TelemetryView, f: Framer, i: int) -> bytes:
    return f.frame_payload(mavlink2.MAVLink_attitude_quaternion_message, v.attitude_quaternion_payloads[i])


def _local_position(v: TelemetryView, f: Framer, i: int) -> bytes | None:
    if not v.ap.position_ok(i):
        return None  # ArduPilot sends it only once the EKF has an origin
    return f.frame_payload(mavlink2.MAVLink_local_position_ned_message, v.local_position_payloads[i])


def _global_position(v: TelemetryView, f: Framer, i: int) -> bytes | None:
    if not v.ap.position_ok(i):
        return None
    return f.frame_payload(mavlink2.MAVLink_global_position_int_message, v.global_position_int_payloads[i])


def _gps_raw(v: TelemetryView, f: Framer, i: int) -> bytes:
    if not v.ap.gps_fix(i):
        return f.pack(
            f.mav.gps_raw_int_encode(v.time_us, mavlink2.GPS_FIX_TYPE_NO_FIX, 0, 0, 0, 9999, 9999, 0, 0, 0)
        )
    lat, lon, alt, _ = v.global_position[i].tolist()
    vn, ve = v.ned[i, 13:15].tolist()
    speed = math.hypot(vn, ve)
    cog = round(math.degrees(math.atan2(ve, vn)) * 100.0) % 36000 if speed > 0.2 else 0
    return f.pack(f.mav.gps_raw_int_encode(
        v.time_us, mavlink2.GPS_FIX_TYPE_3D_FIX, lat, lon, alt, 121, 200, round(speed * 100.0), cog,
        10, alt, 300, 500, 200, 0, 0,
    ))  # fmt: skip


def _extended_sys_state(v: TelemetryView, f: Framer, i: int) -> bytes:
    return f.pack(f.mav.extended_sys_state_encode(mavlink2.MAV_VTOL_STATE_UNDEFINED, v.ap.landed_state(i)))


def _system_time(v: TelemetryView, f: Framer, i: int) -> bytes:
    unix_us = v.unix_epoch_us + v.time_us if v.ap.position_ok(i) else 0  # GPS time once there is a fix
    return f.frame(mavlink2.MAVLink_system_time_message, unix_us, v.time_boot_ms)


def _home_position(v: TelemetryView, f: Framer, i: int) -> bytes | None:
    if not v.ap.position_ok(i):
        return None
    home = v.ap.home[i : i + 1]
    lat, lon, alt = v.geodesy.to_geodetic(home)[0]
    east, north, up = (home[0] - v.ap.origin[i]).tolist()  # to NED (spec 1.1): (north, east, -up)
    return f.pack(f.mav.home_position_encode(
        round(lat * 1e7), round(lon * 1e7), round(alt * 1000.0), north, east, -up, [1.0, 0.0, 0.0, 0.0],
        0.0, 0.0, 0.0, v.time_us,
    ))  # fmt: skip


def _gps_global_origin(v: TelemetryView, f: Framer, i: int) -> bytes | None:
    if not v.ap.position_ok(i):
        return None
    lat, lon, alt = v.geodesy.to_geodetic(v.ap.origin[i : i + 1])[0]
    return f.pack(
        f.mav.gps_global_origin_encode(round(lat * 1e7), round(lon * 1e7), round(alt * 1000.0), v.time_us)
    )


def _fence_status(v: TelemetryView, f: Framer, i: int) -> bytes | None:
    """GCS_MAVLINK::send_fence_status (GCS_Fence.cpp): only while a fence is enabled; mitigation NONE (Copter
    has AC_Avoid, whose velocity limits are not simulated)."""
    fence = v.ap.fence
    if not fence.enabled_mask[i]:
        return None
    return f.pack(f.mav.fence_status_encode(
        int(fence.breaches[i] != 0), int(fence.breach_count[i]) & 0xFFFF, fence.mavlink_breach_type(i),
        int(fence.breach_time_ms[i]) & 0xFFFFFFFF, mavlink2.FENCE_MITIGATE_NONE,
    ))  # fmt: skip


_ENCODERS = {
    mavlink2.MAVLINK_MSG_ID_HEARTBEAT: _heartbeat,
    mavlink2.MAVLINK_MSG_ID_SYS_STATUS: _sys_status,
    mavlink2.MAVLINK_MSG_ID_EKF_STATUS_REPORT: _ekf_status,
    mavlink2.MAVLINK_MSG_ID_ATTITUDE: _attitude,
    mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: _attitude_quaternion,
    mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED: _local_position,
    mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: _global_position,
    mavlink2.MAVLINK_MSG_ID_GPS_RAW_INT: _gps_raw,
    mavlink2.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: _extended_sys_state,
    mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME: _system_time,
    mavlink2.MAVLINK_MSG_ID_HOME_POSITION: _home_position,
    mavlink2.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: _gps_global_origin,
    mavlink2.MAVLINK_MSG_ID_FENCE_STATUS: _fence_status,
}
