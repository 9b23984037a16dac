"""A report that never crashes (issue 38 item 4), end to end: the real `gcs-swarm run` flies the quickstart
(3 vehicles) in lockstep against the real simulator with a read-write forward, and a pymavlink client on that
forward takes the follower "left" to LOITER while it climbs, before the formation phase. The ground station
leaves left to its operator and flies the other two; the run used to end in `KeyError:
'trend_first_settled_s'` with no report (left had no commanded attitude in the formation phase). It must
end with report.json, report.md and report.png written and exit status 1 (not every vehicle reached its goal,
docs/reliability.md "Operator takeover")."""

from __future__ import annotations

import json
import threading
from pathlib import Path

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.ports import free_udp_base
from tests.e2e.flights import MISSIONS, fly

LEFT_SYSID = 3  # quickstart: lead 1, right 2, left 3
LOITER = 5  # ArduCopter custom_mode (ArduCopter/mode.h)
CLIMBING_MM = 2000  # relative_alt above which left is in the air and climbing (formation altitude 10 m)


class ClimbTakeover:
    """A pymavlink client (sysid 250) on the ground station's read-write forward. Once left reports
    GLOBAL_POSITION_INT with relative_alt above CLIMBING_MM it sends DO_SET_MODE LOITER to left, again at
    every HEARTBEAT of left that is not yet LOITER; `relative_alt_mm` keeps the altitude it acted at and
    `confirmed` whether a HEARTBEAT of left showed LOITER afterwards."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=250)
        self.relative_alt_mm: int | None = None
        self.confirmed = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self.conn.close()

    def _loiter(self) -> None:
        self.conn.mav.command_long_send(
            LEFT_SYSID, 1, mavlink2.MAV_CMD_DO_SET_MODE, 0, 1, LOITER, 0, 0, 0, 0, 0
        )

    def _run(self) -> None:
        while not self._stop.is_set():
            msg = self.conn.recv_match(type=["GLOBAL_POSITION_INT", "HEARTBEAT"], blocking=True, timeout=0.2)
            if msg is None or msg.get_srcSystem() != LEFT_SYSID:
                continue
            if msg.get_type() == "GLOBAL_POSITION_INT":
                if self.relative_alt_mm is None and msg.relative_alt > CLIMBING_MM:
                    self.relative_alt_mm = int(msg.relative_alt)
                    self._loiter()
            elif self.relative_alt_mm is not None and not self.confirmed:
                if msg.custom_mode == LOITER:
                    self.confirmed = True
                else:
                    self._loiter()


def test_a_follower_taken_over_while_it_climbs_still_gets_a_report(tmp_path: Path) -> None:
    port = free_udp_base(1)
    client = ClimbTakeover(port)
    client.start()
    try:
        run = fly(
            MISSIONS / "quickstart.yaml",
            tmp_path / "run",
            timeout_s=400,
            extra=[f"--forward=udpout:127.0.0.1:{port}", "--forward-rw"],
        )
    finally:
        client.stop()
    assert "Traceback" not in run.output, run.output[-3000:]
    assert client.relative_alt_mm is not None and client.confirmed, "left was never taken to LOITER"
    flight = json.loads((run.run_dir / "flight.json").read_text())
    (taken,) = flight["taken_over"]
    assert (taken["vehicle"], taken["mode"]) == ("left", "LOITER")
    # taken before the formation phase began (the reported case), and the formation phase did begin
    assert flight["t_formation_start"] is not None and taken["t_s"] < flight["t_formation_start"]
    assert run.status == 1, run.output[-3000:]  # not every vehicle reached its goal (docs/reliability.md)
    for name in ("report.json", "report.md", "report.png"):
        assert (run.run_dir / name).stat().st_size > 0, name
    report = json.loads((run.run_dir / "report.json").read_text())
    reached = {v["name"]: v["reached"] for v in report["vehicles"]}
    assert reached == {"lead": True, "right": True, "left": False}
    # left was never commanded in formation flight: its command-rate figures are absent (None), not made up
    left = next(v for v in report["command_rates"]["vehicles"] if v["name"] == "left")
    assert all(value is None for value in left["pitch_rate"].values()), left
