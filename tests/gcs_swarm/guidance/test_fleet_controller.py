"""FleetController: closed loop on a point-mass plant with attitude lag, topology relay, lost vehicles,
live changes and input errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.evaluation import metrics
from gcs_swarm.guidance.controller import make_position_controller
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets, rotate_to_world, slot_positions
from gcs_swarm.guidance.inversion import thrust_vector
from gcs_swarm.guidance.params import FieldParams, G, ReferenceParams, SeparationParams
from gcs_swarm.guidance.topology import PAPER_SIX_UAV_ADJACENCY, hop_counts

DT = 0.02
ATTITUDE_LAG = 0.08  # s, first-order attitude response (well inside the 5x bandwidth rule of spec 5)


class PointMassFleet:
    """Point masses driven by thrust along the body z axis; roll/pitch/yaw follow the command with a lag."""

    def __init__(self, pos: np.ndarray) -> None:
        self.pos = np.array(pos, dtype=float)
        self.vel = np.zeros_like(self.pos)
        self.att = np.zeros_like(self.pos)

    def step(self, cmd, active: np.ndarray) -> None:
        target = np.stack([cmd.roll_d, cmd.pitch_d, cmd.yaw_d], axis=1)
        d = target - self.att
        d[:, 2] = (d[:, 2] + math.pi) % (2 * math.pi) - math.pi
        att = self.att + d * (DT / ATTITUDE_LAG)
        acc = thrust_vector(att[:, 0], att[:, 1], att[:, 2], cmd.thrust_acc)
        acc[:, 2] -= G
        self.att = np.where(active[:, None], att, self.att)
        self.vel = np.where(active[:, None], self.vel + acc * DT, self.vel)
        self.pos = np.where(active[:, None], self.pos + self.vel * DT, self.pos)


def v_formation(n: int, spacing: float = 15.0) -> np.ndarray:
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("v", n - 1, spacing)
    return offsets


def fly(controller: str, seconds: float = 50.0, field: FieldParams | None = None):
    n = 5
    offsets = v_formation(n)
    goal = np.array([200.0, 40.0, 20.0])
    # centred on the straight line from the leader's start to its goal: a saddle of the paper's field
    obstacles_c, obstacles_r = np.array([[100.0, 20.0, 20.0]]), np.array([8.0])
    law = make_position_controller(controller)
    ctl = FleetController(n, 0, offsets, goal[None, :], position_controller=law, control_dt=DT, field=field)
    start = offsets + np.array([0.0, 0.0, 20.0])
    start[1:, :2] += [[2, 1], [-1, 2], [1, -2], [-2, -1]]  # followers a little off their slots
    plant = PointMassFleet(start)
    ctl.reset(plant.pos, plant.vel, plant.att[:, 2])
    active = np.ones(n, dtype=bool)
    times, track, psi, emergency = [], [], [], 0
    for k in range(int(seconds / DT)):
        cmd = ctl.tick(k * DT, plant.pos, plant.vel, plant.att, obstacles_c, obstacles_r, active)
        plant.step(cmd, active)
        times.append((k + 1) * DT)
        track.append(plant.pos.copy())
        psi.append(cmd.psi_leader)
        emergency += int(cmd.emergency.sum())
    return np.array(times), np.array(track), np.array(psi), offsets, goal, obstacles_c, obstacles_r, emergency


def test_without_circulation_a_goal_straight_behind_an_obstacle_stalls_the_smooth_reference():
    """The obstacle's centre lies on the leader's straight line to the goal, so the paper's repulsion points
    straight back along it: with the braking-path reference and no circulation (spec 8a.4) the leader brakes
    onto the saddle, short of the obstacle, and stays there (it is still > 100 m from the goal after 40 s);
    test_closed_loop_formation_passes_an_obstacle_and_reaches_the_goal flies the same with the default."""
    t, p, *_ = fly("smc", seconds=40.0, field=FieldParams(circulation=0.0))
    goal = np.array([200.0, 40.0, 20.0])
    late = t > 30.0
    assert np.linalg.norm(p[late, 0] - goal, axis=1).min() > 100.0
    assert np.linalg.norm(p[late, 0] - np.array([100.0, 20.0, 20.0]), axis=1).min() > 8.0  # no collision


@pytest.mark.parametrize("controller", ["smc", "pid"])
def test_closed_loop_formation_passes_an_obstacle_and_reaches_the_goal(controller):
    t, p, psi, offsets, goal, oc, orad, emergency = fly(controller)
    t_reach = metrics.reach_time(t, np.linalg.norm(p[:, 0] - goal, axis=1), r_goal=1.0, hold_s=2.0)
    assert t_reach is not None and t_reach < 45.0
    clearance, collided = metrics.min_obstacle_clearance(p, oc, orad)
    assert not collided and clearance > 0.5
    assert metrics.min_separation(p) > SeparationParams().d_emg
    assert emergency == 0
    fe = metrics.formation_error(t, p, 0, psi, offsets)
    assert fe.t_settle is not None and fe.t_settle < 48.0
    assert fe.max <= 1.0
    final_slots = slot_positions(p[-1, 0], psi[-1], offsets)
    assert np.linalg.norm(p[-1] - final_slots, axis=1).max() < 1.0


def test_controller_is_deterministic():
    a = fly("smc", seconds=3.0)
    b = fly("smc", seconds=3.0)
    np.testing.assert_array_equal(a[1], b[1])


def make(n=6, **kwargs) -> FleetController:
    offsets = kwargs.pop("offsets", v_formation(n))
    goal = kwargs.pop("goal", np.array([[500.0, 0.0, 20.0]]))
    return FleetController(n, 0, offsets, goal, **kwargs)


def test_relay_topology_delays_each_follower_by_its_hops():
    """Paper ring (hops 0,1,1,2,3,2): a follower's slot comes from the leader state of `hops` ticks ago."""
    n = 6
    offsets = v_formation(n)
    ctl = make(n, offsets=offsets, adjacency=PAPER_SIX_UAV_ADJACENCY, topology="relay")
    hops = hop_counts(PAPER_SIX_UAV_ADJACENCY, 0)
    pos = offsets + np.array([0.0, 0.0, 20.0])
    zero = np.zeros((n, 3))
    ctl.reset(pos, zero, np.zeros(n))  # heading 0, held: the leader reference is slower than 3 m/s
    leader_path = []
    for k in range(8):
        pos[0] = [k * 0.1, 0.0, 20.0]
        leader_path.append(pos[0].copy())
        cmd = ctl.tick(k * DT, pos, zero, zero, np.zeros((0, 3)), np.zeros(0), np.ones(n, dtype=bool))
        for i in range(1, n):
            heard = leader_path[max(k - hops[i], 0)] if k >= hops[i] else np.array([0.0, 0.0, 20.0])
            np.testing.assert_allclose(cmd.slots[i], heard + offsets[i], atol=1e-12)
        np.testing.assert_allclose(cmd.slots[0], [500.0, 0.0, 20.0])


