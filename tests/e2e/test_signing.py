"""Signed MAVLink end to end: the ground station, pointed at a key by the mission file, flies the quickstart
against the embedded simulator started with the same key (lockstep); no file of the run holds the key."""

from __future__ import annotations

from pathlib import Path

from pymavlink import mavutil

from tests.e2e.flights import derived_mission, fly

KEY = bytes(range(100, 132))


def test_signed_ground_station_flies_the_quickstart(tmp_path: Path) -> None:
    key_file = tmp_path / "swarm.key"
    key_file.write_text(KEY.hex() + "\n")
    mission = derived_mission(
        tmp_path, "quickstart.yaml", "signed-quickstart", run={"signing_key_file": str(key_file)}
    )
    run = fly(mission, tmp_path / "run", timeout_s=300)
    assert run.status == 0, run.output[-3000:]
    assert run.report["reached"] is True and run.report["collisions"] == 0
    assert KEY.hex() not in run.output
    log = mavutil.mavlink_connection(str(run.run_dir / "telemetry.tlog"))
    signed = {}
    while (msg := log.recv_match()) is not None:
        signed.setdefault((msg.get_srcSystem(), msg.get_type()), set()).add(
            bool(msg.get_msgbuf()[2] & mavutil.mavlink.MAVLINK_IFLAG_SIGNED)
        )
    assert signed[(255, "SET_ATTITUDE_TARGET")] == {True}  # the ground station signs its commands
    assert signed[(255, "COMMAND_LONG")] == {True}
    assert signed[(1, "GLOBAL_POSITION_INT")] == {True}  # the vehicles sign their telemetry
    for path in run.run_dir.iterdir():
        content = path.read_bytes()
        assert KEY not in content and KEY.hex().encode() not in content, path.name
