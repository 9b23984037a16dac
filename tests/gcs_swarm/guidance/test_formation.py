"""Formation geometry, leader heading and communication topology (spec 6, 11.4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.formation import (
    LeaderHeading,
    check_offsets,
    formation_offsets,
    formation_targets,
    leader_frame_offsets,
    rotate_to_world,
    slot_positions,
)
from gcs_swarm.guidance.topology import (
    PAPER_SIX_UAV_ADJACENCY,
    LeaderRelay,
    check_adjacency,
    hop_counts,
    laplacian,
    star_adjacency,
)
from swarm_common.obstacle_shapes import NO_SHAPES

TABLE3_OFFSETS = np.array(
    [[0, 0, 0], [-30, -30, 0], [30, -30, 0], [-60, -60, 0], [0, -60, 0], [60, -60, 0]], float
)


def test_slots_rotate_rigidly_with_the_leader_heading():
    offsets = np.vstack([np.zeros(3), formation_offsets("v", 8, 20.0)])
    p_lead = np.array([100.0, -50.0, 30.0])
    base = slot_positions(p_lead, 0.0, offsets)
    dist0 = np.linalg.norm(base[:, None] - base[None], axis=2)
    for psi in np.linspace(-math.pi, math.pi, 13):
        slots = slot_positions(p_lead, psi, offsets)
        np.testing.assert_allclose(np.linalg.norm(slots[:, None] - slots[None], axis=2), dist0, atol=1e-12)
        np.testing.assert_allclose(leader_frame_offsets(slots, p_lead, psi), offsets, atol=1e-12)
        np.testing.assert_allclose(slots[:, 2], p_lead[2] + offsets[:, 2])


@pytest.mark.parametrize("psi_deg", [0.0, 45.0, 90.0, 180.0])
def test_offsets_recovered_and_directions_right(psi_deg):
    """At psi = 90 deg a slot 10 m behind the leader lies 10 m south of it; left is west (spec 11.4)."""
    psi = math.radians(psi_deg)
    offsets = np.array([[0, 0, 0], [-10.0, 0, 0], [0, 5.0, 0]])
    slots = slot_positions(np.zeros(3), psi, offsets)
    np.testing.assert_allclose(leader_frame_offsets(slots, np.zeros(3), psi), offsets, atol=1e-12)
    np.testing.assert_allclose(slots[1, :2], [-10 * math.cos(psi), -10 * math.sin(psi)], atol=1e-12)
    np.testing.assert_allclose(slots[2, :2], [-5 * math.sin(psi), 5 * math.cos(psi)], atol=1e-12)


def test_paper_six_uav_offsets_give_table3_targets():
    """Reading (a) of spec 6: delta_i = R(-45 deg) (target_i - target_1); slots at psi = 45 deg are the
    targets."""
    targets = np.array(
        [[4500, 4500, 200], [4470, 4470, 200], [4530, 4470, 200], [4440, 4440, 200], [4500, 4440, 200]]
        + [[4560, 4440, 200]],
        dtype=float,
    )
    delta = rotate_to_world(targets - targets[0], -math.pi / 4)
    np.testing.assert_allclose(slot_positions(targets[0], math.pi / 4, delta), targets, atol=1e-9)
    np.testing.assert_allclose(rotate_to_world(TABLE3_OFFSETS, 0.0), TABLE3_OFFSETS)


def targets_at(t, p0, v, psi0, rate, offsets, lead=0, margin=0.0, centres=None, radii=None, destination=None):
    """formation_targets for a leader at p0 + v t heading psi0 + rate t (constant v and rate), goal at the
    origin (and the followers' destinations round `destination`, default the goal); every vehicle heard the
    leader now."""
    psi = psi0 + rate * t
    heard = np.tile(np.concatenate([p0 + v * t, v, [psi, rate], np.zeros(3)]), (len(offsets), 1))
    cos, sin = np.full(len(offsets), math.cos(psi)), np.full(len(offsets), math.sin(psi))
    centres = np.zeros((0, 3)) if centres is None else centres
    radii = np.zeros(0) if radii is None else radii
    destination = np.zeros(3) if destination is None else destination
    goal, none = np.zeros(3), np.zeros((0, 3))
    return formation_targets(
        heard, cos, sin, offsets, 1.0, centres, radii, margin, lead, goal, destination, none, *NO_SHAPES
    )


def test_followers_destinations_are_round_the_legs_end_and_the_leaders_is_its_goal():
    """While the leader flies to a via point (the goal, here the origin) of a leg that ends at a waypoint
    elsewhere, the followers' adaptive-factor destinations are their offsets round that waypoint (rotated by
    psi_L), and the leader's is the via point it flies to (spec 6a.8)."""
    offsets = np.vstack([np.zeros(3), formation_offsets("column", 2, 7.0)])
    end = np.array([100.0, 40.0, 10.0])
    dest = targets_at(
        0.0, np.array([5.0, 0.0, 10.0]), np.zeros(3), math.pi / 2, 0.0, offsets, destination=end
    )[3]
    np.testing.assert_allclose(dest[0], np.zeros(3), atol=1e-12)
    np.testing.assert_allclose(dest[1:], [[100.0, 33.0, 10.0], [100.0, 26.0, 10.0]], atol=1e-12)  # by hand


