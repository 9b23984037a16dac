"""Reliability end to end: the real ground station flies the real simulator through degraded links."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from tests.e2e.flights import SHORT_BOOT, fly, static6_short

LAND = 9  # ArduCopter custom_mode: the GCS failsafe of the missions (safety.gcs_failsafe: land, the default)


def _lands_by_its_failsafe(track: np.ndarray, since: float) -> None:
    """After `since` (s) the vehicle is in LAND (its own GCS failsafe), stops and comes down where it is:
    it ends on the ground disarmed, and never crashed."""
    assert set(track["mode"][track["t"] > since].astype(int)) == {LAND}
    end = track[-1]
    assert end["landed"] == 1 and end["armed"] == 0, end
    assert track["crashed"].max() == 0


def _truth(run_dir: Path) -> np.ndarray:
    return np.genfromtxt(run_dir / "truth.csv", names=True, delimiter=",")


def test_follower_killed_mid_flight_leaves_the_rest_flying_and_reported(
    quickstart: Path, tmp_path: Path
) -> None:
    run = fly(
        quickstart, tmp_path / "run", timeout_s=300, extra=["--sim-arg=--link-outage=2@15:inf", SHORT_BOOT]
    )
    assert run.status == 1, run.output[-2000:]  # a vehicle was lost
    assert run.report["lost"] == ["left"]
    assert run.report["collisions"] == 0
    flight = json.loads((run.run_dir / "flight.json").read_text())
    assert flight["arrived"], flight["events"]
    truth = _truth(run.run_dir)
    targets = np.array(flight["final_targets"])
    formation_end = truth[np.isclose(truth["t"], round(flight["t_formation_end"] / 0.02) * 0.02)]
    for i in (0, 1):  # the others reached their slots while the lost one was away
        row = formation_end[formation_end["vehicle"] == i][0]
        assert np.linalg.norm([row["x"] - targets[i, 0], row["y"] - targets[i, 1]]) < 1.5
    _lands_by_its_failsafe(truth[truth["vehicle"] == 2], 15 + 3 + 0.5)  # FS_GCS_TIMEOUT 3 s after the outage


def test_leader_lost_mid_flight_hands_the_lead_on(quickstart: Path, tmp_path: Path) -> None:
    """The leader's link dies at 15 s: the lowest-index live vehicle ("right") takes the lead to the same goal
    and the other follower re-forms on it; the old leader does its own GCS failsafe (LAND where it is)."""
    run = fly(
        quickstart, tmp_path / "run", timeout_s=300, extra=["--sim-arg=--link-outage=0@15:inf", SHORT_BOOT]
    )
    assert run.status == 1, run.output[-2000:]  # a vehicle was lost
    assert run.report["lost"] == ["lead"] and run.report["collisions"] == 0
    flight = json.loads((run.run_dir / "flight.json").read_text())
    assert flight["arrived"] and flight["leader"] == 1, flight["events"]
    assert any("right takes the lead" in e for e in flight["events"])
    # the formation error follows the new leader and leaves the lost vehicle out (formation_timeline)
    assert [entry["leader"] for entry in flight["formation_timeline"]][-1] == 1
    assert run.report["formation_max_m"] < 2.0
    truth = _truth(run.run_dir)
    end = truth[np.isclose(truth["t"], round(flight["t_formation_end"] / 0.02) * 0.02)]
    new_leader = end[end["vehicle"] == 1][0]
    goal = np.array(flight["final_targets"])[1]
    assert np.linalg.norm([new_leader["x"] - goal[0], new_leader["y"] - goal[1]]) < 1.5
    assert goal.tolist() == [160.0, 120.0, 10.0]  # the mission's goal, now the new leader's
    _lands_by_its_failsafe(truth[truth["vehicle"] == 0], 15 + 3 + 0.5)


def test_six_uav_paper_mission_under_ten_percent_loss_and_100ms_jitter(tmp_path: Path) -> None:
    """Section 5.2.1 (shortened as in test_gcs_run) with the faults in the mission file's world.link."""
    mission = static6_short(tmp_path, "static6_faulty", link={"loss": 0.1, "jitter_ms": 100})  # power-on
    run = fly(mission, tmp_path / "run", timeout_s=500)
    assert run.status == 0, run.output[-3000:]
    assert run.report["reached"] and run.report["collisions"] == 0
    # never inside D_Emg (3 m); pairs may dip a little into the 10 m repulsion range (9.4-9.6 m measured)
    assert run.report["min_separation_m"] > 3.0
    flight = json.loads((run.run_dir / "flight.json").read_text())
    assert flight["max_telemetry_age_s"] < 0.3 and flight["degraded_s"] == 0  # prediction covers it
    sim_log = (run.run_dir / "simulator.log").read_text()
    lost = [int(n) for n in re.findall(r"link_lost=(\d+)", sim_log)]
    assert len(lost) == 6 and min(lost) > 100  # the radio really dropped packets on every link
