"""A follower feels an obstacle only within its slot's clearance from it less a margin (field.slot_ranges,
FieldParams.slot_range), the slot looked ahead along the follower's own braking path: the figures worked by
hand from the spec's adaptive repulsion (spec 3.2 Eqs 10-12) with the influence distance l0 replaced by the
pair's range."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_swarm.guidance.field import obstacle_repulsion, slot_ranges
from gcs_swarm.guidance.params import FieldParams, paper_plain_field
from swarm_common.obstacle_shapes import NO_SHAPES, pack_shapes

K_REP, N_EXP, L0 = 1e5, 0.8, 20.0
CENTRES = np.array([[0.0, 0.0, 10.0]])  # one sphere of radius 5 m
RADII = np.array([5.0])


def ranges_of(slots, followers, shapes=NO_SHAPES, margin=3.0, floor=5.0, braking=None):
    slots, followers = np.asarray(slots, dtype=float), np.asarray(followers, dtype=bool)
    braking = np.zeros_like(slots) if braking is None else np.asarray(braking, dtype=float)
    return slot_ranges(slots, braking, followers, CENTRES, RADII, *shapes, L0, margin, floor)


def test_a_followers_range_is_its_slots_clearance_less_the_margin_within_floor_and_l0():
    slots = [
        [20.0, 0.0, 10.0],  # 15 m clear: 15 - 3 = 12 m
        [7.0, 0.0, 10.0],  # 2 m clear: 2 - 3 < 5, the floor
        [0.0, 0.0, 10.0],  # inside the sphere: the floor
        [45.0, 0.0, 10.0],  # 40 m clear: 37 m, no more than l0
        [20.0, 0.0, 10.0],  # the leader's row: l0 whatever its target
    ]
    ranges = ranges_of(slots, [True, True, True, True, False])
    assert ranges.shape == (5, 1)
    assert ranges[:, 0] == pytest.approx([12.0, 5.0, 5.0, 20.0, 20.0])


def test_shapes_count_after_the_spheres_by_their_surface_distance():
    # a vertical cylinder of radius 4 m round (0, 50), 0-30 m high; a slot 12 m from its axis is 8 m clear
    shapes = pack_shapes(cylinders=[((0.0, 50.0), 4.0, 0.0, 30.0)])
    ranges = ranges_of([[0.0, 62.0, 10.0], [30.0, 0.0, 10.0]], [True, True], shapes)
    # row 0: sphere 62.0 - 5 - 3 = 54 -> 20, cylinder 8 - 3 = 5; row 1: sphere 25 - 3 = 22 -> 20, cylinder
    # hypot(30, 50) - 4 - 3 = 51.3 -> 20
    assert ranges == pytest.approx(np.array([[20.0, 5.0], [20.0, 20.0]]))


def test_the_slot_is_looked_ahead_along_the_followers_braking_path():
    # slots 40 m short of the sphere and 13 m to its side, each follower's braking path 50 m along x
    slots = [[-40.0, 13.0, 10.0], [-40.0, 13.0, 10.0], [-40.0, 13.0, 10.0]]
    braking = [
        [50.0, 0.0, 0.0],  # passes (0, 13): 13 - 5 = 8 m clear, less 3: 5 m
        [25.0, 0.0, 0.0],  # ends at (-15, 13): hypot(15, 13) - 5 = 14.85 m clear, less 3
        [-50.0, 0.0, 0.0],  # away from it: the slot's own hypot(40, 13) - 5 - 3 = 34.06 m, no more than l0
    ]
    ranges = ranges_of(slots, [True, True, True], floor=4.0, braking=braking)
    assert ranges[:, 0] == pytest.approx([5.0, np.hypot(15.0, 13.0) - 8.0, L0])
    # without the look-ahead the slot 37 m from the surface keeps l0 on every row
    assert ranges_of(slots, [True, True, True], floor=4.0)[:, 0] == pytest.approx([L0, L0, L0])


def test_a_shapes_range_is_taken_along_the_braking_path_too():
    # the cylinder of radius 4 m round (0, 50): a slot at (-40, 62) braking 60 m along x passes 12 m from
    # its axis, 8 m from its surface: 8 - 3 = 5 m; the sphere stays beyond l0 + margin (hypot(0, 62) - 5)
    shapes = pack_shapes(cylinders=[((0.0, 50.0), 4.0, 0.0, 30.0)])
    ranges = ranges_of([[-40.0, 62.0, 10.0]], [True], shapes, braking=[[60.0, 0.0, 0.0]])
    assert ranges == pytest.approx(np.array([[20.0, 5.0]]), abs=1e-5)


def adaptive_magnitudes(l: float, rho: float, l0: float) -> tuple[float, float]:
    """|F*_rep1| and |F*_rep2| of spec 3.2 Eqs 11-12 at surface distance l, goal distance rho."""
    bracket = 1.0 / l - 1.0 / l0
    return K_REP * bracket * rho**N_EXP / l**2, 0.5 * N_EXP * K_REP * bracket**2 * rho ** (N_EXP - 1.0)


@pytest.mark.parametrize(
    ("x", "reach"),
    [
        (15.0, 12.0),  # 10 m from the surface, within the follower's 12 m: the repulsion with l0 = 12
        (18.0, 12.0),  # 13 m from the surface: beyond its range, nothing (the paper's l0 = 20 m would push)
        (9.0, 5.0),  # a slot in the obstacle: the 5 m floor still pushes a vehicle 4 m off the surface
    ],
)
def test_the_repulsion_within_a_pairs_range_is_the_papers_with_that_range(x, reach):
    fp = paper_plain_field(k_rep=K_REP, n=N_EXP, l0=L0)
    q = np.array([[x, 0.0, 10.0]])
    dest = np.array([[x + 100.0, 0.0, 10.0]])  # straight away from the obstacle, 100 m off
    ranges = np.array([[reach]])
    force = obstacle_repulsion(q, q, dest, CENTRES, RADII, fp, ranges=ranges)[0]
    l = x - 5.0
    if l > reach:
        assert np.all(force == 0.0)
        assert obstacle_repulsion(q, q, dest, CENTRES, RADII, fp)[0][0] > 0.0  # l0 = 20 m reaches it
        return
    f1, f2 = adaptive_magnitudes(l, 100.0, reach)
    # n_o (away from the sphere) and n_g (toward dest) are both +x here
    assert force == pytest.approx([f1 + f2, 0.0, 0.0], rel=1e-12)
    assert force[0] < obstacle_repulsion(q, q, dest, CENTRES, RADII, fp)[0][0]  # weaker than with l0 = 20 m


def test_without_ranges_every_pair_reaches_l0():
    fp = paper_plain_field(k_rep=K_REP, n=N_EXP, l0=L0)
    q = np.array([[20.0, 0.0, 10.0]])  # 15 m from the surface
    dest = np.array([[120.0, 0.0, 10.0]])
    f1, f2 = adaptive_magnitudes(15.0, 100.0, L0)
    assert obstacle_repulsion(q, q, dest, CENTRES, RADII, fp)[0] == pytest.approx([f1 + f2, 0.0, 0.0])


def test_the_paper_variant_turns_it_off_and_the_default_is_on():
    assert paper_plain_field().slot_range is False
    assert FieldParams().slot_range is True
    for floor in (0.0, L0 + 1.0):
        with pytest.raises(ValueError, match="slot_range_floor"):
            FieldParams(l0=L0, slot_range_floor=floor)
    with pytest.raises(ValueError, match="slot_range_margin"):
        FieldParams(slot_range_margin=-1.0)
