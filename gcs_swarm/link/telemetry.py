"""Telemetry into state: one vehicle's packets become its row of the fleet's arrays, here and only here.

Frames are converted once (spec 1.1): GLOBAL_POSITION_INT -> geodetic position (ENU around the mission origin
on demand) and ENU velocity, ATTITUDE / ATTITUDE_QUATERNION -> FLU/ENU Euler angles, HEARTBEAT ->
mode/armed/system status, EKF_STATUS_REPORT + SYS_STATUS -> readiness, EXTENDED_SYS_STATE -> landed state,
STATUSTEXT -> the fleet's event queue. Stamped packets (time_boot_ms) advance the vehicle's clock, reveal late
packets and reboots, and mark the link alive; silence marks it lost.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import frames, intake_kernel
from gcs_swarm.link.autopilots import AutopilotDialect
from gcs_swarm.link.channel import LinkStats
from gcs_swarm.link.connection import MAVLinkMessage
from gcs_swarm.link.intake_kernel import (
    ATTITUDE_KIND,
    HEARTBEAT_DUE,
    INVALID,
    LATE,
    POSITION_STORED,
    REBOOTED,
    REGAINED,
    TIMES_ROWS,
    LawArrays,
)
from swarm_common import rotations

# EKF_STATUS_REPORT.flags: a usable position estimate (as ArduCopter's ekf_position_ok, disarmed case).
EKF_REQUIRED = (
    mavlink2.EKF_ATTITUDE
    | mavlink2.EKF_VELOCITY_HORIZ
    | mavlink2.EKF_VELOCITY_VERT
    | mavlink2.EKF_POS_VERT_ABS
)
EKF_HORIZONTAL = mavlink2.EKF_POS_HORIZ_ABS | mavlink2.EKF_PRED_POS_HORIZ_ABS
EKF_FORBIDDEN = mavlink2.EKF_CONST_POS_MODE | mavlink2.EKF_UNINITIALIZED

_PREARM = mavlink2.MAV_SYS_STATUS_PREARM_CHECK


class Event(NamedTuple):
    """A STATUSTEXT or link event. `time_s` is the vehicle's time since boot (s) when it was received."""

    time_s: float
    vehicle: str
    text: str
    severity: int  # MAV_SEVERITY (0 emergency .. 7 debug)


