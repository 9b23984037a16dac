"""A formation of ArduCopter and PX4 vehicles (missions/mixed_fleet.yaml) flown end to end against the
embedded simulator, each vehicle answering as its autopilot does: the same guidance flies them all, each
autopilot is launched its own way (GUIDED takeoff; PX4's AUTO.TAKEOFF, AUTO.LOITER, then OFFBOARD over a
setpoint stream), and the report names each vehicle's autopilot."""

from __future__ import annotations

import json
from pathlib import Path

from pymavlink import mavutil

from gcs_swarm.link.autopilots import ARDUPILOT, PX4
from tests.e2e.flights import MISSIONS, SHORT_BOOT, fly

D_EMG = 3.0  # m, the mission's safety.separation.d_emg (default)


def _mode_sequences(tlog: Path) -> dict[int, list[str]]:
    """sysid -> the flight modes its HEARTBEATs showed, in order, repeats removed, named in its dialect."""
    log = mavutil.mavlink_connection(str(tlog))
    modes: dict[int, list[str]] = {}
    while (msg := log.recv_match(type="HEARTBEAT")) is not None:
        if msg.type == mavutil.mavlink.MAV_TYPE_GCS:
            continue
        dialect = PX4 if msg.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4 else ARDUPILOT
        seen = modes.setdefault(msg.get_srcSystem(), [])
        name = dialect.mode_name(msg.custom_mode)
        if not seen or seen[-1] != name:
            seen.append(name)
    return modes


def _stream_before_offboard_s(tlog: Path, sysid: int) -> tuple[float, float]:
    """The setpoint stream the ground station sent `sysid` right before its first request for OFFBOARD
    (MAV_CMD_DO_SET_MODE, param2 = main mode 6): its span and longest gap, vehicle s (time_boot_ms)."""
    log = mavutil.mavlink_connection(str(tlog))
    stamps: list[int] = []
    types = ["SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET", "COMMAND_LONG"]
    while (msg := log.recv_match(type=types)) is not None:
        if msg.target_system != sysid:
            continue
        if msg.get_type() != "COMMAND_LONG":
            stamps.append(msg.time_boot_ms)
        elif msg.command == mavutil.mavlink.MAV_CMD_DO_SET_MODE and msg.param2 == 6:
            break
    else:
        raise AssertionError(f"no OFFBOARD request to sysid {sysid}")
    recent = [t for t in stamps if t >= stamps[-1] - 5000]  # the stream right before the request
    gaps = [b - a for a, b in zip(recent, recent[1:], strict=False)]
    return (recent[-1] - recent[0]) / 1000.0, max(gaps, default=0) / 1000.0


def _in_order(sequence: list[str], wanted: list[str]) -> bool:
    it = iter(sequence)
    return all(mode in it for mode in wanted)


def test_mixed_fleet_flies_one_formation(tmp_path: Path) -> None:
    run = fly(MISSIONS / "mixed_fleet.yaml", tmp_path / "run", timeout_s=300, extra=[SHORT_BOOT])
    assert run.status == 0, run.output[-3000:]
    report = run.report
    assert report["reached"] and report["collisions"] == 0
    assert report["min_separation_m"] > D_EMG
    flight = json.loads((run.run_dir / "flight.json").read_text())
    expected = {"lead": "ArduCopter", "px4_right": "PX4", "apm_left": "ArduCopter", "px4_tail": "PX4"}
    assert flight["autopilots"] == expected
    assert {v["name"]: v["autopilot"] for v in report["vehicles"]} == expected
    assert "| px4_tail | PX4 |" in (run.run_dir / "report.md").read_text()
    # each autopilot launched its own way, and landed (sysid i + 1 in the embedded simulator)
    modes = _mode_sequences(run.run_dir / "telemetry.tlog")
    for sysid in (1, 3):
        assert _in_order(modes[sysid], ["GUIDED", "LAND"]), modes[sysid]
    for sysid in (2, 4):
        assert _in_order(modes[sysid], ["LOITER", "TAKEOFF", "LOITER", "OFFBOARD", "LAND"]), modes[sysid]
        # PX4 takes OFFBOARD only over a live setpoint stream: the ground station streamed first (1.5 s)
        span, gap = _stream_before_offboard_s(run.run_dir / "telemetry.tlog", sysid)
        assert span >= 1.4 and gap <= 0.1, (span, gap)  # 1.5 s of setpoints, one per 20 ms frame
    # every parameter the run set was put back, each in its autopilot's own names and encoding
    changed = {(c["vehicle"], c["name"]): c for c in flight["params_changed"]}
    assert all(c["restored"] for c in changed.values()), changed
    assert ("px4_right", "NAV_DLL_ACT") in changed and ("lead", "FS_GCS_ENABLE") in changed
    assert ("px4_right", "GUID_OPTIONS") not in changed and ("lead", "NAV_DLL_ACT") not in changed
    assert changed[("px4_right", "NAV_DLL_ACT")]["flown"] == 3  # Land (the mission's gcs_failsafe)
