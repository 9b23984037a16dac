"""EmbeddedSimulator.start's `while_starting`: work of the ground station done while the simulator starts,
and a simulator stopped when that work fails (nothing left running)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_swarm.flight.embedded_sim import EmbeddedSimulator
from gcs_swarm.mission.loader import load_mission
from swarm_common.ports import free_udp_base

ROOT = Path(__file__).resolve().parents[3]

pytestmark = pytest.mark.sim


def embedded(tmp_path: Path) -> EmbeddedSimulator:
    mission = load_mission(ROOT / "missions" / "quickstart.yaml")
    return EmbeddedSimulator(
        mission,
        base_port=free_udp_base(len(mission.vehicles)),
        truth_log=tmp_path / "truth.csv",
        time_mode="lockstep",
    )


def test_work_while_starting_runs_with_the_simulator_launched(tmp_path):
    sim = embedded(tmp_path)
    seen = []
    try:
        sim.start(
            timeout_s=60.0, while_starting=lambda: seen.append(sim.proc is not None and sim.proc.poll())
        )
        assert seen == [None]  # called once, the simulator's process launched and running
        assert "READY" in sim.output and sim.proc is not None and sim.proc.poll() is None
    finally:
        sim.stop()
    assert sim.proc.poll() is not None


def test_a_failure_while_starting_stops_the_simulator(tmp_path):
    sim = embedded(tmp_path)

    def fail() -> None:
        raise RuntimeError("no kernels")

    with pytest.raises(RuntimeError, match="no kernels"):
        sim.start(timeout_s=60.0, while_starting=fail)
    assert sim.proc is not None and sim.proc.poll() is not None  # stopped, not left running


def test_the_mission_spin_goes_to_the_simulator_in_lockstep_only(tmp_path):
    """run.simulator.lockstep_spin_us reaches `sitl-sim --lockstep-spin-us` (the simulator's own default is
    the same 1000 us; the mission's value wins), and a real-time simulator gets none."""
    mission = load_mission(ROOT / "missions" / "quickstart.yaml")
    lockstep = EmbeddedSimulator(mission, base_port=20000, truth_log=None, time_mode="lockstep")
    k = lockstep.args.index("--lockstep-spin-us")
    assert float(lockstep.args[k + 1]) == mission.run.simulator.lockstep_spin_us == 1000.0
    realtime = EmbeddedSimulator(mission, base_port=20000, truth_log=None, time_mode="realtime")
    assert "--lockstep-spin-us" not in realtime.args