def test_broadcast_topology_has_no_delay():
    n = 4
    offsets = v_formation(n)
    ctl = make(n, offsets=offsets)
    pos = offsets + np.array([0.0, 0.0, 20.0])
    zero = np.zeros((n, 3))
    ctl.reset(pos, zero, np.zeros(n))
    pos[0] = [1.0, 2.0, 21.0]
    cmd = ctl.tick(0.0, pos, zero, zero, np.zeros((0, 3)), np.zeros(0), np.ones(n, dtype=bool))
    np.testing.assert_allclose(cmd.slots[1:], pos[0] + offsets[1:])


def test_lost_vehicle_is_not_commanded_but_still_repels():
    n = 3
    offsets = np.array([[0, 0, 0], [-20.0, 0, 0], [-40.0, 0, 0]])
    pos = offsets + np.array([0.0, 0.0, 20.0])
    zero = np.zeros((n, 3))
    nothing = (np.zeros((0, 3)), np.zeros(0))

    def first_tick(active: np.ndarray, lost_at: np.ndarray) -> object:
        ctl = make(n, offsets=offsets)
        ctl.reset(pos, zero, np.zeros(n))
        moved = pos.copy()
        moved[2] = lost_at
        return ctl.tick(0.0, moved, zero, zero, *nothing, active)

    near = pos[1] + [0.0, 3.0, 0.0]  # 3 m from vehicle 1: inside D_max
    all_on = first_tick(np.ones(n, dtype=bool), near)
    lost = first_tick(np.array([True, True, False]), near)
    assert np.isnan(lost.roll_d[2]) and np.isnan(lost.thrust_acc[2]) and not lost.active[2]
    assert np.isfinite(lost.roll_d[:2]).all()
    # the lost vehicle repels from its last known position (the reset one), not from the stale new telemetry
    ctl = make(n, offsets=offsets)
    ctl.reset(np.vstack([pos[:2], near]), zero, np.zeros(n))
    cmd = ctl.tick(
        0.0, np.vstack([pos[:2], [[0.0, 0.0, 0.0]]]), zero, zero, *nothing, np.array([1, 1, 0], bool)
    )
    assert cmd.field_force[1, 1] < -100.0  # pushed away (-y) from the lost vehicle's last position
    assert all_on.field_force[1, 1] < -100.0