def test_slot_feed_forwards_are_the_time_derivatives_of_the_slot():
    """Spec 8 step 1: the slot velocity and acceleration feed-forwards are the first and second time
    derivatives of the slot of a leader moving at constant velocity and turn rate (central differences);
    the leader's own row is its goal with zero feed-forwards."""
    offsets = np.vstack([np.zeros(3), formation_offsets("grid", 6, 12.0)])
    p0, v = np.array([5.0, 7.0, 20.0]), np.array([3.0, -1.0, 0.5])
    psi0, rate = 0.4, 0.3
    slot = lambda t: targets_at(t, p0, v, psi0, rate, offsets)[0]  # noqa: E731
    targets, v_ff, a_ff, dest = targets_at(1.0, p0, v, psi0, rate, offsets)
    np.testing.assert_allclose(targets[1:], slot_positions(p0 + v, psi0 + rate, offsets)[1:], atol=1e-12)
    h = 1e-4
    velocity = (slot(1.0 + h) - slot(1.0 - h)) / (2 * h)
    acceleration = (slot(1.0 + h) - 2 * slot(1.0) + slot(1.0 - h)) / (h * h)
    np.testing.assert_allclose(v_ff[1:], velocity[1:], atol=1e-6)
    np.testing.assert_allclose(a_ff[1:], acceleration[1:], atol=1e-4)
    np.testing.assert_array_equal(targets[0], np.zeros(3))
    np.testing.assert_array_equal(v_ff[0], np.zeros(3))
    np.testing.assert_array_equal(a_ff[0], np.zeros(3))
    np.testing.assert_allclose(dest, slot_positions(np.zeros(3), psi0 + rate, offsets), atol=1e-12)


