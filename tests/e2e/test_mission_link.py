"""The bundled missions/quickstart_faulty.yaml: its world.link faults reach the embedded simulator through
`--mission`, and the ground station still brings the formation home."""

from __future__ import annotations

import json
import re
from pathlib import Path

from tests.e2e.flights import MISSIONS, fly


def test_quickstart_faulty_flies_through_the_link_faults_of_its_mission_file(tmp_path: Path) -> None:
    run = fly(MISSIONS / "quickstart_faulty.yaml", tmp_path / "run", timeout_s=300)
    assert run.status == 0, run.output[-2000:]
    assert run.report["reached"] and run.report["collisions"] == 0
    lost = [int(n) for n in re.findall(r"link_lost=(\d+)", (run.run_dir / "simulator.log").read_text())]
    assert len(lost) == 3 and min(lost) > 0  # no --link-* flag was given: the faults came from the file
    flight = json.loads((run.run_dir / "flight.json").read_text())
    assert run.report["commands_limited"] == flight["commands_limited"] >= 0
