"""Lockstep against the simulator (sitl_sim --lockstep): every frame answered exactly once, never a deadlock
in a wait, telemetry-clocked ticks. The wire taps show the frames the vehicle sent and the answers it got."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_swarm.link import frames, lockstep

ANSWERS = (
    "SYSTEM_TIME",
    "SET_ATTITUDE_TARGET",
    "SET_POSITION_TARGET_LOCAL_NED",
    "SET_POSITION_TARGET_GLOBAL_INT",
)
FRAME_MS = 20  # --lockstep-hz 50


def answered_exactly_once(wire) -> None:
    """Each frame the vehicle ended (a time_boot_ms on the downlink) since the ground station's first answer,
    but the last (whose answer may still be in flight), got exactly one answer (docs/sitl.md, lockstep)."""
    answers = Counter(m.time_boot_ms for m in wire.uplink if m.get_type() in ANSWERS and m.time_boot_ms > 0)
    first = min(answers)
    ended = sorted({m.time_boot_ms for m in wire.downlink if getattr(m, "time_boot_ms", 0) >= first})
    assert max(answers.values()) == 1
    assert [t for t in ended[:-1] if answers[t] != 1] == []
    assert np.all(np.diff(ended) == FRAME_MS)  # and the vehicle ended no frame in between unseen


def test_blocking_waits_keep_the_lockstep_simulator_running(simulator, fleet_of) -> None:
    vehicles = simulator(1)
    wire = vehicles.tap(0)
    fleet = fleet_of(wire, names=["lead"])
    fleet.connect(timeout_s=10.0)
    fleet.wait_ready(timeout_s=3.0)
    fleet.param_set_all("GUID_OPTIONS", 8)
    fleet.set_mode_all("GUIDED")  # needs a HEARTBEAT: up to 1 s of vehicle time
    fleet.arm_all()
    fleet.takeoff_all(3.0)
    fleet.wait_until(lambda: fleet.pos[0, 2] > 2.9, 20.0, "lead at 3 m")
    assert vehicles.dropped(wire) == []  # the simulator never had to give up waiting for an answer
    assert fleet.time_ms[0] > 1000
    answered_exactly_once(wire)
    frame_of = []  # the vehicle time of each GCS HEARTBEAT: the newest frame answered before it
    latest = 0
    for msg in wire.uplink:
        if msg.get_type() in ANSWERS:
            latest = max(latest, msg.time_boot_ms)
        elif msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 255:
            frame_of.append(latest)
    assert np.diff(frame_of).max() <= 1000 + FRAME_MS  # a GCS HEARTBEAT at least every second of vehicle time


def test_ticks_are_clocked_by_telemetry_and_targets_echo_the_frame(simulator, fleet_of) -> None:
    vehicles = simulator(2)
    w0, w1 = vehicles.tap(0), vehicles.tap(1)
    fleet = fleet_of(w0, w1, names=["lead", "f1"])
    fleet.connect(timeout_s=10.0)
    tick_times = []
    for _ in range(30):
        assert fleet.wait_tick(timeout_s=2.0)
        tick_times.append(fleet.time_ms.copy())
        fleet.send_attitude_targets([0.1, 0.0], [0.2, 0.0], [0.0, 0.0], [0.6, 0.5], mask=[True, False])
        fleet.answer_frame()
    fleet.wait_until(lambda: len(w0.sent("SET_ATTITUDE_TARGET")) == 30, 2.0, "the last target at the vehicle")
    targets = w0.sent("SET_ATTITUDE_TARGET")
    ticks = np.array(tick_times)
    assert np.all(np.diff(ticks, axis=0) == FRAME_MS)  # one tick per frame of each vehicle, none skipped
    assert [m.time_boot_ms for m in targets] == ticks[:, 0].tolist()  # each echoes its frame
    last = targets[-1]
    assert (last.target_system, last.target_component, last.type_mask) == (1, 1, 0b00000111)
    assert last.thrust == pytest.approx(0.6)
    np.testing.assert_allclose(last.q, frames.attitude_target_quaternion([0.1, 0.2, 0.0]), atol=1e-6)
    assert w1.sent("SET_ATTITUDE_TARGET") == []
    for wire in (w0, w1):
        assert vehicles.dropped(wire) == []
        answered_exactly_once(wire)


def test_facing_east_is_ned_yaw_90_on_the_wire(lead) -> None:
    fleet, link, wire = lead()
    assert fleet.wait_tick(timeout_s=2.0)
    fleet.send_attitude_targets([0.0], [0.0], [0.0], [0.5])
    fleet.wait_until(lambda: len(wire.sent("SET_ATTITUDE_TARGET")) > 0, 2.0, "the target")
    q = wire.sent("SET_ATTITUDE_TARGET")[0].q
    yaw_ned = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
    assert math.degrees(yaw_ned) == pytest.approx(90.0)


def test_non_finite_targets_never_leave_the_ground_station(lead) -> None:
    fleet, link, wire = lead()
    with pytest.raises(ValueError, match="non-finite attitude target for lead; nothing sent"):
        fleet.send_attitude_targets([0.0], [math.nan], [0.0], [0.5])
    with pytest.raises(ValueError, match="non-finite attitude target for lead"):
        fleet.send_attitude_targets([0.0], [0.0], [0.0], [math.inf])
    with pytest.raises(ValueError, match="position target for lead"):
        link.setpoints.send_position_target([0.0, math.nan, 1.0])
    with pytest.raises(ValueError, match=r"shape \(1,\)"):
        fleet.send_attitude_targets([0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.5, 0.5])
    fleet.run([link.parameters.op_get("GUID_OPTIONS")])  # round trip: anything sent before has arrived
    assert wire.sent("SET_ATTITUDE_TARGET") == [] and wire.sent("SET_POSITION_TARGET_GLOBAL_INT") == []


def test_unanswered_waits_stall_the_simulator_when_answers_are_off(simulator, fleet_of) -> None:
    """The counter-check of the lockstep tests above: without answers the simulator does wait (and gives
    up after its --lockstep-timeout, 1 s)."""
    vehicles = simulator(1)
    wire = vehicles.tap(0)
    fleet = fleet_of(wire, lockstep_answers=False)
    fleet.connect(timeout_s=10.0)
    fleet.wait_until(lambda: fleet.vehicle(0).lockstep.needs_answer, 3.0, "a frame")
    fleet.answer_frame()  # become a lockstep client once, then stay silent
    fleet.wait_until(lambda: vehicles.dropped(wire) != [], 10.0, "the simulator to drop the silent client")


frame_times = st.integers(-1, 6)  # few distinct times: ties and "nothing yet" (-1) come up often


@given(
    st.lists(st.tuples(st.booleans(), frame_times, frame_times, frame_times), max_size=9),
)
def test_the_frame_check_follows_its_rule(rows) -> None:
    """wait_tick's test of a complete frame (lockstep.take_new_frame) on fleets of 0 to 9 vehicles alive or
    lost, with or without clock ticks, against its rule written out: nobody alive, no frame; else the
    fleet's last tick is the newest of the alive vehicles'; a vehicle is expected when alive, or lost with
    clock ticks at least as new as that last tick on both counts; the frame is complete when every expected
    vehicle has a position or clock tick newer than its own last tick, which then becomes that newest."""
    alive = [r[0] for r in rows]
    position_ms, frame_ms, tick_ms = ([r[k] for r in rows] for k in (1, 2, 3))
    ticks = np.array(tick_ms, dtype=np.int64)
    got = lockstep.take_new_frame(
        np.array(alive, dtype=bool),
        np.array(position_ms, dtype=np.int64),
        np.array(frame_ms, dtype=np.int64),
        ticks,
    )
    if not any(alive):
        assert not got and ticks.tolist() == tick_ms
        return
    last = max(t for t, a in zip(tick_ms, alive, strict=True) if a)
    expected = [
        a or (f >= 0 and f >= last and t >= last) for a, f, t in zip(alive, frame_ms, tick_ms, strict=True)
    ]
    newest = [max(p, f) for p, f in zip(position_ms, frame_ms, strict=True)]
    complete = all(n > t for n, t, e in zip(newest, tick_ms, expected, strict=True) if e)
    assert got is complete
    assert ticks.tolist() == [
        n if complete and e else t for n, t, e in zip(newest, tick_ms, expected, strict=True)
    ]


def test_a_frame_is_complete_when_every_expected_vehicle_has_a_newer_one() -> None:
    """Worked cases of the rule: a lost vehicle whose clock ticks were current at the last tick is waited
    for; one that fell behind is not; the frame taken sets tick_ms to each vehicle's newest stamp."""
    take = lockstep.take_new_frame
    alive = np.array([True, True, False])
    tick = np.array([100, 100, 100], dtype=np.int64)
    # vehicle 2 is lost but its clock ticks kept up: its newer clock tick (120) is waited for
    assert not take(alive, np.array([120, 120, -1]), np.array([-1, -1, 100]), tick)
    assert tick.tolist() == [100, 100, 100]
    assert take(alive, np.array([120, 120, -1]), np.array([-1, -1, 120]), tick)
    assert tick.tolist() == [120, 120, 120]
    # a lost vehicle whose clock fell behind the last tick is not waited for, and keeps its tick_ms
    tick = np.array([100, 100, 80], dtype=np.int64)
    assert take(alive, np.array([120, 140, -1]), np.array([-1, -1, 80]), tick)
    assert tick.tolist() == [120, 140, 80]
    # nobody alive: no tick
    assert not take(np.zeros(2, dtype=bool), np.array([5, 5]), np.array([5, 5]), np.zeros(2, np.int64))
