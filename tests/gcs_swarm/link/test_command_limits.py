"""The ground station never sends an attitude command outside the vehicles' limits, whatever the guidance
computes: the runner's formation tick is driven with extreme states (huge errors and speeds, NaN states,
coincident vehicles, beyond the geofence, below the minimum altitude) and every SET_ATTITUDE_TARGET on the
wire is decoded and checked."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.command_limits import CommandLimits, guard_attitude_commands
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig
from gcs_swarm.mission import load_mission

QUICKSTART = Path(__file__).resolve().parents[3] / "missions" / "quickstart.yaml"


class Capture:
    """Stands in for a vehicle's endpoint: keeps every packet the ground station sends."""

    def __init__(self) -> None:
        self.packets: list[bytes] = []

    def send(self, packet: bytes, sysid: int | None) -> bool:
        self.packets.append(bytes(packet))
        return True


@pytest.fixture
def flying():
    """A runner in formation flight over a fleet whose links send into one Capture."""
    mission = load_mission(QUICKSTART)
    fleet = Fleet(
        [VehicleConfig(v.name, "udpout:127.0.0.1:9", sysid=i + 1) for i, v in enumerate(mission.vehicles)],
        mission.origin,
    )
    capture = Capture()
    for i, link in enumerate(fleet.links):
        link.channel.sysid, link.channel.endpoint = i + 1, capture  # type: ignore[assignment]
    st = fleet.state
    st.alive[:] = True
    st.time_ms[:] = st.position_ms[:] = 1000  # fresh telemetry
    st._pos = np.array([v.start.position for v in mission.vehicles], dtype=float) + [0.0, 0.0, 10.0]
    st.vel[:] = 0.0
    st.att[:] = 0.0
    runner = MissionRunner(mission, fleet, None, progress=lambda _line: None)
    runner._enter_formation()
    return runner, capture


def scenarios(runner: MissionRunner):
    """(name, pos, vel, att) extreme states, (N,3) each."""
    safety = runner.mission.safety
    n = len(runner.mission.vehicles)
    ring = np.array([[math.cos(a), math.sin(a), 0.0] for a in np.linspace(0, 2 * math.pi, n, endpoint=False)])
    yield (
        "huge errors and speeds",
        np.full((n, 3), 1e6) * ring + [0, 0, 20],
        np.full((n, 3), 1e3),
        np.zeros((n, 3)),
    )
    nan_row = np.zeros((n, 3))
    nan_row[0] = np.nan
    yield "NaN state", nan_row + 20.0, nan_row, nan_row
    yield "coincident vehicles", np.tile([5.0, 5.0, 20.0], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3))
    fence = (safety.geofence_radius + 5.0) * ring + [0, 0, 20]
    yield "beyond the geofence", fence, 10.0 * ring, np.zeros((n, 3))
    yield "beyond the geofence, flying back in", fence, -10.0 * ring, np.zeros((n, 3))
    low = np.array([v.start.position for v in runner.mission.vehicles], dtype=float)
    low[:, 2] = safety.min_altitude - 3.0
    yield "below the minimum altitude", low, np.tile([0.0, 0.0, -20.0], (n, 1)), np.zeros((n, 3))
    yield "tumbling", np.tile([0.0, 0.0, 20.0], (n, 1)) + ring * 10, np.zeros((n, 3)), np.full((n, 3), 3.0)


def decode(packets: list[bytes]) -> list[mavlink2.MAVLink_set_attitude_target_message]:
    parser = mavlink2.MAVLink(None)
    messages = [parser.decode(bytearray(p)) for p in packets]
    return [m for m in messages if m.get_type() == "SET_ATTITUDE_TARGET"]


@pytest.mark.parametrize("tight", [False, True], ids=["mission-limits", "guard-tighter-than-guidance"])
def test_every_attitude_target_on_the_wire_is_within_limits(flying, tight: bool) -> None:
    """With the mission's limits the guidance mostly stays inside them itself; a guard tighter than the
    guidance (10 deg tilt, 1.2 g) must change commands, and the runner counts those vehicle-ticks."""
    runner, capture = flying
    st = runner.fleet.state
    if tight:
        runner.command_limits = dataclasses.replace(
            runner.command_limits, tilt_max=math.radians(10), thrust_max_g=1.2
        )
    limits = runner.command_limits
    safety = runner.mission.safety
    for name, pos, vel, att in scenarios(runner):
        capture.packets.clear()
        st._pos, st.vel[:], st.att[:] = np.array(pos, dtype=float), vel, att
        st.time_ms[:] += 20
        st.position_ms[:] = st.time_ms
        runner._formation_tick()
        targets = decode(capture.packets)
        finite = np.isfinite(np.hstack((pos, vel, att))).all(axis=1)
        assert len(targets) == np.count_nonzero(finite), name  # a NaN state gets no command at all
        for msg in targets:
            i = msg.target_system - 1
            w, x, y, z = msg.q
            assert all(math.isfinite(v) for v in (*msg.q, msg.thrust)), name
            assert abs(w * w + x * x + y * y + z * z - 1.0) < 1e-3, name  # ArduPilot's unit-length check
            tilt = math.acos(min(1.0, max(-1.0, 1.0 - 2.0 * (x * x + y * y))))
            assert tilt <= limits.tilt_max + 1e-4, (name, i, math.degrees(tilt))
            assert 0.0 <= msg.thrust <= min(1.0, runner.setup.hover[i] * limits.thrust_max_g) + 1e-6, name
            if not np.isfinite(pos[i]).all():
                continue
            if pos[i, 2] <= safety.min_altitude:
                # never accelerate down below the floor
                assert msg.thrust >= runner.setup.hover[i] - 1e-6, name
            if math.hypot(pos[i, 0], pos[i, 1]) >= safety.geofence_radius:
                # thrust direction (body -z, NED->FRD quaternion) in ENU: outward only to brake
                east, north = -2.0 * (y * z - w * x), -2.0 * (x * z + w * y)
                outward = east * pos[i, 0] + north * pos[i, 1] > 1e-6
                assert not outward or brakes([east, north], pos[i], vel[i]), name
    assert runner.commands_limited > 0 or not tight


