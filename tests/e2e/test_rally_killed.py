"""Rally points used by the autopilots' own RTL when the ground station dies (issue 37 item 5): the quickstart
with `gcs_failsafe: rtl` and three rally points, the ground station SIGKILLed one second into formation flight
(the `assembling` moment). Each vehicle was given its own point in preflight (geofence.rally_by_vehicle: the
least total distance from the starts) with RALLY_INCL_HOME 0 and RALLY_LIMIT_KM 0, so its GCS failsafe RTL
(FS_GCS_ENABLE 1) flies there, not to its home, and lands; no two land on each other (a shared list sends
all three to the one nearest point: seen before the points were shared out). The simulator exits by itself.

Which point is whose, by hand from the starts (ENU m): lead (0, 0) - (25, 20) 32.0 m, right (-1.5, -10) -
(10, -35) 27.5 m, left (-10, 1.5) - (-35, 10) 26.4 m, 85.9 m in all, the least of the six one-to-one choices
(tests/gcs_swarm/flight/test_geofence_site.py). The three paths diverge."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from gcs_swarm.evaluation.gcs_kill import fly_and_kill
from gcs_swarm.evaluation.run_data import load_truth
from swarm_common.ports import free_udp_base
from tests.e2e.flights import ROOT, derived_mission, fly

RALLY = {"lead": (25.0, 20.0), "right": (10.0, -35.0), "left": (-35.0, 10.0)}  # ENU m, 15 m up
ORDER = ("lead", "right", "left")  # the quickstart's vehicle order


def test_gcs_killed_rtl_lands_each_vehicle_at_its_nearest_rally_point(tmp_path: Path) -> None:
    mission = derived_mission(
        tmp_path,
        "quickstart.yaml",
        "rally_killed",
        safety={"gcs_failsafe": "rtl", "rally": [[x, y, 15.0] for x, y in RALLY.values()]},
    )
    reference = fly(mission, tmp_path / "reference", timeout_s=300)
    assert reference.status == 0, reference.output[-2000:]
    flight = json.loads((tmp_path / "reference" / "flight.json").read_text())
    assert any(c["name"] == "rally items" and c["restored"] for c in flight["params_changed"])
    outcome = fly_and_kill(
        mission, tmp_path / "killed", flight["t_formation_start"] + 1.0, free_udp_base(3), cwd=ROOT
    )
    assert outcome.simulator_exit_s is not None, "the orphaned simulator is still running"
    assert outcome.crashed == 0 and outcome.ends == ("landed",) * 3, outcome
    final = load_truth(tmp_path / "killed" / "truth.csv").pos[-1]
    for k, name in enumerate(ORDER):
        # RTL descends once within 1 m of its point (sitl_sim outer_loop RTL_REACHED_M); 2 m allows the
        # landing's own drift
        assert np.hypot(*(final[k, :2] - RALLY[name])) < 2.0, (name, final[k])
