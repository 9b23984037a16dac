"""Telemetry becomes state once, in ENU/FLU; readiness, loss and garbage; position/velocity targets."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import LinkError
from tests.gcs_swarm.link.fake_vehicle import ORIGIN

STATE_STREAMS = {"GLOBAL_POSITION_INT": 50.0, "ATTITUDE": 50.0}


@pytest.mark.parametrize("attitude_stream", ["ATTITUDE", "ATTITUDE_QUATERNION"])
def test_position_velocity_attitude_in_mission_enu(fake, fleet_of, attitude_stream: str) -> None:
    still = fake(1, lockstep=True, position=(10.0, -5.0, 3.0), attitude_ned=(0.1, 0.2, 0.3))
    moving = fake(2, lockstep=True, velocity=(1.0, 2.0, -0.5), attitude_ned=(0.0, 0.0, -2.5))
    fleet = fleet_of(still, moving)
    fleet.connect(timeout_s=3.0)
    fleet.request_streams_all(50.0)
    fleet.run(v.streams.op_set_message_interval(attitude_stream, 50.0) for v in fleet.links)
    if attitude_stream == "ATTITUDE_QUATERNION":
        fleet.run(v.streams.op_set_message_interval("ATTITUDE", 0) for v in fleet.links)
    assert fleet.wait_tick(timeout_s=2.0)
    np.testing.assert_allclose(fleet.pos[0], [10.0, -5.0, 3.0], atol=0.02)  # 1e-7 deg is ~1 cm
    np.testing.assert_allclose(fleet.vel, [[0.0, 0.0, 0.0], [1.0, 2.0, -0.5]], atol=1e-9)
    np.testing.assert_allclose(fleet.att[0], [0.1, -0.2, math.pi / 2 - 0.3], atol=1e-6)
    np.testing.assert_allclose(fleet.att[1], [0.0, 0.0, math.pi / 2 + 2.5 - 2 * math.pi], atol=1e-6)
    assert fleet.time_ms.tolist() == [still.t_ms, moving.t_ms]  # both fakes wait on this frame's answer


def test_ready_needs_a_position_estimate_and_prearm_health(fake, fleet_of) -> None:
    vehicle = fake(1, lockstep=True, ready=False, prearm_ok=False)
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    with pytest.raises(LinkError, match="^timed out after 0.1 s waiting for"):
        fleet.wait_until(lambda: bool(fleet.ready.all()), 0.1, "readiness")
    fleet.request_streams_all(50.0, status_hz=10.0)
    with pytest.raises(
        LinkError, match=r"^not ready to fly after 0.3 s: lead: no usable position estimate \(EKF"
    ):
        fleet.wait_ready(timeout_s=0.3)
    vehicle.ready = True
    with pytest.raises(LinkError, match="^not ready to fly after 0.3 s: lead: pre-arm checks failing"):
        fleet.wait_ready(timeout_s=0.3)
    vehicle.prearm_ok = True
    fleet.wait_ready(timeout_s=3.0)
    assert fleet.ready.tolist() == [True]


def test_loss_by_wall_time_and_regain(fake, fleet_of) -> None:
    vehicle = fake(1, streams={"GLOBAL_POSITION_INT": 20.0})
    fleet = fleet_of(vehicle, names=["lead"], loss_timeout_s=0.3)
    fleet.connect(timeout_s=3.0)
    vehicle.silent = True
    fleet.wait_until(lambda: not fleet.alive[0], 3.0, "the loss")
    vehicle.silent = False
    fleet.wait_until(lambda: bool(fleet.alive[0]), 3.0, "the regain")
    texts = [e.text for e in fleet.events if e.vehicle == "lead"]
    assert any(t.startswith("link lost: no message for") and t.endswith("s of wall time") for t in texts)
    assert texts[-1] == "link regained"
    assert fleet.vehicle("lead").channel.stats.lost == 1
    with pytest.raises(LinkError, match="lead is not responding"):
        vehicle.silent = True
        fleet.wait_until(lambda: not fleet.alive[0], 3.0, "the second loss")
        fleet.run([fleet.vehicle("lead").parameters.op_get("GUID_OPTIONS")])


def test_loss_by_vehicle_time_while_the_others_fly_on(fake, fleet_of) -> None:
    a, b = fake(1, lockstep=True), fake(2, lockstep=True)
    fleet = fleet_of(a, b, names=["a", "b"], loss_timeout_s=0.5, loss_wall_timeout_s=30.0)
    fleet.connect(timeout_s=3.0)
    fleet.request_streams_all(50.0)
    b.silent = True
    fleet.wait_until(lambda: not fleet.alive[1], 10.0, "b's loss")
    assert fleet.alive.tolist() == [True, False]
    lost = [e.text for e in fleet.events if e.vehicle == "b" and e.text.startswith("link lost")]
    assert lost and lost[0].endswith("s of vehicle time")
    assert fleet.wait_tick(timeout_s=2.0)  # the frame wait_until decided on, left for the caller
    before = fleet.time_ms[0]
    fleet.answer_frame()
    assert fleet.wait_tick(timeout_s=2.0)  # ticks continue with the vehicles still alive
    assert fleet.time_ms[0] > before


def test_garbage_is_counted_and_ignored(fake, fleet_of) -> None:
    vehicle = fake(1, streams={"GLOBAL_POSITION_INT": 20.0})
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    link = fleet.vehicle("lead")
    for garbage in (
        b"\x00\x01\x02hello",
        b"\xfd\x09\x00\x00\x00\x01\x01\x21\x00\x00truncated",
        bytes(range(256)),
    ):
        vehicle.send_raw(garbage)
    fleet.wait_until(lambda: link.channel.stats.bad >= 3, 3.0, "the garbage")
    count = fleet.state.position_count[0]
    fleet.wait_until(lambda: fleet.state.position_count[0] > count + 2, 3.0, "positions after the garbage")
    assert fleet.alive[0] and link.channel.stats.received > link.channel.stats.bad


def test_statustext_becomes_an_event(fake, fleet_of) -> None:
    vehicle = fake(1, lockstep=True, arm_refusal="PreArm: Compass not calibrated")
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    with pytest.raises(LinkError):
        fleet.run([fleet.vehicle("lead").commands.op_arm()])
    event = fleet.events[-1]
    assert (event.vehicle, event.text, event.severity) == ("lead", "PreArm: Compass not calibrated", 2)


def test_position_and_velocity_targets_on_the_wire(fake, fleet_of) -> None:
    vehicle = fake(1, lockstep=True, position=(1.0, 2.0, 0.0))
    fleet = fleet_of(vehicle, names=["lead"])
    fleet.connect(timeout_s=3.0)
    fleet.request_streams_all(50.0)
    assert fleet.wait_tick(timeout_s=2.0)
    frame_ms = fleet.time_ms[0]
    link = fleet.vehicle("lead")
    link.setpoints.send_position_target([10.0, 20.0, 5.0], yaw=0.0)
    link.setpoints.send_velocity_target([1.0, 2.0, 3.0])
    link.setpoints.hold()
    fleet.wait_until(lambda: len(vehicle.position_targets) == 3, 2.0, "the targets")
    position, velocity, hold = vehicle.position_targets
    lat, lon, alt = pymap3d.enu2geodetic(10.0, 20.0, 5.0, *ORIGIN)
    assert (position.coordinate_frame, position.lat_int, position.lon_int) == (
        mavlink2.MAV_FRAME_GLOBAL_INT,
        round(lat * 1e7),
        round(lon * 1e7),
    )
    assert position.alt == pytest.approx(alt, abs=1e-3) and position.yaw == pytest.approx(math.pi / 2)
    assert position.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE == 0
    assert velocity.coordinate_frame == mavlink2.MAV_FRAME_LOCAL_NED
    assert (velocity.vx, velocity.vy, velocity.vz) == (2.0, 1.0, -3.0)
    assert velocity.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_X_IGNORE
    assert velocity.type_mask & mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    hold_lat, hold_lon, _ = pymap3d.enu2geodetic(1.0, 2.0, 0.0, *ORIGIN)
    assert abs(hold.lat_int - hold_lat * 1e7) <= 2 and abs(hold.lon_int - hold_lon * 1e7) <= 2
    assert position.time_boot_ms == frame_ms  # targets answer the frame like SET_ATTITUDE_TARGET
