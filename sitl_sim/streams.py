"""Telemetry: which message is due when (per vehicle), and how each is built from the simulated state.

Streams are scheduled at multiples of their interval from boot, checked at every autopilot tick, so a 50 Hz
stream lands on every 20 ms frame end. Intervals shorter than the tick are raised to the tick (the fastest the
autopilot state changes). This module is also the MAVLink frame boundary for telemetry: physics is ENU/FLU,
everything built here is NED/FRD (spec 1.1).
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import pymap3d
from pymavlink.dialects.v20 import ardupilotmega as mavlink

if TYPE_CHECKING:
    from sitl_sim.autopilot import Autopilot

M = mavlink
# Default rates (Hz) like ArduCopter's SRx defaults; 0 = only on request / on change.
DEFAULT_RATES_HZ: dict[int, float] = {
    M.MAVLINK_MSG_ID_HEARTBEAT: 1.0,
    M.MAVLINK_MSG_ID_SYS_STATUS: 2.0,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: 2.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 10.0,
    M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 0.0,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 4.0,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 4.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 2.0,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 2.0,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: 1.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 0.0,
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: 0.0,
}
STREAM_IDS = tuple(DEFAULT_RATES_HZ)
# Legacy REQUEST_DATA_STREAM groups (MAVProxy uses them) -> the messages of ours they contain.
DATA_STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    M.MAV_DATA_STREAM_EXTENDED_STATUS: (
        M.MAVLINK_MSG_ID_SYS_STATUS,
        M.MAVLINK_MSG_ID_GPS_RAW_INT,
        M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    M.MAV_DATA_STREAM_POSITION: (M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, M.MAVLINK_MSG_ID_LOCAL_POSITION_NED),
    M.MAV_DATA_STREAM_EXTRA1: (M.MAVLINK_MSG_ID_ATTITUDE,),
    M.MAV_DATA_STREAM_EXTRA3: (M.MAVLINK_MSG_ID_EKF_STATUS_REPORT, M.MAVLINK_MSG_ID_SYSTEM_TIME),
}
DATA_STREAM_GROUPS[M.MAV_DATA_STREAM_ALL] = tuple(m for group in DATA_STREAM_GROUPS.values() for m in group)

SQRT_HALF = math.sqrt(0.5)


def swap_quat_enu_ned(q: np.ndarray) -> np.ndarray:
    """Body FLU->ENU quaternions (..., 4) [w,x,y,z] <-> body FRD->NED ones (the map is its own inverse).

    q_ned = q(ENU->NED) * q * q(FRD->FLU), both fixed rotations being half turns (about (1,1,0)/sqrt 2 and x).
    """
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return SQRT_HALF * np.stack((w + z, x + y, x - y, w - z), axis=-1)


def euler_zyx(q: np.ndarray) -> np.ndarray:
    """(N,4) quaternions -> (N,3) roll, pitch, yaw (ZYX, rad) in the quaternion's own frames."""
    w, x, y, z = q.T
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return np.stack((roll, pitch, yaw), axis=1)


def enu_to_ned(v: np.ndarray) -> np.ndarray:
    """(..., 3) ENU vectors -> NED (spec 1.1: p_NED = (p_y, p_x, -p_z))."""
    v = np.asarray(v, dtype=float)
    return np.stack((v[..., 1], v[..., 0], -v[..., 2]), axis=-1)


