"""Helpers of the simulator tests: the real `python -m sitl_sim` process on free loopback ports (`start_sim`),
an in-process SimConfig, and a scripted pymavlink ground station (`Pilot`) that can drive it in lockstep.

Every process is started with a bounded wait for READY (READY_TIMEOUT_S); the fixtures in conftest.py
terminate (then kill) it at teardown. Before the first start, this process compiles the simulator's kernels
into numba's on-disk cache (`cache_kernels`), which the simulator shares: the READY bound then times a
start that loads them, as every start but the first after a change does, rather than a cold compile, which
on a loaded 2-core machine (a CI run beside a build job) can outlast the bound without anything hanging; a
simulator that hangs before READY still fails the bound. Import as `tests.sitl_sim.sim_process`.
"""

from __future__ import annotations

import math
import os
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.clock import plan_timing
from sitl_sim.simulator import SimConfig, warm_up_kernels
from sitl_sim.world import Obstacles
from swarm_common.ports import free_udp_base

M = mavlink2
GCS_SYSID, GCS_COMPID = 255, 190
READY_TIMEOUT_S = 30.0
WALL_LIMIT_S = 60.0  # any single wait in a test; simulated-time limits are the real bounds


def in_process_config(start_pos: list[list[float]], **overrides: object) -> SimConfig:
    """A real-time, fault-free SimConfig for an in-process Simulator on free 127.0.0.1 ports: vehicles at
    `start_pos` (ENU m; z > 0 starts airborne in GUIDED), ready at once, no obstacles or wind."""
    pos = np.array(start_pos, dtype=float)
    n = len(pos)
    fields: dict[str, object] = dict(
        base_port=free_udp_base(n),
        bind="127.0.0.1",
        sysid_base=1,
        timing=plan_timing(1000.0, 100.0, None, 50.0),
        speedup=1.0,
        lockstep=False,
        lockstep_timeout=5.0,
        lockstep_delay=1,
        home=(-35.0, 149.0, 500.0),
        start_pos=pos,
        start_vel=np.zeros((n, 3)),
        start_yaw=np.zeros(n),
        obstacles=Obstacles(np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3))),
        wind=(0.0, 0.0, 0.0),
        truth_log=None,
        seed=0,
        ready_delay=0.0,
    )
    fields.update(overrides)
    return SimConfig(**fields)  # type: ignore[arg-type]


