"""A small fake ArduCopter for the link tests: one UDP socket on 127.0.0.1, MAVLink 2, its own thread.

Server mode (default) binds a free port and serves whoever sends to it, like the simulator behind a
`udpout:` connection. Client mode (`gcs_address`) sends from its own free port to a ground station's
`udpin:` port. It answers HEARTBEAT/COMMAND_LONG/PARAM_* and SET_MESSAGE_INTERVAL as ArduCopter does
(ACK first, the refusal's "PreArm: ..." STATUSTEXT after it; a new mode shows in the next HEARTBEAT), with
ArduCopter's answers to repeats: arming an armed vehicle ACCEPTED, a NAV_TAKEOFF off the ground FAILED.
Lost packets: `ignore_commands` (the command never arrives), `drop_acks` / `drop_param_values` (it acts, but
its answer is lost).

Time advances in frames of 1/frame_hz. Streams are due at multiples of their interval from boot;
GLOBAL_POSITION_INT goes last in a frame. With `lockstep=True` it follows the team brief's rule: after
each frame it waits until every lockstep client (a peer that sent SYSTEM_TIME / SET_ATTITUDE_TARGET /
SET_POSITION_TARGET_* with time_boot_ms > 0) has answered the frame (time_boot_ms >= frame), dropping a
client silent for `lockstep_timeout_s` (counted in `lockstep_drops`); at boot it stays at its first frame
until the first lockstep client appears. Frames without a timed stream carry a SYSTEM_TIME, and a new
peer gets HEARTBEAT + SYSTEM_TIME at once, so a client always knows which frame to answer.
"""

from __future__ import annotations

import math
import select
import socket
import threading
import time
from collections import Counter
from typing import Any

import numpy as np
import pymap3d
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

