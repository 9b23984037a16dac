"""MAVSDK flying one `sitl-sim --autopilot px4` vehicle, checked against the simulator's truth log.

MAVSDK is the client PX4 is developed against: a flight it completes is evidence that the PX4 persona answers
on the wire as PX4 does. The `mavsdk` package on PyPI is, since v4, MAVSDK's C++ library through a native
binding (libcmavsdk; no separate mavsdk_server process: the gRPC wrapper that bundled it is `mavsdk-grpc`).

The flight is MAVSDK's offboard example, bounded: connect, wait for health (global position, home, armable),
set the takeoff altitude (PX4's MIS_TAKEOFF_ALT), arm, take off (AUTO.TAKEOFF, which PX4 ends itself in Hold),
give an attitude setpoint BEFORE offboard.start() (MAVSDK refuses to start without one), fly tilted attitude
setpoints in OFFBOARD, stop offboard (MAVSDK switches to Hold), land (MAV_CMD_NAV_LAND), wait until disarmed.
`mavsdk_flight` flies real PX4 SITL unchanged (url udpin://127.0.0.1:14540: PX4's API link sends there).
"""

from __future__ import annotations

import asyncio
import math
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from swarm_common.ports import free_udp_base

mavsdk = pytest.importorskip(
    "mavsdk.asyncio", reason="needs mavsdk>=4 (MAVSDK's native Python binding): pip install 'swarm-gcs[test]'"
)
from mavsdk.asyncio.plugins.action import ActionAsync  # noqa: E402
from mavsdk.asyncio.plugins.offboard import Attitude, OffboardAsync  # noqa: E402
from mavsdk.asyncio.plugins.param import ParamAsync  # noqa: E402
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TAKEOFF_ALT_M = 4.0  # set through MAVSDK (PX4's MIS_TAKEOFF_ALT; default 2.5 m)
TILT_DEG = 8.0  # offboard pitch, NED: negative = nose down = forward
TILT_S = 4.0  # s of tilted flight, then LEVEL_S s level
LEVEL_S = 2.0
ALT_GAIN = 0.05  # normalised thrust per m of altitude error, a gentle altitude hold around the hover thrust
READY_DELAY_S = 5.0  # simulated s to a position estimate (real PX4 SIH: pre-arm checks pass 4.4 s after boot)
STEP_TIMEOUT_S = 60.0  # wall s for any one step of the flight
FLIGHT_TIMEOUT_S = 240.0  # wall s for the whole flight


@dataclass
class FlightRecord:
    """What MAVSDK saw, times in wall s since the connection was added: flight modes in order (repeats
    removed), status texts, when each step finished, relative altitudes (m) sampled at 2 Hz."""

    modes: list[str] = field(default_factory=list)
    texts: list[str] = field(default_factory=list)
    steps: dict[str, float] = field(default_factory=dict)
    altitudes: list[tuple[float, float]] = field(default_factory=list)


async def _until(predicate: Callable[[], bool], what: str) -> None:
    """Poll `predicate()` every 50 ms; TimeoutError naming `what` after STEP_TIMEOUT_S."""
    end = time.monotonic() + STEP_TIMEOUT_S
    while not predicate():
        if time.monotonic() > end:
            raise TimeoutError(f"MAVSDK flight: no {what} within {STEP_TIMEOUT_S} s")
        await asyncio.sleep(0.05)


async def _follow(stream: AsyncIterator[Any], on_value: Callable[[Any], None]) -> None:
    async for value in stream:
        on_value(value)


class _Vehicle:
    """The latest telemetry MAVSDK reported, kept current by subscription tasks (start() .. stop())."""

    def __init__(self, telemetry: TelemetryAsync, record: FlightRecord, t0: float) -> None:
        self.armed = False
        self.relative_alt_m = math.nan
        self.yaw_deg = 0.0
        self.health: Any = None
        self._telemetry, self._record, self._t0 = telemetry, record, t0
        self._tasks: list[asyncio.Task[None]] = []

    def start(self) -> None:
        t = self._telemetry
        streams: list[tuple[AsyncIterator[Any], Callable[[Any], None]]] = [
            (t.subscribe_flight_mode(), self._on_mode),
            (t.subscribe_status_text(), lambda s: self._record.texts.append(s.text)),
            (t.subscribe_armed(), self._on_armed),
            (t.subscribe_position(), self._on_position),
            (t.subscribe_health(), self._on_health),
            (t.subscribe_attitude_euler(), self._on_euler),
        ]
        self._tasks = [asyncio.create_task(_follow(stream, handler)) for stream, handler in streams]

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)

    def healthy(self) -> bool:
        h = self.health
        return h is not None and h.is_global_position_ok and h.is_home_position_ok and h.is_armable

    def _on_mode(self, mode: Any) -> None:
        if not self._record.modes or self._record.modes[-1] != mode.name:
            self._record.modes.append(mode.name)

    def _on_armed(self, armed: bool) -> None:
        self.armed = armed

    def _on_health(self, health: Any) -> None:
        self.health = health

    def _on_euler(self, euler: Any) -> None:
        self.yaw_deg = euler.yaw_deg

    def _on_position(self, position: Any) -> None:
        self.relative_alt_m = position.relative_altitude_m
        now = time.monotonic() - self._t0
        if not self._record.altitudes or now - self._record.altitudes[-1][0] >= 0.5:
            self._record.altitudes.append((round(now, 2), round(position.relative_altitude_m, 2)))