def test_a_slot_inside_an_obstacle_goes_out_horizontally():
    """slot_margin > 0: a slot within r + margin of an obstacle's centre (horizontally, at heights the grown
    sphere covers) goes radially out to that circle at its own height; others stay."""
    offsets = np.array([[0.0, 0.0, 0.0], [-10.0, 0.0, 0.0], [-30.0, 0.0, 0.0]])
    centres, radii = np.array([[-9.0, 0.0, 3.0]]), np.array([4.0])  # slot 1 at (-10, 0, 0): 1 m off centre
    targets = targets_at(0.0, np.zeros(3), np.zeros(3), 0.0, 0.0, offsets, 0, 1.0, centres, radii)[0]
    ring = math.sqrt(5.0**2 - 3.0**2)  # the grown sphere's circle at the slot's height (dz = 3 m)
    np.testing.assert_allclose(targets[1], [-9.0 - ring, 0.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(targets[2], [-30.0, 0.0, 0.0])
    on_axis = targets_at(
        0.0, np.zeros(3), np.zeros(3), 0.0, 0.0, offsets, 0, 1.0, centres + [-1.0, 0, 0], radii
    )[0]
    np.testing.assert_allclose(on_axis[1], [-10.0 + ring, 0.0, 0.0], atol=1e-12)  # on the axis: out along +x


def test_shapes():
    v = formation_offsets("v", 4, 20.0)
    c45 = 20 * math.cos(math.pi / 4)
    np.testing.assert_allclose(
        v, [[-c45, -c45, 0], [-c45, c45, 0], [-2 * c45, -2 * c45, 0], [-2 * c45, 2 * c45, 0]]
    )
    np.testing.assert_allclose(formation_offsets("line", 3, 5.0), [[0, -5, 0], [0, 5, 0], [0, -10, 0]])
    np.testing.assert_allclose(formation_offsets("column", 3, 5.0), [[-5, 0, 0], [-10, 0, 0], [-15, 0, 0]])
    grid = formation_offsets("grid", 8, 10.0)  # rows of 3 behind the leader, centred on its track
    np.testing.assert_allclose(grid[:3], [[-10, 10, 0], [-10, 0, 0], [-10, -10, 0]])
    np.testing.assert_allclose(grid[3:6, 0], -20.0)
    assert len({tuple(r) for r in grid}) == 8
    assert formation_offsets("v", 0, 20.0).shape == (0, 3)
    with pytest.raises(ValueError, match="shape must be one of"):
        formation_offsets("circle", 3, 5.0)
    with pytest.raises(ValueError, match="spacing"):
        formation_offsets("v", 3, 0.0)


def test_explicit_offsets_are_validated():
    check_offsets(TABLE3_OFFSETS, 6, 0)
    with pytest.raises(ValueError, match="leader's offset"):
        check_offsets(TABLE3_OFFSETS, 6, 1)
    with pytest.raises(ValueError, match="shape"):
        check_offsets(TABLE3_OFFSETS[:, :2], 6, 0)
    bad = TABLE3_OFFSETS.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        check_offsets(bad, 6, 0)


def test_leader_heading_follows_course_with_rate_limit_and_holds():
    dt = 0.02
    h = LeaderHeading(0.0, min_speed=3.0, rate_max=math.radians(30), hold_distance=20.0)
    for _ in range(50):  # 1 s toward +y: 30 deg of turn at most
        h.update(np.array([0.0, 10.0]), 500.0, dt)
    assert h.psi == pytest.approx(math.radians(30))
    assert h.rate == pytest.approx(math.radians(30))
    for _ in range(200):
        h.update(np.array([0.0, 10.0]), 500.0, dt)
    assert h.psi == pytest.approx(math.pi / 2)
    held = h.psi
    h.update(np.array([-10.0, 0.0]), 15.0, dt)  # within d_g of the goal: held
    h.update(np.array([-2.0, 0.0]), 500.0, dt)  # slower than heading_min_speed: held
    assert h.psi == held and h.rate == 0.0
    h = LeaderHeading(math.radians(170), 3.0, math.radians(30), 20.0)
    h.update(np.array([-10.0, -1.0]), 500.0, 0.1)  # course -174 deg: turns +3 deg across +-180
    assert h.psi == pytest.approx(math.radians(173))
    for _ in range(10):
        h.update(np.array([-10.0, -1.0]), 500.0, 0.1)
    assert h.psi == pytest.approx(math.atan2(-1.0, -10.0))  # reached across the +-180 deg seam


def test_paper_topology_laplacian_and_hops():
    a = PAPER_SIX_UAV_ADJACENCY
    expected_l = np.array(
        [
            [2, -1, -1, 0, 0, 0],
            [-1, 2, 0, -1, 0, 0],
            [-1, 0, 2, 0, 0, -1],
            [0, -1, 0, 2, -1, 0],
            [0, 0, 0, -1, 2, -1],
            [0, 0, -1, 0, -1, 2],
        ],
        dtype=float,
    )
    np.testing.assert_array_equal(np.diag(laplacian(a)), [2] * 6)  # every vehicle of the ring has degree 2
    np.testing.assert_array_equal(laplacian(a), expected_l)
    np.testing.assert_allclose(np.sort(np.linalg.eigvalsh(laplacian(a))), [0, 1, 1, 3, 3, 4], atol=1e-12)
    np.testing.assert_array_equal(hop_counts(a, 0), [0, 1, 1, 2, 3, 2])
    np.testing.assert_array_equal(check_adjacency(a, 6, 0), [0, 1, 1, 2, 3, 2])
    np.testing.assert_array_equal(hop_counts(star_adjacency(5, 2), 2), [1, 1, 0, 1, 1])


def test_adjacency_validation():
    a = PAPER_SIX_UAV_ADJACENCY.copy()
    a[3, :] = a[:, 3] = 0  # UAV4 cut off, and UAV5 then only through UAV6
    with pytest.raises(ValueError, match="vehicles 3 cannot hear the leader"):
        check_adjacency(a, 6, 0)
    with pytest.raises(ValueError, match="shape"):
        check_adjacency(np.zeros((5, 5)), 6, 0)
    with pytest.raises(ValueError, match="diagonal"):
        check_adjacency(np.eye(6) + PAPER_SIX_UAV_ADJACENCY, 6, 0)
    directed = np.zeros((3, 3))
    directed[1, 0] = directed[2, 1] = 1  # 0 -> 1 -> 2, one way
    np.testing.assert_array_equal(hop_counts(directed, 0), [0, 1, 2])
    np.testing.assert_array_equal(hop_counts(directed, 2), [-1, -1, 0])


def test_relay_delays_the_leader_state_one_tick_per_hop():
    hops = hop_counts(PAPER_SIX_UAV_ADJACENCY, 0)
    relay = LeaderRelay(hops, np.array([-1.0]))
    for tick in range(6):
        relay.push(np.array([float(tick)]))
        heard = relay.read()[:, 0]
        np.testing.assert_array_equal(heard, np.maximum(tick - hops, -1))
