"""The followers' top speeds measured from telemetry, and the leader's cap from them (guidance.capability)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.capability import NO_BUDGET, AccelBudget, SpeedEnvelope, within_budget
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.params import PAPER_PLAIN, CapabilityParams, G, Limits, ReferenceParams
from gcs_swarm.guidance.reference import ReferenceGenerator, no_budgets

PARAMS = CapabilityParams()
START_CAP = CapabilityParams(start_lead_m_s=2.0)  # the start's cap, as by default
NO_START_CAP = CapabilityParams(start_lead_m_s=0.0)
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


def fitted(
    drag: np.ndarray, wind: np.ndarray, seconds: float = 40.0, params: CapabilityParams = PARAMS
) -> SpeedEnvelope:
    envelope = SpeedEnvelope(len(drag), params, TILT_MAX, G)
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
    # one heading per vehicle and another share: the same balance, vehicle 0 north, vehicle 1 south-west
    headings = np.array([math.pi / 2, -3 * math.pi / 4])
    own = envelope.top_speeds(headings, tilt_share=0.9)
    for c, v, psi in zip(drag, own, headings, strict=True):
        u = np.array([math.cos(psi), math.sin(psi)])
        assert c * np.linalg.norm(v * u - wind) == pytest.approx(0.9 * G * math.tan(TILT_MAX), rel=0.05)


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
    ctl = slow_follower_controller(PARAMS)
    expected = PARAMS.tilt_share * G * math.tan(TILT_MAX) / 1.0
    assert ctl.speed_caps()[0] == pytest.approx(expected, rel=0.05)
    events = [e for e in ctl.drain_events() if "pace" in e]
    assert events and "leader capped at" in events[0] and "what c flies" in events[0]
    assert ctl.drain_events() == []


def slow_follower_controller(pace: CapabilityParams) -> FleetController:
    """The leader "a", a follower "b" with sitl-sim's drag and a slow follower "c" (c = 1.0 1/s), weaving
    through 30 s of telemetry (`telemetry`) while the positions stay put."""
    drag = np.array([0.278, 0.278, 1.0])
    offsets = np.array([[0.0, 0.0, 0.0], [-10.0, 10.0, 0.0], [-10.0, -10.0, 0.0]])
    ctl = FleetController(3, 0, offsets, np.array([[500.0, 0.0, 10.0]]), pace=pace, names=("a", "b", "c"))
    pos = offsets + np.array([0.0, 0.0, 10.0])
    ctl.reset(pos, np.zeros((3, 3)), np.zeros(3))
    active = np.ones(3, dtype=bool)
    for t, vel, att in telemetry(drag, np.zeros(2), 30.0):
        ctl.tick(t, pos, vel, att, np.zeros((0, 3)), np.zeros(0), active)
    return ctl


def test_the_leaders_acceleration_budget_is_its_slowest_followers_and_the_event_says_so():
    """The slow follower's disc: drag 1.0 1/s, no wind, radius accel_tilt_share g tan 35 = 6.87 m/s^2 (the
    tilt limit itself by default); one event names it, after the speed cap's. With accel_tilt_share 0 the
    leader keeps no budget."""
    ctl = slow_follower_controller(PARAMS)
    budget = ctl.leader_budget
    assert budget.drag == pytest.approx(1.0, rel=0.03)
    assert abs(budget.drag_wind_x) < 0.05 and abs(budget.drag_wind_y) < 0.05
    assert budget.budget == pytest.approx(G * math.tan(TILT_MAX))
    events = [e for e in ctl.drain_events() if "pace" in e]
    assert "leader accelerates within what c can at 100% tilt against its measured drag 1.00 1/s" in events[1]
    off = slow_follower_controller(CapabilityParams(accel_tilt_share=0.0))
    assert off.leader_budget == NO_BUDGET
    assert not any("accelerates within" in e for e in off.drain_events())


@pytest.mark.parametrize(
    ("accel", "expected"),
    [
        ((3.0, 0.0), (1.0, 0.0)),  # ahead: the thrust a + c v = 7 is cut to 5 along the same line
        ((0.0, 4.0), (0.0, 3.0)),  # across: shortened to 3, where the thrust (4, 3) has length 5
        ((-2.0, 1.0), (-2.0, 1.0)),  # braking: the drag helps, thrust |(2, 1)| inside
        ((-8.0, 0.0), (-8.0, 0.0)),  # hard braking: thrust 4 the other way, inside
    ],
)
def test_within_budget_by_the_thrust_a_follower_needs(accel, expected):
    """Drag 1 1/s, no wind, moving east at 4 m/s, budget 5 m/s^2: the thrust per unit mass a follower needs to
    make the acceleration a at this velocity is a + c v; it may be at most 5, and the acceleration keeps its
    direction. Hand values, and the result's thrust checked directly."""
    a_x, a_y = within_budget(accel[0], accel[1], 4.0, 0.0, 1.0, 0.0, 0.0, 5.0)
    assert (a_x, a_y) == pytest.approx(expected)
    assert math.hypot(a_x + 4.0, a_y) <= 5.0 + 1e-12
    assert within_budget(30.0, 0.0, 4.0, 0.0, *NO_BUDGET) == (30.0, 0.0)


