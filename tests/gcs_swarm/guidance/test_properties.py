"""Property tests: forces and commands stay finite and point the right way at the awkward points (at the goal,
on and inside an obstacle, two vehicles at one point, zero velocity, vertical thrust vector)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_swarm.guidance.field import attraction, obstacle_repulsion
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.inversion import invert
from gcs_swarm.guidance.params import FieldParams, Limits, SeparationParams
from gcs_swarm.guidance.separation import DENSE_PAIRS_MAX, neighbour_pairs, uav_repulsion

coord = st.floats(-100, 100, allow_nan=False)
vec3 = st.tuples(coord, coord, coord).map(np.array)
unit = (
    st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1))
    .filter(lambda v: np.linalg.norm(v) > 1e-3)
    .map(lambda v: np.array(v) / np.linalg.norm(v))
)
methods = st.sampled_from(["apf", "iaapf"])
FAST = settings(max_examples=60, deadline=None)


@FAST
@given(goal=vec3, method=methods, n=st.floats(0.2, 2.0))
def test_at_the_goal_attraction_and_rep2_vanish(goal, method, n):
    centre = goal + np.array([[10.0, 0.0, 0.0]])  # goal 5 m from the surface, inside l0
    fp = FieldParams(method=method, n=n)
    q = goal[None, :]
    att = attraction(q, q, fp, 15.0)
    rep = obstacle_repulsion(q, q, q, centre, np.array([5.0]), fp)
    assert np.all(att == 0.0)
    assert np.isfinite(rep).all()
    if method == "iaapf":
        assert np.all(rep == 0.0)  # rho^n = 0 and rho < rho_eps: the goal is an equilibrium (spec 3.2)
    else:
        assert rep[0] @ (goal - centre[0]) > 0  # APF still pushes off the goal: the GNRON offset


@FAST
@given(
    centre=vec3,
    radius=st.floats(0.5, 20),
    direction=unit,
    depth=st.one_of(st.just(0.0), st.floats(1e-6, 1.0)),
    method=methods,
    goal=vec3,
)
def test_on_and_inside_an_obstacle_is_finite_flagged_and_pushes_out(
    centre, radius, direction, depth, method, goal
):
    """depth 0 = on the surface, 1 = at the centre (direction +z there, spec 2.1). The paper's terms (no
    circulation, full vertical weight); the IAAPF's destination lies 50 m outward, so both of its terms
    push out. Elsewhere (`goal`) the force is finite."""
    q = (centre + direction * radius * (1.0 - depth))[None, :]
    offset = q[0] - centre  # rounding can put q exactly on the centre before depth reaches 1
    gap = np.linalg.norm(offset)
    outward = offset / gap if gap > 0 else np.array([0.0, 0.0, 1.0])
    fp = FieldParams(method=method, circulation=0.0, obstacle_vertical=1.0)
    rep = obstacle_repulsion(q, q, q + 50.0 * outward, centre[None, :], np.array([radius]), fp)
    assert np.isfinite(rep).all()
    assert rep[0] @ outward > 0
    anywhere = obstacle_repulsion(
        q, q, goal[None, :], centre[None, :], np.array([radius]), FieldParams(method=method)
    )
    assert np.isfinite(anywhere).all()


@FAST
@given(p=vec3, i=st.integers(0, 4), j=st.integers(0, 4), mode=st.sampled_from(["constant", "formula"]))
def test_two_vehicles_at_one_point_are_pushed_apart_vertically(p, i, j, mode):
    if i == j:
        j = (i + 1) % 5
    pos = np.full((5, 3), 1e4) + np.arange(5)[:, None] * 100.0  # the others far away
    pos[i] = pos[j] = p
    sep = SeparationParams(mode=mode)
    fp = FieldParams(k_uav=5e4, n_uav=0.8, l_min=0.05)
    still, valid = np.zeros_like(pos), np.ones(5, dtype=bool)
    force, emergency = uav_repulsion(
        pos, pos, still, valid, still, 0.0, fp, 10.0, mode == "formula", sep.d_emg, sep.a_e, sep.s_s
    )
    assert np.isfinite(force).all()
    assert emergency[i] and emergency[j]
    up, down = (i, j) if i > j else (j, i)  # larger index pushed up (Eq 18)
    assert force[up, 2] > 0 > force[down, 2]
    np.testing.assert_allclose(force[i], -force[j])


@FAST
@given(
    u=st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-50, 50)).map(np.array),
    yaw=st.floats(-np.pi, np.pi),
    roll=st.floats(-1.5, 1.5),
    pitch=st.floats(-1.5, 1.5),
)
def test_inversion_is_finite_and_within_limits_for_any_demand(u, yaw, roll, pitch):
    lim = Limits()
    for measured in (None, (roll, pitch)):
        mr, mp = (None, None) if measured is None else (np.array([measured[0]]), np.array([measured[1]]))
        cmd = invert(u[None, :], np.array([yaw]), lim, 9.8, mr, mp)
        assert np.isfinite([cmd.roll[0], cmd.pitch[0], cmd.thrust_acc[0]]).all()
        tilt = np.arccos(np.cos(cmd.roll[0]) * np.cos(cmd.pitch[0]))
        assert tilt <= lim.tilt_max + 1e-9
        assert 0 < cmd.thrust_acc[0] <= lim.thrust_max_g * 9.8 + 1e-9


@FAST
@given(yaw=st.floats(-np.pi, np.pi), thrust=st.floats(0.3 * 9.8, 2 * 9.8))
def test_vertical_thrust_vector_gives_level_attitude(yaw, thrust):
    cmd = invert(np.array([[0.0, 0.0, thrust]]), np.array([yaw]), Limits())
    assert abs(cmd.roll[0]) < 1e-12 and abs(cmd.pitch[0]) < 1e-12
    assert cmd.thrust_acc[0] == thrust


@FAST
@given(yaw=st.floats(-np.pi, np.pi), spread=st.floats(0.0, 30.0))
def test_fleet_at_rest_gives_finite_commands_and_holds_heading(yaw, spread):
    """Zero velocity everywhere (and possibly every vehicle at one point): finite commands, psi_L held."""
    n = 4
    offsets = np.array([[0, 0, 0], [-10, 10, 0], [-10, -10, 0], [-20, 0, 0]], dtype=float)
    ctl = FleetController(n, 0, offsets, np.array([[0.0, 0.0, 20.0]]))
    pos = np.array([[0.0, 0.0, 20.0]]) + offsets * (spread / 30.0)
    vel = np.zeros((n, 3))
    att = np.zeros((n, 3))
    att[:, 2] = yaw
    ctl.reset(pos, vel, att[:, 2])
    cmd = ctl.tick(0.0, pos, vel, att, np.zeros((0, 3)), np.zeros(0), np.ones(n, dtype=bool))
    for arr in (cmd.roll_d, cmd.pitch_d, cmd.yaw_d, cmd.thrust_acc, cmd.ref_pos, cmd.field_force):
        assert np.isfinite(arr).all()
    assert cmd.psi_leader == np.float64(np.asarray(yaw + np.pi) % (2 * np.pi) - np.pi)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    radius=st.floats(0.5, 40.0),
    n=st.sampled_from([40, 210]),
)
def test_neighbour_pairs_are_the_brute_force_pairs(seed, radius, n):
    """Dense (40 x 40 candidates) and hash grid (210 x 210 > DENSE_PAIRS_MAX): exactly the pairs closer than
    the radius by a brute-force distance matrix, in ascending i; NaN rows of p_at match nothing. Some points
    sit exactly on grid-cell boundaries (multiples of the radius)."""
    rng = np.random.default_rng(seed)
    p_src = rng.uniform(-120.0, 120.0, (n, 3))
    p_src[: n // 4, :2] = np.round(p_src[: n // 4, :2] / radius) * radius
    p_at = p_src + rng.normal(0.0, radius, (n, 3)) * rng.integers(0, 2, (n, 1))
    p_at[rng.integers(0, n, 3)] = np.nan
    assert (n * n > DENSE_PAIRS_MAX) == (n == 210)
    pairs = neighbour_pairs(p_at, p_src, radius)
    with np.errstate(invalid="ignore"):
        close = np.linalg.norm(p_at[:, None, :] - p_src[None, :, :], axis=2) < radius
    assert sorted(map(tuple, pairs.tolist())) == sorted(zip(*np.nonzero(close), strict=True))
    assert np.all(np.diff(pairs[:, 0]) >= 0)
