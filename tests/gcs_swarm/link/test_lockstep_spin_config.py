"""Where the ground station's spin comes from: run.simulator.lockstep_spin_us, used only with the embedded
simulator in lockstep (gcs_swarm.flight.fly.lockstep_spin_s), down to the fleet's network."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from gcs_swarm.flight.fly import lockstep_spin_s, mission_fleet
from gcs_swarm.mission import MissionError, load_mission

QUICKSTART = Path(__file__).resolve().parents[3] / "missions" / "quickstart.yaml"


def mission_with_simulator(tmp_path: Path, **simulator: object) -> Path:
    data = yaml.safe_load(QUICKSTART.read_text())
    data["run"].setdefault("simulator", {}).update(simulator)
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_default_is_1_ms_in_lockstep_with_the_embedded_simulator() -> None:
    mission = load_mission(str(QUICKSTART))
    assert mission.run.simulator.time_mode == "lockstep"
    assert lockstep_spin_s(mission, embedded=True) == pytest.approx(1e-3)


def test_no_spin_against_anything_but_a_lockstep_embedded_simulator(tmp_path: Path) -> None:
    mission = load_mission(str(QUICKSTART))
    assert lockstep_spin_s(mission, embedded=False) == 0.0  # real vehicles, an external simulator
    assert lockstep_spin_s(mission, embedded=True, time_mode="realtime") == 0.0  # --time-mode realtime
    realtime = load_mission(str(mission_with_simulator(tmp_path, time_mode="realtime")))
    assert lockstep_spin_s(realtime, embedded=True) == 0.0
    assert lockstep_spin_s(realtime, embedded=True, time_mode="lockstep") == pytest.approx(1e-3)


def test_mission_value_reaches_the_network(tmp_path: Path) -> None:
    mission = load_mission(str(mission_with_simulator(tmp_path, lockstep_spin_us=120)))
    fleet = mission_fleet(mission, 14540, tmp_path, None, lockstep_spin_s(mission, embedded=True))
    assert fleet.network.spin_s == pytest.approx(120e-6)
    fleet.close()
    off = load_mission(str(mission_with_simulator(tmp_path, lockstep_spin_us=0)))
    assert lockstep_spin_s(off, embedded=True) == 0.0


@pytest.mark.parametrize("value", [-1, 20001, "fast"])
def test_out_of_range_is_a_mission_error(tmp_path: Path, value: object) -> None:
    with pytest.raises(MissionError, match="lockstep_spin_us"):
        load_mission(str(mission_with_simulator(tmp_path, lockstep_spin_us=value)))