@dataclass
class SimProcess:
    """A running simulator: its process, base port, vehicle count and stdout lines."""

    proc: subprocess.Popen[str]
    base_port: int
    vehicles: int
    stdout: list[str] = field(default_factory=list)

    def port(self, i: int) -> int:
        """UDP port of vehicle i."""
        return self.base_port + i

    def stop(self, sig: int = signal.SIGTERM, timeout_s: float = 15.0) -> tuple[int, str]:
        """Signal the process, wait; returns (exit status, stderr). Killed if it does not exit in time."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            _, err = self.proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
        return self.proc.returncode, err


_kernels_cached = False


def cache_kernels() -> None:
    """Compile (or load) the simulator's kernels in this process once, filling numba's on-disk cache that the
    simulator processes load (module doc); no bound: compiling is slow on a loaded machine, never stuck."""
    global _kernels_cached  # noqa: PLW0603 - once per test process
    if not _kernels_cached:
        warm_up_kernels()
        _kernels_cached = True


def start_sim(*args: str, vehicles: int = 1, extra_env: dict[str, str] | None = None) -> SimProcess:
    """Start `python -m sitl_sim` (vehicles given or with a --mission in args) and wait for READY."""
    cache_kernels()
    base = free_udp_base(vehicles)
    command = [sys.executable, "-m", "sitl_sim", "--base-port", str(base), *args]
    if "--mission" not in args:
        command += ["--vehicles", str(vehicles)]
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1", **(extra_env or {})},
    )
    sim = SimProcess(proc, base, vehicles)
    deadline = time.monotonic() + READY_TIMEOUT_S
    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    pending = b""
    while True:
        remaining = deadline - time.monotonic()
        if remaining <= 0 or proc.poll() is not None:
            code, err = sim.stop(signal.SIGKILL)
            raise AssertionError(f"simulator not READY (status {code}): {err[-2000:]}")
        ready, _, _ = select.select([fd], [], [], remaining)
        if ready:
            pending += os.read(fd, 65536)
            *lines, pending = pending.split(b"\n")
            sim.stdout += [line.decode().strip() for line in lines]
            if "READY" in sim.stdout:
                return sim


class Vehicle:
    """pymavlink client of one simulated vehicle: latest message per type, texts, acks, params."""

    def __init__(self, port: int, sysid: int, source_system: int = GCS_SYSID) -> None:
        self.sysid = sysid
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}",
            source_system=source_system,
            source_component=GCS_COMPID,
            dialect="ardupilotmega",
        )
        self.latest: dict[str, mavlink2.MAVLink_message] = {}
        self.texts: list[str] = []
        self.acks: list[mavlink2.MAVLink_command_ack_message] = []
        self.params: dict[str, mavlink2.MAVLink_param_value_message] = {}
        self.time_boot_ms = 0
        self.answered_ms = 0
        self.last_heartbeat_ms: int | None = None

    @property
    def mav(self) -> mavlink2.MAVLink:
        """The connection's MAVLink encoder (replaced when pymavlink switches to MAVLink 2)."""
        return self.conn.mav

    def drain(self) -> int:
        """Handle every message waiting; returns how many arrived."""
        count = 0
        while (msg := self.conn.recv_match(blocking=False)) is not None:
            count += 1
            kind = msg.get_type()
            if kind == "BAD_DATA" or msg.get_srcSystem() != self.sysid:
                continue
            self.latest[kind] = msg
            if kind == "STATUSTEXT":
                self.texts.append(msg.text)
            elif kind == "COMMAND_ACK":
                self.acks.append(msg)
            elif kind == "PARAM_VALUE":
                self.params[msg.param_id] = msg
            stamp = getattr(msg, "time_boot_ms", None)
            if stamp is not None:
                self.time_boot_ms = max(self.time_boot_ms, stamp)
        return count

    @property
    def t(self) -> float:
        """Vehicle time (s) of the latest timestamped telemetry."""
        return self.time_boot_ms / 1000.0

    def request_streams(self, hz: int = 10) -> None:
        """What a ground station does first (MAVProxy, QGroundControl): ask for the telemetry, which a
        vehicle (like ArduCopter) does not stream until asked; EXTENDED_SYS_STATE is in no stream group."""
        self.mav.request_data_stream_send(self.sysid, 1, M.MAV_DATA_STREAM_ALL, hz, 1)
        self.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 1e6 / hz)

    def heartbeat(self) -> None:
        """GCS HEARTBEAT."""
        self.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE)

    def command(self, command: int, *params: float) -> None:
        """COMMAND_LONG with up to 7 params."""
        p = [*params, *[0.0] * (7 - len(params))]
        self.mav.command_long_send(self.sysid, 1, command, 0, *p)

    def attitude(self, roll: float, pitch: float, yaw: float, thrust: float, type_mask: int = 0b111) -> None:
        """SET_ATTITUDE_TARGET of NED/FRD Euler angles (rad), rates ignored by default."""
        q = euler_to_quat_ned(roll, pitch, yaw)
        self.mav.set_attitude_target_send(
            self.time_boot_ms, self.sysid, 1, type_mask, q, 0.0, 0.0, 0.0, thrust
        )

    @property
    def armed(self) -> bool:
        hb = self.latest.get("HEARTBEAT")
        return bool(hb and hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)

    @property
    def mode(self) -> int | None:
        hb = self.latest.get("HEARTBEAT")
        return None if hb is None else hb.custom_mode

    @property
    def ready(self) -> bool:
        """SYS_STATUS says pre-arm checks pass (what MAVSDK calls armable)."""
        status = self.latest.get("SYS_STATUS")
        return bool(status and status.onboard_control_sensors_health & M.MAV_SYS_STATUS_PREARM_CHECK)

    @property
    def altitude(self) -> float:
        """Height above home from GLOBAL_POSITION_INT, m (nan before any)."""
        pos = self.latest.get("GLOBAL_POSITION_INT")
        return math.nan if pos is None else pos.relative_alt / 1000.0

    def close(self) -> None:
        """Close the socket."""
        self.conn.close()


def euler_to_quat_ned(roll: float, pitch: float, yaw: float) -> list[float]:
    """ZYX Euler angles (rad) -> [w, x, y, z]."""
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]


