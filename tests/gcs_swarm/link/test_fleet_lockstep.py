"""Lockstep: every frame answered exactly once, never a deadlock in a wait, telemetry-clocked ticks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.link import frames
from gcs_swarm.link.autopilots.ardupilot import thrust_from_acc


def answered_exactly_once(vehicle) -> None:
    """Each frame the fake sent (but the last, which may still be in flight) got exactly one answer."""
    assert max(vehicle.answers.values()) == 1
    unanswered = [t for t in vehicle.frames_sent[:-1] if vehicle.answers[t] != 1]
    assert unanswered == []


def test_blocking_waits_keep_the_lockstep_simulator_running(fake, fleet_of) -> None:
    vehicle = fake(1, lockstep=True, lockstep_timeout_s=1.0)
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    fleet.request_streams_all(50.0)
    fleet.wait_ready(timeout_s=3.0)
    fleet.param_set_all("GUID_OPTIONS", 8)
    fleet.set_mode_all("GUIDED")  # needs a HEARTBEAT: up to 1 s of vehicle time
    fleet.arm_all()
    fleet.takeoff_all(3.0)
    fleet.wait_until(lambda: fleet.pos[0, 2] > 2.9, 5.0, "lead at 3 m")
    assert vehicle.lockstep_drops == 0  # the fake never had to give up waiting for an answer
    assert vehicle.t_ms > 1000
    answered_exactly_once(vehicle)
    gaps = np.diff(vehicle.gcs_heartbeats_ms)
    assert gaps.max() <= 1000 + vehicle.dt_ms  # a GCS HEARTBEAT at least every second of vehicle time


def test_ticks_are_clocked_by_telemetry_and_targets_echo_the_frame(fake, fleet_of) -> None:
    v0, v1 = fake(1, lockstep=True, lockstep_timeout_s=1.0), fake(2, lockstep=True, lockstep_timeout_s=1.0)
    fleet = fleet_of(v0, v1, names=["lead", "f1"])
    fleet.connect(timeout_s=3.0)
    fleet.request_streams_all(50.0)
    tick_times = []
    for _ in range(30):
        assert fleet.wait_tick(timeout_s=2.0)
        tick_times.append(fleet.time_ms.copy())
        fleet.send_attitude_targets([0.1, 0.0], [0.2, 0.0], [0.0, 0.0], [0.6, 0.5], mask=[True, False])
        fleet.answer_frame()
    fleet.wait_until(lambda: len(v0.attitude_targets) == 30, 2.0, "the last target at the vehicle")
    ticks = np.array(tick_times)
    assert np.all(np.diff(ticks, axis=0) == 20)  # one tick per 20 ms frame of each vehicle, none skipped
    assert [m.time_boot_ms for m in v0.attitude_targets] == ticks[:, 0].tolist()  # each echoes its frame
    last = v0.attitude_targets[-1]
    assert (last.target_system, last.target_component, last.type_mask) == (1, 1, 0b00000111)
    assert last.thrust == pytest.approx(0.6)
    np.testing.assert_allclose(last.q, frames.attitude_target_quaternion([0.1, 0.2, 0.0]), atol=1e-6)
    assert v1.attitude_targets == []
    for vehicle in (v0, v1):
        assert vehicle.lockstep_drops == 0
        answered_exactly_once(vehicle)


def test_facing_east_is_ned_yaw_90_on_the_wire(fake, fleet_of) -> None:
    vehicle = fake(1, lockstep=True)
    fleet = fleet_of(vehicle)
    fleet.connect(timeout_s=3.0)
    fleet.request_streams_all(50.0)
    assert fleet.wait_tick(timeout_s=2.0)
    fleet.vehicle(0).setpoints.send_attitude_target(0.0, 0.0, 0.0, 0.5)
    fleet.wait_until(lambda: len(vehicle.attitude_targets) > 0, 2.0, "the target")
    q = vehicle.attitude_targets[0].q
    yaw_ned = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
    assert math.degrees(yaw_ned) == pytest.approx(90.0)


def test_non_finite_targets_never_leave_the_ground_station(fake, fleet_of) -> None:
    vehicle = fake(1, lockstep=True)
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    with pytest.raises(ValueError, match="non-finite attitude target for lead; nothing sent"):
        fleet.send_attitude_targets([0.0], [math.nan], [0.0], [0.5])
    with pytest.raises(ValueError, match="non-finite attitude target for lead"):
        fleet.vehicle("lead").setpoints.send_attitude_target(0.0, 0.0, 0.0, math.inf)
    with pytest.raises(ValueError, match="position target for lead"):
        fleet.vehicle("lead").setpoints.send_position_target([0.0, math.nan, 1.0])
    with pytest.raises(ValueError, match=r"shape \(1,\)"):
        fleet.send_attitude_targets([0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.5, 0.5])
    fleet.run(
        [fleet.vehicle("lead").parameters.op_get("GUID_OPTIONS")]
    )  # round trip: anything sent before has arrived
    assert (
        vehicle.received["SET_ATTITUDE_TARGET"] == 0
        and vehicle.received["SET_POSITION_TARGET_GLOBAL_INT"] == 0
    )


def test_thrust_from_acceleration() -> None:
    np.testing.assert_allclose(
        thrust_from_acc([9.8, 0.0, 19.6, 100.0, -1.0], 0.35, 9.8), [0.35, 0.0, 0.7, 1.0, 0.0]
    )
    assert thrust_from_acc(9.8, [0.3, 0.5], 9.8).tolist() == pytest.approx([0.3, 0.5])


def test_unanswered_waits_stall_the_simulator_when_answers_are_off(fake, fleet_of) -> None:
    """The counter-check of the lockstep tests above: without answers the fake does wait (and gives up)."""
    vehicle = fake(1, lockstep=True, lockstep_timeout_s=0.2)
    fleet = fleet_of(vehicle, lockstep_answers=False)
    fleet.connect(timeout_s=3.0)
    fleet.wait_until(lambda: fleet.vehicle(0).lockstep.needs_answer, 3.0, "a frame")
    fleet.answer_frame()  # become a lockstep client once, then stay silent
    fleet.wait_until(lambda: vehicle.lockstep_drops > 0, 3.0, "the fake to drop the silent client")
