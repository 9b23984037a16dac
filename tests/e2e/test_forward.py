"""Forwarding end to end: the real `gcs-swarm run` flies the real simulator with another ground station
attached to its forward: a pymavlink client (read-only) and a real MAVProxy (read-write)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections import Counter
from pathlib import Path

import pexpect
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.ports import free_udp_base
from swarm_common.signing_keys import timestamp_now
from tests.e2e.flights import MISSIONS, ROOT, derived_mission, fly

MAVPROXY = Path(sys.executable).parent / "mavproxy.py"
QUICKSTART_SYSIDS = (1, 2, 3)  # lead, right, left
LOITER = 5  # ArduCopter custom_mode
WALL_LIMIT_S = 120.0
GCS = (255, 190)  # the ground station's own sysid and compid (docs/watching-with-qgc.md)


def _figures(report: dict) -> dict:
    return {k: v for k, v in report.items() if k not in ("wall_duration_s", "link_use")}  # wall-clock paced


def test_read_only_forward_sees_every_vehicle_and_changes_nothing(tmp_path: Path) -> None:
    """A pymavlink client on the forward hears every vehicle's HEARTBEAT with its own sysid; the command it
    sends is refused, and the lockstep flight is the same, figure for figure, as without a forward."""
    port = free_udp_base(1)
    heartbeats: Counter[int] = Counter()
    client = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=250)
    stop = threading.Event()

    def watch() -> None:
        commanded = False
        while not stop.is_set():
            msg = client.recv_match(type="HEARTBEAT", blocking=True, timeout=0.2)
            if msg is None or msg.type == mavlink2.MAV_TYPE_GCS:
                continue
            heartbeats[msg.get_srcSystem()] += 1
            if not commanded and len(heartbeats) == len(QUICKSTART_SYSIDS):
                client.mav.command_long_send(1, 1, mavlink2.MAV_CMD_DO_SET_MODE, 0, 1, LOITER, 0, 0, 0, 0, 0)
                commanded = True

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        forwarded = fly(
            MISSIONS / "quickstart.yaml", tmp_path / "forwarded", extra=[f"--forward=udpout:127.0.0.1:{port}"]
        )
    finally:
        stop.set()
        watcher.join(5)
        client.close()
    assert forwarded.status == 0, forwarded.output
    assert set(heartbeats) == set(QUICKSTART_SYSIDS) and min(heartbeats.values()) >= 10
    stats = json.loads((forwarded.run_dir / "flight.json").read_text())["link_stats"]["forwards"]
    (only,) = stats.values()
    assert only["commands_refused"] >= 1 and only["routed"] == 0
    plain = fly(MISSIONS / "quickstart.yaml", tmp_path / "plain")
    assert plain.status == 0, plain.output
    assert _figures(forwarded.report) == _figures(plain.report)


class Output:
    """The lines a process writes, read by a thread (so that waiting for one never blocks the process)."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.lines: list[str] = []
        assert proc.stdout is not None
        stream = proc.stdout
        self._thread = threading.Thread(
            target=lambda: self.lines.extend(iter(stream.readline, "")), daemon=True
        )
        self._thread.start()

    def wait_for(self, text: str, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while not any(text in line for line in list(self.lines)):
            assert time.monotonic() < deadline, f"no {text!r} within {timeout_s} s:\n{''.join(self.lines)}"
            time.sleep(0.1)


def _target(msg: object) -> int | None:
    return getattr(msg, "target_system", None)


def _heartbeat_modes(tlog: Path) -> dict[int, set[int]]:
    """custom_mode values of the vehicles' HEARTBEATs in a tlog, by sysid."""
    modes: dict[int, set[int]] = {}
    log = mavutil.mavlink_connection(str(tlog))
    while (msg := log.recv_match(type="HEARTBEAT")) is not None:
        if msg.type != mavlink2.MAV_TYPE_GCS:
            modes.setdefault(msg.get_srcSystem(), set()).add(msg.custom_mode)
    return modes


def test_mavproxy_on_a_read_write_forward_takes_one_vehicle_over(tmp_path: Path) -> None:
    """A real MAVProxy attached to the forward detects every vehicle, and `vehicle 2` then `mode loiter`
    mid-flight (real time) reaches vehicle 2 only. The ground station sees the takeover: it stops commanding
    vehicle 2 ("right"), never switches it back, and the other two arrive without a collision (issue 17)."""
    port, base = free_udp_base(1), free_udp_base(len(QUICKSTART_SYSIDS))
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "gcs_swarm", "run", str(MISSIONS / "quickstart.yaml"), "--out", str(run_dir)]
    cmd += ["--base-port", str(base), "--time-mode=realtime", "--sim-arg=--ready-delay=3"]
    cmd += [f"--forward=udpout:127.0.0.1:{port}", "--forward-rw"]
    run = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    mavproxy = pexpect.spawn(
        str(MAVPROXY),
        [f"--master=udpin:127.0.0.1:{port}", f"--state-basedir={tmp_path}", "--default-modules=link,mode"],
        cwd=str(tmp_path),
        encoding="utf-8",
        timeout=60,
    )
    output = Output(run)
    try:
        for sysid in QUICKSTART_SYSIDS:
            mavproxy.expect(f"Detected vehicle {sysid}:1", timeout=60)
        output.wait_for("phase formation", WALL_LIMIT_S)
        mavproxy.sendline("vehicle 2")
        mavproxy.expect("Set vehicle 2", timeout=10)
        mavproxy.sendline("mode loiter")
        mavproxy.expect("LOITER>", timeout=20)  # MAVProxy's prompt: vehicle 2's HEARTBEAT says LOITER
        output.wait_for("right taken over: now in LOITER", 10.0)
        status = run.wait(WALL_LIMIT_S)  # the others fly on, arrive and land; right is left to MAVProxy
    finally:
        mavproxy.terminate(force=True)
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGINT)  # the run stops, closes its tlog, writes flight.json
        try:
            run.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(run.pid, signal.SIGKILL)
            run.wait(10)
    text = "".join(output.lines)
    assert "Traceback" not in text, text[-3000:]
    assert status == 1, text[-3000:]  # not every vehicle reached its goal (docs/reliability.md)
    modes = _heartbeat_modes(run_dir / "telemetry.tlog")
    assert LOITER in modes[2]
    assert LOITER not in modes[1] | modes[3]
    flight = json.loads((run_dir / "flight.json").read_text())
    (only,) = flight["link_stats"]["forwards"].values()
    assert only["routed"] >= 1 and only["commands_refused"] == 0
    (taken,) = flight["taken_over"]
    assert (taken["vehicle"], taken["mode"], taken["by"]) == ("right", "LOITER", "someone else")
    assert flight["arrived"] and flight["left_to_operator"] == ["right"]
    report = json.loads((run_dir / "report.json").read_text())
    reached = {v["name"]: v["reached"] for v in report["vehicles"]}
    assert reached == {"lead": True, "right": False, "left": True}
    assert report["collisions"] == 0 and not report["safety_events"], report["safety_events"]
    # after right's first LOITER heartbeat the ground station (255/190; MAVProxy is 255/230) sent it nothing
    log = mavutil.mavlink_connection(str(run_dir / "telemetry.tlog"))
    seen_loiter, after = False, []
    while (msg := log.recv_match()) is not None:
        if msg.get_srcSystem() == 2 and msg.get_type() == "HEARTBEAT" and msg.custom_mode == LOITER:
            seen_loiter = True
        elif seen_loiter and (msg.get_srcSystem(), msg.get_srcComponent()) == GCS and _target(msg) == 2:
            after.append(msg.get_type())
    assert seen_loiter and after == [], after


