"""The link layer against the real simulator process in lockstep: connect, preflight, take off, fly
attitude targets, land; telemetry in the mission frame matches the simulator's ground truth."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots import ARDUPILOT
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.streams import STREAM_QUIET_S
from gcs_swarm.link.vehicle import VehicleConfig
from swarm_common.ports import free_udp_base
from tests.process_output import OutputLines

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("sitl_sim.__main__") is None, reason="the sitl_sim simulator is not installed"
)

ORIGIN = (47.397742, 8.545594, 488.0)
N = 2
BOOT_TIMEOUT_S = 60.0


@pytest.fixture
def simulator(tmp_path: Path, request: pytest.FixtureRequest) -> Iterator[tuple[int, Path]]:
    """A lockstep sitl_sim with N vehicles: (base port, truth log path); terminated afterwards. Extra
    command-line arguments through indirect parametrisation (request.param, a list)."""
    base = free_udp_base(N)
    truth = tmp_path / "truth.csv"
    home = ",".join(f"{v:.7f}" for v in ORIGIN)
    args = [sys.executable, "-m", "sitl_sim", "--vehicles", str(N), "--base-port", str(base), "--lockstep"]
    args += ["--home", home, "--ready-delay", "1", "--truth-log", str(truth), "--lockstep-timeout", "3"]
    args += list(getattr(request, "param", []))
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output = OutputLines(proc)
    try:
        output.wait_for(lambda line: line.strip() == "READY", BOOT_TIMEOUT_S, "READY from sitl_sim")
        yield base, truth
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
        output.reader.join(timeout=5)


def test_fly_and_land_two_vehicles_in_lockstep(simulator: tuple[int, Path], tmp_path: Path) -> None:
    base, truth_path = simulator
    configs = [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{base + i}", i + 1) for i in range(N)]
    samples = []
    with Fleet(configs, ORIGIN, tlog_path=tmp_path / "flight.tlog") as fleet:
        fleet.connect(timeout_s=10.0)
        fleet.wait_ready(timeout_s=20.0)
        fleet.param_set_all("GUID_OPTIONS", 8)
        hover = fleet.param_get_all("MOT_THST_HOVER")
        assert np.all((hover > 0.1) & (hover < 0.7))
        fleet.set_mode_all("GUIDED")
        fleet.arm_all()
        fleet.takeoff_all(3.0)
        fleet.wait_until(lambda: bool(np.all(fleet.pos[:, 2] > 2.7)), 20.0, "both at 3 m")
        for _ in range(100):  # 2 s of level attitude at hover thrust, yaw held
            assert fleet.wait_tick(timeout_s=5.0)
            samples.append((fleet.time_ms.copy(), fleet.pos, fleet.att))
            yaw = samples[0][2][:, 2]
            level = np.zeros(N)
            thrust = ARDUPILOT.thrust(np.full(N, 9.8), level, level, hover, np.zeros(N, dtype=bool), 9.8)
            fleet.send_attitude_targets(level, level, yaw, thrust)
            fleet.answer_frame()
        assert np.all(np.abs(fleet.vel) < 1.0) and np.all(fleet.pos[:, 2] > 1.5)
        fleet.land_all()
        fleet.wait_until(lambda: not fleet.armed.any(), 60.0, "both landed and disarmed")
        assert np.all(fleet.alive) and all(c["bad"] == 0 and c["lost"] == 0 for c in fleet.stats().values())
        # TIMESYNC round trips (one a wall second) were measured on every link
        assert np.all(np.isfinite(fleet.rtt_ms)) and np.all((fleet.rtt_ms > 0) & (fleet.rtt_ms < 5000))
    truth = np.genfromtxt(truth_path, names=True, delimiter=",")
    rows = {(round(t * 1000), int(v)): r for t, v, r in zip(truth["t"], truth["vehicle"], truth, strict=True)}
    for time_ms, pos, att in samples[::10]:
        for i in range(N):
            row = rows[(int(time_ms[i]), i)]
            np.testing.assert_allclose(pos[i], [row["x"], row["y"], row["z"]], atol=0.02)
            np.testing.assert_allclose(att[i], [row["roll"], row["pitch"], row["yaw"]], atol=1e-4)


def test_streams_are_asked_for_at_connect_and_again_when_they_stop(simulator: tuple[int, Path]) -> None:
    """The simulator, like ArduCopter, streams nothing until asked: a client that never asks hears no
    telemetry; the Fleet asks at connect. When the position stream stops (here the test switches it off),
    the link's watchdog asks again once the vehicle has been quiet for STREAM_QUIET_S of its own time, and
    positions resume."""
    base, _ = simulator
    silent = mavutil.mavlink_connection(f"udpout:127.0.0.1:{base + 1}", source_system=200)
    silent.mav.heartbeat_send(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    kinds: set[str] = set()
    deadline = time.monotonic() + 3.0
    while time.monotonic() < deadline:
        msg = silent.recv_match(blocking=True, timeout=0.2)
        if msg is not None:
            kinds.add(msg.get_type())
    silent.close()
    assert "HEARTBEAT" in kinds and not kinds & {"GLOBAL_POSITION_INT", "ATTITUDE", "SYS_STATUS"}

    configs = [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{base + i}", i + 1) for i in range(N)]
    with Fleet(configs, ORIGIN, stream_rate_hz=25.0) as fleet:
        fleet.connect(timeout_s=10.0)  # asks for the telemetry itself
        fleet.wait_ready(timeout_s=20.0)
        link = fleet.vehicle("v0")
        assert link.channel.stats.stream_requests == 0
        fleet.run([link.streams.op_set_message_interval("GLOBAL_POSITION_INT", 0.0)])  # the stream stops
        fleet.wait_until(lambda: link.channel.stats.stream_requests >= 1, 10.0, "the watchdog asks again")
        quiet_ms = link.streams.asked_ms - int(fleet.state.position_ms[0])
        assert quiet_ms >= STREAM_QUIET_S * 1000
        seen = int(fleet.state.position_count[0])
        fleet.wait_until(lambda: fleet.state.position_count[0] > seen + 10, 5.0, "positions again")


@pytest.mark.parametrize("simulator", [["--param-names", "4.6"]], indirect=True)
def test_parameters_read_under_the_name_the_vehicle_has(simulator: tuple[int, Path]) -> None:
    """An ArduCopter before 4.7 calls the sysid SYSID_THISMAV: asked for MAV_SYSID, the link tries it, finds
    nothing, and reads SYSID_THISMAV; later reads and writes go straight to that spelling."""
    base, _ = simulator
    configs = [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{base + i}", i + 1) for i in range(N)]
    with Fleet(configs, ORIGIN) as fleet:
        fleet.connect(timeout_s=10.0)
        link = fleet.vehicle("v1")
        assert fleet.run([link.parameters.op_get("MAV_SYSID")])[0] == 2.0
        assert link.parameters.spelling("MAV_SYSID") == "SYSID_THISMAV"
        assert fleet.run([link.parameters.op_get("SYSID_MYGCS")])[0] == 255.0
        assert (
            fleet.run([link.parameters.op_set("MAV_GCS_SYSID", 254)])[0] == 254.0
        )  # written under the vehicle's own name
        assert (
            link.parameters.values["SYSID_MYGCS"] == 254.0 and "MAV_GCS_SYSID" not in link.parameters.values
        )