class TelemetryState:
    """The fleet's telemetry as per-vehicle arrays, row i = vehicle i. Written only by the law of
    link.intake_kernel (through `VehicleTelemetry` or link.intake) and `VehicleTelemetry` (and the lockstep
    bookkeeping: tick_ms, frame_ms).

    Units: geodetic (N,3) lat deg, lon deg, alt m AMSL; vel (N,3) ENU m/s; att (N,3) FLU/ENU roll, pitch,
    yaw rad; time_ms (N,) latest time_boot_ms (-1 = none yet). mode: the autopilot's custom_mode (-1 unknown).
    """

    def __init__(self, n: int, origin: frames.Origin) -> None:
        self.n = n
        self.origin = origin
        self.geodetic = np.full((n, 3), np.nan)
        self.vel = np.full((n, 3), np.nan)
        self.att = np.full((n, 3), np.nan)
        # the int64 rows the law (link.intake_kernel) reads and writes, one (9, N) matrix (TIMES_ROWS): views,
        # never rebound
        self.times = np.zeros((len(TIMES_ROWS), n), dtype=np.int64)
        (
            self.time_ms,  # latest time_boot_ms (-1 = none yet)
            self.position_ms,  # time_boot_ms of the latest GLOBAL_POSITION_INT (-1 = none yet)
            self.tick_ms,  # latest frame consumed by a tick or a lockstep answer (-1 = none yet)
            self.position_count,  # GLOBAL_POSITION_INT messages received
            # GLOBAL_POSITION_INT frames replaced by a newer one before a tick or a lockstep answer used them
            self.frames_missed,
            self.progress_ms,  # the vehicle's time progress since connect, ms (reboots do not count back)
            self.heard_clock_ms,  # the fleet clock (clock_ms) at the vehicle's last packet
            self.gcs_heartbeat_ms,  # its time_boot_ms when the latest GCS HEARTBEAT went (-1 = none yet)
            self.frame_ms,  # latest lockstep clock tick (link.lockstep; -1 = none yet)
        ) = self.times
        self.time_ms[:] = self.position_ms[:] = self.tick_ms[:] = self.gcs_heartbeat_ms[:] = -1
        self.frame_ms[:] = -1
        self.alive = np.zeros(n, dtype=bool)
        self.armed = np.zeros(n, dtype=bool)
        self.mode = np.full(n, -1, dtype=np.int64)
        self.system_status = np.full(n, -1, dtype=np.int64)  # MAV_STATE
        self.landed_state = np.zeros(n, dtype=np.int64)  # MAV_LANDED_STATE (0 = undefined)
        self.ekf_flags = np.full(n, -1, dtype=np.int64)  # EKF_STATUS_REPORT.flags (-1 = none yet)
        # (N,) readiness waits for EKF_STATUS_REPORT (the autopilot's dialect: ArduPilot yes, PX4 no)
        self.ekf_required = np.ones(n, dtype=bool)
        # (N,) SYS_STATUS PREARM_CHECK counts only when also in `enabled` (ArduPilot: checks switched on); PX4
        # sets it in `health` alone (dialect's prearm_bit_in_enabled)
        self.prearm_gated = np.ones(n, dtype=bool)
        self.prearm = np.full(n, -1, dtype=np.int8)  # SYS_STATUS pre-arm check: -1 unknown, 0 failing, 1 ok
        self.gps_fix = np.full(n, -1, dtype=np.int64)  # GPS_RAW_INT.fix_type (-1 = none received)
        self.rtt_ms = np.full(n, np.nan)  # round trip of the latest TIMESYNC exchange, wall ms
        # the fleet vehicle clock: ms of the largest time progress of any vehicle since connect, and the
        # time.monotonic() at which it last advanced
        self.clock = np.array([0.0, -math.inf])
        # per vehicle (2, N): time.monotonic() at which progress_ms last advanced, and of its last packet
        self.walls = np.full((2, n), -math.inf)
        self.progress_wall, self.last_rx_wall = self.walls
        # (N, 3) the time_boot_ms of its newest packet of each kind (columns POSITION_KIND, ATTITUDE_KIND,
        # CLOCK_KIND; -1: none yet)
        self.latest_ms = np.full((n, 3), -1, dtype=np.int64)
        self.law = LawArrays(
            self.times, self.latest_ms, self.walls, self.clock, self.alive, self.geodetic, self.vel, self.att
        )  # what the law of link.intake_kernel reads and writes
        self._pos = np.full((n, 3), np.nan)
        self.pos_stale = False  # set by GLOBAL_POSITION_INT: `pos` recomputes lazily

    @property
    def clock_ms(self) -> int:
        """The fleet vehicle clock: the largest time progress of any vehicle since connect, ms."""
        return int(self.clock[0])

    def vehicle_clock(self) -> tuple[int, float]:
        """The fleet vehicle clock for a `Timeout`: (clock_ms, time.monotonic() it last advanced)."""
        return self.clock_ms, float(self.clock[1])

    @property
    def pos(self) -> NDArray[np.float64]:
        """(N,3) ENU metres around the origin (NaN before the first GLOBAL_POSITION_INT)."""
        if self.pos_stale:
            self._pos = frames.geodetic_rows_to_enu(self.geodetic, self.origin)
            self.pos_stale = False
        return self._pos

    @property
    def ekf_ok(self) -> NDArray[np.bool_]:
        f = self.ekf_flags
        return (
            (f >= 0)
            & ((f & EKF_REQUIRED) == EKF_REQUIRED)
            & ((f & EKF_HORIZONTAL) != 0)
            & ((f & EKF_FORBIDDEN) == 0)
        )

    @property
    def ready(self) -> NDArray[np.bool_]:
        """(N,) usable position estimate, pre-arm checks passing, position received, link alive."""
        return (
            self.alive & (self.position_count > 0) & (self.ekf_ok | ~self.ekf_required) & (self.prearm == 1)
        )


