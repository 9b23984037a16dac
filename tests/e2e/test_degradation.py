"""Stale telemetry end to end (docs/reliability.md): a link that goes quiet for 2 s (less than lost_s) makes
the fleet predict, fly degraded (slower, wider) and hold the silent vehicle, then recover and arrive."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from tests.e2e.flights import SHORT_BOOT, fly

OUTAGE_S = (20.0, 2.0)  # start, duration in simulated s: the quickstart cruises past its obstacles by then


def _window(events: list[str], start: str, end: str) -> tuple[float, float]:
    """Vehicle times (s) of the first event containing `start` and the first later one containing `end`."""
    times = [(float(m.group(1)), e) for e in events if (m := re.match(r"t=([\d.]+) s ", e))]
    t0 = next(t for t, e in times if start in e)
    t1 = next(t for t, e in times if end in e and t > t0)
    return t0, t1


def _truth(run_dir: Path) -> np.ndarray:
    return np.genfromtxt(run_dir / "truth.csv", names=True, delimiter=",")


def test_a_follower_quiet_for_two_seconds_is_held_and_the_fleet_slows_then_recovers(
    quickstart: Path, tmp_path: Path
) -> None:
    outage = f"--sim-arg=--link-outage=1@{OUTAGE_S[0]:g}:{OUTAGE_S[1]:g}"
    run = fly(quickstart, tmp_path / "run", timeout_s=300, extra=[outage, SHORT_BOOT])
    assert run.status == 0, run.output[-2000:]  # nobody lost: 2 s < lost_s
    assert run.report["collisions"] == 0 and run.report["reached"]
    flight = json.loads((run.run_dir / "flight.json").read_text())
    events = flight["events"]
    held, rejoined = _window(events, "right held: telemetry", "right rejoins")
    degraded, normal = _window(events, "degraded flight", "normal flight")
    start, duration = OUTAGE_S
    assert start + 0.3 <= degraded <= start + 0.4  # age passes predict_s
    assert start + 1.0 <= held <= start + 1.1  # age passes hold_s
    assert start + duration <= rejoined <= start + duration + 0.1  # fresh again when the link returns
    assert normal - rejoined >= 2.0 - 0.021  # recover_s (less one tick) of fresh telemetry first
    assert flight["holds"] == 1 and flight["lost"] == []
    assert abs(flight["degraded_s"] - (normal - degraded)) < 0.1
    truth = _truth(run.run_dir)
    lead = truth[truth["vehicle"] == 0]
    speed = np.hypot(lead["vx"], lead["vy"])
    before = speed[(lead["t"] > degraded - 1.0) & (lead["t"] < degraded)]
    # from 10 to 5 m/s at 4 m/s^2 and 5 m/s^3 (guidance.reference accel_xy_max, jerk_max) takes
    # dv / A + A / J = 1.25 + 0.8 = 2.05 s at best, so look from 2.5 s on
    slowed = speed[(lead["t"] > degraded + 2.5) & (lead["t"] < normal)]
    assert before.min() > 9.0  # cruising at about 10 m/s before the outage
    assert slowed.size and slowed.max() < 6.0  # about degraded_speed x v_xy_leader = 5 m/s


def test_a_quiet_leader_holds_the_whole_fleet_until_it_is_heard_again(
    quickstart: Path, tmp_path: Path
) -> None:
    outage = f"--sim-arg=--link-outage=0@{OUTAGE_S[0]:g}:{OUTAGE_S[1]:g}"
    run = fly(quickstart, tmp_path / "run", timeout_s=300, extra=[outage, SHORT_BOOT])
    assert run.status == 0, run.output[-2000:]
    assert run.report["collisions"] == 0 and run.report["reached"]
    flight = json.loads((run.run_dir / "flight.json").read_text())
    events = flight["events"]
    assert flight["holds"] == 3 and flight["leader"] == 0, events
    held, rejoined = _window(events, "left held: the leader's telemetry is stale", "left rejoins")
    truth = _truth(run.run_dir)
    left = truth[truth["vehicle"] == 2]
    speed = np.hypot(left["vx"], left["vy"])
    braking = speed[(left["t"] >= held) & (left["t"] <= rejoined)]
    # the follower (fresh link) brakes on its own autopilot while the leader is unheard
    assert braking[0] > 6.0 and braking[-1] < 0.5 * braking[0]
