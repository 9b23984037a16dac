"""Lockstep clock: bit-identical runs, passive clients never stall it, silent clients get dropped; the timing
plan that ties physics, autopilot, frames and the truth log together."""

from __future__ import annotations

import math
import select
import time

import pytest

from sitl_sim.clock import plan_timing
from tests.sitl_sim.sim_process import M, Vehicle

LAND = 9


def scripted_flight(sitl, pilot_for, log) -> None:
    """Two vehicles, turbulent wind, take-offs, an attitude-target stream, a landing; stopped at t = 9 s."""
    sim = sitl(
        "--lockstep",
        "--lockstep-timeout",
        "60",
        "--ready-delay",
        "1",
        "--seed",
        "7",
        "--truth-log",
        str(log),
        vehicles=2,
    )
    pilot = pilot_for(sim)
    pilot.spin(lambda: pilot[0].ready and pilot[1].ready, 5.0)
    pilot.set_param(1, "SIM_WIND_SPD", 4.0)
    pilot.set_param(1, "SIM_WIND_TURB", 1.5)
    pilot.take_off(0, 4.0)
    pilot.take_off(1, 6.0)

    def weave(vehicle: Vehicle) -> None:
        vehicle.attitude(0.2 * math.sin(vehicle.t), -0.1, 0.3 * vehicle.sysid, 0.5)

    pilot.spin(lambda: pilot[0].t >= 7.0, 10.0, each_frame=weave)
    assert pilot.set_mode(0, LAND) == M.MAV_RESULT_ACCEPTED
    pilot.spin(lambda: pilot[0].t >= 9.0, 5.0)  # returns before answering: the simulator waits here
    assert sim.stop()[0] == 0


def test_same_seed_and_client_give_identical_truth_logs(sitl, pilot_for, tmp_path):
    logs = [tmp_path / "a.csv", tmp_path / "b.csv"]
    for log in logs:
        scripted_flight(sitl, pilot_for, log)
    first, second = (log.read_bytes() for log in logs)
    assert len(first.splitlines()) > 800  # 2 vehicles x 50 Hz x 9 s
    assert first == second


def test_passive_client_does_not_stall_and_silent_client_is_dropped(sitl, pilot_for):
    sim = sitl("--lockstep", "--lockstep-timeout", "0.5")
    watcher = Vehicle(sim.port(0), 1, source_system=254)
    try:
        watcher.heartbeat()
        watcher.mav.system_time_send(0, 0)  # time_boot_ms 0: never a lockstep client (MAVProxy does this)
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:  # nobody answers: paused at the first frame
            watcher.drain()
            select.select([watcher.conn.port], [], [], 0.05)
        assert watcher.time_boot_ms == 20

        pilot = pilot_for(sim)
        pilot.spin(
            lambda: pilot[0].t >= 2.0, 3.0
        )  # the lockstep client drives; the watcher does not stall it
        watcher.drain()
        assert watcher.time_boot_ms >= 1900
        stopped_at = pilot[0].time_boot_ms
        deadline = time.monotonic() + 3.0  # the pilot falls silent: dropped after 0.5 s, then real time
        while time.monotonic() < deadline and watcher.time_boot_ms < stopped_at + 1000:
            watcher.drain()
            select.select([watcher.conn.port], [], [], 0.05)
        assert watcher.time_boot_ms >= stopped_at + 1000
    finally:
        watcher.close()
    assert "dropped" in sim.stop()[1]


def test_timing_plan():
    plan = plan_timing(1000.0, 100.0, 50.0, 50.0)
    assert (plan.steps_per_tick, plan.ticks_per_frame, plan.steps_per_truth) == (10, 2, 20)
    plan = plan_timing(1000.0, 100.0, 40.0, 50.0)  # 25-step frames: 5-step ticks (200 Hz)
    assert (plan.steps_per_tick, plan.ticks_per_frame) == (5, 5)
    assert plan_timing(400.0, 100.0, None, 50.0).tick_s == pytest.approx(0.01)
    with pytest.raises(ValueError, match="--lockstep-hz"):
        plan_timing(1000.0, 100.0, 30.0, 50.0)
    with pytest.raises(ValueError, match="--outer-hz"):
        plan_timing(1000.0, 3000.0, None, 50.0)
    with pytest.raises(ValueError, match="--truth-rate-hz"):
        plan_timing(1000.0, 100.0, None, 200.0)