def test_a_reference_faster_than_its_follower_can_fly_is_braked():
    """At 6 m/s east with drag 1 1/s the follower would need thrust 6 > 5 just to hold the speed: whatever is
    asked (here nothing), the reference brakes, by 1 m/s^2, the least that brings the thrust within 5."""
    assert within_budget(0.0, 0.0, 6.0, 0.0, 1.0, 0.0, 0.0, 5.0) == pytest.approx((-1.0, 0.0))
    assert within_budget(2.0, 0.0, 6.0, 0.0, 1.0, 0.0, 0.0, 5.0) == pytest.approx((-1.0, 0.0))


def test_a_budgeted_reference_needs_no_more_thrust_of_its_follower_than_the_budget():
    """A reference set off toward a point 400 m east at the leader's 10 m/s cap: a follower with drag
    c = 0.5 1/s in a 3 m/s north wind, keeping pace with it, needs the thrust a + c (v - w). With the budget
    (f g tan 35 deg at f = 0.7: 4.81 m/s^2) it never needs more than that; without, it needs more (the
    reference accelerates at up to accel_xy_max = 4 m/s^2 with the drag besides). With the budget the
    reference comes up to the follower's top speed east with the wind abeam, where the drag c |v - w| takes
    the whole budget: sqrt(4.81^2 - (0.5 3)^2) / 0.5 = 9.1 m/s, and no further."""
    c, wind = 0.5, np.array([0.0, 3.0])
    radius = 0.7 * G * math.tan(TILT_MAX)
    target = np.array([[400.0, 0.0, 10.0]])
    needs = {}
    for budgeted in (True, False):
        gen = ReferenceGenerator(ReferenceParams(), Limits(), k_att=1.0)
        gen.reset(np.array([[0.0, 0.0, 10.0]]), np.zeros((1, 3)))
        budgets = no_budgets(1)
        if budgeted:
            budgets[0] = AccelBudget(c, c * wind[0], c * wind[1], radius)
        thrust, speeds = [], []
        for _ in range(1500):  # 30 s
            force = 1.0 * (target - gen.p)  # the attraction's pull, unit gain: a demand well over the cap
            p, v, a = gen.step(force, np.zeros((1, 3)), np.array([10.0]), 0.02, np.ones(1, dtype=bool),
                               budgets=budgets)  # fmt: skip
            thrust.append(np.hypot(*(a[0, :2] + c * (v[0, :2] - wind))))
            speeds.append(np.hypot(*v[0, :2]))
        needs[budgeted] = max(thrust)
        if budgeted:
            top = math.sqrt(radius**2 - (c * wind[1]) ** 2) / c
            assert max(speeds) <= top + 1e-6
            assert speeds[-1] == pytest.approx(top, rel=0.02)
    assert needs[True] <= radius + 1e-9
    assert needs[False] > radius + 0.5


def test_paper_plain_turns_the_pace_off():
    assert PAPER_PLAIN["guidance.pace"] == {"enabled": False}
    off = CapabilityParams(**PAPER_PLAIN["guidance.pace"])  # type: ignore[arg-type]
    ctl = FleetController(2, 0, np.array([[0.0, 0.0, 0.0], [-5.0, 0.0, 0.0]]), np.zeros((1, 3)), pace=off)
    assert ctl.envelope is None