def brakes(a: list[float], pos: np.ndarray, vel: np.ndarray) -> bool:
    """Horizontal acceleration direction a (east, north) slows vel down without steering further out than -vel
    (the guard's exception to "never tilt outward beyond the fence")."""
    a_h, x, v = np.asarray(a, dtype=float), pos[:2], vel[:2]
    steeper = np.dot(a_h, x) * np.linalg.norm(v) > -np.dot(v, x) * np.linalg.norm(a_h) + 1e-9
    return bool(np.dot(a_h, v) < 0 and not steeper)


FENCE = CommandLimits(math.radians(35), 2.0, 1.0, 100.0, 50.0)
OUTSIDE = [110.0, 0.0, 10.0]  # east of the origin, 10 m beyond the fence: east is outward


def _guard_toward(east: float, north: float, vel: list[float] | None, pos: list[float] = OUTSIDE):  # noqa: B006
    """Guard one command at yaw 0 whose thrust tilts 0.3 rad toward the horizontal direction (east, north)."""
    s = math.sin(0.3) / math.hypot(east, north)
    roll = math.asin(-north * s)  # horizontal thrust direction at yaw 0: (sin p cos r, -sin r)
    pitch = math.asin(east * s / math.cos(roll))
    return guard_attitude_commands(
        np.array([roll]),
        np.array([pitch]),
        np.zeros(1),
        np.array([0.5]),
        np.array([pos]),
        np.zeros(1),
        np.full(1, 0.5),
        FENCE,
        vel=None if vel is None else np.array([vel]),
    )


@pytest.mark.parametrize(
    ("why", "toward", "vel"),
    [
        ("flying straight back in, braking", (1.0, 0.0), [-8.0, 0.0, 0.0]),
        ("flying in and sideways, braking straight", (8.0, -3.0), [-8.0, 3.0, 0.0]),
        ("flying in and sideways, braking less outward", (1.0, -1.0), [-8.0, 3.0, 0.0]),
    ],
)
def test_outside_the_fence_a_vehicle_flying_back_in_may_brake(
    why: str, toward: tuple[float, float], vel: list[float]
) -> None:
    roll, pitch, _, _, changed = _guard_toward(*toward, vel)
    assert not changed[0] and math.hypot(roll[0], pitch[0]) > 0.29, why


@pytest.mark.parametrize(
    ("why", "toward", "vel"),
    [
        ("no velocity given (the old rule)", (1.0, 0.0), None),
        ("moving outward", (1.0, 0.0), [8.0, 0.0, 0.0]),
        ("standing still", (1.0, 0.0), [0.0, 0.0, 0.0]),
        ("moving sideways", (1.0, -1.0), [0.0, 8.0, 0.0]),
        ("velocity unknown", (1.0, 0.0), [math.nan, math.nan, math.nan]),
        ("flying in and sideways, braking more outward than -v", (1.0, 0.0), [-8.0, 3.0, 0.0]),
        ("flying in, speeding up sideways", (1.0, 3.0), [-8.0, 3.0, 0.0]),
    ],
)
def test_outside_the_fence_an_outward_tilt_that_does_not_only_brake_is_levelled(
    why: str, toward: tuple[float, float], vel: list[float]
) -> None:
    roll, pitch, _, _, changed = _guard_toward(*toward, vel)
    assert (roll[0], pitch[0], changed[0]) == (0.0, 0.0, True), why


def test_inside_the_fence_velocity_changes_nothing() -> None:
    roll, pitch, _, _, changed = _guard_toward(1.0, 0.0, [8.0, 0.0, 0.0], pos=[50.0, 0.0, 10.0])
    assert not changed[0] and pitch[0] == pytest.approx(0.3)


def test_guard_leaves_commands_within_limits_unchanged() -> None:
    limits = CommandLimits(math.radians(35), 2.0, 1.0, 100.0, 50.0)
    roll, pitch, yaw, thrust = (
        np.array([0.2, -0.3]),
        np.array([0.1, 0.2]),
        np.array([1.0, -2.0]),
        np.array([0.5, 0.7]),
    )
    pos = np.array([[0.0, 0.0, 10.0], [10.0, 0.0, 10.0]])
    r, p, y, t, changed = guard_attitude_commands(roll, pitch, yaw, thrust, pos, yaw, np.full(2, 0.5), limits)
    assert not changed.any()
    np.testing.assert_array_equal(np.stack([r, p, y, t]), np.stack([roll, pitch, yaw, thrust]))