def test_unknown_vehicle_is_ignored_and_reinitialised_when_it_returns():
    n = 3
    offsets = np.array([[0, 0, 0], [-20.0, 0, 0], [-40.0, 0, 0]])
    pos = offsets + np.array([0.0, 0.0, 20.0])
    zero = np.zeros((n, 3))
    nothing = (np.zeros((0, 3)), np.zeros(0))
    ctl = make(n, offsets=offsets)
    unknown = pos.copy()
    unknown[2] = np.nan
    ctl.reset(unknown, zero, np.zeros(n))
    cmd = ctl.tick(0.0, unknown, zero, zero, *nothing, np.array([True, True, False]))
    assert np.isfinite(cmd.field_force[:2]).all()
    back = pos.copy()
    back[2] = [-45.0, 3.0, 18.0]
    cmd = ctl.tick(DT, back, zero, zero, *nothing, np.ones(n, dtype=bool))
    assert np.linalg.norm(cmd.ref_pos[2] - back[2]) < 0.1  # the reference restarts at the vehicle


def test_waypoints_set_goal_and_set_offsets():
    n = 2
    offsets = np.array([[0, 0, 0], [-10.0, 0, 0]])
    waypoints = np.array([[3.0, 0.0, 20.0], [100.0, 0.0, 20.0]])
    ctl = FleetController(n, 0, offsets, waypoints)
    pos = offsets + [0.0, 0.0, 20.0]
    zero = np.zeros((n, 3))
    nothing = (np.zeros((0, 3)), np.zeros(0))
    ctl.reset(pos, zero, np.zeros(n))
    cmd = ctl.tick(0.0, pos, zero, zero, *nothing, np.ones(n, dtype=bool))
    assert cmd.waypoint_index == 1  # within waypoint_radius (5 m) of the first: on to the second
    assert cmd.leader_goal_distance == pytest.approx(100.0)
    ctl.set_goal(np.array([0.0, 50.0, 30.0]))
    ctl.set_offsets(np.array([[0, 0, 0], [0.0, 8.0, 0]]))
    cmd = ctl.tick(DT, pos, zero, zero, *nothing, np.ones(n, dtype=bool))
    assert cmd.waypoint_index == 0
    np.testing.assert_allclose(cmd.slots[0], [0.0, 50.0, 30.0])
    np.testing.assert_allclose(cmd.slots[1], pos[0] + rotate_to_world(np.array([[0.0, 8.0, 0]]), 0.0)[0])
    with pytest.raises(ValueError, match="leader's offset"):
        ctl.set_offsets(np.array([[1.0, 0, 0], [0.0, 8.0, 0]]))
    with pytest.raises(ValueError, match="shape"):
        ctl.set_goal(np.array([1.0, 2.0]))


