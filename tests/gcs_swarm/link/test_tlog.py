"""The fleet's .tlog holds both directions and is readable by pymavlink (in a child process, because
pymavlink's log reader switches its global dialect to MAVLink 2 when it meets a MAVLink 2 packet)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

from gcs_swarm.link.tlog import TlogWriter

READER = """
import collections, json, sys
from pymavlink import mavutil
log = mavutil.mavlink_connection(sys.argv[1])
counts, stamps = collections.Counter(), []
while (m := log.recv_match()) is not None:
    if m.get_type() != "BAD_DATA":
        counts[f"{m.get_srcSystem()}:{m.get_type()}"] += 1
        stamps.append(m._timestamp)
ordered = stamps == sorted(stamps)
print(json.dumps({"counts": counts, "first": stamps[0], "last": stamps[-1], "sorted": ordered}))
"""


def read_tlog(path: Path) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", READER, str(path)], capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


def test_fleet_tlog_records_sent_and_received_packets(simulator, fleet_of, tmp_path: Path) -> None:
    path = tmp_path / "run" / "flight.tlog"
    started = time.time()
    fleet = fleet_of(simulator(1).tap(0), names=["lead"], tlog_path=path)
    fleet.connect(timeout_s=10.0)
    for _ in range(10):
        assert fleet.wait_tick(timeout_s=2.0)
        fleet.send_attitude_targets([0.0], [0.0], [0.0], [0.5])
    fleet.close()
    log = read_tlog(path)
    counts = log["counts"]
    assert counts["255:HEARTBEAT"] >= 1 and counts["255:COMMAND_LONG"] >= 5
    assert counts["255:SET_ATTITUDE_TARGET"] == 10
    assert (
        counts["1:HEARTBEAT"] >= 1 and counts["1:GLOBAL_POSITION_INT"] >= 10 and counts["1:COMMAND_ACK"] >= 5
    )
    assert log["sorted"] and started - 1 <= log["first"] <= log["last"] <= time.time() + 1


def test_tlog_writer_format(tmp_path: Path) -> None:
    path = tmp_path / "x.tlog"
    with TlogWriter(path) as tlog:
        tlog.write(b"\xfe\x09\x00\x01\x01\x00" + bytes(11), unix_time_s=1.5)
    data = path.read_bytes()
    assert data[:8] == (1_500_000).to_bytes(8, "big") and len(data) == 8 + 17


def test_mavlogdump_reads_the_fleet_tlog(simulator, fleet_of, tmp_path: Path) -> None:
    mavlogdump = Path(sys.executable).parent / "mavlogdump.py"  # installed with pymavlink into the venv
    assert mavlogdump.is_file(), f"{mavlogdump} is missing: pymavlink installs it"
    path = tmp_path / "flight.tlog"
    fleet = fleet_of(simulator(1).tap(0), tlog_path=path)
    fleet.connect(timeout_s=10.0)
    fleet.run([fleet.vehicle(0).parameters.op_get("GUID_OPTIONS")])
    fleet.close()
    out = subprocess.run(
        [sys.executable, str(mavlogdump), "--types", "PARAM_VALUE", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0 and "GUID_OPTIONS" in out.stdout