@pytest.mark.parametrize(
    "bad",
    [
        {"tilt_share": 0.0},
        {"tilt_share": 1.5},
        {"memory_s": 0.0},
        {"min_samples": 1},
        {"accel_tilt_share": 0.5},  # under tilt_share: a leader at its cap would have to brake
        {"accel_tilt_share": 1.2},
        {"own_tilt_share": 0.5},  # under tilt_share: a follower could not keep the leader's cruise
        {"own_tilt_share": 1.1},
        {"start_lead_m_s": -1.0},
    ],
)
def test_impossible_settings_are_refused(bad):
    with pytest.raises(ValueError):
        CapabilityParams(**bad)


def closed_loop(pace: CapabilityParams, behind_m: float, seconds: float) -> list[float]:
    """`slow_follower_controller`'s fleet with its fitted drags, then the slow follower "c" put `behind_m` m
    west of where it was, every reference started at rest at its vehicle, and every vehicle flying its
    reference exactly for `seconds` s (its next state the reference's state integrated over the tick, its
    attitude the one whose thrust makes the reference's acceleration against its drag, as in `telemetry`);
    the horizontal speeds of c's reference, one per tick."""
    ctl = slow_follower_controller(pace)
    drag = np.array([0.278, 0.278, 1.0])
    pos = np.array([[0.0, 0.0, 10.0], [-10.0, 10.0, 10.0], [-10.0 - behind_m, -10.0, 10.0]])
    vel = np.zeros((3, 3))
    ctl.generator.reset(pos, vel)
    att = np.zeros((3, 3))
    active = np.ones(3, dtype=bool)
    speeds = []
    dt = 0.02
    for k in range(int(seconds / dt)):
        cmd = ctl.tick(30.0 + k * dt, pos, vel, att, np.zeros((0, 3)), np.zeros(0), active)
        speeds.append(float(np.hypot(*cmd.ref_vel[2, :2])))
        thrust = cmd.ref_acc[:, :2] + drag[:, None] * cmd.ref_vel[:, :2]
        pitch = np.arctan(thrust[:, 0] / G)
        roll = np.arctan(-thrust[:, 1] * np.cos(pitch) / G)
        att = np.stack([roll, pitch, np.zeros(3)], axis=1)
        vel = cmd.ref_vel + cmd.ref_acc * dt
        pos = cmd.ref_pos + vel * dt
    return speeds


def test_no_reference_runs_faster_than_its_own_vehicle_flies_at_own_tilt_share():
    """The slow follower c (drag 1.0 1/s, calm air) 40 m behind its slot flies at most
    own_tilt_share g tan 35 / c = 0.9 x 6.87 / 1.0 = 6.18 m/s (the drag then takes that share of the tilt
    limit's thrust), where a reference without the cap runs on toward v_xy (20 m/s) and leaves the vehicle
    behind on the leash."""
    top = PARAMS.own_tilt_share * G * math.tan(TILT_MAX) / 1.0
    capped = closed_loop(PARAMS, 40.0, 12.0)
    assert max(capped) <= top * 1.03
    assert capped[-1] >= top * 0.97  # it does catch up at that speed
    free = closed_loop(CapabilityParams(own_tilt_share=0.0), 40.0, 12.0)
    assert max(free) > top + 2.0


def test_until_a_followers_drag_is_measured_the_leader_keeps_within_start_lead_of_it():
    """Heading east, start_lead_m_s 2: followers flying (4, 0) and (1.5, 3) m/s are 4 and 1.5 m/s along the
    heading, so no slot may run ahead of its follower by more than 2 m/s: the leader's cap is 1.5 + 2 = 3.5
    m/s; if the slower one's slot falls back in the formation at 1 m/s, the leader may fly 1 m/s faster (4.5);
    one flying west at 2 m/s allows 0 (the floor, when there is one); the leader's own row and followers whose
    drag is measured do not count."""
    envelope = SpeedEnvelope(4, START_CAP, TILT_MAX, G)
    vel = np.array([[9.0, 0.0, 0.0], [4.0, 0.0, 0.0], [1.5, 3.0, 0.0], [-2.0, 0.0, 0.0]])
    still = np.zeros(4)
    followers = np.array([False, True, True, False])
    assert envelope.start_cap(vel, 0.0, still, followers, 0.0) == pytest.approx(3.5)
    falling_back = np.array([0.0, 0.0, -1.0, 0.0])
    assert envelope.start_cap(vel, 0.0, falling_back, followers, 0.0) == pytest.approx(4.5)
    followers[3] = True
    assert envelope.start_cap(vel, 0.0, still, followers, 0.0) == pytest.approx(0.0)
    assert envelope.start_cap(vel, 0.0, still, followers, 3.75) == pytest.approx(3.75)
    off = SpeedEnvelope(4, NO_START_CAP, TILT_MAX, G)
    assert off.start_cap(vel, 0.0, still, followers, 3.75) == math.inf
    measured = fitted(np.array([0.278, 0.278, 1.0, 1.0]), np.zeros(2), params=START_CAP)
    assert measured.measured.all()
    assert measured.start_cap(vel, 0.0, still, followers, 3.75) == math.inf
    # a long steady cruise forgets the samples that spread the fit; the cap stays off all the same
    active = np.ones(4, dtype=bool)
    for k in range(1000):
        measured.update(40.0 + 0.2 * k, np.tile([5.0, 0.0, 0.0], (4, 1)), np.zeros((4, 3)), active)
    assert not measured.measured.any()
    assert measured.start_cap(vel, 0.0, still, followers, 3.75) == math.inf