def test_paper_literal_follower_reference_is_the_slot_without_obstacles():
    n = 3
    offsets = np.array([[0, 0, 0], [-20.0, 10.0, 0], [-20.0, -10.0, 0]])
    ctl = make(n, offsets=offsets, reference=ReferenceParams(paper_literal=True))
    pos = offsets + np.array([0.0, 0.0, 20.0]) + 1.0  # every follower 1.7 m off its slot
    zero = np.zeros((n, 3))
    ctl.reset(pos, zero, np.zeros(n))
    cmd = ctl.tick(0.0, pos, zero, zero, np.zeros((0, 3)), np.zeros(0), np.ones(n, dtype=bool))
    np.testing.assert_allclose(cmd.ref_pos[1:], pos[0] + offsets[1:], atol=1e-12)
    assert not cmd.ref_acc[1:].any()
    assert np.linalg.norm(cmd.ref_pos[0] - pos[0]) < 0.01  # the leader keeps the generator


def test_thrust_modes_agree_when_level():
    n = 2
    offsets = np.array([[0, 0, 0], [-10.0, 0, 0]])
    pos = offsets + [0.0, 0.0, 20.0]
    zero = np.zeros((n, 3))
    out = []
    for mode in ("measured", "norm"):
        ctl = make(n, offsets=offsets, goal=pos[0][None, :], thrust_mode=mode)
        ctl.reset(pos, zero, np.zeros(n))
        out.append(ctl.tick(0.0, pos, zero, zero, np.zeros((0, 3)), np.zeros(0), np.ones(n, dtype=bool)))
    np.testing.assert_allclose(out[0].thrust_acc, G)
    np.testing.assert_allclose(out[0].thrust_acc, out[1].thrust_acc)


def test_bad_inputs_give_clear_errors():
    n = 3
    offsets = np.array([[0, 0, 0], [-20.0, 0, 0], [-40.0, 0, 0]])
    goal = np.array([[10.0, 0, 20]])
    with pytest.raises(ValueError, match="controller"):
        make_position_controller("lqr")
    with pytest.raises(ValueError, match="topology"):
        FleetController(n, 0, offsets, goal, topology="mesh")
    with pytest.raises(ValueError, match="leader index"):
        FleetController(n, 3, offsets, goal)
    with pytest.raises(ValueError, match="goal waypoints"):
        FleetController(n, 0, offsets, np.zeros((0, 3)))
    with pytest.raises(ValueError, match="cannot hear the leader"):
        FleetController(n, 0, offsets, goal, topology="relay", adjacency=np.zeros((3, 3)))
    ctl = FleetController(n, 0, offsets, goal)
    pos, zero, on = offsets + [0, 0, 20.0], np.zeros((n, 3)), np.ones(n, dtype=bool)
    with pytest.raises(RuntimeError, match="reset"):
        ctl.tick(0.0, pos, zero, zero, np.zeros((0, 3)), np.zeros(0), on)
    ctl.reset(pos, zero, np.zeros(n))
    with pytest.raises(ValueError, match="pos must have shape"):
        ctl.tick(0.0, pos[:2], zero, zero, np.zeros((0, 3)), np.zeros(0), on)
    bad = pos.copy()
    bad[1, 0] = np.inf
    with pytest.raises(ValueError, match="vehicle\\(s\\) 1"):
        ctl.tick(0.0, bad, zero, zero, np.zeros((0, 3)), np.zeros(0), on)
    with pytest.raises(ValueError, match="2 obstacle centres but 1 radii"):
        ctl.tick(0.0, pos, zero, zero, np.zeros((2, 3)), np.ones(1), on)
    with pytest.raises(ValueError, match="radii"):
        ctl.tick(0.0, pos, zero, zero, np.zeros((1, 3)), -np.ones(1), on)
    with pytest.raises(ValueError, match="leader"):
        ctl.reset(np.full((n, 3), np.nan), zero, np.zeros(n))


