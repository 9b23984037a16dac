"""The ground station never sends an attitude command outside the vehicles' limits, whatever the guidance
computes: the runner's formation tick is driven with extreme states (huge errors and speeds, NaN states,
coincident vehicles, beyond the geofence, below the minimum altitude) and every SET_ATTITUDE_TARGET on the
wire is decoded and checked."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.command_limits import CommandLimits, guard_attitude_commands
from gcs_swarm.link.fleet import Fleet, VehicleConfig
from gcs_swarm.mission import load_mission
from gcs_swarm.runner import MissionRunner

QUICKSTART = Path(__file__).resolve().parents[2] / "missions" / "quickstart.yaml"


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
        link.sysid, link.endpoint = i + 1, capture  # type: ignore[assignment]
    st = fleet.state
    st.alive[:] = True
    st.time_ms[:] = 1000
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
    low = np.array([v.start.position for v in runner.mission.vehicles], dtype=float)
    low[:, 2] = safety.min_altitude - 3.0
    yield "below the minimum altitude", low, np.tile([0.0, 0.0, -20.0], (n, 1)), np.zeros((n, 3))
    yield "tumbling", np.tile([0.0, 0.0, 20.0], (n, 1)) + ring * 10, np.zeros((n, 3)), np.full((n, 3), 3.0)


def decode(packets: list[bytes]) -> list[mavlink2.MAVLink_set_attitude_target_message]:
    parser = mavlink2.MAVLink(None)
    messages = [parser.decode(bytearray(p)) for p in packets]
    return [m for m in messages if m.get_type() == "SET_ATTITUDE_TARGET"]


def test_every_attitude_target_on_the_wire_is_within_limits(flying) -> None:
    runner, capture = flying
    st = runner.fleet.state
    limits = runner.command_limits
    safety = runner.mission.safety
    for name, pos, vel, att in scenarios(runner):
        capture.packets.clear()
        st._pos, st.vel[:], st.att[:] = np.array(pos, dtype=float), vel, att
        st.time_ms[:] += 20
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
            assert 0.0 <= msg.thrust <= min(1.0, runner.hover[i] * limits.thrust_max_g) + 1e-6, name
            if not np.isfinite(pos[i]).all():
                continue
            if pos[i, 2] <= safety.min_altitude:
                assert msg.thrust >= runner.hover[i] - 1e-6, name  # never accelerate down below the floor
            if math.hypot(pos[i, 0], pos[i, 1]) >= safety.geofence_radius:
                # body z (up) in ENU from the NED->FRD quaternion: horizontal part must not point outward
                north = 2.0 * (x * z + w * y)
                east = 2.0 * (y * z - w * x)
                assert -(east * pos[i, 0] + north * pos[i, 1]) <= 1e-6, name
    assert runner.commands_limited > 0


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
