"""The followers' top speeds measured from telemetry, and the leader's cap from them (guidance.capability)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.capability import SpeedEnvelope
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.params import PAPER_PLAIN, CapabilityParams, G

PARAMS = CapabilityParams()
TILT_MAX = math.radians(35.0)


def telemetry(drag: np.ndarray, wind: np.ndarray, seconds: float, rate_hz: float = 50.0):
    """Level flight of len(drag) point masses under the linear drag model of sitl-sim's airframe
    (m dv/dt = thrust - drag_lin (v - w), here per unit mass: c = drag), each weaving with its own horizontal
    acceleration a(t) = 3 (cos 0.4 t, sin 0.3 t) m/s^2, integrated with small steps. Yields (t, vel (N, 3),
    att (N, 3)) at rate_hz, the attitude being the one whose thrust makes a(t) against the drag at height."""
    n, step = len(drag), 1e-3
    vel = np.zeros((n, 2))
    t, next_out = 0.0, 0.0
    while t <= seconds:
        accel = (
            3.0 * np.array([math.cos(0.4 * t + k) for k in range(n)]),
            3.0 * np.array([math.sin(0.3 * t + k) for k in range(n)]),
        )
        a = np.stack(accel, axis=1)
        if t >= next_out - 1e-12:
            thrust = a + drag[:, None] * (vel - wind)  # horizontal thrust per unit mass; vertical: g
            pitch = np.arctan(thrust[:, 0] / G)  # yaw 0: axis = (cos r sin p, -sin r, cos r cos p)
            roll = np.arctan(-thrust[:, 1] * np.cos(pitch) / G)
            att = np.stack([roll, pitch, np.zeros(n)], axis=1)
            yield t, np.column_stack([vel, np.zeros(n)]), att
            next_out += 1.0 / rate_hz
        vel = vel + a * step
        t += step


def fitted(drag: np.ndarray, wind: np.ndarray, seconds: float = 40.0) -> SpeedEnvelope:
    envelope = SpeedEnvelope(len(drag), PARAMS, TILT_MAX, G)
    active = np.ones(len(drag), dtype=bool)
    for t, vel, att in telemetry(drag, wind, seconds):
        envelope.update(t, vel, att, active)
    return envelope


def test_the_fit_recovers_each_vehicles_drag_in_calm_air():
    """sitl-sim's airframe: drag_lin 0.25 N s/m on 0.9 kg is c = 0.278 1/s; a PX4 SIH-like one that tops out
    at 6.9 m/s at 35 deg has c = g tan 35 / 6.9 = 0.996 1/s."""
    drag = np.array([0.25 / 0.9, G * math.tan(TILT_MAX) / 6.9])
    envelope = fitted(drag, np.zeros(2))
    np.testing.assert_allclose(envelope.drag, drag, rtol=0.03)


def test_top_speed_is_where_the_drag_takes_the_tilt_share_of_the_thrust():
    """At the top speed along the heading the drag force c |v u - w| (per unit mass) uses exactly the share
    tilt_share of g tan(tilt_max): checked by that force balance, not by the formula the code uses. With a
    6 m/s wind from the north-west, heading east."""
    drag = np.array([0.5, 1.0])
    wind = np.array([4.0, -4.5])
    envelope = fitted(drag, wind)
    heading = 0.0
    speeds = envelope.top_speeds(heading)
    u = np.array([1.0, 0.0])
    for c, v in zip(drag, speeds, strict=True):
        balance = c * np.linalg.norm(v * u - wind)
        assert balance == pytest.approx(PARAMS.tilt_share * G * math.tan(TILT_MAX), rel=0.05)
    # a tail wind adds to the top speed: slower into the wind (heading west)
    assert (envelope.top_speeds(math.pi) < speeds).all()


def test_no_cap_until_the_fit_has_seen_enough_speeds():
    """Hovering vehicles (no velocity spread) give no drag estimate, so no cap: the leader flies its own."""
    envelope = SpeedEnvelope(2, PARAMS, TILT_MAX, G)
    active = np.ones(2, dtype=bool)
    for k in range(200):
        envelope.update(k * 0.02, np.zeros((2, 3)), np.zeros((2, 3)), active)
    assert np.isnan(envelope.drag).all()
    assert envelope.leader_cap(0.0, active) == math.inf


def test_the_leader_is_capped_by_its_slowest_follower_and_the_event_says_so():
    """Three vehicles: the leader and a fast follower (sitl-sim's airframe, top speed 17 m/s at 70 % of the
    tilt) and a slow one (c = 1.0: g tan 35 0.7 / 1.0 = 4.8 m/s in calm air). After the fits settle, the
    leader's cap is the slow follower's top speed, not v_xy_leader (10 m/s), and one event names it."""
    drag = np.array([0.278, 0.278, 1.0])
    offsets = np.array([[0.0, 0.0, 0.0], [-10.0, 10.0, 0.0], [-10.0, -10.0, 0.0]])
    ctl = FleetController(3, 0, offsets, np.array([[500.0, 0.0, 10.0]]), pace=PARAMS, names=("a", "b", "c"))
    pos = offsets + np.array([0.0, 0.0, 10.0])
    ctl.reset(pos, np.zeros((3, 3)), np.zeros(3))
    active = np.ones(3, dtype=bool)
    no_obstacles = np.zeros((0, 3)), np.zeros(0)
    for t, vel, att in telemetry(drag, np.zeros(2), 30.0):
        ctl.tick(t, pos, vel, att, *no_obstacles, active)
    expected = PARAMS.tilt_share * G * math.tan(TILT_MAX) / 1.0
    assert ctl.speed_caps()[0] == pytest.approx(expected, rel=0.05)
    events = [e for e in ctl.drain_events() if "pace" in e]
    assert events and "leader capped at" in events[0] and "what c flies" in events[0]
    assert ctl.drain_events() == []


def test_paper_plain_turns_the_pace_off():
    assert PAPER_PLAIN["guidance.pace"] == {"enabled": False}
    off = CapabilityParams(**PAPER_PLAIN["guidance.pace"])  # type: ignore[arg-type]
    ctl = FleetController(2, 0, np.array([[0.0, 0.0, 0.0], [-5.0, 0.0, 0.0]]), np.zeros((1, 3)), pace=off)
    assert ctl.envelope is None


@pytest.mark.parametrize(
    "bad", [{"tilt_share": 0.0}, {"tilt_share": 1.5}, {"memory_s": 0.0}, {"min_samples": 1}]
)
def test_impossible_settings_are_refused(bad):
    with pytest.raises(ValueError):
        CapabilityParams(**bad)