@pytest.mark.parametrize("closing_leash", [1.0, 0.0])
def test_a_vehicle_closing_too_fast_has_its_reference_held_at_its_closing_leash(closing_leash):
    """Vehicle 1 is 7 m from vehicle 0 (hovering) and flies at it at 6 m/s. The closing-speed cap (2 m/s^2
    at 35 deg, 1 m outside D_Emg = 3 m) allows sqrt(2 x 2 x (7 - 4)) = 3.46 m/s, so it binds. Vehicle 1's
    reference, run 5 m ahead of it sideways, is put back onto the closing leash round vehicle 1
    (closing_leash_m), so that the cap brakes the vehicle itself. With the
    closing leash as long as the leash (5 m) the reference stays where it was; vehicle 0, which closes on
    nobody, keeps its reference."""
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, -10.0, 0.0]])
    ctl = make(2, offsets=offsets, separation=SeparationParams(closing_leash_m=closing_leash))
    free = make(2, offsets=offsets, separation=SeparationParams(closing_leash_m=5.0))
    pos = np.array([[0.0, 0.0, 20.0], [0.0, -7.0, 20.0]])
    vel = np.array([[0.0, 0.0, 0.0], [0.0, 6.0, 0.0]])
    ahead = pos + np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.0]])
    no_obstacles = np.zeros((0, 3)), np.zeros(0)
    refs = []
    for c in (ctl, free):
        c.reset(pos, vel, np.zeros(2))
        c.generator.reset(ahead, vel)
        cmd = c.tick(0.02, pos, vel, np.zeros((2, 3)), *no_obstacles, np.ones(2, dtype=bool))
        refs.append(cmd.ref_pos)
    held, kept = refs
    np.testing.assert_allclose(held[1], [closing_leash, -7.0, 20.0], atol=1e-12)
    np.testing.assert_allclose(kept[1], [5.0, -7.0, 20.0], atol=1e-12)
    np.testing.assert_allclose(held[0], kept[0], atol=1e-12)
    with pytest.raises(ValueError, match="closing_leash_m"):
        SeparationParams(closing_leash_m=-1.0)


def test_vehicles_within_d_emg_are_in_emergency_though_their_references_are_clear():
    """Two vehicles 2 m apart (under D_Emg = 3 m), side by side, whose references have run 5 m ahead of them
    (a vehicle at its tilt limit, its reference on the leash): each reference is sqrt(5^2 + 2^2) = 5.4 m from
    the other vehicle, so only the vehicles' own distance shows the emergency (spec 4, Eq 19). Both are
    flagged, and the pair is pushed apart vertically, the larger index up (Eq 18)."""
    offsets = np.array([[0.0, 0.0, 0.0], [0.0, 10.0, 0.0]])
    ctl = make(2, offsets=offsets)
    pos = np.array([[0.0, 0.0, 20.0], [0.0, 2.0, 20.0]])
    vel = np.array([[4.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    ctl.reset(pos, vel, np.zeros(2))
    ahead = pos + np.array([5.0, 0.0, 0.0])
    ctl.generator.reset(ahead, vel)
    no_obstacles = np.zeros((0, 3)), np.zeros(0)
    cmd = ctl.tick(0.02, pos, vel, np.zeros((2, 3)), *no_obstacles, np.ones(2, dtype=bool))
    reference_distance = np.linalg.norm(ahead[0] - pos[1])
    assert reference_distance > 5.0 > ctl.separation.d_emg
    assert cmd.emergency.tolist() == [True, True]
    assert cmd.field_force[1, 2] > 0.0 > cmd.field_force[0, 2]
