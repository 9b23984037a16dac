"""The leader waits for its followers (gcs_swarm.guidance.leader_wait): the slot error and the cap factor by
hand, and closed loop on point masses with PX4 SIH's drag, where followers cannot outrun the leader."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets, slot_positions
from gcs_swarm.guidance.inversion import thrust_vector
from gcs_swarm.guidance.leader_wait import (
    leader_cap_scale,
    leader_wait_scale,
    turn_wait_scale,
    worst_slot_error,
)
from gcs_swarm.guidance.params import G, ReferenceParams

DT = 0.02
ATTITUDE_LAG = 0.08  # s
SIH_DRAG = 1.0  # 1/s: PX4 SIH's quad, 1 N per m/s on 1 kg; at 35 deg tilt its top speed is g tan 35 = 6.9 m/s


def test_worst_slot_error_by_hand():
    # leader at (10, 0, 5) heading north (psi = 90 deg): the slot 10 m behind it is at (10, -10)
    pos = np.array([[10.0, 0.0, 5.0], [13.0, -6.0, 9.0], [500.0, 500.0, 5.0]])
    offsets = np.array([[0.0, 0.0, 0.0], [-10.0, 0.0, 0.0], [-20.0, 0.0, 0.0]])
    world = np.array([[0.0, 0.0, 0.0], [0.0, -10.0, 0.0], [0.0, -20.0, 0.0]])
    followers = np.array([False, True, False])  # the far vehicle is not waited for
    assert worst_slot_error(pos, 0, world, followers) == pytest.approx(
        5.0
    )  # hypot(3, 4); 4 m of height ignored
    assert worst_slot_error(pos, 0, world, np.zeros(3, dtype=bool)) == 0.0
    # leader_cap_scale rotates the offsets itself; 5 m against a wait of 3 m over 10 m: 1 - 2/10
    assert leader_cap_scale(pos, 0, offsets, math.pi / 2, followers, 3.0, 10.0, 0.2) == pytest.approx(0.8)
    followers[2] = True  # 20 m behind a slot 20 m south of the leader: (500, 500) vs (10, -20)
    assert leader_cap_scale(pos, 0, offsets, math.pi / 2, followers, 3.0, 10.0, 0.2) == 0.2
    pos[2] = np.nan  # a vehicle never heard from is not waited for
    assert leader_cap_scale(pos, 0, offsets, math.pi / 2, followers, 3.0, 10.0, 0.2) == pytest.approx(0.8)


@pytest.mark.parametrize(
    ("error", "expected"),
    [(0.0, 1.0), (3.0, 1.0), (5.5, 0.75), (8.0, 0.5), (11.0, 0.2), (100.0, 0.2)],
)
def test_cap_factor_falls_linearly_from_the_wait_to_the_floor(error, expected):
    assert leader_wait_scale(error, 3.0, 10.0, 0.2) == pytest.approx(expected)


def test_no_wait_when_off():
    assert leader_wait_scale(50.0, 0.0, 10.0, 0.2) == 1.0


@pytest.mark.parametrize(
    "bad",
    [
        {"leader_wait_m": -1.0},
        {"leader_wait_span_m": 0.0},
        {"leader_wait_floor": 0.0},
        {"leader_wait_floor": 1.5},
        {"turn_wait_deg": -1.0},
        {"turn_wait_span_deg": 0.0},
        {"turn_wait_floor": 0.0},
        {"turn_wait_floor": 1.5},
    ],
)
def test_bad_parameters_are_refused(bad):
    with pytest.raises(ValueError, match=next(iter(bad)).split("_wait")[0] + "_wait"):
        ReferenceParams(**bad)


class DraggedPointMasses:
    """Point masses with linear drag SIH_DRAG (1/s): thrust along body z, attitude follows the command with a
    lag. At the 35 deg tilt limit the level top speed is g tan(35 deg) / SIH_DRAG = 6.9 m/s."""

    def __init__(self, pos: np.ndarray) -> None:
        self.pos = np.array(pos, dtype=float)
        self.vel = np.zeros_like(self.pos)
        self.att = np.zeros_like(self.pos)

    def step(self, cmd) -> None:
        target = np.stack([cmd.roll_d, cmd.pitch_d, cmd.yaw_d], axis=1)
        d = target - self.att
        d[:, 2] = (d[:, 2] + math.pi) % (2 * math.pi) - math.pi
        self.att = self.att + d * (DT / ATTITUDE_LAG)
        acc = thrust_vector(self.att[:, 0], self.att[:, 1], self.att[:, 2], cmd.thrust_acc)
        acc[:, 2] -= G
        acc -= SIH_DRAG * self.vel
        self.vel = self.vel + acc * DT
        self.pos = self.pos + self.vel * DT


def slot_errors(reference: ReferenceParams, seconds: float = 60.0) -> tuple[np.ndarray, float]:
    """A V of 5 (10 m spacing) from a line abreast, leader cap 10 m/s, a 90 deg turn at the first waypoint:
    ((steps,) worst horizontal follower slot error m, leader's time s to its final goal within 1 m)."""
    n = 5
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("v", n - 1, 10.0)
    waypoints = np.array([[150.0, 0.0, 20.0], [150.0, 250.0, 20.0]])
    ctl = FleetController(n, 0, offsets, waypoints, reference=reference, control_dt=DT)
    start = np.column_stack([np.zeros(n), 10.0 * np.arange(n), np.full(n, 20.0)])
    plant = DraggedPointMasses(start)
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    active = np.ones(n, dtype=bool)
    worst, arrived = [], math.inf
    for k in range(int(seconds / DT)):
        cmd = ctl.tick(k * DT, plant.pos, plant.vel, plant.att, np.zeros((0, 3)), np.zeros(0), active)
        plant.step(cmd)
        slots = slot_positions(plant.pos[0], cmd.psi_leader, offsets)
        worst.append(np.hypot(*(plant.pos[1:, :2] - slots[1:, :2]).T).max())
        if math.isinf(arrived) and np.linalg.norm(plant.pos[0] - waypoints[-1]) < 1.0:
            arrived = (k + 1) * DT
    return np.array(worst), arrived


def test_a_waiting_leader_keeps_followers_that_cannot_outrun_it_near_their_slots():
    """(The compiled tick when numba is installed; tick_replay's grid_7_slow shows the numpy steps give the
    same bytes.)"""
    plain, plain_arrival = slot_errors(ReferenceParams(leader_wait_m=0.0, turn_wait_deg=0.0), 80.0)
    waiting, waiting_arrival = slot_errors(
        ReferenceParams(leader_wait_m=3.0, leader_wait_span_m=10.0, turn_wait_deg=0.0), 80.0
    )
    # straight flight after the V assembled (15-30 s) and after the turn at the first waypoint (50-60 s)
    straight = np.r_[int(15.0 / DT) : int(30.0 / DT), int(50.0 / DT) : int(60.0 / DT)]
    # the paper's leader flies flat out at the airframe's g tan(35 deg) / drag = 6.86 m/s, as fast as its
    # followers: the ones that fell behind stay behind
    assert np.median(plain[straight]) > 15.0
    # waiting: a follower flat out at 6.86 m/s holds the leader's cap at 6.86 m/s, factor 0.686, so it trails
    # its slot by at most 3 + 10 x (1 - 0.686) = 6.14 m in the steady state
    assert waiting[straight].max() < 6.6
    # the turn swings the outer slots faster than any follower can fly: a transient, smaller than the
    # paper's steady trail
    assert waiting[int(15.0 / DT) :].max() < plain[int(15.0 / DT) :].max()
    assert np.isfinite(plain_arrival) and np.isfinite(waiting_arrival)  # both get there; waiting costs time
    assert waiting_arrival > plain_arrival


def test_a_tight_formation_flies_as_if_the_wait_were_off():
    """Below leader_wait_m the commands are the paper's, bit for bit."""
    n = 3
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("v", n - 1, 10.0)
    goal = np.array([[100.0, 0.0, 20.0]])
    pos = slot_positions(np.array([0.0, 0.0, 20.0]), 0.0, offsets)
    pos[1:, :2] += [[1.0, -0.5], [-0.5, 1.0]]  # within 3 m of the slots
    commands = []
    for reference in (ReferenceParams(leader_wait_m=0.0), ReferenceParams(leader_wait_m=3.0)):
        ctl = FleetController(n, 0, offsets, goal, reference=reference, control_dt=DT)
        ctl.reset(pos, np.zeros((n, 3)), np.zeros(n))
        cmd = ctl.tick(
            0.0, pos, np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((0, 3)), np.zeros(0), np.ones(n, bool)
        )
        commands.append((cmd.roll_d, cmd.pitch_d, cmd.thrust_acc, cmd.ref_vel))
        assert ctl.leader_speed_scale == 1.0
    for off, on in zip(*commands, strict=True):
        np.testing.assert_array_equal(off, on)


def test_only_the_leaders_cap_is_scaled():
    offsets = np.zeros((3, 3))
    offsets[1:] = formation_offsets("v", 2, 10.0)
    ctl = FleetController(3, 1, offsets[[1, 0, 2]], np.array([[100.0, 0.0, 20.0]]))  # the leader is row 1
    ctl.leader_speed_scale = 0.5
    ctl.set_degraded(0.8, 1.0)
    # v_xy_leader 10 m/s x 0.5, v_xy 20 m/s; all x the degraded-flight 0.8
    np.testing.assert_allclose(ctl.speed_caps(), [16.0, 4.0, 16.0])


def test_the_leader_waits_for_the_formation_to_turn():
    """turn_wait_scale: 1 while psi_L lags the direction to the waypoint by up to turn_wait_deg, then falling
    linearly over turn_wait_span_deg to turn_wait_floor; either way round; 1 while the heading holds."""
    ref = ReferenceParams(turn_wait_deg=20.0, turn_wait_span_deg=30.0, turn_wait_floor=0.4)
    here = np.array([10.0, 10.0, 20.0])
    north = here + [0.0, 100.0, 0.0]  # the waypoint bears 90 deg (ENU)
    for psi_deg, expected in ((90.0, 1.0), (75.0, 1.0), (70.0, 1.0), (55.0, 0.5), (125.0, 0.5), (45.0, 0.4)):
        scale = turn_wait_scale(here, north, math.radians(psi_deg), True, ref, 10.0)
        assert scale == pytest.approx(expected), psi_deg
    assert turn_wait_scale(here, north, math.radians(-90.0), True, ref, 10.0) == pytest.approx(0.4)  # 180 deg
    assert turn_wait_scale(here, north, math.radians(-90.0), False, ref, 10.0) == 1.0  # holding near the goal
    # a leg capped at 6 m/s: never below 1.25 x heading_min_speed (3 m/s) = 3.75 m/s, 0.625 of the cap, or
    # psi_L would stop turning; a cap at or under that: no wait at all
    assert turn_wait_scale(here, north, math.radians(-90.0), True, ref, 6.0) == pytest.approx(0.625)
    assert turn_wait_scale(here, north, math.radians(-90.0), True, ref, 3.0) == 1.0


def test_the_formation_turns_before_the_leader_runs_down_the_new_leg():
    """A column of 4, 7 m apart, flies east to a waypoint and turns 90 deg north. Its heading turns no faster
    than its tail can swing at heading_sweep_max (4 m/s over 21 m: 11 deg/s): without the turn wait the leader
    runs down the new leg at full speed with the column still pointing east behind it; with it the leader
    creeps until psi_L is within 50 deg of north, so the column has turned before the leader is 40 m up the
    leg (point masses on their references)."""
    n = 4
    offsets = np.zeros((n, 3))
    offsets[1:, 0] = [-7.0, -14.0, -21.0]
    route = np.array([[60.0, 0.0, 20.0], [60.0, 200.0, 20.0]])
    up_the_leg = {}
    for wait in (0.0, 20.0):
        ctl = FleetController(
            n, 0, offsets, route, reference=ReferenceParams(turn_wait_deg=wait), control_dt=DT
        )
        pos = slot_positions(np.array([0.0, 0.0, 20.0]), 0.0, offsets)
        ctl.reset(pos, np.zeros((n, 3)), np.zeros(n))
        for k in range(int(40.0 / DT)):
            cmd = ctl.tick(
                k * DT,
                pos,
                ctl.generator.v,
                np.zeros((n, 3)),
                np.zeros((0, 3)),
                np.zeros(0),
                np.ones(n, bool),
            )
            pos = ctl.generator.p.copy()
            if ctl.waypoint_index == 1 and abs(cmd.psi_leader - math.pi / 2) < math.radians(10.0):
                up_the_leg[wait] = pos[0, 1]
                break
    assert up_the_leg[20.0] < 40.0 < up_the_leg[0.0]


@pytest.mark.parametrize("sweep_accel", [0.0, 1.0])
def test_the_formations_turn_speeds_up_no_harder_than_its_tail_can_follow(sweep_accel):
    """The column of 4 above (its tail 21 m astern) flies east and turns north at its waypoint. psi_L's turn
    rate changes by at most heading_accel_max_deg (20 deg/s^2 = 0.349 rad/s^2) and, with heading_sweep_accel
    1 m/s^2, by at most 1 / 21 = 0.0476 rad/s^2, so that the tail slot's swing round the leader speeds up
    and slows down by at most 1 m/s^2; without it the turn starts at the full 0.349 rad/s^2, 7.3 m/s^2 at
    the tail. Either way psi_L ends up north."""
    n = 4
    offsets = np.zeros((n, 3))
    offsets[1:, 0] = [-7.0, -14.0, -21.0]
    route = np.array([[60.0, 0.0, 20.0], [60.0, 200.0, 20.0]])
    reference = ReferenceParams(heading_sweep_accel=sweep_accel)
    ctl = FleetController(n, 0, offsets, route, reference=reference, control_dt=DT)
    pos = slot_positions(np.array([0.0, 0.0, 20.0]), 0.0, offsets)
    ctl.reset(pos, np.zeros((n, 3)), np.zeros(n))
    rates = []
    for k in range(int(60.0 / DT)):
        ctl.tick(
            k * DT, pos, ctl.generator.v, np.zeros((n, 3)), np.zeros((0, 3)), np.zeros(0), np.ones(n, bool)
        )
        pos = ctl.generator.p.copy()
        assert ctl.heading is not None
        rates.append(ctl.heading.rate)
    turn_accel = np.max(np.abs(np.diff(rates))) / DT
    if sweep_accel > 0.0:
        assert turn_accel <= sweep_accel / 21.0 + 1e-9
    else:
        assert turn_accel == pytest.approx(math.radians(20.0))
    assert ctl.heading.psi == pytest.approx(math.pi / 2, abs=math.radians(1.0))
