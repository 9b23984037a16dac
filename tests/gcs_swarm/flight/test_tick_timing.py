"""Per-tick timing of the formation ticks (flight.tick_timing) on a scripted clock, and the frames missed
split by mission phase. Every expected figure is worked out by hand from the script."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from gcs_swarm.flight.tick_timing import (
    ASSESS,
    GUIDANCE,
    RECORD,
    SEND,
    TICK_PHASES,
    MissedFramesByPhase,
    TickTiming,
)


class Clock:
    """A wall clock the test sets (s)."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def formation_tick(
    timing: TickTiming, clock: Clock, link: SimpleNamespace, t_s: float, start: float, ms: dict[str, float]
) -> None:
    """One step at wall `start` s: the link waits ms["wait"] and receives ms["receive"], then ms["check"] of
    frame checks (rest) before the tick at vehicle time t_s, then assess, guidance, send and record, and
    ms["answer"] of lockstep answers (rest)."""
    clock.now = start
    timing.begin(link)
    link.pump_wait_s += ms["wait"] / 1000
    link.pump_work_s += ms["receive"] / 1000
    clock.now += (ms["wait"] + ms["receive"] + ms["check"]) / 1000
    timing.at(t_s)
    for phase, name in ((ASSESS, "assess"), (GUIDANCE, "guidance"), (SEND, "send"), (RECORD, "record")):
        clock.now += ms[name] / 1000
        timing.mark(phase)
    clock.now += ms["answer"] / 1000
    timing.end(link)


TICK_A = {"wait": 3.0, "receive": 1.0, "check": 0.5, "assess": 0.5, "guidance": 1.0, "send": 0.5}
TICK_A |= {"record": 0.25, "answer": 0.25}
TICK_B = {"wait": 0.0, "receive": 4.0, "check": 1.0, "assess": 1.0, "guidance": 8.0, "send": 2.0}
TICK_B |= {"record": 1.0, "answer": 1.0}


def test_a_tick_is_split_into_waiting_and_its_phases() -> None:
    clock, link = Clock(), SimpleNamespace(pump_wait_s=5.0, pump_work_s=7.0)
    timing = TickTiming(clock)
    formation_tick(timing, clock, link, 12.34, 100.0, TICK_A)
    ((t_s, wait, work, *phases),) = timing.rows
    assert t_s == 12.34
    assert wait == pytest.approx(0.003)
    # receive 1 + assess 0.5 + guidance 1 + send 0.5 + record 0.25 + rest (checks 0.5 + answers 0.25)
    assert work == pytest.approx(0.004)
    expected = {"receive": 1.0, "assess": 0.5, "guidance": 1.0, "send": 0.5, "record": 0.25, "rest": 0.75}
    assert dict(zip(TICK_PHASES, np.array(phases) * 1000, strict=True)) == pytest.approx(expected)


def test_only_formation_ticks_are_kept() -> None:
    clock, link = Clock(), SimpleNamespace(pump_wait_s=0.0, pump_work_s=0.0)
    timing = TickTiming(clock)
    timing.at(1.0)  # a formation tick outside begin/end (the controller tested on its own): not kept
    timing.begin(link)  # a landing step: no formation tick in it
    clock.now = 0.01
    timing.end(link)
    assert timing.rows == []
    formation_tick(timing, clock, link, 2.0, 1.0, TICK_A)
    assert [row[0] for row in timing.rows] == [2.0]


def test_the_worst_tick_is_the_one_with_the_most_work() -> None:
    clock, link = Clock(), SimpleNamespace(pump_wait_s=0.0, pump_work_s=0.0)
    timing = TickTiming(clock)
    formation_tick(timing, clock, link, 1.00, 0.0, TICK_A)  # 4 ms of work, 3 ms waited
    formation_tick(timing, clock, link, 1.02, 1.0, TICK_B)  # 18 ms of work, no wait
    formation_tick(timing, clock, link, 1.04, 2.0, TICK_A)
    summary = timing.summary()
    worst = summary["worst_tick"]
    assert worst["t_s"] == 1.02 and worst["wait_ms"] == pytest.approx(0.0)
    assert worst["work_ms"] == pytest.approx(18.0)
    assert worst["phases_ms"] == pytest.approx(
        {"receive": 4.0, "assess": 1.0, "guidance": 8.0, "send": 2.0, "record": 1.0, "rest": 2.0}
    )
    phases = summary["tick_phases_ms"]
    assert phases["ticks"] == 3
    # from the start of the first tick's work (0 + 4.5 ms) to that of the last (2 s + 4.5 ms); vehicle time
    # 1.00 -> 1.04
    assert phases["vehicle_s"] == pytest.approx(0.04) and phases["wall_s"] == pytest.approx(2.0)
    # guidance over the ticks: 1, 8, 1 ms -> median 1; p99 (linear) 1 + 0.98 * (8 - 1); max 8
    assert phases["median"]["guidance"] == pytest.approx(1.0)
    assert phases["p99"]["guidance"] == pytest.approx(7.86)
    assert phases["max"]["work"] == pytest.approx(18.0) and phases["max"]["wait"] == pytest.approx(3.0)


def test_no_timed_tick_no_entries() -> None:
    assert TickTiming().summary() == {}


def test_frames_missed_are_split_by_the_phase_they_happened_in() -> None:
    counts = np.zeros(2, dtype=np.int64)  # the link's cumulative count, updated in place
    missed = MissedFramesByPhase(["v0", "v1"], counts)
    counts += [4, 4]  # before the first phase: not the mission's
    missed.enter("launch")
    counts += [1, 0]
    missed.enter("formation")
    counts += [0, 2]
    missed.enter("hold")
    missed.enter("formation")  # formation again: added to the first stretch
    counts += [0, 1]
    assert missed.summary() == {
        "total": 4,
        "by_phase": {
            "launch": {"total": 1, "by_vehicle": {"v0": 1}},
            "formation": {"total": 3, "by_vehicle": {"v1": 3}},
            "hold": {"total": 0, "by_vehicle": {}},
        },
    }
