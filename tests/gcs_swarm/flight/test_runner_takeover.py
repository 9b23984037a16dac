"""The mission runner's decisions when a vehicle is taken over (gcs_swarm.flight.runner with
gcs_swarm.flight.takeover; docs/reliability.md "Operator takeover"), read from what it sends over a scripted
fleet (tests/gcs_swarm/flight/scripted_fleet.py): the quickstart's three vehicles at 10 m, heading 37 deg.

A leader taken over: the others brake and hold (position targets, no attitude target), `resume` is refused,
and after run.leader_takeover_timeout_s they land; or `leader NAME` promotes a follower (slots re-formed
round it, it flies to the goal), or `rejoin` hands the old leader back. A vehicle switched away during the
climb is taken over too, and the formation starts without it.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.connection import LinkError
from gcs_swarm.mission import load_mission
from tests.gcs_swarm.flight.scripted_fleet import TICK_MS, ScriptedFleet

MISSIONS = Path(__file__).resolve().parents[3] / "missions"
NAMES = ["lead", "right", "left"]
LEAD, RIGHT, LEFT = 0, 1, 2
GUIDED, LOITER = 4, 5  # ArduCopter custom_mode (ArduCopter/mode.h)
GOAL = np.array([160.0, 120.0, 10.0])  # quickstart's goal, m ENU
YAW = math.radians(37.0)  # every vehicle's heading (ENU, counter-clockwise from East)
# right is placed 25 m from the lead, far from everything (> d_max 10 m and > l0 20 m + lost_radius 3 m
# from any other vehicle and obstacle), so that as a leader only the goal's attraction acts on it
START = np.array([[0.0, 0.0, 10.0], [20.0, -15.0, 10.0], [-10.0, 1.5, 10.0]])
TIMEOUT_S = 5.0  # run.leader_takeover_timeout_s of these tests


def v_slot(side: float) -> np.ndarray:
    """First V slot of the quickstart (spacing 10 m, half-angle 45 deg) in the leader frame: 10 m behind
    along the arm, `side` -1 right, +1 left: (-10 cos 45, side 10 sin 45, 0)."""
    return np.array([-10.0 * math.cos(math.pi / 4), side * 10.0 * math.sin(math.pi / 4), 0.0])


def flying(stage: str = "formation") -> tuple[MissionRunner, ScriptedFleet, list[str]]:
    """A runner over the scripted fleet: at `stage` "ground" nothing commanded yet (on the ground, 0 m);
    "climbing" the launch commanded (GUIDED, arm, takeoff: its own) and the climb under way (0 m);
    "formation" launched at 10 m, then in formation flight for five ticks."""
    mission = load_mission(MISSIONS / "quickstart.yaml")
    run = dataclasses.replace(mission.run, leader_takeover_timeout_s=TIMEOUT_S)
    mission = dataclasses.replace(mission, run=run)
    start = START.copy()
    if stage != "formation":
        start[:, 2] = 0.0
    fleet = ScriptedFleet(NAMES, start, yaw=YAW)
    lines: list[str] = []
    runner = MissionRunner(mission, fleet, None, progress=lines.append)  # type: ignore[arg-type]
    if stage == "ground":
        return runner, fleet, lines
    runner.command_launch()
    if stage == "formation":
        runner.start_formation()
        for _ in range(5):
            runner.step()
        assert runner.phase == "formation"
        assert fleet.kinds_at(fleet.now_ms) == {i: {"attitude"} for i in range(3)}
    return runner, fleet, lines


def take_over(fleet: ScriptedFleet, runner: MissionRunner, row: int) -> int:
    """Someone else switches vehicle `row` to LOITER; the next tick sees it. Returns that tick's vehicle
    ms."""
    fleet.state.mode[row] = LOITER
    runner.step()
    return fleet.now_ms


def test_leader_taken_the_others_brake_and_hold_resume_is_refused() -> None:
    runner, fleet, lines = flying()
    fleet.state.vel[RIGHT] = [3.0, 0.0, 0.0]  # still fast: braked on the spot, re-targeted where it is
    fleet.state.vel[LEFT] = [0.2, 0.0, 0.0]  # below HOLD_LATCH_SPEED 0.5 m/s: that point is held
    t_ms = take_over(fleet, runner, LEAD)

    assert runner.phase == "hold"
    assert runner.controller.leader == LEAD  # a leader taken over keeps the lead until the operator decides
    assert any("leader lead taken over: the formation holds" in line for line in lines)
    # that very tick: a position target to each follower where it is, nothing at all to the leader
    assert fleet.kinds_at(t_ms) == {RIGHT: {"position"}, LEFT: {"position"}}
    sent = {s.row: s.value for s in fleet.sent_to(RIGHT, t_ms) + fleet.sent_to(LEFT, t_ms)}
    np.testing.assert_array_equal(sent[RIGHT], START[RIGHT])
    np.testing.assert_array_equal(sent[LEFT], START[LEFT])
    # both drift 1 m east: right (fast) is re-targeted there, left keeps its latched point
    fleet.state.pos[[RIGHT, LEFT]] += [1.0, 0.0, 0.0]
    runner.step()
    now = {s.row: s.value for s in fleet.sent if s.t_ms == fleet.now_ms}
    np.testing.assert_array_equal(now[RIGHT], START[RIGHT] + [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(now[LEFT], START[LEFT])

    with pytest.raises(ValueError, match="the leader lead is taken over"):
        runner.resume()
    assert runner.phase == "hold"
    assert fleet.sent_to(LEAD, t_ms) == []


def test_no_decision_within_the_timeout_lands_the_others_never_the_leader() -> None:
    runner, fleet, lines = flying()
    t_ms = take_over(fleet, runner, LEAD)
    held = 0
    while runner.phase == "hold" and held < 1000:
        runner.step()
        held += 1
    ticks = round(TIMEOUT_S * 1000 / TICK_MS)  # 5 s of 20 ms ticks: 250 (one more for float rounding)
    assert runner.phase == "land" and ticks <= held <= ticks + 1
    assert any("no decision within 5 s: landing the others" in line for line in lines)
    runner.land()  # as `gcs-swarm run` does when the loop leaves formation/hold

    assert runner.phase == "done"
    landings = [(s.row, s.value) for s in fleet.sent if s.kind == "mode" and s.t_ms > t_ms]
    assert landings == [(RIGHT, "LAND"), (LEFT, "LAND")]
    assert fleet.sent_to(LEAD, t_ms) == []  # never commanded after its takeover, not even LAND
    assert fleet.state.mode[LEAD] == LOITER and fleet.state.armed[LEAD]
    assert runner.result.left_to_operator == ["lead"] and not runner.result.arrived


def test_promoting_a_follower_reforms_round_it_and_flies_it_to_the_goal() -> None:
    runner, fleet, lines = flying()
    t_ms = take_over(fleet, runner, LEAD)
    runner.promote(RIGHT)

    assert runner.phase == "formation"  # the hold was for the leader: the formation flies on
    ctl = runner.controller
    assert ctl.leader == RIGHT
    # one follower flown: left takes the V's first slot (right arm) round right; lead (taken) and right
    # (leader) have none
    np.testing.assert_allclose(ctl.offsets, [np.zeros(3), np.zeros(3), v_slot(-1.0)], atol=1e-12)
    np.testing.assert_array_equal(ctl.waypoints[-1], GOAL)
    runner.step()
    assert fleet.kinds_at(fleet.now_ms) == {RIGHT: {"attitude"}, LEFT: {"attitude"}}
    cmd = runner.last_command
    assert cmd is not None
    # right leads to the goal: 194.49 m = |(140, 135)| away, its horizontal thrust along that bearing
    assert cmd.leader_goal_distance == pytest.approx(math.hypot(140.0, 135.0))
    targets = runner.result.final_targets
    assert targets is not None
    np.testing.assert_array_equal(targets[RIGHT], GOAL)
    u = cmd.u[RIGHT, :2]
    assert math.atan2(u[1], u[0]) == pytest.approx(math.atan2(135.0, 140.0), abs=math.radians(1.0))
    # left's slot: right's position + the right-arm slot turned by the heading 37 deg
    c, s = math.cos(YAW), math.sin(YAW)
    x, y, _ = v_slot(-1.0)
    np.testing.assert_allclose(cmd.slots[LEFT], START[RIGHT] + [c * x - s * y, s * x + c * y, 0.0], atol=1e-9)
    assert "right promoted to leader by the operator" in runner.result.events
    assert any(line == "! right promoted to leader by the operator" for line in lines)
    assert fleet.sent_to(LEAD, t_ms) == []


def test_promote_refusals() -> None:
    runner, fleet, _ = flying()
    with pytest.raises(ValueError, match="lead already leads"):
        runner.promote(LEAD)
    take_over(fleet, runner, LEFT)
    with pytest.raises(ValueError, match=r"left is taken over \(rejoin it first\): it cannot lead"):
        runner.promote(LEFT)


def test_rejoin_of_the_leader_hands_it_back_and_the_formation_flies_on() -> None:
    runner, fleet, _ = flying()
    t_ms = take_over(fleet, runner, LEAD)
    runner.step()
    runner.rejoin(LEAD)

    # the one command to it since the takeover: GUIDED, on the operator's request
    assert [(s.kind, s.value) for s in fleet.sent_to(LEAD, t_ms)] == [("mode", "GUIDED")]
    assert runner.phase == "formation" and runner.controller.leader == LEAD
    assert runner.result.left_to_operator == []
    np.testing.assert_allclose(runner.controller.offsets[LEAD], np.zeros(3))
    runner.step()
    assert fleet.kinds_at(fleet.now_ms) == {i: {"attitude"} for i in range(3)}
    runner.resume()  # no longer refused (and a no-op in formation flight)


def test_the_old_leader_rejoins_as_a_follower_of_the_promoted_one() -> None:
    runner, fleet, _ = flying()
    take_over(fleet, runner, LEAD)
    runner.promote(RIGHT)
    runner.step()
    runner.rejoin(LEAD)

    ctl = runner.controller
    assert ctl.leader == RIGHT
    # two followers: the V's two first slots (right arm, left arm), in whichever order travels least
    slots = sorted(map(tuple, np.round(ctl.offsets[[LEAD, LEFT]], 9)))
    assert slots == sorted([tuple(np.round(v_slot(-1.0), 9)), tuple(np.round(v_slot(1.0), 9))])
    runner.step()
    assert fleet.kinds_at(fleet.now_ms) == {i: {"attitude"} for i in range(3)}


def test_a_vehicle_switched_away_during_the_climb_is_taken_over_and_not_waited_for() -> None:
    """The launch's own GUIDED, arm and takeoff are no takeover; left switched to LOITER at 4 m is, the
    formation starts without it once the other two are up, and it is never commanded again."""
    runner, fleet, lines = flying("climbing")
    sent = [(s.row, s.kind) for s in fleet.sent]
    assert sent == [(i, "mode") for i in range(3)] + [(i, "arm") for i in range(3)] + [
        (i, "takeoff") for i in range(3)
    ]
    runner._launch_since = fleet.now_ms / 1000.0  # as `begin` does (console, tick-driven launch)
    fleet.state.pos[:, 2] = 4.0
    runner.step()
    assert runner.phase == "launch" and not runner.takeover.taken.any()
    t_ms = take_over(fleet, runner, LEFT)
    assert runner.phase == "launch" and runner.result.left_to_operator == ["left"]
    assert any("left taken over: now in LOITER" in line for line in lines)
    fleet.state.pos[[LEAD, RIGHT], 2] = 10.0  # left stays at 4 m, in LOITER
    runner.step()
    assert runner.phase == "formation"
    np.testing.assert_array_equal(runner.controller.offsets[LEFT], np.zeros(3))  # re-formed without it
    runner.step()
    assert fleet.kinds_at(fleet.now_ms) == {LEAD: {"attitude"}, RIGHT: {"attitude"}}
    assert fleet.sent_to(LEFT, t_ms) == []


def test_a_leader_switched_away_during_the_climb_makes_the_formation_start_in_hold() -> None:
    """`gcs-swarm run`'s launch (wait_until): the lead switched to LOITER while climbing is not waited for;
    the formation starts holding, the others get position targets."""
    runner, fleet, lines = flying("ground")

    def climb() -> None:  # each tick: the two followers reach 10 m at once; 1 s in, lead goes to LOITER
        fleet.state.pos[[RIGHT, LEFT], 2] = 10.0
        if fleet.now_ms >= t0_ms + 1000:
            fleet.state.mode[LEAD] = LOITER

    t0_ms = fleet.now_ms
    fleet.on_tick = climb
    runner.launch()  # returns: lead is taken over (seen on the tick it switched), the others are at 10 m
    t_ms = fleet.now_ms
    assert t_ms == t0_ms + 1000
    assert runner.result.left_to_operator == ["lead"]
    assert [s.kind for s in fleet.sent_to(LEAD)] == ["mode", "arm", "takeoff"]  # the launch, nothing after
    runner.start_formation()
    assert runner.phase == "hold"
    assert any("leader lead taken over: the formation holds" in line for line in lines)
    assert fleet.kinds_at(fleet.now_ms) == {RIGHT: {"position"}, LEFT: {"position"}}
    assert fleet.sent_to(LEAD, t_ms) == []


def test_the_launch_waits_for_the_vehicles_still_ours() -> None:
    """Without any takeover the climb is awaited for every vehicle: one stuck at 4 m times the launch out
    (as before takeover detection existed)."""
    runner, fleet, _ = flying("ground")
    fleet.state.pos[[LEAD, RIGHT], 2] = 10.0
    fleet.state.pos[LEFT, 2] = 4.0
    with pytest.raises(LinkError, match="timed out after 60 s waiting for every vehicle at its takeoff"):
        runner.launch()