ORIGIN = (47.397742, 8.545594, 488.0)
READY_EKF_FLAGS = 0x1 | 0x2 | 0x4 | 0x8 | 0x10 | 0x20 | 0x200
_SENSORS = (
    mavlink2.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink2.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink2.MAV_SYS_STATUS_PREARM_CHECK
)
_TIMED = {"ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "SYSTEM_TIME", "GLOBAL_POSITION_INT"}
_ANSWERS = {
    "SYSTEM_TIME",
    "SET_ATTITUDE_TARGET",
    "SET_POSITION_TARGET_LOCAL_NED",
    "SET_POSITION_TARGET_GLOBAL_INT",
}
_EMIT_ORDER = [
    "HEARTBEAT",
    "SYS_STATUS",
    "EKF_STATUS_REPORT",
    "EXTENDED_SYS_STATE",
    "ATTITUDE",
    "ATTITUDE_QUATERNION",
    "LOCAL_POSITION_NED",
    "SYSTEM_TIME",
    "GLOBAL_POSITION_INT",
]
DEFAULT_PARAMS = {
    "GUID_OPTIONS": 0.0,
    "FS_GCS_ENABLE": 0.0,
    "MOT_THST_HOVER": 0.35,
    "SYSID_THISMAV": 1.0,
    "FS_GCS_TIMEOUT": 5.0,
    "WPNAV_SPEED": 1000.0,
    "RTL_ALT": 1500.0,
}


class FakeVehicle:
    """See the module docstring. Attributes prefixed by nothing are for tests to read or set."""

    def __init__(
        self,
        sysid: int = 1,
        *,
        lockstep: bool = False,
        frame_hz: float = 50.0,
        lockstep_timeout_s: float = 5.0,
        gcs_address: tuple[str, int] | None = None,
        position: tuple[float, float, float] = (0.0, 0.0, 0.0),
        velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
        attitude_ned: tuple[float, float, float] = (0.0, 0.0, 0.0),
        ready: bool = True,
        prearm_ok: bool = True,
        arm_refusal: str | None = None,
        params: dict[str, float] | None = None,
        readonly_params: tuple[str, ...] = (),
        drop_param_indices: tuple[int, ...] = (),
        streams: dict[str, float] | None = None,
    ) -> None:
        self.sysid = sysid
        self.lockstep = lockstep
        self.dt_ms = int(round(1000.0 / frame_hz))
        self.lockstep_timeout_s = lockstep_timeout_s
        self.position = np.array(position, dtype=float)  # ENU m around ORIGIN
        self.velocity = np.array(velocity, dtype=float)  # ENU m/s
        self.attitude_ned = attitude_ned  # roll, pitch, yaw rad, FRD/NED
        self.ready = ready  # EKF_STATUS_REPORT shows a usable position estimate
        self.prearm_ok = prearm_ok  # SYS_STATUS shows the pre-arm checks passing
        self.arm_refusal = arm_refusal
        self.params = dict(DEFAULT_PARAMS if params is None else params)
        self.readonly_params = set(readonly_params)
        self.drop_param_indices = set(drop_param_indices)
        self.ignore_commands = 0  # swallow this many COMMAND_LONGs (tests retries)
        self.drop_acks = 0  # act on commands but lose this many of their COMMAND_ACKs
        self.drop_param_values = 0  # lose this many PARAM_VALUE answers
        self.ignore_mode_changes = False  # ACK DO_SET_MODE but keep the old mode
        self.refuse_message_interval = False  # answer SET_MESSAGE_INTERVAL with DENIED (older firmware)
        self.silent = False  # send nothing at all (tests loss detection)
        self.t_ms = 0
        self.armed = False
        self.mode = 0  # STABILIZE
        self.landed_state = mavlink2.MAV_LANDED_STATE_ON_GROUND
        self.takeoff_alt: float | None = None
        self.intervals_ms: dict[int, int] = {mavlink2.MAVLINK_MSG_ID_HEARTBEAT: 1000}
        for name, hz in (streams or {}).items():
            self.intervals_ms[getattr(mavlink2, f"MAVLINK_MSG_ID_{name}")] = self._interval(1e6 / hz)
        # records for the tests
        self.commands: list[tuple[int, int, int]] = []  # (command, confirmation, target_system)
        self.command_ms: list[int] = []  # vehicle time at which each of `commands` arrived
        self.results: list[tuple[int, int]] = []  # (command, MAV_RESULT) of each answer, lost or not
        self.received: Counter[str] = Counter()
        self.answers: Counter[int] = Counter()  # time_boot_ms -> lockstep answers carrying it
        self.frames_sent: list[int] = []  # frame times whose telemetry carried time_boot_ms
        self.gcs_heartbeats_ms: list[int] = []  # vehicle time of each GCS HEARTBEAT received
        self.attitude_targets: list[Any] = []
        self.position_targets: list[Any] = []
        self.lockstep_drops = 0
        # internals
        self._mav = mavlink2.MAVLink(None, sysid, 1)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(("127.0.0.1", 0))
        self._sock.setblocking(False)
        self.port: int = self._sock.getsockname()[1]
        self._client_mode = gcs_address is not None
        self.peers: list[tuple[str, int]] = [gcs_address] if gcs_address is not None else []
        self._clients: dict[tuple[str, int], int] = {}  # lockstep client -> latest time_boot_ms answered
        self._had_client = False
        self._delayed: list[tuple[int, int, tuple[int, int]]] = []  # (due t_ms, command, (sysid, compid))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"fake-vehicle-{sysid}", daemon=True)

    @property
    def connection(self) -> str:
        return f"udpout:127.0.0.1:{self.port}"

    def start(self) -> FakeVehicle:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self._sock.close()

    def __enter__(self) -> FakeVehicle:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def send_raw(self, data: bytes) -> None:
        """Send bytes as one datagram to every peer (garbage tests)."""
        for peer in self.peers:
            self._sock.sendto(data, peer)

    # ------------------------------------------------------------------ main loop

    def _run(self) -> None:
        next_wall = time.monotonic()
        while not self._stop.is_set():
            self.t_ms += self.dt_ms
            self._step(self.dt_ms / 1000.0)
            self._emit_frame()
            next_wall += self.dt_ms / 1000.0
            if self.lockstep and (self._clients or not self._had_client):
                self._wait_for_answers()
                next_wall = time.monotonic()
            else:
                self._serve_until(next_wall)

    def _wait_for_answers(self) -> None:
        started = next_hello = time.monotonic()
        while not self._stop.is_set():
            if not self._had_client:  # paused at the first frame until a lockstep client appears
                if time.monotonic() >= next_hello:  # say hello so a udpin ground station learns of us
                    self._send(self._message("HEARTBEAT"))
                    self._send(self._message("SYSTEM_TIME"))
                    next_hello = time.monotonic() + 0.2
                self._serve(0.01)
                continue
            late = [a for a, t in self._clients.items() if t < self.t_ms]
            if not late:
                return
            if time.monotonic() - started > self.lockstep_timeout_s:
                for addr in late:
                    del self._clients[addr]
                    self.lockstep_drops += 1
                return
            self._serve(0.01)

    def _serve_until(self, wall: float) -> None:
        while not self._stop.is_set():
            remaining = wall - time.monotonic()
            if remaining <= 0:
                return
            self._serve(remaining)

    def _serve(self, timeout_s: float) -> None:
        readable, _, _ = select.select([self._sock], [], [], timeout_s)
        if not readable:
            return
        while True:
            try:
                data, addr = self._sock.recvfrom(65535)
            except (BlockingIOError, OSError):
                return
            parser = mavlink2.MAVLink(None)
            parser.robust_parsing = True
            for msg in parser.parse_buffer(data) or []:
                self._handle(msg, addr)

    def _step(self, dt: float) -> None:
        self.position += self.velocity * dt
        if self.takeoff_alt is not None:
            self.position[2] = min(self.takeoff_alt, self.position[2] + 5.0 * dt)
            self.landed_state = mavlink2.MAV_LANDED_STATE_IN_AIR
        for due, command, source in [d for d in self._delayed if d[0] <= self.t_ms]:
            self._delayed.remove((due, command, source))
            self._ack(command, mavlink2.MAV_RESULT_ACCEPTED, source)

    # ------------------------------------------------------------------ output

    def _send(self, msg: Any, to: tuple[str, int] | None = None) -> None:
        if self.silent:
            return
        packet = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256
        for peer in [to] if to is not None else self.peers:
            try:
                self._sock.sendto(packet, peer)
            except OSError:
                pass

    def _emit_frame(self) -> None:
        due = {
            mavlink2.mavlink_map[msg_id].msgname
            for msg_id, iv in self.intervals_ms.items()
            if iv > 0 and self.t_ms // iv != (self.t_ms - self.dt_ms) // iv
        }
        if self.lockstep and not due & _TIMED:
            due.add("SYSTEM_TIME")
        if due & _TIMED and self.peers and not self.silent:
            self.frames_sent.append(self.t_ms)
        for name in _EMIT_ORDER:
            if name in due:
                self._send(self._message(name))

    def _message(self, name: str) -> Any:
        m, t = self._mav, self.t_ms
        roll, pitch, yaw = self.attitude_ned
        if name == "HEARTBEAT":
            base = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            base |= mavlink2.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0
            status = mavlink2.MAV_STATE_ACTIVE if self.armed else mavlink2.MAV_STATE_STANDBY
            return m.heartbeat_encode(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, base, self.mode, status
            )
        if name == "SYS_STATUS":
            health = (
                _SENSORS if self.prearm_ok or self.armed else _SENSORS & ~mavlink2.MAV_SYS_STATUS_PREARM_CHECK
            )
            return m.sys_status_encode(_SENSORS, _SENSORS, health, 0, 12000, -1, -1, 0, 0, 0, 0, 0, 0)
        if name == "EKF_STATUS_REPORT":
            return m.ekf_status_report_encode(
                READY_EKF_FLAGS if self.ready else 0x400, 0.1, 0.1, 0.1, 0.1, 0.0
            )
        if name == "EXTENDED_SYS_STATE":
            return m.extended_sys_state_encode(0, self.landed_state)
        if name == "ATTITUDE":
            return m.attitude_encode(t, roll, pitch, yaw, 0.0, 0.0, 0.0)
        if name == "ATTITUDE_QUATERNION":
            q = _euler_to_quaternion(roll, pitch, yaw)
            return m.attitude_quaternion_encode(t, *q, 0.0, 0.0, 0.0)
        if name == "LOCAL_POSITION_NED":
            e, n, u = self.position
            ve, vn, vu = self.velocity
            return m.local_position_ned_encode(t, n, e, -u, vn, ve, -vu)
        if name == "SYSTEM_TIME":
            return m.system_time_encode(int(time.time() * 1e6), t)
        lat, lon, alt = pymap3d.enu2geodetic(*self.position, *ORIGIN)
        ve, vn, vu = self.velocity
        return m.global_position_int_encode(
            t,
            int(round(lat * 1e7)),
            int(round(lon * 1e7)),
            int(round(alt * 1000)),
            int(round(self.position[2] * 1000)),
            int(round(vn * 100)),
            int(round(ve * 100)),
            int(round(-vu * 100)),
            int(math.degrees(yaw) % 360 * 100),
        )

    def _ack(self, command: int, result: int, source: tuple[int, int]) -> None:
        self.results.append((command, result))
        if self.drop_acks > 0:
            self.drop_acks -= 1
            return
        self._send(self._mav.command_ack_encode(command, result, 0, 0, source[0], source[1]))

    def _statustext(self, text: str, severity: int = mavlink2.MAV_SEVERITY_CRITICAL) -> None:
        self._send(self._mav.statustext_encode(severity, text.encode()))

    def _send_param_value(self, name: str) -> None:
        if self.drop_param_values > 0:
            self.drop_param_values -= 1
            return
        self._send(self._param_value(name))

    def _param_value(self, name: str) -> Any:
        names = list(self.params)
        return self._mav.param_value_encode(
            name.encode(), self.params[name], mavlink2.MAV_PARAM_TYPE_REAL32, len(names), names.index(name)
        )

    # ------------------------------------------------------------------ input

    def _handle(self, msg: Any, addr: tuple[str, int]) -> None:
        mtype = msg.get_type()
        self.received[mtype] += 1
        if mtype == "BAD_DATA":
            return
        if not self._client_mode and addr not in self.peers:
            self.peers.append(addr)
            self._send(self._message("HEARTBEAT"), addr)
            self._send(self._message("SYSTEM_TIME"), addr)
        target = getattr(msg, "target_system", 0)
        if target not in (0, self.sysid):
            return
        if mtype == "HEARTBEAT" and msg.get_srcSystem() == 255:
            self.gcs_heartbeats_ms.append(self.t_ms)
        if mtype in _ANSWERS and msg.time_boot_ms > 0:
            self.answers[msg.time_boot_ms] += 1
            if self.lockstep:
                self._clients[addr] = max(self._clients.get(addr, 0), msg.time_boot_ms)
                self._had_client = True
        if mtype == "SET_ATTITUDE_TARGET":
            self.attitude_targets.append(msg)
        elif mtype.startswith("SET_POSITION_TARGET"):
            self.position_targets.append(msg)
        elif mtype == "COMMAND_LONG":
            self._command(msg)
        elif mtype == "PARAM_REQUEST_READ":
            names = list(self.params)
            name = names[msg.param_index] if 0 <= msg.param_index < len(names) else msg.param_id
            if name in self.params:
                self._send_param_value(name)
        elif mtype == "PARAM_SET":
            if msg.param_id in self.params:
                if msg.param_id not in self.readonly_params:
                    self.params[msg.param_id] = msg.param_value
                self._send_param_value(msg.param_id)
        elif mtype == "PARAM_REQUEST_LIST":
            for index, name in enumerate(self.params):
                if index not in self.drop_param_indices:
                    self._send(self._param_value(name))
            self.drop_param_indices = set()

    def _command(self, msg: Any) -> None:
        command = msg.command
        self.commands.append((command, msg.confirmation, msg.target_system))
        self.command_ms.append(self.t_ms)
        if self.ignore_commands > 0:
            self.ignore_commands -= 1
            return
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        result = mavlink2.MAV_RESULT_ACCEPTED
        if command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
            if msg.param1 == 1 and self.arm_refusal and msg.param2 != 2989:  # ArduPilot force-arm
                self._ack(command, mavlink2.MAV_RESULT_FAILED, source)
                self._statustext(self.arm_refusal)  # after the ACK, as ArduPilot's queued text
                return
            self.armed = msg.param1 == 1
        elif command == mavlink2.MAV_CMD_DO_SET_MODE:
            if int(msg.param2) not in mavutil.mode_mapping_acm:
                result = mavlink2.MAV_RESULT_FAILED
            elif not self.ignore_mode_changes:
                self.mode = int(msg.param2)
        elif command == mavlink2.MAV_CMD_NAV_TAKEOFF:  # ArduCopter: armed, GUIDED and still on the ground
            if self.armed and self.mode == 4 and self.landed_state == mavlink2.MAV_LANDED_STATE_ON_GROUND:
                self.takeoff_alt = msg.param7
                self.landed_state = mavlink2.MAV_LANDED_STATE_TAKEOFF
            else:
                result = mavlink2.MAV_RESULT_FAILED
        elif command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL and self.refuse_message_interval:
            result = mavlink2.MAV_RESULT_DENIED
        elif command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL:
            if msg.param2 < 0:
                self.intervals_ms.pop(int(msg.param1), None)
            else:
                self.intervals_ms[int(msg.param1)] = self._interval(msg.param2)
        elif command == mavlink2.MAV_CMD_REQUEST_MESSAGE:
            name = mavlink2.mavlink_map[int(msg.param1)].msgname
            if name in _EMIT_ORDER:
                self._send(self._message(name))
            else:
                result = mavlink2.MAV_RESULT_UNSUPPORTED
        elif command == mavlink2.MAV_CMD_PREFLIGHT_CALIBRATION:  # slow: IN_PROGRESS, then ACCEPTED
            self._ack(command, mavlink2.MAV_RESULT_IN_PROGRESS, source)
            self._delayed.append((self.t_ms + 10 * self.dt_ms, command, source))
            return
        else:
            result = mavlink2.MAV_RESULT_UNSUPPORTED
        self._ack(command, result, source)

    def _interval(self, interval_us: float) -> int:
        return max(self.dt_ms, int(round(interval_us / 1000.0 / self.dt_ms)) * self.dt_ms)


def _euler_to_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that was free a moment ago (for a ground station's udpin endpoint)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])
