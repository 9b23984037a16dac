"""Where forwards come from: the mission's run.forward / run.forward_rw and the command line's --forward /
--forward-rw (gcs_swarm.flight.fly.with_forwards), down to the fleet's forward configs."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from gcs_swarm.flight.fly import mission_fleet, with_forwards
from gcs_swarm.link.forward import ForwardConfig
from gcs_swarm.mission import MissionError, load_mission

QUICKSTART = Path(__file__).resolve().parents[3] / "missions" / "quickstart.yaml"


def mission_with_run(tmp_path: Path, **run: object) -> Path:
    data = yaml.safe_load(QUICKSTART.read_text())
    data["run"].update(run)
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_mission_and_command_line_forwards_add_up(tmp_path: Path) -> None:
    mission = load_mission(str(mission_with_run(tmp_path, forward=["udpout:127.0.0.1:14550"])))
    assert (mission.run.forward, mission.run.forward_rw) == (("udpout:127.0.0.1:14550",), False)
    mission = with_forwards(mission, ("udpin:0.0.0.0:14551",), True)
    fleet = mission_fleet(mission, None, tmp_path, None)
    expected = [ForwardConfig("udpout:127.0.0.1:14550", True), ForwardConfig("udpin:0.0.0.0:14551", True)]
    assert fleet.network.forward_configs == expected
    fleet.close()


def test_no_forward_by_default() -> None:
    mission = load_mission(str(QUICKSTART))
    assert (mission.run.forward, mission.run.forward_rw) == ((), False)


def test_a_forward_that_is_no_connection_string_is_refused_with_its_line(tmp_path: Path) -> None:
    with pytest.raises(MissionError, match=r"run\.forward\[0\]: a connection string such as udpout"):
        load_mission(str(mission_with_run(tmp_path, forward=["14550"])))