async def mavsdk_flight(url: str, record: FlightRecord) -> None:
    """Fly one PX4 vehicle through MAVSDK at `url`: "udpout://127.0.0.1:P" for sitl-sim (it binds P and
    answers the peer that speaks first), "udpin://127.0.0.1:14540" for real PX4 SITL. Raises on any refused
    action."""
    t0 = time.monotonic()
    config = mavsdk.Configuration.create_with_component_type(mavsdk.ComponentType.GROUND_STATION)
    async with mavsdk.Mavsdk(config) as sdk:
        await sdk.add_any_connection(url)
        system = await sdk.first_autopilot(timeout_s=STEP_TIMEOUT_S)
        assert system is not None, f"no autopilot heard on {url}"
        record.steps["connected"] = time.monotonic() - t0
        action, offboard, param = ActionAsync(system), OffboardAsync(system), ParamAsync(system)
        vehicle = _Vehicle(TelemetryAsync(system), record, t0)
        vehicle.start()
        try:
            await _until(vehicle.healthy, "health (global position, home, armable)")
            record.steps["healthy"] = time.monotonic() - t0
            await action.set_takeoff_altitude(TAKEOFF_ALT_M)
            hover = await param.get_param_float("MPC_THR_HOVER")
            await action.arm()
            await action.takeoff()
            await _until(lambda: "TAKEOFF" in record.modes, "AUTO.TAKEOFF")
            await _until(lambda: record.modes[-1] == "HOLD", "Hold at the end of the takeoff")
            record.steps["took_off"] = time.monotonic() - t0
            hold_alt, yaw = vehicle.relative_alt_m, vehicle.yaw_deg

            def attitude(pitch_deg: float) -> Attitude:
                thrust = hover + ALT_GAIN * (hold_alt - vehicle.relative_alt_m)
                return Attitude(0.0, pitch_deg, yaw, min(max(thrust, 0.1), 0.9))

            await offboard.set_attitude(attitude(0.0))  # MAVSDK requires a setpoint before start()
            await offboard.start()
            record.steps["offboard"] = time.monotonic() - t0
            for pitch_deg, seconds in ((-TILT_DEG, TILT_S), (0.0, LEVEL_S)):
                end = time.monotonic() + seconds
                while time.monotonic() < end:
                    await offboard.set_attitude(attitude(pitch_deg))
                    await asyncio.sleep(0.05)
            await offboard.stop()
            await action.land()
            await _until(lambda: not vehicle.armed, "disarm after landing")
            record.steps["disarmed"] = time.monotonic() - t0
        finally:
            await vehicle.stop()


def test_mavsdk_flies_a_px4_persona_vehicle(tmp_path: Path) -> None:
    port = free_udp_base(1)
    truth_path = tmp_path / "truth.csv"
    command = [sys.executable, "-m", "sitl_sim", "--autopilot", "px4", "--vehicles", "1"]
    command += ["--base-port", str(port), "--ready-delay", str(READY_DELAY_S), "--truth-log", str(truth_path)]
    record = FlightRecord()
    with (tmp_path / "sitl_sim.out").open("w") as sim_output:
        sim = subprocess.Popen(command, cwd=ROOT, stdout=sim_output, stderr=subprocess.STDOUT)
        try:
            flight = mavsdk_flight(f"udpout://127.0.0.1:{port}", record)
            asyncio.run(asyncio.wait_for(flight, timeout=FLIGHT_TIMEOUT_S))
        finally:
            sim.terminate()
            try:
                sim.wait(timeout=20)
            except subprocess.TimeoutExpired:
                sim.kill()
                sim.wait()

    # MAVSDK's view: PX4's own mode names, in the order the flight asked for them
    modes = iter(record.modes)
    assert all(mode in modes for mode in ["TAKEOFF", "HOLD", "OFFBOARD", "LAND"]), record

    # the simulator's ground truth: ENU metres in the mission frame, origin at home (docs/sitl.md, Truth log)
    truth = np.genfromtxt(truth_path, names=True, delimiter=",")
    armed = truth[truth["armed"] == 1]
    # climbed to the takeoff altitude MAVSDK set
    assert armed["z"].max() >= TAKEOFF_ALT_M - 0.5
    # flew the attitude setpoints: 4 s pitched 8 deg accelerate at g tan(8 deg) = 1.38 m/s^2, 11 m without
    # drag; 3 m is a bound any sane multirotor drag keeps; the tilt itself reached at least half the setpoint
    start_xy = np.array([armed["x"][0], armed["y"][0]])
    end_xy = np.array([truth["x"][-1], truth["y"][-1]])
    assert np.linalg.norm(end_xy - start_xy) > 3.0
    assert np.degrees(np.abs(armed["pitch"]).max()) > TILT_DEG / 2
    # landed and disarmed, in one piece
    assert truth["armed"][-1] == 0 and truth["landed"][-1] == 1
    assert truth["z"][-1] < 0.3
    assert truth["crashed"].max() == 0
