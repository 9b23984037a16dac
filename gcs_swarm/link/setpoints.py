"""Guided-mode targets for one vehicle: SET_ATTITUDE_TARGET and SET_POSITION_TARGET_* from mission-frame
(ENU/FLU) values, converted to the wire's NED/FRD once (spec 1.1). Each target echoes the vehicle's latest
time_boot_ms and so answers its lockstep frame (gcs_swarm.link.lockstep).

Holds (position or velocity targets: `send_position_target`, `send_velocity_target`, `hold`) are sent when
they change and otherwise repeated only every HOLD_RESEND_S of the vehicle's time, as a keep-alive: a held
vehicle's target would otherwise go every tick (50 Hz, 63-65 bytes: a SiK radio's whole uplink for three
vehicles). "Unchanged" is judged on the wire: the same type mask, the same position (1e-7 deg, the same
altitude to the cm) or velocity, and a yaw within HOLD_YAW_RAD (the callers pass the measured heading, which
jitters). A frame a repeat is not sent on is answered by the fleet's SYSTEM_TIME (Fleet.answer_frame).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import frames
from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.lockstep import LockstepAnswer
from swarm_common.mavlink_codec import Packer
from swarm_common.rotations import yaw_ned_enu

ATTITUDE_TARGET_IGNORE_RATES = 0b00000111  # SET_ATTITUDE_TARGET.type_mask: use quaternion + thrust only
_SET_ATTITUDE_TARGET = Packer(mavlink2.MAVLink_set_attitude_target_message)

HOLD_RESEND_S = 0.25  # s of vehicle time between repeats of an unchanged hold: 4 Hz, twice the 2 Hz "proof of
# life" PX4 OFFBOARD asks (offboardCheck.cpp: setpoints older than COM_OF_LOSS_T, default 1 s, are lost);
# ArduCopter GUIDED keeps a position target for good and zeroes a velocity target after GUID_TIMEOUT
# (mode_guided.cpp get_timeout_ms, default 3 s): a zero-velocity hold then stays what it was
HOLD_YAW_RAD = 0.02  # rad: hold yaws closer than this are the same target

_IGNORE_ACCEL = (
    mavlink2.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
_IGNORE_POSITION = (
    mavlink2.POSITION_TARGET_TYPEMASK_X_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_Y_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_Z_IGNORE
)
_IGNORE_VELOCITY = (
    mavlink2.POSITION_TARGET_TYPEMASK_VX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VZ_IGNORE
)


def _require_finite(name: str, what: str, values: NDArray[np.float64], yaw: float | None) -> None:
    if (
        values.shape != (3,)
        or not np.all(np.isfinite(values))
        or (yaw is not None and not math.isfinite(yaw))
    ):
        raise ValueError(
            f"{what} for {name} must be 3 finite numbers and a finite yaw: {values.tolist()}, {yaw}"
        )


class Setpoints:
    """Sends targets to the vehicle behind `channel`; its state row (for `hold`) is `lockstep`'s."""

    def __init__(self, channel: Channel, lockstep: LockstepAnswer) -> None:
        self.channel = channel
        self.lockstep = lockstep
        self.name = channel.name
        # the last hold sent: (its wire fields but yaw, its NED yaw rad, vehicle ms); None after other targets
        self._hold: tuple[tuple[object, ...], float, int] | None = None
        self.holds_repeated = 0  # unchanged holds not sent (within HOLD_RESEND_S of the last)

    def _unchanged_hold(self, fields: tuple[object, ...], yaw_ned: float) -> bool:
        """Whether the hold with wire `fields` and yaw_ned is the last one sent, less than HOLD_RESEND_S of
        vehicle time ago (then it is not sent: counted in holds_repeated); else it becomes the last."""
        st, i = self.lockstep.state, self.lockstep.index
        now_ms = int(st.time_ms[i])
        last = self._hold
        if (
            last is not None
            and last[0] == fields
            and abs(math.remainder(yaw_ned - last[1], 2 * math.pi)) < HOLD_YAW_RAD
            and 0 <= now_ms - last[2] < HOLD_RESEND_S * 1000
        ):
            self.holds_repeated += 1
            return True
        self._hold = (fields, yaw_ned, now_ms)
        return False

    def send_attitude_quaternion(self, q_ned_frd: ArrayLike, thrust: float) -> None:
        """SET_ATTITUDE_TARGET with a LOCAL_NED->BODY_FRD quaternion (w,x,y,z), thrust clipped to [0,1]."""
        # Fleet.send_attitude_targets passes lists of floats: no numpy round trip for them
        q = q_ned_frd if type(q_ned_frd) is list else np.asarray(q_ned_frd, dtype=float).tolist()
        thrust = min(max(float(thrust), 0.0), 1.0)
        self._hold = None
        ch = self.channel
        ch.send_packed(  # wire order: time_boot_ms, q, body rates, thrust, target, type_mask
            _SET_ATTITUDE_TARGET,
            self.lockstep.answer_time_ms(),
            *q,
            0.0,
            0.0,
            0.0,
            thrust,
            ch.target_sysid,
            ch.compid,
            ATTITUDE_TARGET_IGNORE_RATES,
        )

    def send_velocity_target(self, vel_enu: ArrayLike, yaw: float | None = None) -> None:
        """SET_POSITION_TARGET_LOCAL_NED velocity (ENU m/s) and optional ENU yaw (rad); GUIDED mode."""
        v = np.asarray(vel_enu, dtype=float)
        _require_finite(self.name, "velocity target", v, yaw)
        vn = frames.enu_to_ned(v) + 0.0  # + 0.0: no -0.0 on the wire
        mask, yaw_ned = _with_yaw(_IGNORE_POSITION | _IGNORE_ACCEL, yaw)
        if self._unchanged_hold(("velocity", mask, *vn.tolist()), yaw_ned):
            return
        ch = self.channel
        ch.send(
            ch.mav.set_position_target_local_ned_encode(
                self.lockstep.answer_time_ms(),
                ch.target_sysid,
                ch.compid,
                mavlink2.MAV_FRAME_LOCAL_NED,
                mask,
                0.0,
                0.0,
                0.0,
                float(vn[0]),
                float(vn[1]),
                float(vn[2]),
                0.0,
                0.0,
                0.0,
                yaw_ned,
                0.0,
            )
        )

    def send_position_target(
        self, pos_enu: ArrayLike, yaw: float | None = None, stream: bool = False
    ) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT at a mission-frame ENU position (m); GUIDED mode. A hold (module
        doc: an unchanged one is only repeated as a keep-alive), unless `stream`: a stream whose rate the
        caller keeps (PX4's proof of life before OFFBOARD, VehicleLink.op_take_control), sent every call.

        Global coordinates, because each vehicle's LOCAL_NED frame has its own (EKF) origin.
        """
        p = np.asarray(pos_enu, dtype=float)
        _require_finite(self.name, "position target", p, yaw)
        mask, yaw_ned = _with_yaw(_IGNORE_VELOCITY | _IGNORE_ACCEL, yaw)
        self._send_global_target(p, np.zeros(3), np.zeros(3), mask, yaw_ned, hold=not stream)

    def send_trajectory_target(
        self, pos_enu: ArrayLike, vel_enu: ArrayLike, acc_enu: ArrayLike, yaw: float
    ) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT with a mission-frame ENU position (m), velocity (m/s), acceleration
        (m/s^2) and ENU yaw (rad): a point of a trajectory, which ArduCopter GUIDED flies with its
        pos-vel-accel controller (propagating the position with the velocity and acceleration until the next
        target) and PX4 OFFBOARD as a position setpoint with velocity feed-forward (docs/command-modes.md).
        Global coordinates, as send_position_target."""
        p, v, a = (np.asarray(x, dtype=float) for x in (pos_enu, vel_enu, acc_enu))
        for what, values in (("position", p), ("velocity", v), ("acceleration", a)):
            _require_finite(self.name, f"trajectory target {what}", values, yaw)
        mask = mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
        self._send_global_target(p, v, a, mask, float(yaw_ned_enu(yaw)))

    def _send_global_target(
        self, p: np.ndarray, v: np.ndarray, a: np.ndarray, mask: int, yaw_ned: float, hold: bool = False
    ) -> None:
        """One SET_POSITION_TARGET_GLOBAL_INT: ENU position p (3,) m about the mission origin, velocity v (3,)
        m/s and acceleration a (3,) m/s^2 turned to the wire's lat/lon/alt and NED here, `mask` its type mask,
        yaw_ned rad; a `hold` unchanged since the last one is only repeated as the module doc says."""
        lat, lon, alt = frames.enu_to_geodetic(p, self.lockstep.state.origin)
        lat_e7, lon_e7 = int(round(float(lat) * 1e7)), int(round(float(lon) * 1e7))
        if not hold:
            self._hold = None
        elif self._unchanged_hold(("position", mask, lat_e7, lon_e7, round(float(alt), 2)), yaw_ned):
            return
        vn, an = frames.enu_to_ned(v) + 0.0, frames.enu_to_ned(a) + 0.0  # + 0.0: no -0.0 on the wire
        ch = self.channel
        ch.send(
            ch.mav.set_position_target_global_int_encode(
                self.lockstep.answer_time_ms(),
                ch.target_sysid,
                ch.compid,
                mavlink2.MAV_FRAME_GLOBAL_INT,
                mask,
                lat_e7,
                lon_e7,
                float(alt),
                float(vn[0]),
                float(vn[1]),
                float(vn[2]),
                float(an[0]),
                float(an[1]),
                float(an[2]),
                yaw_ned,
                0.0,
            )
        )

    def hold(self) -> None:
        """Hold the current position and heading with a position target (vehicle must be in GUIDED)."""
        st, i = self.lockstep.state, self.lockstep.index
        if st.position_count[i] == 0:
            raise LinkError(f"{self.name} cannot hold position: no position received yet")
        self.send_position_target(st.pos[i], yaw=float(st.att[i, 2]) if np.isfinite(st.att[i, 2]) else None)


def _with_yaw(mask: int, yaw: float | None) -> tuple[int, float]:
    """A position-target type mask and its yaw field: ENU yaw (rad, counter-clockwise from East) as NED yaw
    (clockwise from North) in [-pi, pi), or the yaw ignored (0.0 sent) when None."""
    if yaw is None:
        return mask | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE, 0.0
    return mask, float(yaw_ned_enu(yaw))