class Pilot:
    """A scripted ground station for vehicles of one simulator.

    lockstep=True: answers every frame of every vehicle with SYSTEM_TIME after `each_frame` (so its
    commands land in that frame). It sends its HEARTBEAT whenever a second of vehicle time has passed
    (heartbeat=False stops that, to trigger the GCS failsafe).
    """

    def __init__(self, sim: SimProcess, lockstep: bool = True, sysid_base: int = 1) -> None:
        self.vehicles = [Vehicle(sim.port(i), sysid_base + i) for i in range(sim.vehicles)]
        self.lockstep = lockstep
        self.heartbeat = True
        self.holding = False  # spin returned at a frame it has not answered yet
        for vehicle in self.vehicles:
            vehicle.heartbeat()
            vehicle.request_streams()
            vehicle.last_heartbeat_ms = 0

    def __getitem__(self, i: int) -> Vehicle:
        return self.vehicles[i]

    def spin(
        self,
        until: Callable[[], bool],
        sim_s: float,
        each_frame: Callable[[Vehicle], None] | None = None,
    ) -> None:
        """Serve the link until until() holds; AssertionError after sim_s more simulated s (or a wall limit).

        A decision (until, then each_frame and the answers) is taken once per frame, when every vehicle has
        sent newer telemetry than the last answer. When until() holds, spin returns *before* answering: what
        the caller sends next belongs to that frame, and the next spin answers it first. So the script acts on
        exactly the messages sent before each frame end, whatever the timing.
        """
        start = max(v.t for v in self.vehicles)
        wall_deadline = time.monotonic() + WALL_LIMIT_S
        while True:
            arrived = sum(v.drain() for v in self.vehicles)
            if all(v.time_boot_ms > v.answered_ms for v in self.vehicles):
                if not self.holding and until():
                    self.holding = True
                    return
                self.holding = False
                assert max(v.t for v in self.vehicles) - start <= sim_s, (
                    f"not met within {sim_s} s of vehicle time"
                )
                for v in self.vehicles:
                    if self.heartbeat and v.time_boot_ms - (v.last_heartbeat_ms or 0) >= 1000:
                        v.heartbeat()
                        v.last_heartbeat_ms = v.time_boot_ms
                    if each_frame is not None:
                        each_frame(v)
                    if self.lockstep:
                        v.mav.system_time_send(0, v.time_boot_ms)
                    v.answered_ms = v.time_boot_ms
            assert time.monotonic() < wall_deadline, "condition not met within the wall-clock limit"
            if not arrived:
                select.select([v.conn.port for v in self.vehicles], [], [], 0.05)

    def command(self, i: int, command: int, *params: float, sim_s: float = 5.0) -> int:
        """Send a COMMAND_LONG to vehicle i and return the result of its COMMAND_ACK."""
        vehicle = self.vehicles[i]
        vehicle.acks.clear()
        vehicle.command(command, *params)
        self.spin(lambda: any(a.command == command for a in vehicle.acks), sim_s)
        return next(a.result for a in vehicle.acks if a.command == command)

    def set_mode(self, i: int, mode: int) -> int:
        """MAV_CMD_DO_SET_MODE with a custom mode; returns the ACK result."""
        return self.command(i, M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode)

    def set_param(self, i: int, name: str, value: float) -> float:
        """PARAM_SET; returns the value the vehicle echoes."""
        vehicle = self.vehicles[i]
        vehicle.params.pop(name, None)
        vehicle.mav.param_set_send(vehicle.sysid, 1, name.encode(), value, M.MAV_PARAM_TYPE_REAL32)
        self.spin(lambda: name in vehicle.params, 5.0)
        return vehicle.params[name].param_value

    def param(self, i: int, name: str) -> float:
        """PARAM_REQUEST_READ; returns the value the vehicle reports."""
        vehicle = self.vehicles[i]
        vehicle.params.pop(name, None)
        vehicle.mav.param_request_read_send(vehicle.sysid, 1, name.encode(), -1)
        self.spin(lambda: name in vehicle.params, 5.0)
        return vehicle.params[name].param_value

    def take_off(self, i: int, altitude: float) -> None:
        """Wait for ready, GUIDED, arm, NAV_TAKEOFF and climb to within 0.5 m of altitude."""
        vehicle = self.vehicles[i]
        self.spin(lambda: vehicle.ready, 30.0)
        assert self.set_mode(i, 4) == M.MAV_RESULT_ACCEPTED
        assert self.command(i, M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        assert self.command(i, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, altitude) == M.MAV_RESULT_ACCEPTED
        self.spin(lambda: vehicle.altitude > altitude - 0.5, 30.0)

    def close(self) -> None:
        """Close every socket."""
        for vehicle in self.vehicles:
            vehicle.close()


def read_truth(path: Path):  # noqa: ANN201 - numpy structured array
    """The truth log as a numpy structured array (the documented way to read it)."""
    import numpy as np

    return np.genfromtxt(path, names=True, delimiter=",")
