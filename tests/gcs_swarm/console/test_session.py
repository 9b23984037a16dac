"""The flight thread keeps the table live: snapshots go on being published while a blocking command runs; a
command handler that raises (a bug) leaves its traceback in the run folder's errors.log, a bad command gets
one sentence and no traceback.

Three simulated ArduCopters (one real-time sitl_sim for the module, free ports on 127.0.0.1, so vehicle time
runs with the wall clock; each test talks to them through its own wire taps) behind the quickstart mission's
Fleet and MissionRunner.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from gcs_swarm.console import session as session_module
from gcs_swarm.console.commands import Request
from gcs_swarm.console.session import FlightSession
from gcs_swarm.console.snapshot import Snapshot
from gcs_swarm.evaluation.error_log import ERRORS_FILE
from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.fleet import Fleet, VehicleConfig
from gcs_swarm.mission import load_mission
from tests.gcs_swarm.link.simulated_vehicles import ORIGIN, SimulatedVehicles, reap, start_vehicles
from tests.gcs_swarm.link.wire_tap import WireTap

MISSIONS = Path(__file__).resolve().parents[3] / "missions"


@pytest.fixture(scope="module")
def vehicles() -> Iterator[SimulatedVehicles]:
    """The quickstart's three vehicles (sysids 1-3) in a real-time simulator, ready at once; terminated after
    the module (tests share it: without lockstep a finished client holds nothing up)."""
    sim = start_vehicles(3, "--ready-delay", "0")
    try:
        yield sim
    finally:
        sim.sim.proc.terminate()
        reap([sim.sim.proc])


@pytest.fixture
def session(vehicles: SimulatedVehicles, tmp_path: Path) -> Iterator[tuple[FlightSession, list[WireTap]]]:
    """A connected FlightSession over the three vehicles, each behind a wire tap, with its run folder in
    tmp_path, stopped and closed afterwards."""
    mission = load_mission(MISSIONS / "quickstart.yaml")
    taps = [vehicles.tap(k) for k in range(len(mission.vehicles))]  # vehicle k has sysid k + 1
    configs = [
        VehicleConfig(v.name, t.connection, v.sysid) for v, t in zip(mission.vehicles, taps, strict=True)
    ]
    fleet = Fleet(configs, ORIGIN)
    flight = FlightSession(
        # the timeouts only bound a hang: a loaded CI machine once took over 5 s to relay the first HEARTBEAT
        MissionRunner(mission, fleet, None, progress=lambda _: None),
        tmp_path,
        connect_timeout_s=15.0,
    )
    try:
        flight.start()
        end = time.monotonic() + 20.0
        while flight.snapshot().state == "connecting" and time.monotonic() < end:
            time.sleep(0.02)
        assert flight.snapshot().state == "ready", flight.snapshot().error
        yield flight, taps
    finally:
        flight.stop()
        fleet.close()
        vehicles.close_taps()


def test_snapshots_keep_coming_while_a_command_blocks(
    session: tuple[FlightSession, list[WireTap]],
) -> None:
    """`param get` whose first answer is lost blocks for its 1 s retry timeout; meanwhile the table's figures
    (vehicle time, packet age) and the command's elapsed time keep being republished."""
    flight, taps = session
    taps[0].drop_downlink("PARAM_VALUE", 1)
    ticket = flight.submit(Request("param_get", "param get MOT_THST_HOVER lead", (0,), name="MOT_THST_HOVER"))
    seen: list[Snapshot] = []
    while not ticket.wait(0.01):
        snapshot = flight.snapshot()
        if snapshot.mission.busy and (not seen or snapshot is not seen[-1]):
            seen.append(snapshot)
    assert ticket.ok
    assert {s.mission.busy for s in seen} == {"param get MOT_THST_HOVER lead"}
    times = [s.mission.vehicle_time for s in seen]
    assert len(set(times)) > 2 and times == sorted(times)  # published over and over, not once per command
    assert times[-1] - times[0] > 0.5  # ... through the 1 s wait, not just at its ends
    elapsed = [s.mission.busy_s for s in seen]
    assert elapsed == sorted(elapsed) and elapsed[-1] > 0.5
    assert not flight.snapshot().mission.busy  # cleared once the command is done


def test_a_handler_that_raises_leaves_its_traceback_in_errors_log(
    session: tuple[FlightSession, list[WireTap]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A bug in a command handler ends the flight session as before, but its full traceback is in
    <run folder>/errors.log and the one line the operator sees names that file."""
    flight, _ = session

    def broken_handler(_session: FlightSession, _request: Request) -> bool:
        raise KeyError("slot 7")

    monkeypatch.setitem(session_module._HANDLERS, "hold", broken_handler)
    ticket = flight.submit(Request("hold", "hold"))
    assert ticket.wait(10.0), "the ticket of the failed command was never finished"
    assert not ticket.ok
    errors = tmp_path / ERRORS_FILE
    log = errors.read_text()
    assert "Traceback (most recent call last)" in log
    assert "in broken_handler" in log and "KeyError: 'slot 7'" in log
    flight.stop()
    snapshot = flight.snapshot()
    assert snapshot.state == "failed"
    assert snapshot.error.count("\n") == 0 and f"traceback in {errors}" in snapshot.error
    assert "Traceback" not in snapshot.error


def test_a_bad_command_is_one_sentence_and_no_traceback(
    session: tuple[FlightSession, list[WireTap]], tmp_path: Path
) -> None:
    """`hold` before the mission flies is the operator's mistake: refused in one sentence, nothing logged."""
    flight, _ = session
    ticket = flight.submit(Request("hold", "hold"))
    assert ticket.wait(10.0) and not ticket.ok
    refusals = [e for e in flight.events_after(0) if e.level == "error"]
    assert [e.text for e in refusals] == ["hold needs formation flight; the mission is in phase connect"]
    assert flight.snapshot().state == "ready"
    assert not (tmp_path / ERRORS_FILE).exists()