def leader_ahead_of_hovering_followers(
    pace: CapabilityParams, seconds: float, leader_speed: float = 0.0
) -> list[float]:
    """The leader "a" flying its reference exactly toward a goal 500 m east (the vehicle's next state the
    reference's, integrated over the tick), from `leader_speed` m/s east when the formation starts, its
    followers "b" and "c" hovering where they started, for `seconds` s; the leader's reference speeds, one per
    tick."""
    offsets = np.array([[0.0, 0.0, 0.0], [-10.0, 10.0, 0.0], [-10.0, -10.0, 0.0]])
    ctl = FleetController(3, 0, offsets, np.array([[500.0, 0.0, 10.0]]), pace=pace, names=("a", "b", "c"))
    pos = offsets + np.array([0.0, 0.0, 10.0])
    vel = np.zeros((3, 3))
    vel[0, 0] = leader_speed
    ctl.reset(pos, vel, np.zeros(3))
    active = np.ones(3, dtype=bool)
    speeds, dt = [], 0.02
    for k in range(int(seconds / dt)):
        cmd = ctl.tick(k * dt, pos, vel, np.zeros((3, 3)), np.zeros((0, 3)), np.zeros(0), active)
        speeds.append(float(np.hypot(*cmd.ref_vel[0, :2])))
        vel[0], pos[0] = cmd.ref_vel[0], cmd.ref_pos[0] + cmd.ref_vel[0] * dt
    return speeds


def test_a_leader_does_not_run_away_from_followers_whose_drag_is_not_measured():
    """Followers still hovering (no drag fit yet, 0 m/s along the heading): the leader's reference stays at
    the floor TURNING_MARGIN x heading_min_speed = 1.25 x 3 = 3.75 m/s (start_lead_m_s 2 is less), where with
    the cap off it is at v_xy_leader (10 m/s) within 8 s (accelerating at accel_xy_max, 4 m/s^2)."""
    floor = 1.25 * ReferenceParams().heading_min_speed
    held = leader_ahead_of_hovering_followers(START_CAP, 8.0)
    assert max(held) <= floor + 0.05
    assert held[-1] >= floor - 0.05
    free = leader_ahead_of_hovering_followers(NO_START_CAP, 8.0)
    assert free[-1] >= Limits().v_xy_leader - 0.05


def test_the_start_cap_does_not_apply_to_a_formation_that_starts_in_flight():
    """The leader flying 6 m/s east when the formation starts, faster than the cap's floor (1.25 x 3 = 3.75
    m/s; the bundled paper missions start in flight), its followers hovering: no start cap, the leader
    speeds up to v_xy_leader (10 m/s) as with the cap off. At 3 m/s, under the floor, the cap holds it
    there."""
    in_flight = leader_ahead_of_hovering_followers(START_CAP, 8.0, leader_speed=6.0)
    free = leader_ahead_of_hovering_followers(NO_START_CAP, 8.0, leader_speed=6.0)
    assert in_flight == free
    assert in_flight[-1] >= Limits().v_xy_leader - 0.05
    floor = 1.25 * ReferenceParams().heading_min_speed
    slow = leader_ahead_of_hovering_followers(START_CAP, 8.0, leader_speed=3.0)
    assert max(slow) <= floor + 0.05


def test_the_start_cap_ends_once_every_followers_drag_is_measured_and_the_event_says_so():
    ctl = slow_follower_controller(START_CAP)
    assert ctl.start_pace == math.inf
    events = [e for e in ctl.drain_events() if "start" in e]
    assert len(events) == 1 and "every follower's drag measured" in events[0]