class VehicleTelemetry:
    """Decodes one vehicle's telemetry into `state` row `index`; keeps its clock, events and liveness.

    The law of the stamped packets is link.intake_kernel's, here called for the packets pymavlink decodes;
    `follow_up` does what it leaves to Python, for those and for the packets link.intake takes:
    `on_heartbeat_due()` is called when a vehicle-time GCS HEARTBEAT is due and `on_reboot()` when the
    vehicle reboots (its stream rates are gone): the link's GCS heartbeat and stream watchdog.
    """

    def __init__(
        self,
        index: int,
        name: str,
        state: TelemetryState,
        events: deque[Event],
        stats: LinkStats,
        on_heartbeat_due: Callable[[], None],
        on_reboot: Callable[[], None],
    ) -> None:
        self.index = index
        self.name = name
        self.state = state
        self.events = events
        self.stats = stats
        self._on_heartbeat_due = on_heartbeat_due
        self._on_reboot_hook = on_reboot
        self.statustexts = 0  # STATUSTEXT messages received so far
        self.last_statustext = ""
        self.last_prearm = ""  # the latest "PreArm: ..." / "Arm: ..." STATUSTEXT (ArduPilot's own reason)
        self.handlers: dict[str, Callable[[MAVLinkMessage], None]] = {
            "HEARTBEAT": self._on_heartbeat,
            "GLOBAL_POSITION_INT": self._on_global_position_int,
            "ATTITUDE": self._on_attitude,
            "ATTITUDE_QUATERNION": self._on_attitude_quaternion,
            "LOCAL_POSITION_NED": self._on_timed,
            "SYSTEM_TIME": self._on_timed,
            "SYS_STATUS": self._on_sys_status,
            "EKF_STATUS_REPORT": self._on_ekf_status_report,
            "GPS_RAW_INT": self._on_gps_raw_int,
            "EXTENDED_SYS_STATE": self._on_extended_sys_state,
        }
        """Message type -> decoder, for the telemetry messages this class turns into state."""

    @property
    def heard_clock_ms(self) -> int:
        """The fleet clock (`TelemetryState.clock_ms`) at the last packet from this vehicle (0: none yet);
        like that clock, it only moves forward."""
        return int(self.state.heard_clock_ms[self.index])

    @property
    def last_rx_wall(self) -> float:
        """time.monotonic() of the last packet from the autopilot (-inf: none yet)."""
        return float(self.state.last_rx_wall[self.index])

    def vehicle_clock(self) -> tuple[int, float]:
        """This vehicle's clock for a `Timeout`: (ms of its time_boot_ms progress since connect, wall time it
        last advanced)."""
        st, i = self.state, self.index
        return int(st.progress_ms[i]), float(st.progress_wall[i])

    def add_event(self, text: str, severity: int = mavlink2.MAV_SEVERITY_WARNING) -> None:
        """Append an event for this vehicle, stamped with its latest time since boot."""
        self.events.append(
            Event(max(int(self.state.time_ms[self.index]), 0) / 1000.0, self.name, text, severity)
        )

    def heard(self, now: float) -> None:
        """A packet from the autopilot arrived at `now` (time.monotonic()): the link is alive."""
        self.follow_up(intake_kernel.heard(self.index, now, self.state.law))

    def follow_up(self, outcome: int) -> None:
        """What the law's `outcome` (link.intake_kernel bits) leaves to Python: counters, the reboot and
        heartbeat hooks, the "link regained" event, the stale ENU positions."""
        if outcome & INVALID:
            self.stats.invalid += 1
        if outcome & REBOOTED:
            self._on_reboot_hook()
        if outcome & HEARTBEAT_DUE:
            self._on_heartbeat_due()
        if outcome & LATE:
            self.stats.late += 1
        if outcome & POSITION_STORED:
            self.state.pos_stale = True
        if outcome & REGAINED and self.stats.lost:
            self.add_event("link regained", mavlink2.MAV_SEVERITY_NOTICE)

    def on_time(self, t_ms: int, kind: int = -1) -> bool:
        """A packet stamped with the vehicle's time_boot_ms (link.intake_kernel.on_time, then `follow_up`).
        False for a late packet of `kind` (POSITION_KIND, ATTITUDE_KIND, CLOCK_KIND; -1: none), whose data
        must not overwrite newer data."""
        outcome = intake_kernel.on_time(self.index, t_ms, kind, self.state.law, time.monotonic())
        self.follow_up(outcome)
        return not outcome & LATE

    def _on_heartbeat(self, m: MAVLinkMessage) -> None:
        st, i = self.state, self.index
        st.mode[i] = m.custom_mode
        st.armed[i] = bool(m.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
        st.system_status[i] = m.system_status

    def _on_global_position_int(self, m: MAVLinkMessage) -> None:
        law, i = self.state.law, self.index
        fields = (m.time_boot_ms, m.lat, m.lon, m.alt, m.vx, m.vy, m.vz)
        self.follow_up(intake_kernel.position_packet(i, *fields, law, time.monotonic()))

    def _on_attitude(self, m: MAVLinkMessage) -> None:
        law, i = self.state.law, self.index
        fields = (m.time_boot_ms, m.roll, m.pitch, m.yaw)
        self.follow_up(intake_kernel.attitude_packet(i, *fields, law, time.monotonic()))

    def _on_attitude_quaternion(self, m: MAVLinkMessage) -> None:
        q = (m.q1, m.q2, m.q3, m.q4)
        if not all(math.isfinite(c) for c in q) or not 0.5 < math.hypot(*q) < 1.5:
            self.stats.invalid += 1
            return
        if not self.on_time(m.time_boot_ms, ATTITUDE_KIND):
            return
        q_enu = frames.quaternion_ned_to_enu((m.q1, m.q2, m.q3, m.q4))
        self.state.att[self.index] = rotations.quaternion_to_euler(q_enu)

    def _on_timed(self, m: MAVLinkMessage) -> None:
        self.on_time(m.time_boot_ms)

    def _on_sys_status(self, m: MAVLinkMessage) -> None:
        # ArduPilot: PREARM_CHECK enabled when arming checks are on; healthy when armed or checks pass. PX4:
        # healthy when the checks pass, never in present or enabled (seen on PX4 SITL 1.17-dev).
        st, i = self.state, self.index
        checked = not st.prearm_gated[i] or bool(m.onboard_control_sensors_enabled & _PREARM)
        st.prearm[i] = 1 if not checked or m.onboard_control_sensors_health & _PREARM else 0

    def _on_gps_raw_int(self, m: MAVLinkMessage) -> None:
        self.state.gps_fix[self.index] = m.fix_type

    def _on_ekf_status_report(self, m: MAVLinkMessage) -> None:
        self.state.ekf_flags[self.index] = m.flags

    def _on_extended_sys_state(self, m: MAVLinkMessage) -> None:
        self.state.landed_state[self.index] = m.landed_state

    def on_statustext(self, m: MAVLinkMessage) -> str:
        """A STATUSTEXT: remembered (the latest, the latest pre-arm reason), queued as an event; its text."""
        text = m.text.decode(errors="replace") if isinstance(m.text, bytes | bytearray) else str(m.text)
        self.last_statustext = text
        if text.startswith("PreArm:") or text.startswith("Arm:"):
            self.last_prearm = text
        self.statustexts += 1
        self.add_event(text, m.severity)
        return text

    def check_loss(self, now: float, timeout_s: float, wall_timeout_s: float) -> None:
        """Mark the vehicle lost after `timeout_s` of fleet vehicle time or `wall_timeout_s` without a packet.

        Vehicle time catches a silent vehicle while the others' clocks run (a lockstep simulator keeps
        stepping for them); wall time catches everything else (the whole simulator or network gone).
        """
        st, i = self.state, self.index
        if not st.alive[i]:
            return
        silent_vehicle_s = (st.clock_ms - int(st.heard_clock_ms[i])) / 1000.0
        silent_wall_s = now - float(st.last_rx_wall[i])
        if silent_vehicle_s > timeout_s:
            reason = f"no message for {silent_vehicle_s:.1f} s of vehicle time"
        elif silent_wall_s > wall_timeout_s:
            reason = f"no message for {silent_wall_s:.1f} s of wall time"
        else:
            return
        st.alive[i] = False
        self.stats.lost += 1
        self.add_event(f"link lost: {reason}", mavlink2.MAV_SEVERITY_WARNING)

    def not_ready_reason(self, dialect: AutopilotDialect, streams_asked: bool) -> str | None:
        """Why the vehicle is not ready to arm (None when it is), as a clause for an error sentence, in the
        autopilot's words where it gives them (`dialect`); `streams_asked`: its telemetry was asked for."""
        st, i = self.state, self.index
        if not st.alive[i]:
            return "its link is down"
        gps = "" if st.gps_fix[i] < 0 else f"; GPS: {dialect.gps_fix_name(int(st.gps_fix[i]))}"
        said = f'; it says "{self.last_prearm}"' if self.last_prearm else ""
        if st.position_count[i] == 0:
            asked = "asked for" if streams_asked else "not yet asked for"
            return f"no GLOBAL_POSITION_INT received (telemetry {asked}){gps}{said}"
        if st.ekf_required[i] and st.ekf_flags[i] < 0:
            return f"no EKF_STATUS_REPORT received{gps}{said}"
        if st.ekf_required[i] and not st.ekf_ok[i]:
            flags = int(st.ekf_flags[i])
            why = dialect.ekf_missing(flags, EKF_REQUIRED, EKF_HORIZONTAL, EKF_FORBIDDEN)
            return f"no usable position estimate (EKF: {why}; flags 0x{flags:04x}){gps}{said}"
        if st.prearm[i] < 0:
            return f"no SYS_STATUS received{said}"
        if st.prearm[i] == 0:
            return f"pre-arm checks failing{gps}{said or ' (no PreArm message yet)'}"
        return None
