"""The ground station killed (SIGKILL) mid-flight at the worst moments: from the simulator's ground truth, no
vehicle touches anything, every one ends landed or holding (the GCS failsafe: BRAKE, docs/reliability.md),
the embedded simulator lands or holds them and then exits by itself (nothing is left running), and the logs
are intact up to the kill.

Kill moments are found on an undisturbed lockstep run of the same mission (the flight repeats exactly up to
the kill; gcs_swarm/evaluation/gcs_kill.kill_moments): (a) the moment a vehicle at speed is closest in time to
an obstacle along its course, (b) the leader's closest pass of an obstacle (mid avoidance), (c) one second
into formation flight while the followers are still assembling."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pymavlink import mavutil

from gcs_swarm.evaluation.gcs_kill import fly_and_kill, kill_moments
from swarm_common.ports import free_udp_base
from tests.e2e.flights import ROOT, derived_mission, fly, static6_short

D_EMG = 3.0  # m, the missions' safety.separation.d_emg


def _reference(mission: Path, folder: Path) -> dict[str, float]:
    run = fly(mission, folder / "reference", timeout_s=300)
    assert run.status == 0, run.output[-2000:]
    data = json.loads((folder / "reference" / "flight.json").read_text())
    return kill_moments(folder / "reference", data["t_formation_start"], data["t_formation_end"])


@pytest.fixture(scope="module")
def quickstart_moments(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, float]]:
    folder = tmp_path_factory.mktemp("quickstart_killed")
    mission = derived_mission(folder, "quickstart.yaml", "killed")  # a copy: same flight, own run folders
    return mission, _reference(mission, folder)


@pytest.fixture(scope="module")
def mixed_moments(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, float]]:
    folder = tmp_path_factory.mktemp("mixed_killed")
    mission = derived_mission(folder, "mixed_fleet.yaml", "mixed_killed")
    return mission, _reference(mission, folder)


@pytest.fixture(scope="module")
def static6_moments(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, float]]:
    folder = tmp_path_factory.mktemp("static6_killed")
    mission = static6_short(folder, "static6_killed")
    return mission, _reference(mission, folder)


def _killed_at(mission: Path, run_dir: Path, t_kill: float, vehicles: int) -> None:
    outcome = fly_and_kill(mission, run_dir, t_kill, free_udp_base(vehicles), cwd=ROOT)
    assert outcome.simulator_exit_s is not None, "the orphaned simulator is still running"
    assert outcome.crashed == 0, outcome
    assert outcome.separation_after_m >= D_EMG, outcome
    assert all(end in ("landed", "holding") for end in outcome.ends), outcome.ends
    assert outcome.record_to_kill, "record.csv does not reach the kill"
    log = mavutil.mavlink_connection(str(run_dir / "telemetry.tlog"))
    count = 0
    while log.recv_match() is not None:
        count += 1
    assert count > 500  # the tlog reads back to its end


@pytest.mark.parametrize("moment", ["heading_at_obstacle", "mid_avoidance", "assembling"])
def test_quickstart_killed_at_the_worst_moments(
    moment: str, quickstart_moments: tuple[Path, dict[str, float]], tmp_path: Path
) -> None:
    mission, moments = quickstart_moments
    _killed_at(mission, tmp_path / "run", moments[moment], 3)


@pytest.mark.parametrize("moment", ["heading_at_obstacle", "mid_avoidance", "assembling"])
def test_mixed_ardupilot_px4_fleet_killed_at_the_worst_moments(
    moment: str, mixed_moments: tuple[Path, dict[str, float]], tmp_path: Path
) -> None:
    """PX4 vehicles fly their last OFFBOARD target for COM_OF_LOSS_T, then Land (COM_OBL_RC_ACT); the
    ArduCopters level after GUID_TIMEOUT, then Land on FS_GCS_TIMEOUT: none touches anything."""
    mission, moments = mixed_moments
    _killed_at(mission, tmp_path / "run", moments[moment], 4)


@pytest.mark.parametrize("moment", ["mid_avoidance", "assembling"])
def test_six_uav_paper_mission_killed_at_the_worst_moments(
    moment: str, static6_moments: tuple[Path, dict[str, float]], tmp_path: Path
) -> None:
    mission, moments = static6_moments
    _killed_at(mission, tmp_path / "run", moments[moment], 6)
