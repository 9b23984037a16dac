"""Handlers of one vehicle's guided setpoints: SET_POSITION_TARGET_LOCAL_NED, SET_POSITION_TARGET_GLOBAL_INT,
SET_ATTITUDE_TARGET. This is the frame boundary for targets: NED/FRD in, ENU/FLU to the autopilot (spec 1.1).

Fields ArduCopter would not accept (NaN/inf/absurd values, unsupported frames) are counted in
`counters.invalid`, targets the autopilot declines in `counters.refused`; no handler raises on input.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot import modes
from sitl_sim.network.counters import LinkCounters
from sitl_sim.network.message_fields import finite, ned_to_enu
from sitl_sim.network.services import SimulatorServices
from sitl_sim.network.streams import swap_quat_enu_ned
from sitl_sim.vehicle_model.attitude_control import yaw_from_quat
from swarm_common.rotations import yaw_ned_enu

MAX_POSITION_M = 1e6  # target position offsets beyond this (m) are absurd
MAX_SPEED = 100.0  # m/s, velocity targets beyond are absurd
MAX_ACCEL = 100.0  # m/s^2
MAX_RATE = 50.0  # rad/s, body/yaw rates beyond are absurd
LOCAL_FRAMES = (
    mavlink2.MAV_FRAME_LOCAL_NED,
    mavlink2.MAV_FRAME_LOCAL_OFFSET_NED,
    mavlink2.MAV_FRAME_BODY_NED,
    mavlink2.MAV_FRAME_BODY_OFFSET_NED,
)
BODY_FRAMES = (mavlink2.MAV_FRAME_BODY_NED, mavlink2.MAV_FRAME_BODY_OFFSET_NED)
AMSL_FRAMES = (mavlink2.MAV_FRAME_GLOBAL, mavlink2.MAV_FRAME_GLOBAL_INT)
ABOVE_HOME_FRAMES = (
    mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,  # flat terrain at home altitude
    mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
)
# SET_POSITION_TARGET_* type_mask groups (ArduCopter: any bit of a group set ignores the whole group)
POS_IGNORE, VEL_IGNORE, ACC_IGNORE = 0b111, 0b111 << 3, 0b111 << 6
YAW_IGNORE, YAW_RATE_IGNORE = 1 << 10, 1 << 11
RATES_IGNORE = 0b111
THROTTLE_IGNORE = mavlink2.ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE
ATTITUDE_IGNORE = mavlink2.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE


class SetpointHandlers:
    """Guided position, velocity, acceleration and attitude targets of vehicle `index`, served by `sim`;
    refusals go to `counters`."""

    def __init__(self, index: int, counters: LinkCounters, sim: SimulatorServices) -> None:
        self.index = index
        self.counters = counters
        self.sim = sim

    def handlers(self) -> dict[int, Callable[[mavlink2.MAVLink_message, tuple[str, int]], None]]:
        """Message id -> handler(msg, sender address)."""
        return {
            mavlink2.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED: self._on_position_target_local,
            mavlink2.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT: self._on_position_target_global,
            mavlink2.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET: self._on_attitude_target,
        }

    def _on_position_target_local(
        self, msg: mavlink2.MAVLink_set_position_target_local_ned_message, addr: tuple[str, int]
    ) -> None:
        if msg.coordinate_frame not in LOCAL_FRAMES:
            self.counters.invalid += 1
            return
        mask = msg.type_mask
        state = self.sim.autopilot.state
        yaw_ned = yaw_ned_enu(float(yaw_from_quat(state.quat[self.index])))
        body = msg.coordinate_frame in BODY_FRAMES

        def to_north_east(v: list[float]) -> list[float]:
            if not body:
                return v
            c, s = math.cos(yaw_ned), math.sin(yaw_ned)
            return [v[0] * c - v[1] * s, v[0] * s + v[1] * c, v[2]]

        pos = vel = acc = None
        if not mask & POS_IGNORE:
            values = [msg.x, msg.y, msg.z]
            if not finite(*values) or max(map(abs, values)) > MAX_POSITION_M:
                self.counters.invalid += 1
                return
            offset = ned_to_enu(to_north_east(values))
            base = (
                self.sim.autopilot.origin[self.index]
                if msg.coordinate_frame == mavlink2.MAV_FRAME_LOCAL_NED
                else None
            )
            pos = offset + (state.pos[self.index] if base is None else base)
        vel, acc, ok = self._velocity_accel(msg, mask, to_north_east)
        if not ok:
            return
        self._apply_position_target(msg, mask, pos, vel, acc, yaw_offset=yaw_ned if body else 0.0)

    def _on_position_target_global(
        self, msg: mavlink2.MAVLink_set_position_target_global_int_message, addr: tuple[str, int]
    ) -> None:
        frame = msg.coordinate_frame
        if frame not in AMSL_FRAMES and frame not in ABOVE_HOME_FRAMES:
            self.counters.invalid += 1
            return
        mask = msg.type_mask
        pos = None
        if not mask & POS_IGNORE:
            lat, lon, alt = msg.lat_int / 1e7, msg.lon_int / 1e7, msg.alt
            if not (finite(alt) and abs(lat) <= 90.0 and abs(lon) <= 180.0 and abs(alt) <= MAX_POSITION_M):
                self.counters.invalid += 1
                return
            geodesy = self.sim.geodesy
            home_amsl = geodesy.alt0 + self.sim.autopilot.home[self.index, 2]
            pos = geodesy.to_enu(lat, lon, alt if frame in AMSL_FRAMES else home_amsl + alt)
        vel, acc, ok = self._velocity_accel(msg, mask, lambda v: v)
        if not ok:
            return
        self._apply_position_target(msg, mask, pos, vel, acc, yaw_offset=0.0)

    def _velocity_accel(self, msg: mavlink2.MAVLink_message, mask: int, rotate) -> tuple:  # noqa: ANN001
        """Velocity and acceleration (ENU) of a position target, or (None, None, False) if absurd."""
        vel = acc = None
        if not mask & VEL_IGNORE:
            values = [msg.vx, msg.vy, msg.vz]
            if not finite(*values) or max(map(abs, values)) > MAX_SPEED:
                self.counters.invalid += 1
                return None, None, False
            vel = ned_to_enu(rotate(values))
        if not mask & ACC_IGNORE:
            values = [msg.afx, msg.afy, msg.afz]
            if not finite(*values) or max(map(abs, values)) > MAX_ACCEL:
                self.counters.invalid += 1
                return None, None, False
            acc = ned_to_enu(rotate(values))
        return vel, acc, True

    def _apply_position_target(self, msg, mask: int, pos, vel, acc, yaw_offset: float) -> None:  # noqa: ANN001
        yaw = yaw_rate = None
        if not mask & YAW_IGNORE:
            if not (finite(msg.yaw) and abs(msg.yaw) <= 4 * math.pi):
                self.counters.invalid += 1
                return
            yaw = yaw_ned_enu(msg.yaw + yaw_offset)  # NED heading -> ENU yaw
        if not mask & YAW_RATE_IGNORE:
            if not (finite(msg.yaw_rate) and abs(msg.yaw_rate) <= MAX_RATE):
                self.counters.invalid += 1
                return
            yaw_rate = -msg.yaw_rate
        if not self.sim.autopilot.set_position_target(self.index, pos, vel, acc, yaw, yaw_rate):
            self.counters.refused += 1

    def _on_attitude_target(
        self, msg: mavlink2.MAVLink_set_attitude_target_message, addr: tuple[str, int]
    ) -> None:
        self.attitude_target(
            msg.type_mask, msg.q, msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate, msg.thrust
        )

    def attitude_target(
        self,
        mask: int,
        q: Sequence[float],
        roll_rate: float,
        pitch_rate: float,
        yaw_rate: float,
        thrust: float,
    ) -> None:
        """SET_ATTITUDE_TARGET's fields as ArduCopter's GCS_MAVLINK_Copter::handle_message_set_attitude_target
        takes them: type_mask, q (4,) [w,x,y,z] body FRD -> NED, body rates FRD rad/s, thrust 0..1; the target
        goes to the autopilot as FLU -> ENU (spec 1.1). Also called by the endpoint with the fields of a lone
        SET_ATTITUDE_TARGET datagram (no message object)."""
        autopilot = self.sim.autopilot
        w, x, y, z = q
        if (
            not all(map(math.isfinite, (w, x, y, z, roll_rate, pitch_rate, yaw_rate, thrust)))
            or max(abs(roll_rate), abs(pitch_rate), abs(yaw_rate)) > MAX_RATE
        ):
            self.counters.invalid += 1
            return
        if autopilot.mode[self.index] not in (modes.GUIDED, modes.GUIDED_NOGPS) or mask & THROTTLE_IGNORE:
            self.counters.refused += 1
            return
        quat = None
        if not mask & ATTITUDE_IGNORE:
            if abs(w * w + x * x + y * y + z * z - 1.0) >= 1e-3:  # ArduPilot Quaternion::is_unit_length
                self.counters.refused += 1
                return
            quat = swap_quat_enu_ned(q)
        rate_bits = mask & RATES_IGNORE
        if rate_bits not in (0, RATES_IGNORE):  # some but not all rates ignored: ill-defined, stop
            self.counters.refused += 1
            autopilot.guided_stop(self.index)
            return
        rates = None if rate_bits else (roll_rate, -pitch_rate, -yaw_rate)
        autopilot.set_attitude_target(self.index, quat, rates, thrust)
