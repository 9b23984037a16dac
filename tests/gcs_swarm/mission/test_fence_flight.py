"""The site fence flies (issue 37 item 5): a mission with an inclusion polygon and an exclusion polygon beside
the route, uploaded to the simulated autopilots too, loads to fly, flies in lockstep (`gcs-swarm run` and the
simulator on 127.0.0.1 free ports) to its goal, and its ground truth never crosses the fence. Also the
report's fence figures on hand-made tracks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gcs_swarm.evaluation.fence_figures import fence_figures
from gcs_swarm.mission import MissionError, parse_mission
from tests.e2e.flights import SHORT_BOOT, fly

# The leader flies east from (0, 0) to (60, 0) at 10 m, its followers in a V (spacing 10 m, half-angle 45 deg:
# slots (-7.07, -+7.07), 10 m from it). The fence (a pentagon) is 25 m south of the leg and 30 m west of
# the start / east of the goal; the "hangar" exclusion square stands 20 m north of the leg, so the left
# follower passes 20 - 7.07 = 12.9 m from it. The formation needs 10 + 0.175 + 10^2 / (2 * 9.8 * tan 35 deg)
# = 17.46 m beside the leg (checks.fence_reach): 20 and 25 m leave it.
FENCED = """
mission: {name: fenced}
run: {time_limit_s: 120}
vehicles:
  - {name: lead, role: leader, start: {position: [0, 0, 0], yaw_deg: 0}}
  - {name: right, start: {position: [-7, -7, 0], yaw_deg: 0}}
  - {name: left, start: {position: [-7, 7, 0], yaw_deg: 0}}
goal: [60, 0, 10]
safety:
  geofence:
    polygon: [[-30, -25], [90, -25], [90, 30], [30, 40], [-30, 30]]
    exclusions:
      - {name: hangar, polygon: [[20, 20], [40, 20], [40, 30], [20, 30]]}
    upload: true
"""


def test_a_fenced_mission_loads_to_fly() -> None:
    mission = parse_mission(FENCED)
    assert mission.fence.polygon is not None and len(mission.fence.exclusions) == 1


def test_the_hangar_moved_onto_the_route_is_refused_for_flight() -> None:
    # 15 m north of the leg: less than the 17.46 m the formation needs
    with pytest.raises(
        MissionError, match=r"goal: the leg .* comes within 15.00 m of exclusion zone 'hangar'"
    ):
        parse_mission(
            FENCED.replace("[[20, 20], [40, 20], [40, 30], [20, 30]]", "[[20, 15], [40, 15], [40, 30]]")
        )


def test_upload_without_a_site_fence_is_one_clear_error() -> None:
    text = FENCED.split("safety:")[0] + "safety: {geofence: {upload: true}}\n"
    with pytest.raises(MissionError, match=r"safety.geofence.upload: there is no site fence to upload"):
        parse_mission(text)


def test_fence_figures_count_entries_and_the_closest_approach() -> None:
    # one vehicle: inside, 2 m into the hangar (y = 22, edge y = 20), out, in again at (30, 21): 2 entries;
    # the other stays 5 m inside the south edge (y = -20 against -25); closest: -2 m (2 m into the hangar)
    pos = np.full((5, 2, 3), 10.0)
    pos[:, 0, :2] = [[30, 10], [30, 22], [30, 10], [30, 21], [30, 10]]
    pos[:, 1, :2] = [[0, -20]] * 5
    pos[2, 1] = np.nan  # a missing sample is skipped
    mission = parse_mission(FENCED)
    assert fence_figures(pos, mission) == {"fence_breaches": 2, "min_fence_margin_m": -2.0}
    pos[:, 0, :2] = [[30, 10]] * 5  # 10 m from the hangar, 5 m from the south edge: no breach, 5 m
    assert fence_figures(pos, mission) == {"fence_breaches": 0, "min_fence_margin_m": 5.0}
    pos[0, 1, :2] = [95, 0]  # 5 m east of the fence polygon at the first sample: one breach
    assert fence_figures(pos, mission) == {"fence_breaches": 1, "min_fence_margin_m": -5.0}


def test_a_mission_without_a_site_fence_gets_no_fence_figures() -> None:
    mission = parse_mission(FENCED.split("safety:")[0])
    assert fence_figures(np.zeros((3, 3, 3)), mission) == {}


@pytest.mark.e2e
def test_the_fenced_mission_reaches_its_goal_without_a_fence_breach(tmp_path: Path) -> None:
    path = tmp_path / "fenced.yaml"
    path.write_text(FENCED)
    flight = fly(path, tmp_path / "run", extra=["--time-mode", "lockstep", SHORT_BOOT])
    assert flight.status == 0, flight.output[-2000:]
    report = flight.report
    assert report["reached"] and report["collisions"] == 0, flight.output[-2000:]
    assert report["fence_breaches"] == 0
    # the autopilots had the fence too (upload: true) and never took over
    assert any("the site fence (9 items) on every vehicle" in line for line in flight.output.splitlines())
    assert not [event for event in report["events"] if "breached" in event]
    # the left follower's lane is 20 - 7.07 = 12.9 m from the hangar; it and the others keep well clear
    assert report["min_fence_margin_m"] > 5.0
