"""One vehicle's MAVLink link: telemetry into the fleet's state arrays, GCS heartbeat, commands, parameters.

Telemetry becomes state here and only here (spec 1.1, frames converted once): GLOBAL_POSITION_INT ->
geodetic position (ENU around the mission origin on demand) and ENU velocity, ATTITUDE /
ATTITUDE_QUATERNION -> FLU/ENU Euler angles, HEARTBEAT -> mode/armed/system status, EKF_STATUS_REPORT +
SYS_STATUS -> readiness, EXTENDED_SYS_STATE -> landed state, STATUSTEXT -> the fleet's event queue.

Blocking exchanges (command + ACK, mode confirmation, parameter echo) are written as `Operation`
generators: they send, then yield while waiting; the fleet pumps every link (and answers lockstep frames)
between steps, so many vehicles can wait at once in one thread and the simulator is never left waiting.

Their timeouts count vehicle time (`Timeout`: the vehicle's time_boot_ms as it advances), so a retry means the
same against hardware in real time and against a lockstep simulator running 20x faster, and a lockstep run
resends at the same frames whatever the machine's speed. Repeats are safe because ArduCopter answers them
idempotently (arm when armed, disarm when disarmed, the current mode: ACCEPTED); the one exception, a repeated
NAV_TAKEOFF refused because the first one (whose ACK was lost) already started the climb, is recognised by
`op_takeoff`.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Generator, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link import frames, signing
from gcs_swarm.link.autopilots import ardupilot
from gcs_swarm.link.connection import Endpoint, LinkError, MAVLinkMessage
from gcs_swarm.link.tlog import TlogWriter
from swarm_common import rotations

T = TypeVar("T")
MessageT = TypeVar("MessageT", bound=str | int)  # a MAVLink message name or id
Operation = Generator[None, None, T]
"""A blocking exchange with one vehicle; yields while it waits, returns its result (see module doc)."""

ARDUCOPTER_MODES: dict[str, int] = {name: number for number, name in mavutil.mode_mapping_acm.items()}
"""ArduCopter flight mode name -> custom_mode number (pymavlink's table)."""

FORCE_ARM_MAGIC = 2989  # MAV_CMD_COMPONENT_ARM_DISARM param2 (ArduPilot): arm skipping the pre-arm checks
FORCE_DISARM_MAGIC = 21196  # ... and disarm even in flight
ATTITUDE_TARGET_IGNORE_RATES = 0b00000111  # SET_ATTITUDE_TARGET.type_mask: use quaternion + thrust only
REBOOT_BACKSTEP_MS = 5000  # a time_boot_ms this much older than the latest means a reboot, not a late packet
STATUSTEXT_GRACE_S = 0.3  # vehicle s: ArduPilot queues the "PreArm: ..." text, so it may follow the ACK
CLOCK_STALL_S = 2.0  # [add] wall s a vehicle clock must stand still before timeouts also end on wall time
COMMAND_RETRIES = 10  # [add] resends after a silent timeout: at 10 % loss each way 11 attempts fail ~1e-8
STREAM_QUIET_S = (
    2.0  # [add] vehicle s without a position from a heard vehicle before its streams are asked again
)
CONFIRM_TIMEOUT_S = 5.0  # [add] vehicle s for a 1 Hz HEARTBEAT to show a new mode / arming state
GCS_HEARTBEAT_MS = 500  # [add] vehicle ms between GCS HEARTBEATs: under 10 % loss a 5 s FS_GCS_TIMEOUT
# then needs ~10 lost in a row, not 5
HEARTBEAT_STAGGER_MS = 7  # [add] offset between consecutive vehicles' heartbeat periods, so that a fleet's
# vehicle-time heartbeats (clocks in step) spread over the frames of a period instead of all leaving in one
TAKEOFF_EVIDENCE_S = 3.0  # [add] vehicle s to wait for signs of a climb after a repeated takeoff is refused
TAKEOFF_CLIMB_M = 0.5  # [add] climb since the first NAV_TAKEOFF that shows the vehicle is taking off

# EKF_STATUS_REPORT.flags: a usable position estimate (as ArduCopter's ekf_position_ok, disarmed case).
_EKF_REQUIRED = (
    mavlink2.EKF_ATTITUDE
    | mavlink2.EKF_VELOCITY_HORIZ
    | mavlink2.EKF_VELOCITY_VERT
    | mavlink2.EKF_POS_VERT_ABS
)
_EKF_HORIZONTAL = mavlink2.EKF_POS_HORIZ_ABS | mavlink2.EKF_PRED_POS_HORIZ_ABS
_EKF_FORBIDDEN = mavlink2.EKF_CONST_POS_MODE | mavlink2.EKF_UNINITIALIZED

_PREARM = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
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


@dataclass(frozen=True)
class VehicleConfig:
    """A vehicle to connect to: its name, connection string and (optionally) the sysid it must report."""

    name: str
    connection: str
    sysid: int | None = None


class Timeout:
    """`seconds` of vehicle time, read from `clock()` -> (ms of vehicle time elapsed since some start, never
    decreasing; monotonic wall s at which it last advanced).

    Vehicle time makes a timeout mean the same in lockstep at any simulator speed and in real time against
    hardware. Backstop for a clock that stands still (no stamped telemetry: link down, nothing streamed): once
    it has not advanced for CLOCK_STALL_S wall seconds, `seconds` of wall time since the start also end it.
    """

    def __init__(self, seconds: float, clock: Callable[[], tuple[int, float]]) -> None:
        self.seconds = seconds
        self._clock = clock
        self.restart()

    def restart(self) -> None:
        """Count from now."""
        self._start_ms = self._clock()[0]
        self._start_wall = time.monotonic()

    def expired(self) -> bool:
        ms, advanced_wall = self._clock()
        if ms - self._start_ms >= self.seconds * 1000.0:
            return True
        now = time.monotonic()
        return now - self._start_wall >= self.seconds and now - advanced_wall >= CLOCK_STALL_S


class Event(NamedTuple):
    """A STATUSTEXT or link event. `time_s` is the vehicle's time since boot (s) when it was received."""

    time_s: float
    vehicle: str
    text: str
    severity: int  # MAV_SEVERITY (0 emergency .. 7 debug)


@dataclass
class LinkCounters:
    """Packets received / sent; garbage (bad); from other systems or components (ignored); losses; unsent."""

    received: int = 0
    sent: int = 0
    bad: int = 0
    ignored: int = 0
    lost: int = 0
    unsent: int = 0
    late: int = 0  # stamped telemetry older than what was already received (delayed or reordered): ignored
    invalid: int = 0  # well-formed packets with non-finite or impossible values (hostile or broken): ignored
    stream_requests: int = 0  # times the stream watchdog asked a quiet vehicle for its telemetry again


def mode_number(mode: str | int) -> int:
    """ArduCopter mode name (case-insensitive) or number -> custom_mode number; ValueError if unknown."""
    if isinstance(mode, int | np.integer):
        if int(mode) in mavutil.mode_mapping_acm:
            return int(mode)
    elif mode.strip().upper() in ARDUCOPTER_MODES:
        return ARDUCOPTER_MODES[mode.strip().upper()]
    raise ValueError(f"unknown ArduCopter mode {mode!r} (known: {', '.join(ARDUCOPTER_MODES)})")


def mode_name(number: int) -> str:
    """custom_mode number -> ArduCopter mode name ("MODE_<n>" when unknown, "UNKNOWN" for -1)."""
    return "UNKNOWN" if number < 0 else mavutil.mode_mapping_acm.get(int(number), f"MODE_{number}")


def message_id(message: str | int) -> int:
    """MAVLink message name (e.g. "ATTITUDE") or id -> id; ValueError if this dialect does not know it."""
    if isinstance(message, int):
        if message in mavlink2.mavlink_map:
            return message
    else:
        msg_id = getattr(mavlink2, f"MAVLINK_MSG_ID_{message.strip().upper()}", None)
        if isinstance(msg_id, int):
            return msg_id
    raise ValueError(f"unknown MAVLink message {message!r}")


def _enum_name(enum: str, value: int, prefix: str) -> str:
    entry = mavlink2.enums[enum].get(value)
    return entry.name.removeprefix(prefix) if entry is not None else f"{prefix}{value}"


def command_name(command: int) -> str:
    """MAV_CMD number -> "MAV_CMD_..." name."""
    return _enum_name("MAV_CMD", command, "")


def result_name(result: int) -> str:
    """MAV_RESULT number -> short name, e.g. "FAILED"."""
    return _enum_name("MAV_RESULT", result, "MAV_RESULT_")


def telemetry_rates(
    control_hz: float, status_hz: float = 2.0, local_position: bool = False
) -> dict[str, float]:
    """Message rates (Hz) the ground station needs: state at the control rate, health at `status_hz`."""
    rates = {
        "ATTITUDE": control_hz,
        "GLOBAL_POSITION_INT": control_hz,
        "SYS_STATUS": status_hz,
        "EKF_STATUS_REPORT": status_hz,
        "EXTENDED_SYS_STATE": status_hz,
        "GPS_RAW_INT": status_hz,
    }
    if local_position:
        rates["LOCAL_POSITION_NED"] = control_hz
    return rates


class FleetState:
    """Per-vehicle state arrays, row i = vehicle i. Written only by `VehicleLink` message handlers.

    Units: geodetic (N,3) lat deg, lon deg, alt m AMSL; vel (N,3) ENU m/s; att (N,3) FLU/ENU roll, pitch,
    yaw rad; time_ms (N,) latest time_boot_ms (-1 = none yet). mode: ArduCopter custom_mode (-1 unknown).
    """

    def __init__(self, n: int, origin: frames.Origin) -> None:
        self.n = n
        self.origin = origin
        self.geodetic = np.full((n, 3), np.nan)
        self.vel = np.full((n, 3), np.nan)
        self.att = np.full((n, 3), np.nan)
        self.time_ms = np.full(n, -1, dtype=np.int64)
        self.alive = np.zeros(n, dtype=bool)
        self.armed = np.zeros(n, dtype=bool)
        self.mode = np.full(n, -1, dtype=np.int64)
        self.system_status = np.full(n, -1, dtype=np.int64)  # MAV_STATE
        self.landed_state = np.zeros(n, dtype=np.int64)  # MAV_LANDED_STATE (0 = undefined)
        self.ekf_flags = np.full(n, -1, dtype=np.int64)  # EKF_STATUS_REPORT.flags (-1 = none yet)
        self.prearm = np.full(n, -1, dtype=np.int8)  # SYS_STATUS pre-arm check: -1 unknown, 0 failing, 1 ok
        self.gps_fix = np.full(n, -1, dtype=np.int64)  # GPS_RAW_INT.fix_type (-1 = none received)
        self.rtt_ms = np.full(n, np.nan)  # round trip of the latest TIMESYNC exchange, wall ms
        self.position_count = np.zeros(n, dtype=np.int64)  # GLOBAL_POSITION_INT messages received
        self.position_ms = np.full(n, -1, dtype=np.int64)  # time_boot_ms of the latest GLOBAL_POSITION_INT
        self.tick_ms = np.full(n, -1, dtype=np.int64)  # latest frame consumed by a tick or a lockstep answer
        self.frame_ms = np.full(n, -1, dtype=np.int64)  # latest lockstep clock tick (see _on_clock_tick)
        self.clock_ms = 0  # fleet vehicle clock: the largest time progress of any vehicle since connect
        self.clock_wall = -math.inf  # time.monotonic() at which clock_ms last advanced
        self._pos = np.full((n, 3), np.nan)
        self.pos_stale = False  # set by GLOBAL_POSITION_INT: `pos` recomputes lazily

    def vehicle_clock(self) -> tuple[int, float]:
        """The fleet vehicle clock for a `Timeout`: (clock_ms, wall time it last advanced)."""
        return self.clock_ms, self.clock_wall

    @property
    def pos(self) -> NDArray[np.float64]:
        """(N,3) ENU metres around the origin (NaN before the first GLOBAL_POSITION_INT)."""
        if self.pos_stale:
            g = self.geodetic
            self._pos = frames.geodetic_to_enu(g[:, 0], g[:, 1], g[:, 2], self.origin)
            self.pos_stale = False
        return self._pos

    @property
    def ekf_ok(self) -> NDArray[np.bool_]:
        f = self.ekf_flags
        return (
            (f >= 0)
            & ((f & _EKF_REQUIRED) == _EKF_REQUIRED)
            & ((f & _EKF_HORIZONTAL) != 0)
            & ((f & _EKF_FORBIDDEN) == 0)
        )

    @property
    def ready(self) -> NDArray[np.bool_]:
        """(N,) usable position estimate, pre-arm checks passing, position received, link alive."""
        return self.alive & (self.position_count > 0) & self.ekf_ok & (self.prearm == 1)


class VehicleLink:
    """The link to one vehicle: decodes its packets into `state` row `index`, sends its commands.

    Created by `Fleet`; blocking methods run through the fleet's loop (`run`) so that every other link
    keeps being served while this one waits.
    """

    def __init__(
        self,
        index: int,
        config: VehicleConfig,
        state: FleetState,
        events: deque[Event],
        run: Callable[[Operation[Any]], Any],
        gcs_sysid: int = 255,
        gcs_compid: int = 190,
        signing_key: bytes | None = None,
    ) -> None:
        self.index = index
        self.config = config
        self.name = config.name
        self.state = state
        self.events = events
        self.endpoint: Endpoint | None = None
        self.tlog: TlogWriter | None = None
        self.sysid: int | None = None  # bound at the first vehicle HEARTBEAT (config.sysid if given)
        self.compid = mavlink2.MAV_COMP_ID_AUTOPILOT1
        self.counters = LinkCounters()
        self.foreign_heartbeats: dict[int, int] = {}  # other vehicles' sysids heard on this connection
        self.params: dict[str, float] = {}
        self.param_types: dict[str, int] = {}
        self.param_count: int | None = None
        self.last_statustext = ""
        self.last_prearm = ""  # the latest "PreArm: ..." / "Arm: ..." STATUSTEXT (ArduPilot's own reason)
        self.answered_ms = -1  # time_boot_ms of the last lockstep answer sent
        self.last_rx_wall = -math.inf  # time.monotonic() of the last packet from the autopilot
        self._run = run
        self._mav = mavlink2.MAVLink(None, gcs_sysid, gcs_compid)
        if signing_key is not None:
            signing.sign_outgoing(self._mav, signing_key)
        self._gcs_sysid = gcs_sysid
        self._statustexts = 0
        self._heartbeats = 0
        self._progress_ms = 0  # this vehicle's time progress since connect (reboots do not count back)
        self._progress_wall = -math.inf  # time.monotonic() at which _progress_ms last advanced
        self._heard_clock_ms = 0  # fleet clock at the last packet from this vehicle
        self._hb_wall = -math.inf
        self._timesync_ns = -1  # ts1 of our latest TIMESYNC request (monotonic ns)
        self._hb_time_ms = -1  # time_boot_ms of the latest GCS HEARTBEAT
        self._hb_phase_ms = index * HEARTBEAT_STAGGER_MS % GCS_HEARTBEAT_MS
        self._acks: dict[int, MAVLinkMessage] = {}
        self._pending_commands: set[int] = set()
        self._param_updates: dict[str, int] = {}
        self._param_listing: dict[int, str] = {}
        self._param_values = 0  # PARAM_VALUE messages received
        self._latest_ms: dict[str, int] = {}  # time_boot_ms of the newest packet of each kind (see _on_time)
        self.stream_rates: dict[str | int, float] = {}  # the telemetry asked for (op_request_streams), Hz
        self.streams_asked_ms = -1  # time_boot_ms of the watchdog's latest request (check_streams), -1: none
        # MISSION_* messages from the vehicle, read by the mission-protocol operations (flight.geofence)
        self.mission_messages: deque[MAVLinkMessage] = deque(maxlen=512)
        self.statustext_hooks: list[Callable[[VehicleLink, str], None]] = []  # called with every STATUSTEXT

    # ------------------------------------------------------------------ receiving

    def handle(self, msg: MAVLinkMessage, now: float) -> None:
        """Decode one packet from this vehicle's connection (`now` = time.monotonic())."""
        self.counters.received += 1
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.counters.bad += 1
            return
        sysid = msg.get_srcSystem()
        if sysid != self.sysid and not self._bind(msg, mtype, sysid):
            self.counters.ignored += 1
            return
        if mtype == "STATUSTEXT":
            self._on_statustext(msg)
        elif msg.get_srcComponent() != self.compid:
            self.counters.ignored += 1
            return
        elif mtype == "SYSTEM_TIME" and msg.time_unix_usec == 0:
            self._on_clock_tick(msg)
            return  # a clock tick is no evidence that the radio link works
        else:
            handler = _HANDLERS.get(mtype)
            if handler is not None:
                handler(self, msg)
        self._heard(now)

    def _bind(self, msg: MAVLinkMessage, mtype: str, sysid: int) -> bool:
        """Accept the first vehicle HEARTBEAT with the expected sysid; remember other vehicles' sysids."""
        if mtype != "HEARTBEAT" or msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
            return False
        if msg.type == mavlink2.MAV_TYPE_GCS:
            return False
        if self.sysid is None and self.config.sysid in (None, sysid):
            self.sysid, self.compid = sysid, msg.get_srcComponent()
            return True
        self.foreign_heartbeats[sysid] = self.foreign_heartbeats.get(sysid, 0) + 1
        if self.sysid is not None and self.foreign_heartbeats[sysid] == 1:
            self.add_event(f"its connection also carries sysid {sysid}; those packets are ignored")
        return False

    def _heard(self, now: float) -> None:
        st, i = self.state, self.index
        self.last_rx_wall = now
        self._heard_clock_ms = st.clock_ms
        if not st.alive[i]:
            st.alive[i] = True
            if self.counters.lost:
                self.add_event("link regained", mavlink2.MAV_SEVERITY_NOTICE)

    def _on_time(self, t_ms: int, kind: str | None = None) -> bool:
        """A packet stamped with the vehicle's time_boot_ms: advance clocks, heartbeat per GCS_HEARTBEAT_MS.

        False for a late packet of `kind` (older than the latest of that kind: delayed or reordered on the
        way), whose data must not overwrite newer data. Lateness is per kind: a
        delayed position report older than the latest attitude is still the newest position. A stamp older
        than the vehicle's newest by more than REBOOT_BACKSTEP_MS is a reboot.
        """
        st, i = self.state, self.index
        prev = int(st.time_ms[i])
        if t_ms > prev or t_ms < prev - REBOOT_BACKSTEP_MS:
            if t_ms > prev and prev >= 0:
                self._progress_ms += t_ms - prev
                self._progress_wall = time.monotonic()
                if self._progress_ms > st.clock_ms:
                    st.clock_ms, st.clock_wall = self._progress_ms, self._progress_wall
            elif t_ms < prev:  # rebooted: frames start again from zero, and its stream rates are gone
                st.tick_ms[i] = -1
                st.frame_ms[i] = -1
                st.position_ms[i] = -1
                self._latest_ms.clear()
                self.streams_asked_ms = -1
            st.time_ms[i] = t_ms
            if self._heartbeat_due(t_ms):
                self.send_heartbeat()  # brief: the simulator times its GCS failsafe in vehicle time
        if kind is None:
            return True
        if t_ms < self._latest_ms.get(kind, -1):
            self.counters.late += 1
            return False
        self._latest_ms[kind] = t_ms
        return True

    def _heartbeat_due(self, t_ms: int) -> bool:
        """A GCS HEARTBEAT is due at time_boot_ms `t_ms`: the first one, then one per GCS_HEARTBEAT_MS period
        of vehicle time (vehicle i's periods start HEARTBEAT_STAGGER_MS * i ms later, modulo the period), and
        one after a reboot."""
        last = self._hb_time_ms
        if last < 0 or t_ms < last:
            return True
        shift = GCS_HEARTBEAT_MS - self._hb_phase_ms
        return (t_ms + shift) // GCS_HEARTBEAT_MS > (last + shift) // GCS_HEARTBEAT_MS

    def _on_clock_tick(self, m: MAVLinkMessage) -> None:
        """SYSTEM_TIME(time_unix_usec=0): a lockstep simulator with link faults marks each frame end with it
        (docs/sitl.md), so a frame is complete even when the vehicle's telemetry was lost or delayed."""
        if self._on_time(m.time_boot_ms, "clock"):
            self.state.frame_ms[self.index] = max(int(self.state.frame_ms[self.index]), m.time_boot_ms)

    def _on_heartbeat(self, m: MAVLinkMessage) -> None:
        st, i = self.state, self.index
        st.mode[i] = m.custom_mode
        st.armed[i] = bool(m.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
        st.system_status[i] = m.system_status
        self._heartbeats += 1

    def _invalid(self) -> None:
        self.counters.invalid += 1

    def _on_global_position_int(self, m: MAVLinkMessage) -> None:
        if abs(m.lat) > 900_000_000 or abs(m.lon) > 1_800_000_000:
            return self._invalid()
        if not self._on_time(m.time_boot_ms, "position"):
            return
        st, i = self.state, self.index
        st.geodetic[i] = (m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3)  # degE7, degE7, mm AMSL
        st.vel[i] = (m.vy * 0.01, m.vx * 0.01, -m.vz * 0.01)  # cm/s NED -> m/s ENU (spec 1.1)
        st.pos_stale = True
        st.position_count[i] += 1
        st.position_ms[i] = m.time_boot_ms

    def _on_attitude(self, m: MAVLinkMessage) -> None:
        if not (math.isfinite(m.roll) and math.isfinite(m.pitch) and math.isfinite(m.yaw)):
            return self._invalid()
        if not self._on_time(m.time_boot_ms, "attitude"):
            return
        yaw = (0.5 * math.pi - m.yaw + math.pi) % (2.0 * math.pi) - math.pi
        self.state.att[self.index] = (m.roll, -m.pitch, yaw)  # FRD/NED -> FLU/ENU (spec 1.1)

    def _on_attitude_quaternion(self, m: MAVLinkMessage) -> None:
        q = (m.q1, m.q2, m.q3, m.q4)
        if not all(math.isfinite(c) for c in q) or not 0.5 < math.hypot(*q) < 1.5:
            return self._invalid()
        if not self._on_time(m.time_boot_ms, "attitude"):
            return
        q_enu = frames.quaternion_ned_to_enu((m.q1, m.q2, m.q3, m.q4))
        self.state.att[self.index] = rotations.quaternion_to_euler(q_enu)

    def _on_timed(self, m: MAVLinkMessage) -> None:
        self._on_time(m.time_boot_ms)

    def _on_sys_status(self, m: MAVLinkMessage) -> None:
        # ArduPilot: PREARM_CHECK enabled when arming checks are on; healthy when armed or checks pass.
        checked = bool(m.onboard_control_sensors_enabled & _PREARM)
        self.state.prearm[self.index] = 1 if not checked or m.onboard_control_sensors_health & _PREARM else 0

    def _on_gps_raw_int(self, m: MAVLinkMessage) -> None:
        self.state.gps_fix[self.index] = m.fix_type

    def _on_ekf_status_report(self, m: MAVLinkMessage) -> None:
        self.state.ekf_flags[self.index] = m.flags

    def _on_extended_sys_state(self, m: MAVLinkMessage) -> None:
        self.state.landed_state[self.index] = m.landed_state

    def _on_command_ack(self, m: MAVLinkMessage) -> None:
        if m.target_system in (0, self._gcs_sysid):
            self._acks[m.command] = m

    def _on_param_value(self, m: MAVLinkMessage) -> None:
        if not math.isfinite(m.param_value):
            return self._invalid()
        name = m.param_id
        self.params[name] = float(m.param_value)
        self.param_types[name] = m.param_type
        self.param_count = m.param_count
        self._param_updates[name] = self._param_updates.get(name, 0) + 1
        if 0 <= m.param_index < m.param_count:
            self._param_listing[m.param_index] = name
        self._param_values += 1

    def _on_statustext(self, m: MAVLinkMessage) -> None:
        text = m.text.decode(errors="replace") if isinstance(m.text, bytes | bytearray) else str(m.text)
        self.last_statustext = text
        if text.startswith("PreArm:") or text.startswith("Arm:"):
            self.last_prearm = text
        self._statustexts += 1
        self.add_event(text, m.severity)
        for hook in self.statustext_hooks:
            hook(self, text)

    def _on_mission(self, m: MAVLinkMessage) -> None:
        if m.target_system in (0, self._gcs_sysid):
            self.mission_messages.append(m)

    @property
    def mav(self) -> mavlink2.MAVLink:
        """This link's encoder (GCS sysid/compid, signing): messages built with it go out with `send`."""
        return self._mav

    @property
    def statustexts(self) -> int:
        """STATUSTEXT messages received so far."""
        return self._statustexts

    def vehicle_clock(self) -> tuple[int, float]:
        """This vehicle's clock for a `Timeout`: (ms of its time_boot_ms progress since connect, wall time it
        last advanced)."""
        return self._progress_ms, self._progress_wall

    def add_event(self, text: str, severity: int = mavlink2.MAV_SEVERITY_WARNING) -> None:
        """Append an event for this vehicle, stamped with its latest time since boot."""
        self.events.append(
            Event(max(int(self.state.time_ms[self.index]), 0) / 1000.0, self.name, text, severity)
        )

    def check_loss(self, now: float, timeout_s: float, wall_timeout_s: float) -> None:
        """Mark the vehicle lost after `timeout_s` of fleet vehicle time or `wall_timeout_s` without a packet.

        Vehicle time catches a silent vehicle while the others' clocks run (a lockstep simulator keeps
        stepping for them); wall time catches everything else (the whole simulator or network gone).
        """
        st, i = self.state, self.index
        if not st.alive[i]:
            return
        silent_vehicle_s = (st.clock_ms - self._heard_clock_ms) / 1000.0
        silent_wall_s = now - self.last_rx_wall
        if silent_vehicle_s > timeout_s:
            reason = f"no message for {silent_vehicle_s:.1f} s of vehicle time"
        elif silent_wall_s > wall_timeout_s:
            reason = f"no message for {silent_wall_s:.1f} s of wall time"
        else:
            return
        st.alive[i] = False
        self.counters.lost += 1
        self.add_event(f"link lost: {reason}", mavlink2.MAV_SEVERITY_WARNING)

    def not_ready_reason(self) -> str | None:
        """Why the vehicle is not ready to arm (None when it is), as a clause for an error sentence."""
        st, i = self.state, self.index
        if not st.alive[i]:
            return "its link is down"
        gps = "" if st.gps_fix[i] < 0 else f"; GPS: {ardupilot.gps_fix_name(int(st.gps_fix[i]))}"
        said = f'; it says "{self.last_prearm}"' if self.last_prearm else ""
        if st.position_count[i] == 0:
            asked = "asked for" if self.stream_rates else "not yet asked for"
            return f"no GLOBAL_POSITION_INT received (telemetry {asked}){gps}{said}"
        if st.ekf_flags[i] < 0:
            return f"no EKF_STATUS_REPORT received{gps}{said}"
        if not st.ekf_ok[i]:
            flags = int(st.ekf_flags[i])
            why = ardupilot.ekf_missing(flags, _EKF_REQUIRED, _EKF_HORIZONTAL, _EKF_FORBIDDEN)
            return f"no usable position estimate (EKF: {why}; flags 0x{flags:04x}){gps}{said}"
        if st.prearm[i] < 0:
            return f"no SYS_STATUS received{said}"
        if st.prearm[i] == 0:
            return f"pre-arm checks failing{gps}{said or ' (no PreArm message yet)'}"
        return None

    # ------------------------------------------------------------------ sending

    def send(self, msg: MAVLinkMessage) -> None:
        """Pack (GCS sysid/compid, this link's sequence) and send one message; it goes to the tlog too."""
        if self.endpoint is None:
            raise LinkError(f"{self.name} is not connected")
        packet = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256
        if self.endpoint.send(packet, self.sysid if self.sysid is not None else self.config.sysid):
            self.counters.sent += 1
            if self.tlog is not None:
                self.tlog.write(packet)
        else:
            self.counters.unsent += 1

    def send_heartbeat(self) -> None:
        """GCS HEARTBEAT (MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID)."""
        self.send(
            self._mav.heartbeat_encode(
                mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, mavlink2.MAV_STATE_ACTIVE
            )
        )
        self._hb_wall = time.monotonic()
        self._hb_time_ms = int(self.state.time_ms[self.index])

    def heartbeat_if_due(self, now: float) -> None:
        """Send the 1 Hz wall-clock heartbeat when due (the vehicle-time one goes out from `_on_time`), with a
        TIMESYNC request whose echo measures the link's round-trip time."""
        if now - self._hb_wall >= 1.0:
            self.send_heartbeat()
            self._timesync_ns = time.monotonic_ns()
            self.send(self._mav.timesync_encode(0, self._timesync_ns))

    def _on_timesync(self, m: MAVLinkMessage) -> None:
        """A vehicle's reply (tc1 != 0) to our request echoes our ts1: round trip = now - ts1."""
        if m.tc1 != 0 and m.ts1 == self._timesync_ns:
            self.state.rtt_ms[self.index] = (time.monotonic_ns() - m.ts1) / 1e6

    @property
    def needs_answer(self) -> bool:
        """A telemetry frame (time_boot_ms) has arrived that no lockstep answer has covered yet."""
        t = int(self.state.time_ms[self.index])
        return t > 0 and t != self.answered_ms

    def _answer_time_ms(self) -> int:
        """time_boot_ms to echo in an outgoing target: the latest frame, now answered (and consumed, so
        the next tick waits for a newer GLOBAL_POSITION_INT)."""
        t = max(int(self.state.time_ms[self.index]), 0)
        if t > 0:
            self.answered_ms = t
            self.state.tick_ms[self.index] = t
        return t

    def answer_frame(self) -> bool:
        """Answer the latest frame with SYSTEM_TIME(time_unix_usec=0, time_boot_ms=frame) if not answered yet.

        A real ArduPilot ignores it (it refuses UNIX times before 2022), so this is always safe to send.
        """
        if not self.needs_answer:
            return False
        self.send(self._mav.system_time_encode(0, self._answer_time_ms()))
        return True

    def send_attitude_target(self, roll: float, pitch: float, yaw: float, thrust: float) -> None:
        """SET_ATTITUDE_TARGET from FLU/ENU angles (rad) and normalised thrust; ValueError if not finite."""
        values = np.array([roll, pitch, yaw, thrust], dtype=float)
        if not np.all(np.isfinite(values)):
            raise ValueError(f"non-finite attitude target for {self.name}: {values.tolist()}")
        self.send_attitude_quaternion(frames.attitude_target_quaternion(values[:3]), float(values[3]))

    def send_attitude_quaternion(self, q_ned_frd: ArrayLike, thrust: float) -> None:
        """SET_ATTITUDE_TARGET with a LOCAL_NED->BODY_FRD quaternion (w,x,y,z), thrust clipped to [0,1]."""
        q = np.asarray(q_ned_frd, dtype=float).tolist()
        thrust = min(max(float(thrust), 0.0), 1.0)
        self.send(
            self._mav.set_attitude_target_encode(
                self._answer_time_ms(),
                self.sysid or 0,
                self.compid,
                ATTITUDE_TARGET_IGNORE_RATES,
                q,
                0.0,
                0.0,
                0.0,
                thrust,
            )
        )

    def send_velocity_target(self, vel_enu: ArrayLike, yaw: float | None = None) -> None:
        """SET_POSITION_TARGET_LOCAL_NED velocity (ENU m/s) and optional ENU yaw (rad); GUIDED mode."""
        v = np.asarray(vel_enu, dtype=float)
        _require_finite(self.name, "velocity target", v, yaw)
        vn = frames.enu_to_ned(v)
        mask = _IGNORE_POSITION | _IGNORE_ACCEL
        yaw_ned = 0.0
        if yaw is None:
            mask |= mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
        else:
            yaw_ned = float(rotations.wrap_pi(0.5 * math.pi - yaw))
        self.send(
            self._mav.set_position_target_local_ned_encode(
                self._answer_time_ms(),
                self.sysid or 0,
                self.compid,
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

    def send_position_target(self, pos_enu: ArrayLike, yaw: float | None = None) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT at a mission-frame ENU position (m); GUIDED mode.

        Global coordinates, because each vehicle's LOCAL_NED frame has its own (EKF) origin.
        """
        p = np.asarray(pos_enu, dtype=float)
        _require_finite(self.name, "position target", p, yaw)
        lat, lon, alt = frames.enu_to_geodetic(p, self.state.origin)
        mask = _IGNORE_VELOCITY | _IGNORE_ACCEL
        yaw_ned = 0.0
        if yaw is None:
            mask |= mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
        else:
            yaw_ned = float(rotations.wrap_pi(0.5 * math.pi - yaw))
        self.send(
            self._mav.set_position_target_global_int_encode(
                self._answer_time_ms(),
                self.sysid or 0,
                self.compid,
                mavlink2.MAV_FRAME_GLOBAL_INT,
                mask,
                int(round(float(lat) * 1e7)),
                int(round(float(lon) * 1e7)),
                float(alt),
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
                yaw_ned,
                0.0,
            )
        )

    def hold(self) -> None:
        """Hold the current position and heading with a position target (vehicle must be in GUIDED)."""
        st, i = self.state, self.index
        if st.position_count[i] == 0:
            raise LinkError(f"{self.name} cannot hold position: no position received yet")
        self.send_position_target(st.pos[i], yaw=float(st.att[i, 2]) if np.isfinite(st.att[i, 2]) else None)

    def request_message(self, message: str | int) -> None:
        """MAV_CMD_REQUEST_MESSAGE, not waiting for the ACK (used to learn the vehicle's time at connect)."""
        self._send_command(mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, [float(message_id(message))] + [0.0] * 6)

    def _send_command(self, command: int, confirmation: int, params: list[float]) -> None:
        self.send(
            self._mav.command_long_encode(
                self.sysid or 0, self.compid, command, min(confirmation, 255), *params
            )
        )

    # ------------------------------------------------------------------ operations (generators)

    def op_command(
        self,
        command: int,
        *params: float,
        retries: int = COMMAND_RETRIES,
        timeout_s: float = 1.0,
        in_progress_timeout_s: float = 10.0,
    ) -> Operation[int]:
        """COMMAND_LONG until COMMAND_ACK: resend with `confirmation` + 1 after each silent `timeout_s`.

        MAV_RESULT_IN_PROGRESS stops the resending and waits up to `in_progress_timeout_s` for the final
        result. Both are seconds of vehicle time (`Timeout`). Returns MAV_RESULT_ACCEPTED; any other result
        raises LinkError with the result's name and the vehicle's last STATUSTEXT (ArduPilot explains refusals
        there).
        """
        texts_before = self._statustexts
        result, _ = yield from self._op_exchange(command, params, retries, timeout_s, in_progress_timeout_s)
        if result != mavlink2.MAV_RESULT_ACCEPTED:
            raise (yield from self._op_refusal(command, result, texts_before))
        return result

    def _op_exchange(
        self,
        command: int,
        params: tuple[float, ...],
        retries: int,
        timeout_s: float,
        in_progress_timeout_s: float,
    ) -> Operation[tuple[int, int]]:
        """The COMMAND_LONG / COMMAND_ACK exchange of `op_command`; returns (final MAV_RESULT, attempts)."""
        if len(params) > 7:
            raise ValueError("COMMAND_LONG has 7 parameters")
        if command in self._pending_commands:
            raise RuntimeError(f"{command_name(command)} is already pending on {self.name}")
        self._require_alive()
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"non-finite parameter in {command_name(command)} for {self.name}: {values}")
        self._acks.pop(command, None)
        self._pending_commands.add(command)
        try:
            attempt, in_progress = 0, False
            self._send_command(command, attempt, values)
            timeout = Timeout(timeout_s, self.vehicle_clock)
            while True:
                yield
                ack = self._acks.pop(command, None)
                if ack is not None and ack.result != mavlink2.MAV_RESULT_IN_PROGRESS:
                    return int(ack.result), attempt + 1
                if ack is not None:
                    in_progress, timeout = True, Timeout(in_progress_timeout_s, self.vehicle_clock)
                elif timeout.expired():
                    if in_progress:
                        raise LinkError(
                            f"{self.name} did not finish {command_name(command)} within "
                            f"{in_progress_timeout_s:g} s of reporting it in progress"
                        )
                    if attempt >= retries:
                        raise LinkError(
                            f"{self.name} did not acknowledge {command_name(command)} "
                            f"({attempt + 1} attempts, {timeout_s:g} s each)"
                        )
                    attempt += 1
                    self._send_command(command, attempt, values)
                    timeout.restart()
        finally:
            self._pending_commands.discard(command)

    def _op_refusal(self, command: int, result: int, texts_before: int) -> Operation[LinkError]:
        """The LinkError for a refused command, once the STATUSTEXT that may explain it had time to arrive."""
        grace = Timeout(STATUSTEXT_GRACE_S, self.vehicle_clock)
        while self._statustexts == texts_before and not grace.expired():
            yield
        reason = f" ({self.last_statustext})" if self._statustexts > texts_before else ""
        return LinkError(f"{self.name} refused {command_name(command)}: {result_name(result)}{reason}")

    def _op_wait(
        self, done: Callable[[], bool], timeout_s: float, failure: Callable[[], str]
    ) -> Operation[None]:
        timeout = Timeout(timeout_s, self.vehicle_clock)
        while not done():
            if timeout.expired():
                raise LinkError(failure())
            yield

    def op_set_mode(self, mode: str | int, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """MAV_CMD_DO_SET_MODE (ArduCopter custom mode); done once a HEARTBEAT shows the new mode, which must
        happen within `timeout_s` of vehicle time after the ACK."""
        try:
            number = mode_number(mode)
        except ValueError as err:
            raise LinkError(f"{self.name}: {err}") from None
        st, i = self.state, self.index
        if st.mode[i] == number:
            return
        yield from self.op_command(
            mavlink2.MAV_CMD_DO_SET_MODE, mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, float(number)
        )
        yield from self._op_wait(
            lambda: bool(st.mode[i] == number),
            timeout_s,
            lambda: (
                f"{self.name} accepted mode {mode_name(number)} but its HEARTBEAT still shows "
                f"{mode_name(int(st.mode[i]))} after {timeout_s:g} s"
            ),
        )

    def _op_arm_disarm(self, arm: bool, force: bool, timeout_s: float) -> Operation[None]:
        st, i = self.state, self.index
        if bool(st.armed[i]) == arm:
            return
        yield from self.op_command(
            mavlink2.MAV_CMD_COMPONENT_ARM_DISARM,
            1.0 if arm else 0.0,
            (FORCE_ARM_MAGIC if arm else FORCE_DISARM_MAGIC) if force else 0.0,
        )
        word = "armed" if arm else "disarmed"
        yield from self._op_wait(
            lambda: bool(st.armed[i]) == arm,
            timeout_s,
            lambda: (
                f"{self.name} accepted the {word[:-2]} command but its HEARTBEAT does not show it {word} "
                f"after {timeout_s:g} s"
            ),
        )

    def op_arm(self, force: bool = False, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """Arm (force skips pre-arm checks); done once a HEARTBEAT shows the vehicle armed (within `timeout_s`
        vehicle seconds of the ACK). A repeat after a lost ACK is harmless: ArduCopter accepts arming an armed
        vehicle (AP_Arming_Copter::arm)."""
        return self._op_arm_disarm(True, force, timeout_s)

    def op_disarm(self, force: bool = False, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """Disarm (force also in flight: the motors stop); done once a HEARTBEAT shows it disarmed."""
        return self._op_arm_disarm(False, force, timeout_s)

    def op_takeoff(
        self, alt_m: float, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> Operation[int]:
        """MAV_CMD_NAV_TAKEOFF to `alt_m` above the vehicle's home (ArduCopter: GUIDED and armed).

        ArduCopter refuses a takeoff once the vehicle has left the ground (Mode::do_user_takeoff, "can't
        takeoff again"). So when the first command's ACK was lost and a repeat is refused, the takeoff counts
        as done (ACCEPTED, with an event) if within TAKEOFF_EVIDENCE_S of vehicle time the vehicle, on the
        ground at the first command, is evidently taking off: armed, in the same mode, and EXTENDED_SYS_STATE
        shows it taking off or in the air, or it has climbed TAKEOFF_CLIMB_M.
        """
        st, i = self.state, self.index
        mode, alt0 = int(st.mode[i]), float(st.geodetic[i, 2])
        on_ground = st.landed_state[i] in (
            mavlink2.MAV_LANDED_STATE_UNDEFINED,
            mavlink2.MAV_LANDED_STATE_ON_GROUND,
        )
        command, texts_before = mavlink2.MAV_CMD_NAV_TAKEOFF, self._statustexts
        result, attempts = yield from self._op_exchange(
            command, (0, 0, 0, 0, 0, 0, float(alt_m)), retries, timeout_s, in_progress_timeout_s=10.0
        )
        if result == mavlink2.MAV_RESULT_ACCEPTED:
            return result

        def taking_off() -> bool:
            if not (on_ground and st.armed[i] and st.mode[i] == mode):
                return False
            lifted = st.landed_state[i] in (
                mavlink2.MAV_LANDED_STATE_TAKEOFF,
                mavlink2.MAV_LANDED_STATE_IN_AIR,
            )
            return bool(lifted or st.geodetic[i, 2] - alt0 >= TAKEOFF_CLIMB_M)

        if attempts > 1:
            evidence = Timeout(TAKEOFF_EVIDENCE_S, self.vehicle_clock)
            while not evidence.expired():
                if taking_off():
                    self.add_event(
                        "a repeated NAV_TAKEOFF was refused while the first one (its ACK lost) is climbing",
                        mavlink2.MAV_SEVERITY_INFO,
                    )
                    return mavlink2.MAV_RESULT_ACCEPTED
                yield
        raise (yield from self._op_refusal(command, result, texts_before))

    def op_set_message_interval(self, message: str | int, hz: float) -> Operation[int]:
        """MAV_CMD_SET_MESSAGE_INTERVAL: `message` every 1/hz s (hz <= 0 stops it)."""
        try:
            msg_id = message_id(message)
        except ValueError as err:
            raise LinkError(f"{self.name}: {err}") from None
        interval_us = 1e6 / hz if hz > 0 else -1.0
        return self.op_command(mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, float(msg_id), interval_us)

    def op_request_streams(self, rates: Mapping[MessageT, float]) -> Operation[None]:
        """Ask for each message at its rate (Hz): SET_MESSAGE_INTERVAL, acknowledged, one after the other; a
        message the vehicle refuses (COMMAND_ACK other than ACCEPTED) is asked for by REQUEST_DATA_STREAM of
        its ArduPilot stream group instead (no ACK exists for that; the stream watchdog, `check_streams`,
        asks again if the telemetry does not come). The rates are remembered for `check_streams`."""
        self.stream_rates = {message: float(hz) for message, hz in rates.items()}
        for message, hz in rates.items():
            try:
                yield from self.op_set_message_interval(message, hz)
            except LinkError as err:
                if "refused" not in str(err):
                    raise
                self.request_data_stream(message, hz)

    def request_data_stream(self, message: str | int, hz: float) -> None:
        """REQUEST_DATA_STREAM of the ArduPilot stream group that carries `message` (if any), at `hz`."""
        name = message if isinstance(message, str) else mavlink2.mavlink_map[int(message)].msgname
        group = ardupilot.STREAM_GROUP.get(str(name))
        if group is None:
            return
        rate = max(1, min(int(round(hz)), 0xFFFF)) if hz > 0 else 0
        self.send(
            self._mav.request_data_stream_encode(self.sysid or 0, self.compid, group, rate, 1 if rate else 0)
        )

    def check_streams(self) -> None:
        """Stream watchdog: a vehicle that is heard (HEARTBEATs) but whose positions stopped for
        STREAM_QUIET_S of its own time (after a reboot ArduPilot forgets every rate; a message interval can
        also be lost) is asked again for every stream, by both SET_MESSAGE_INTERVAL and REQUEST_DATA_STREAM
        without waiting for ACKs, at most once per STREAM_QUIET_S. Called by the fleet on every pump."""
        if not self.stream_rates or self.sysid is None or not self.state.alive[self.index]:
            return
        now_ms = int(self.state.time_ms[self.index])
        last_position = int(self.state.position_ms[self.index])
        quiet = now_ms - max(last_position, self.streams_asked_ms) > STREAM_QUIET_S * 1000
        if now_ms < 0 or not quiet:
            return
        self.streams_asked_ms = now_ms
        self.counters.stream_requests += 1
        for message, hz in self.stream_rates.items():
            try:
                msg_id = message_id(message)
            except ValueError:
                continue
            self._send_command(
                mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, 0, [float(msg_id), 1e6 / hz, 0, 0, 0, 0, 0]
            )
            self.request_data_stream(message, hz)

    def param_name(self, name: str) -> str:
        """The spelling of parameter `name` this vehicle answers to (ArduCopter 4.7 renamed some,
        gcs_swarm.link.autopilots.ardupilot.other_param_name), as learned from its PARAM_VALUEs; `name` until
        known."""
        other = ardupilot.other_param_name(name)
        if name not in self.params and other is not None and other in self.params:
            return other
        return name

    def op_param_get(
        self, name: str, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> Operation[float]:
        """PARAM_REQUEST_READ by name until its PARAM_VALUE arrives, resent after each silent `timeout_s` of
        vehicle time; returns the value. A renamed parameter (SYSID_THISMAV / MAV_SYSID, ...) is read under
        whichever name the vehicle has: one quick try of the given name, then the other spelling."""
        other = ardupilot.other_param_name(name)
        name = self.param_name(name)
        if other is None or name in self.params or other in self.params:
            return (yield from self._op_param_get(name, retries, timeout_s))
        try:
            return (yield from self._op_param_get(name, 0, timeout_s))
        except LinkError:
            pass
        try:
            return (yield from self._op_param_get(other, retries, timeout_s))
        except LinkError:
            return (yield from self._op_param_get(name, retries, timeout_s))

    def _op_param_get(self, name: str, retries: int, timeout_s: float) -> Operation[float]:
        param_id = self._param_id(name)
        self._require_alive()
        timeout = Timeout(timeout_s, self.vehicle_clock)
        for _ in range(retries + 1):
            seen = self._param_updates.get(name, 0)
            self.send(self._mav.param_request_read_encode(self.sysid or 0, self.compid, param_id, -1))
            timeout.restart()
            while not timeout.expired():
                yield
                if self._param_updates.get(name, 0) > seen:
                    return self.params[name]
        raise LinkError(
            f"{self.name} did not report parameter {name} ({retries + 1} requests; does it exist?)"
        )

    def op_param_set(
        self, name: str, value: float, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> Operation[float]:
        """PARAM_SET, verified by the PARAM_VALUE echo (float32 equality); resent up to `retries` times, after
        each silent `timeout_s` of vehicle time (a repeat is harmless: the same value is set again). A
        renamed parameter is read first, so that it is set under the vehicle's own spelling."""
        if ardupilot.other_param_name(name) is not None and self.param_name(name) not in self.params:
            yield from self.op_param_get(name, retries, timeout_s)
        name = self.param_name(name)
        param_id = self._param_id(name)
        if not math.isfinite(value):
            raise LinkError(f"{self.name}: parameter {name} needs a finite value, not {value}")
        self._require_alive()
        wanted = np.float32(value)
        echo: float | None = None
        timeout = Timeout(timeout_s, self.vehicle_clock)
        for _ in range(retries + 1):
            seen = self._param_updates.get(name, 0)
            param_type = self.param_types.get(name, mavlink2.MAV_PARAM_TYPE_REAL32)
            self.send(
                self._mav.param_set_encode(self.sysid or 0, self.compid, param_id, float(value), param_type)
            )
            timeout.restart()
            while not timeout.expired():
                yield
                if self._param_updates.get(name, 0) > seen:
                    echo = self.params[name]
                    if np.float32(echo) == wanted:
                        return echo
                    break
        if echo is None:
            raise LinkError(
                f"{self.name} did not confirm parameter {name} ({retries + 1} attempts; does it exist?)"
            )
        raise LinkError(f"{self.name} did not accept {name} = {value:g}: it reads back {echo:g}")

    def op_params_all(self, timeout_s: float = 60.0, gap_s: float = 0.5) -> Operation[dict[str, float]]:
        """PARAM_REQUEST_LIST; after `gap_s` without a PARAM_VALUE, missing indices are read one by one (both
        seconds of vehicle time)."""
        self._require_alive()
        self._param_listing = {}
        self.send(self._mav.param_request_list_encode(self.sysid or 0, self.compid))
        timeout, gap = Timeout(timeout_s, self.vehicle_clock), Timeout(gap_s, self.vehicle_clock)
        received = self._param_values
        while self.param_count is None or len(self._param_listing) < self.param_count:
            yield
            if timeout.expired():
                raise LinkError(
                    f"{self.name} sent {len(self._param_listing)} of {self.param_count or '?'} parameters "
                    f"in {timeout_s:g} s"
                )
            if self._param_values != received:
                received = self._param_values
                gap.restart()
                continue
            if not gap.expired():
                continue
            gap.restart()
            if self.param_count is None:
                self.send(self._mav.param_request_list_encode(self.sysid or 0, self.compid))
                continue
            missing = [k for k in range(self.param_count) if k not in self._param_listing]
            for index in missing[:32]:
                self.send(self._mav.param_request_read_encode(self.sysid or 0, self.compid, b"", index))
        return {name: self.params[name] for name in self._param_listing.values()}

    def _param_id(self, name: str) -> bytes:
        if not name or len(name) > 16 or not name.isascii():
            raise LinkError(f"{self.name}: parameter name {name!r} must be 1-16 ASCII characters")
        return name.encode()

    def _require_alive(self) -> None:
        if self.endpoint is None or self.sysid is None:
            raise LinkError(f"{self.name} is not connected")
        if not self.state.alive[self.index]:
            raise LinkError(f"{self.name} is not responding (its link is down)")

    # ------------------------------------------------------------------ blocking forms

    def command_long(
        self, command: int, *params: float, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> int:
        """Blocking `op_command`; returns MAV_RESULT_ACCEPTED or raises LinkError."""
        return int(self._run(self.op_command(command, *params, retries=retries, timeout_s=timeout_s)))

    def set_mode(self, mode: str | int, timeout_s: float = CONFIRM_TIMEOUT_S) -> None:
        self._run(self.op_set_mode(mode, timeout_s))

    def arm(self, force: bool = False, timeout_s: float = CONFIRM_TIMEOUT_S) -> None:
        self._run(self.op_arm(force, timeout_s))

    def disarm(self, force: bool = False, timeout_s: float = CONFIRM_TIMEOUT_S) -> None:
        self._run(self.op_disarm(force, timeout_s))

    def takeoff(self, alt_m: float) -> None:
        self._run(self.op_takeoff(alt_m))

    def land(self) -> None:
        self.set_mode("LAND")

    def rtl(self) -> None:
        self.set_mode("RTL")

    def brake(self) -> None:
        self.set_mode("BRAKE")

    def set_message_interval(self, message: str | int, hz: float) -> None:
        self._run(self.op_set_message_interval(message, hz))

    def request_streams(self, rates: Mapping[MessageT, float]) -> None:
        self._run(self.op_request_streams(rates))

    def param_get(self, name: str, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0) -> float:
        return float(self._run(self.op_param_get(name, retries, timeout_s)))

    def param_set(
        self, name: str, value: float, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> float:
        return float(self._run(self.op_param_set(name, value, retries, timeout_s)))

    def params_all(self, timeout_s: float = 60.0) -> dict[str, float]:
        return dict(self._run(self.op_params_all(timeout_s)))


def _require_finite(name: str, what: str, values: NDArray[np.float64], yaw: float | None) -> None:
    if (
        values.shape != (3,)
        or not np.all(np.isfinite(values))
        or (yaw is not None and not math.isfinite(yaw))
    ):
        raise ValueError(
            f"{what} for {name} must be 3 finite numbers and a finite yaw: {values.tolist()}, {yaw}"
        )


_HANDLERS: dict[str, Callable[[VehicleLink, MAVLinkMessage], None]] = {
    "HEARTBEAT": VehicleLink._on_heartbeat,
    "GLOBAL_POSITION_INT": VehicleLink._on_global_position_int,
    "ATTITUDE": VehicleLink._on_attitude,
    "ATTITUDE_QUATERNION": VehicleLink._on_attitude_quaternion,
    "LOCAL_POSITION_NED": VehicleLink._on_timed,
    "SYSTEM_TIME": VehicleLink._on_timed,
    "SYS_STATUS": VehicleLink._on_sys_status,
    "EKF_STATUS_REPORT": VehicleLink._on_ekf_status_report,
    "GPS_RAW_INT": VehicleLink._on_gps_raw_int,
    "EXTENDED_SYS_STATE": VehicleLink._on_extended_sys_state,
    "COMMAND_ACK": VehicleLink._on_command_ack,
    "PARAM_VALUE": VehicleLink._on_param_value,
    "TIMESYNC": VehicleLink._on_timesync,
    "MISSION_COUNT": VehicleLink._on_mission,
    "MISSION_REQUEST": VehicleLink._on_mission,
    "MISSION_REQUEST_INT": VehicleLink._on_mission,
    "MISSION_ITEM_INT": VehicleLink._on_mission,
    "MISSION_ACK": VehicleLink._on_mission,
}
