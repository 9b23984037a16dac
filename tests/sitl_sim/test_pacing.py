"""RealTimePacer: wall deadlines for simulated time, and the lag it reports when the simulator is behind; how
the simulator waits for them."""

from __future__ import annotations

import pytest

from sitl_sim.clock import LATE_S, MAX_LAG_S, PacingLag, RealTimePacer


def test_deadlines_follow_the_speedup_from_the_anchor():
    pacer = RealTimePacer(speedup=2.0)
    assert pacer.deadline(10.0, 100.0) == 100.0  # the first call anchors: sim 10 s is wall 100 s
    assert pacer.deadline(11.0, 100.0) == pytest.approx(100.5)  # 1 simulated s at 2x: half a wall second
    assert pacer.lag.worst_s == 0.0 and pacer.lag.late_ticks == 0 and pacer.lag.paced_ticks == 2


def test_lag_counts_ticks_more_than_one_frame_behind_and_keeps_the_worst():
    pacer = RealTimePacer(speedup=1.0)
    pacer.deadline(0.0, 50.0)
    pacer.deadline(0.010, 50.010 + LATE_S / 2)  # half a frame behind: not late
    pacer.deadline(0.020, 50.020 + LATE_S + 0.005)  # 25 ms behind: late
    assert pacer.lag.late_ticks == 1 and pacer.lag.paced_ticks == 3
    assert pacer.lag.worst_s == pytest.approx(LATE_S + 0.005)
    assert pacer.lag.summary() == "real-time pacing: worst lag 25.0 ms, 1 of 3 ticks more than 20 ms behind"


def test_a_lag_beyond_max_lag_is_recorded_then_forgiven():
    pacer = RealTimePacer(speedup=1.0)
    pacer.deadline(0.0, 0.0)
    assert pacer.deadline(1.0, 1.0 + MAX_LAG_S + 0.1) == 1.0 + MAX_LAG_S + 0.1  # re-anchored: due now
    assert pacer.lag.worst_s == pytest.approx(MAX_LAG_S + 0.1)
    assert pacer.deadline(1.5, 1.6 + MAX_LAG_S) == pytest.approx(1.5 + MAX_LAG_S + 0.1)  # from the new anchor


def test_a_pacer_that_takes_over_keeps_adding_to_the_same_lag():
    lag = PacingLag()
    first = RealTimePacer(1.0, lag)
    first.deadline(0.0, 0.0)
    first.deadline(0.1, 0.15)
    second = RealTimePacer(3.0, first.lag)  # e.g. the orphaned simulator's pacer
    second.deadline(5.0, 9.0)
    second.deadline(5.3, 9.13)  # due at 9.1: 30 ms behind
    assert lag.paced_ticks == 4 and lag.late_ticks == 2 and lag.worst_s == pytest.approx(0.05)


def test_an_unpaced_run_is_due_at_once_and_never_behind():
    pacer = RealTimePacer(speedup=float("inf"))  # e.g. an orphaned lockstep run, as fast as it can
    assert pacer.deadline(0.0, 7.0) == 7.0
    assert pacer.deadline(100.0, 7.5) == 7.5
    assert pacer.lag == PacingLag()  # nothing paced, nothing to report


def test_a_paced_simulator_reads_its_sockets_once_per_step_after_sleeping(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Between physics steps the simulator sleeps to the step's deadline and then reads what arrived
    without blocking, rather than waking for each datagram (Simulator._pace): a client's burst of commands
    does not wake it once per command. A fake clock advanced only by sleeping."""
    from types import SimpleNamespace

    from sitl_sim import simulator

    clock = [100.0]
    calls: list[tuple[str, float]] = []

    def sleep(s: float) -> None:
        calls.append(("sleep", s))
        clock[0] += s

    monkeypatch.setattr(simulator, "time", SimpleNamespace(monotonic=lambda: clock[0], sleep=sleep))
    pacer = RealTimePacer(speedup=1.0)
    pacer.deadline(0.0, 100.0)  # anchored: simulated 0 s is wall 100 s
    fake = SimpleNamespace(pacer=pacer, t=0.001, _serve=lambda timeout: calls.append(("serve", timeout)))
    simulator.Simulator._pace(fake, lambda: False)  # type: ignore[arg-type]
    assert calls == [("sleep", pytest.approx(0.001)), ("serve", 0.0)]