class Geodesy:
    """Local ENU metres (mission frame) <-> WGS84 around home = the ENU origin (lat, lon deg, alt m AMSL)."""

    def __init__(self, home: tuple[float, float, float]) -> None:
        self.lat0, self.lon0, self.alt0 = home

    def to_geodetic(self, enu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N,3) ENU -> lat, lon (deg), alt (m AMSL), each (N,)."""
        lat, lon, alt = pymap3d.enu2geodetic(enu[:, 0], enu[:, 1], enu[:, 2], self.lat0, self.lon0, self.alt0)
        return np.asarray(lat), np.asarray(lon), np.asarray(alt)

    def to_enu(self, lat: float, lon: float, alt: float) -> np.ndarray:
        """One WGS84 point (deg, deg, m AMSL) -> (3,) ENU m."""
        e, n, u = pymap3d.geodetic2enu(lat, lon, alt, self.lat0, self.lon0, self.alt0)
        return np.array([float(e), float(n), float(u)])


class StreamSchedule:
    """Per-vehicle stream intervals (N, M) us (0 = off) and next due times, M = len(STREAM_IDS)."""

    def __init__(self, n: int, tick_us: int) -> None:
        self.tick_us = tick_us
        self.column = {msg_id: j for j, msg_id in enumerate(STREAM_IDS)}
        default = np.array([self.default_interval(m) for m in STREAM_IDS], dtype=np.int64)
        self.interval_us = np.tile(default, (n, 1))
        self.next_due_us = np.zeros((n, len(STREAM_IDS)), dtype=np.int64)

    def default_interval(self, msg_id: int) -> int:
        """Default interval of a stream in us (0 = off)."""
        rate = DEFAULT_RATES_HZ[msg_id]
        return 0 if rate <= 0 else max(self.tick_us, round(1e6 / rate))

    def set_interval(self, i: int, msg_id: int, interval_us: float, now_us: int) -> bool:
        """SET_MESSAGE_INTERVAL semantics: us > 0 period, 0 default, -1 off. False if msg_id is not a stream."""
        j = self.column.get(msg_id)
        if j is None:
            return False
        if interval_us < 0:
            value = 0
        elif interval_us == 0:
            value = self.default_interval(msg_id)
        else:
            value = max(self.tick_us, round(interval_us))
        self.interval_us[i, j] = value
        if value:
            self.next_due_us[i, j] = -(-now_us // value) * value  # next multiple of the interval from boot
        return True

    def interval(self, i: int, msg_id: int) -> int | None:
        """Current interval (us, -1 = off) or None when msg_id is not a stream."""
        j = self.column.get(msg_id)
        if j is None:
            return None
        value = int(self.interval_us[i, j])
        return value if value else -1

    def due(self, now_us: int) -> list[tuple[int, int]]:
        """(vehicle, msg_id) pairs due at now_us, in vehicle then STREAM_IDS order; schedules the next ones."""
        on = self.interval_us > 0
        mask = on & (self.next_due_us <= now_us)
        if not mask.any():
            return []
        rows, cols = np.nonzero(mask)
        interval = self.interval_us[rows, cols]
        self.next_due_us[rows, cols] = (now_us // interval + 1) * interval
        return [(int(r), STREAM_IDS[c]) for r, c in zip(rows, cols, strict=True)]


class TelemetryView:
    """The fleet as MAVLink sees it at one instant; arrays computed on first use, as Python lists."""

    def __init__(self, autopilot: Autopilot, time_us: int, geodesy: Geodesy, unix_epoch_us: int) -> None:
        self.ap = autopilot
        self.time_us = time_us
        self.time_boot_ms = time_us // 1000
        self.geodesy = geodesy
        self.unix_epoch_us = unix_epoch_us

    @cached_property
    def attitude(self) -> tuple[list, list, list]:
        """(quat NED/FRD (N,4), euler NED (N,3), body rates FRD (N,3)) as lists."""
        state = self.ap.state
        q_ned = swap_quat_enu_ned(state.quat)
        rates = state.omega * np.array([1.0, -1.0, -1.0])
        return q_ned.tolist(), euler_zyx(q_ned).tolist(), rates.tolist()

    @cached_property
    def local(self) -> tuple[list, list]:
        """(position NED from each vehicle's EKF origin, velocity NED) as (N,3) lists."""
        state = self.ap.state
        return enu_to_ned(state.pos - self.ap.origin).tolist(), enu_to_ned(state.vel).tolist()

    @cached_property
    def global_position(self) -> tuple[list, list, list, list]:
        """(lat 1e7, lon 1e7, alt mm AMSL, alt mm above home) as (N,) integer lists."""
        lat, lon, alt = self.geodesy.to_geodetic(self.ap.state.pos)
        rel = (self.ap.state.pos[:, 2] - self.ap.home[:, 2]) * 1000.0
        return (
            np.round(lat * 1e7).astype(np.int64).tolist(),
            np.round(lon * 1e7).astype(np.int64).tolist(),
            np.round(alt * 1000.0).astype(np.int64).tolist(),
            np.round(rel).astype(np.int64).tolist(),
        )

    def encode(self, mav: mavlink.MAVLink, msg_id: int, i: int) -> mavlink.MAVLink_message | None:
        """The message msg_id of vehicle i now, or None when the vehicle has nothing to say yet."""
        return _ENCODERS[msg_id](self, mav, i)


def _heartbeat(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    ap = v.ap
    return mav.heartbeat_encode(
        M.MAV_TYPE_QUADROTOR,
        M.MAV_AUTOPILOT_ARDUPILOTMEGA,
        ap.base_mode(i),
        int(ap.mode[i]),
        ap.system_status(i),
        3,
    )


def _sys_status(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    present, enabled, health = v.ap.sensor_bits(i)
    return mav.sys_status_encode(present, enabled, health, 120, 12600, 100, 100, 0, 0, 0, 0, 0, 0)


def _ekf_status(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    return mav.ekf_status_report_encode(v.ap.ekf_flags(i), 0.02, 0.02, 0.02, 0.02, 0.0, 0.0)


def _attitude(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    _, euler, rates = v.attitude
    return mav.attitude_encode(v.time_boot_ms, *euler[i], *rates[i])


def _attitude_quaternion(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    quat, _, rates = v.attitude
    return mav.attitude_quaternion_encode(v.time_boot_ms, *quat[i], *rates[i])


def _local_position(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message | None:
    if not v.ap.position_ok(i):
        return None  # ArduPilot sends it only once the EKF has an origin
    pos, vel = v.local
    return mav.local_position_ned_encode(v.time_boot_ms, *pos[i], *vel[i])


def _global_position(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message | None:
    if not v.ap.position_ok(i):
        return None
    lat, lon, alt, rel = v.global_position
    _, vel = v.local
    _, euler, _ = v.attitude
    hdg = round(math.degrees(euler[i][2]) * 100.0) % 36000
    vn, ve, vd = (max(-32768, min(32767, round(c * 100.0))) for c in vel[i])
    return mav.global_position_int_encode(v.time_boot_ms, lat[i], lon[i], alt[i], rel[i], vn, ve, vd, hdg)


def _gps_raw(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    if not v.ap.position_ok(i):
        return mav.gps_raw_int_encode(v.time_us, M.GPS_FIX_TYPE_NO_FIX, 0, 0, 0, 9999, 9999, 0, 0, 0)
    lat, lon, alt, _ = v.global_position
    _, vel = v.local
    speed = math.hypot(vel[i][0], vel[i][1])
    cog = round(math.degrees(math.atan2(vel[i][1], vel[i][0])) * 100.0) % 36000 if speed > 0.2 else 0
    return mav.gps_raw_int_encode(
        v.time_us, M.GPS_FIX_TYPE_3D_FIX, lat[i], lon[i], alt[i], 121, 200, round(speed * 100.0), cog, 10,
        alt[i], 300, 500, 200, 0, 0,
    )  # fmt: skip


def _extended_sys_state(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    return mav.extended_sys_state_encode(M.MAV_VTOL_STATE_UNDEFINED, v.ap.landed_state(i))


def _system_time(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message:
    unix_us = v.unix_epoch_us + v.time_us if v.ap.position_ok(i) else 0  # GPS time once there is a fix
    return mav.system_time_encode(unix_us, v.time_boot_ms)


def _home_position(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message | None:
    if not v.ap.position_ok(i):
        return None
    home = v.ap.home[i : i + 1]
    lat, lon, alt = v.geodesy.to_geodetic(home)
    x, y, z = enu_to_ned(home[0] - v.ap.origin[i]).tolist()
    return mav.home_position_encode(
        round(lat[0] * 1e7), round(lon[0] * 1e7), round(alt[0] * 1000.0), x, y, z, [1.0, 0.0, 0.0, 0.0],
        0.0, 0.0, 0.0, v.time_us,
    )  # fmt: skip


def _gps_global_origin(v: TelemetryView, mav: mavlink.MAVLink, i: int) -> mavlink.MAVLink_message | None:
    if not v.ap.position_ok(i):
        return None
    lat, lon, alt = v.geodesy.to_geodetic(v.ap.origin[i : i + 1])
    return mav.gps_global_origin_encode(
        round(lat[0] * 1e7), round(lon[0] * 1e7), round(alt[0] * 1000.0), v.time_us
    )


_ENCODERS = {
    M.MAVLINK_MSG_ID_HEARTBEAT: _heartbeat,
    M.MAVLINK_MSG_ID_SYS_STATUS: _sys_status,
    M.MAVLINK_MSG_ID_EKF_STATUS_REPORT: _ekf_status,
    M.MAVLINK_MSG_ID_ATTITUDE: _attitude,
    M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: _attitude_quaternion,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: _local_position,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: _global_position,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: _gps_raw,
    M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: _extended_sys_state,
    M.MAVLINK_MSG_ID_SYSTEM_TIME: _system_time,
    M.MAVLINK_MSG_ID_HOME_POSITION: _home_position,
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN: _gps_global_origin,
}