def test_on_a_signed_fleet_only_signed_forward_frames_reach_the_vehicles(tmp_path: Path) -> None:
    """Signed quickstart, read-write forward: the forward's unsigned LOITER for vehicle 2 and its unsigned
    parameter read never reach a vehicle; its read signed with the fleet's key does (vehicle 3 answers it)."""
    key = bytes(range(100, 132))
    key_file = tmp_path / "swarm.key"
    key_file.write_text(key.hex() + "\n")
    mission = derived_mission(
        tmp_path, "quickstart.yaml", "signed-forward", run={"signing_key_file": str(key_file)}
    )
    port = free_udp_base(1)
    client = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=250)
    signed = mavlink2.MAVLink(None, 250, 190)
    signed.signing.secret_key, signed.signing.link_id, signed.signing.sign_outgoing = key, 1, True
    signed.signing.timestamp = timestamp_now()
    answered: set[str] = set()
    stop = threading.Event()

    def watch() -> None:
        asked = False
        while not stop.is_set():
            msg = client.recv_match(type=["HEARTBEAT", "PARAM_VALUE"], blocking=True, timeout=0.2)
            if msg is None:
                continue
            if msg.get_type() == "PARAM_VALUE" and msg.get_srcSystem() == 3:
                answered.add(msg.param_id)
            elif not asked and msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 3:
                client.mav.command_long_send(2, 1, mavlink2.MAV_CMD_DO_SET_MODE, 0, 1, LOITER, 0, 0, 0, 0, 0)
                client.mav.param_request_read_send(3, 1, b"ANGLE_MAX", -1)
                client.write(signed.param_request_read_encode(3, 1, b"LAND_SPEED", -1).pack(signed))
                asked = True

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        run = fly(mission, tmp_path / "run", extra=[f"--forward=udpout:127.0.0.1:{port}", "--forward-rw"])
    finally:
        stop.set()
        watcher.join(5)
        client.close()
    assert run.status == 0, run.output[-3000:]
    assert "LAND_SPEED" in answered and "ANGLE_MAX" not in answered  # the ground station reads neither
    assert LOITER not in _heartbeat_modes(run.run_dir / "telemetry.tlog")[2]
    stats = json.loads((run.run_dir / "flight.json").read_text())["link_stats"]
    (forward,) = stats["forwards"].values()
    assert (forward["unsigned"], forward["routed"]) == (2, 1)
    assert all(v["unsigned"] == 0 and v["bad_signature"] == 0 for v in stats["vehicles"].values())
