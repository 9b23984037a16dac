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


def scripted_flight(sitl, pilot_for, log, *extra: str) -> str:
    """Two vehicles, turbulent wind, take-offs, an attitude-target stream, a landing; stopped at t = 9 s.
    extra: more simulator options. Returns the simulator's stderr (its counters)."""
    sim = sitl(
        *extra,
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
    status, err = sim.stop()
    assert status == 0
    return err


def test_same_seed_and_client_give_identical_truth_logs(sitl, pilot_for, tmp_path):
    logs = [tmp_path / "a.csv", tmp_path / "b.csv"]
    for log in logs:
        scripted_flight(sitl, pilot_for, log)
    first, second = (log.read_bytes() for log in logs)
    assert len(first.splitlines()) > 800  # 2 vehicles x 50 Hz x 9 s
    assert first == second


def test_a_shared_radio_in_lockstep_gives_identical_runs_and_counters(sitl, pilot_for, tmp_path):
    """The same flight over one shared half-duplex 200 kbit/s medium twice: the same truth log and the same
    radio counters (bytes, packets, drops, queue delays), which a radio timed by the wall clock would not
    give; the medium is busy enough that packets queue. (`received` may differ by the uplink packets due at
    the frame end where the stop signal lands: handled there or not, depending on when it came.)"""
    radio = ("--link-capacity-bps", "200000", "--link-shared", "--link-half-duplex")
    logs = [tmp_path / "a.csv", tmp_path / "b.csv"]
    errs = [scripted_flight(sitl, pilot_for, log, *radio) for log in logs]
    counters = [
        [line[line.index("radio_up_packets=") :] for line in e.splitlines() if "radio_up_" in line]
        for e in errs
    ]
    assert len(counters[0]) == 2 and counters[0] == counters[1]
    assert "radio_down_delay_max_ms=0.00" not in counters[0][0]
    assert logs[0].read_bytes() == logs[1].read_bytes()


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


HOVER_UNTIL_S = 0.5  # s of vehicle time with no attitude target (GUIDED holds)
FRAME_S = 0.02  # the default 50 Hz lockstep frame


def airborne_mission(path) -> None:
    """One vehicle spawned at 10 m (GUIDED, armed), turbulent wind."""
    path.write_text(
        "mission: {name: delay}\n"
        "vehicles:\n"
        "  - {name: a, role: leader, start: {position: [0, 0, 10]}}\n"
        "goal: [50, 0, 10]\n"
        "world: {wind: {speed: 3, direction_deg: 40, turbulence: 1}}\n"
        "run: {airborne_start: true}\n"
    )


def weave_flight(sitl, pilot_for, tmp_path, delay: int, lead_s: float) -> bytes:
    """Fly airborne_mission with `--lockstep-delay delay`; the pilot answers the frame at time t with the
    attitude target of time t + lead_s. Returns the truth log once the pilot has seen t >= 3 s."""
    mission, log = tmp_path / "delay.yaml", tmp_path / f"truth{delay}.csv"
    airborne_mission(mission)
    sim = sitl(
        "--mission", str(mission), "--lockstep", "--lockstep-delay", str(delay), "--ready-delay", "0",
        "--truth-log", str(log),
    )  # fmt: skip
    pilot = pilot_for(sim)

    def weave(vehicle: Vehicle) -> None:
        t = vehicle.t + lead_s
        if t >= HOVER_UNTIL_S:
            vehicle.attitude(0.2 * math.sin(2 * t), 0.1 * math.cos(3 * t), 0.4 * t, 0.5 + 0.1 * math.sin(t))

    pilot.spin(lambda: pilot[0].t >= 3.0, 5.0, each_frame=weave)
    assert sim.stop()[0] == 0
    return log.read_bytes()


def test_pipelined_lockstep_acts_exactly_one_frame_later(sitl, pilot_for, tmp_path):
    # With --lockstep-delay 1 the answer to frame k steers the frame after the next one, so a pilot that
    # answers every frame one frame ahead of time (t + 20 ms) must fly exactly the physics of a pilot that
    # answers on time with --lockstep-delay 0: the same truth log, row for row. The pipelined simulator
    # stops one frame further (it integrated the frame after the pilot's last unanswered one).
    strict = weave_flight(sitl, pilot_for, tmp_path, 0, 0.0)
    pipelined = weave_flight(sitl, pilot_for, tmp_path, 1, FRAME_S)
    assert len(strict.splitlines()) > 100  # 50 Hz x 3 s
    assert pipelined.startswith(strict)
    assert len(pipelined.splitlines()) == len(strict.splitlines()) + 1
    # and the delay is real: answering on time with the pipelined clock flies a different path
    late = weave_flight(sitl, pilot_for, tmp_path, 1, 0.0)
    assert not late.startswith(strict)


def test_pipelined_lockstep_never_shows_a_frame_before_the_previous_one_is_answered(sitl):
    # the simulator computes the next frame while the client thinks, but holds its telemetry until the
    # answer: a slow client sees frame after frame, never two at once
    sim = sitl("--lockstep", "--lockstep-delay", "1", "--ready-delay", "0")
    vehicle = Vehicle(sim.port(0), 1)
    try:
        vehicle.heartbeat()
        vehicle.request_streams(50)
        seen = []
        deadline = time.monotonic() + 20.0
        while len(seen) < 15 and time.monotonic() < deadline:
            select.select([vehicle.conn.port], [], [], 0.05)
            vehicle.drain()
            if vehicle.time_boot_ms <= vehicle.answered_ms:
                continue
            frame = vehicle.time_boot_ms
            time.sleep(0.03)  # think longer than the simulator takes for a frame
            vehicle.drain()
            seen.append((frame, vehicle.time_boot_ms))
            vehicle.mav.system_time_send(0, frame)
            vehicle.answered_ms = frame
        assert len(seen) == 15
        assert all(after == frame for frame, after in seen)  # nothing newer arrived while thinking
        frames = [frame for frame, _ in seen[1:]]
        assert all(b - a == 20 for a, b in zip(frames, frames[1:], strict=False))  # one frame per answer
    finally:
        vehicle.close()
