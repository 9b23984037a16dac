"""Every potential-field force against the central-difference gradient of its potential (spec 11.1), and the
spec's force figures. The forces are the flight's 3-D kernels; a 2-D scene is their z = 0 plane."""

from __future__ import annotations

import numpy as np
import pytest

from gcs_swarm.guidance import apf, iaapf
from gcs_swarm.guidance.field import attraction_force, obstacle_repulsion
from gcs_swarm.guidance.params import FieldParams, SeparationParams, paper_plain_field
from gcs_swarm.guidance.separation import d_max_formula, repulsion_range, uav_potential, uav_repulsion

H = 1e-6


def in_3d(points: np.ndarray) -> np.ndarray:
    """(N, D) points as (N, 3), z = 0 for D = 2."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    out = np.zeros((len(points), 3))
    out[:, : points.shape[1]] = points
    return out


def attraction(q, goal, k_att, d_g=None):
    """The field's attraction (N, D) toward goal (D,): APF without d_g, IAAPF's segmented with it."""
    target = np.repeat(in_3d(goal), len(q), axis=0)
    segmented = d_g is not None
    force = attraction_force(in_3d(q), target, k_att, d_g if segmented else 0.0, segmented)
    return force[:, : q.shape[1]]


def repulsion(q, centres, radii, dest, method, k_rep, l0, n=0.8, l_min=0.05, rho_eps=1e-3):
    """The field's summed obstacle repulsion (N, D) at q (the paper's terms only: no circulation, full
    vertical weight), adaptive factor toward dest (D,)."""
    fp = paper_plain_field(method=method, k_rep=k_rep, l0=l0, n=n, l_min=l_min, rho_eps=rho_eps)
    q3 = in_3d(q)
    dest3 = np.repeat(in_3d(dest), len(q), axis=0)
    return obstacle_repulsion(q3, q3, dest3, in_3d(centres), radii, fp)[:, : q.shape[1]]


def uav(p_at, p_src, vel, k_uav, n, d_max, sep, l_min, src_valid=None):
    """The inter-UAV force (N, 3) and emergency flags (N,) without the braking sweep."""
    fp = FieldParams(k_uav=k_uav, n_uav=n, l_min=l_min)
    p_at, p_src, vel = in_3d(p_at), in_3d(p_src), in_3d(vel)
    valid = np.ones(len(p_src), dtype=bool) if src_valid is None else src_valid
    return uav_repulsion(
        p_at, p_src, vel, valid, np.zeros_like(vel), 0.0, fp, d_max, sep.mode == "formula",
        min(sep.d_emg, d_max), sep.a_e, sep.s_s,
    )  # fmt: skip


def rep_components(force: np.ndarray, n_o: np.ndarray, n_g: np.ndarray) -> np.ndarray:
    """(N, 2) the magnitudes (f1, f2) with force = f1 n_o + f2 n_g, row by row (least squares)."""
    return np.array(
        [
            np.linalg.lstsq(np.stack([o, g], axis=1), f, rcond=None)[0]
            for f, o, g in zip(force, n_o, n_g, strict=True)
        ]
    )


def numerical_force(potential, q: np.ndarray) -> np.ndarray:
    """-grad U by central differences, (N, D)."""
    grad = np.zeros_like(q)
    for d in range(q.shape[1]):
        step = np.zeros_like(q)
        step[:, d] = H
        grad[:, d] = (potential(q + step) - potential(q - step)) / (2 * H)
    return -grad


def assert_gradient(force: np.ndarray, expected: np.ndarray) -> None:
    scale = np.maximum(np.linalg.norm(expected, axis=1, keepdims=True), 1.0)
    assert np.max(np.abs(force - expected) / scale) < 1e-5


def points_in_shells(rng, dim, centres, radii, l0, n):
    """Points at surface distance 0.3..l0-0.3 of a random obstacle, so every force is non-trivial."""
    k = rng.integers(0, len(radii), n)
    direction = rng.normal(size=(n, dim))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    dist = radii[k] + rng.uniform(0.3, l0 - 0.3, n)
    return centres[k] + direction * dist[:, None]


@pytest.fixture(params=[2, 3], ids=["2d", "3d"])
def scene(request):
    dim = request.param
    rng = np.random.default_rng(dim)
    centres = rng.uniform(-30, 30, (4, dim))
    radii = rng.uniform(1, 6, 4)
    goal = rng.uniform(-40, 40, dim)
    return rng, dim, centres, radii, goal


def test_apf_attraction_is_minus_gradient(scene):
    rng, dim, _, _, goal = scene
    q = rng.uniform(-50, 50, (50, dim))
    expected = numerical_force(lambda x: apf.attraction_potential(x, goal, 100.0), q)
    assert_gradient(attraction(q, goal, 100.0), expected)


def test_apf_repulsion_is_minus_gradient(scene):
    rng, dim, centres, radii, _ = scene
    q = points_in_shells(rng, dim, centres, radii, 10.0, 60)
    expected = numerical_force(lambda x: apf.repulsion_potential(x, centres, radii, 1e3, 10.0, 0.05), q)
    assert_gradient(repulsion(q, centres, radii, np.zeros(dim), "apf", 1e3, 10.0), expected)


@pytest.mark.parametrize("d_g", [5.0, 15.0, 50.0])
def test_segmented_attraction_is_minus_gradient(scene, d_g):
    rng, dim, _, _, goal = scene
    q = goal + rng.uniform(-60, 60, (60, dim))
    pot = lambda x: iaapf.segmented_attraction_potential(x, goal, 100.0, d_g)  # noqa: E731
    expected = numerical_force(pot, q)
    assert_gradient(attraction(q, goal, 100.0, d_g), expected)


@pytest.mark.parametrize("n", [0.5, 0.8, 1.0, 1.5, 2.0])
def test_adaptive_repulsion_is_minus_gradient(scene, n):
    rng, dim, centres, radii, goal = scene
    q = points_in_shells(rng, dim, centres, radii, 20.0, 60)
    pot = lambda x: iaapf.adaptive_repulsion_potential(x, centres, radii, goal, 1e3, 20.0, n, 0.05)  # noqa: E731
    expected = numerical_force(pot, q)
    assert_gradient(repulsion(q, centres, radii, goal, "iaapf", 1e3, 20.0, n=n), expected)


@pytest.mark.parametrize("n", [0.5, 0.8, 1.5])
def test_inter_uav_force_is_minus_gradient(n):
    rng = np.random.default_rng(7)
    for dim in (2, 3):
        p = rng.uniform(0, 12, (6, dim))  # dense enough that most pairs are inside D_max = 10

        def potential(x, i, p=p):
            moved = p.copy()
            moved[i] = x[0]
            return uav_potential(moved, moved, 5e4, n, 10.0)[i : i + 1]

        sep = SeparationParams(d_emg=0.001)  # no emergency term: compare the pure potential force
        force, _ = uav(p, p, np.zeros_like(p), 5e4, n, 10.0, sep, 1e-6)
        for i in range(len(p)):
            expected = numerical_force(lambda x, i=i: potential(x, i), p[i : i + 1])
            assert_gradient(force[i : i + 1, :dim], expected)


def test_segmented_attraction_is_c1_at_d_g_and_capped():
    """Spec 11.1: slopes k_att d_g on both sides of d_g (1500 | 1500), max |F*_att| = k_att d_g."""
    goal = np.zeros(2)
    d_g, k = 15.0, 100.0
    for rho in (d_g - 1e-4, d_g + 1e-4):
        q = np.array([[rho, 0.0]])
        slope = -numerical_force(lambda x: iaapf.segmented_attraction_potential(x, goal, k, d_g), q)[0, 0]
        assert slope == pytest.approx(k * d_g, rel=1e-4)
    value_in = iaapf.segmented_attraction_potential(np.array([[d_g - 1e-9, 0.0]]), goal, k, d_g)
    value_out = iaapf.segmented_attraction_potential(np.array([[d_g + 1e-9, 0.0]]), goal, k, d_g)
    assert value_in[0] == pytest.approx(value_out[0], rel=1e-9)
    q = np.random.default_rng(1).uniform(-200, 200, (2000, 2))
    assert np.linalg.norm(attraction(q, goal, k, d_g), axis=1).max() <= k * d_g + 1e-9


def test_adaptive_repulsion_directions():
    """F*_rep1 has a non-negative component along q - c, F*_rep2 along q_g - q (spec 11.1)."""
    rng = np.random.default_rng(3)
    for dim in (2, 3):
        centre, radius = np.zeros((1, dim)), np.array([5.0])
        q = points_in_shells(rng, dim, centre, radius, 20.0, 500)
        goal = rng.uniform(-40, 40, dim)
        n_o = (q - centre) / np.linalg.norm(q - centre, axis=1, keepdims=True)
        n_g = (goal - q) / np.linalg.norm(goal - q, axis=1, keepdims=True)
        apart = np.abs(np.einsum("nd,nd->n", n_o, n_g)) < 0.95  # the two directions tell apart
        force = repulsion(q[apart], centre, radius, goal, "iaapf", 1e5, 20.0)
        f1, f2 = rep_components(force, n_o[apart], n_g[apart]).T
        assert np.all(f1 >= 0) and np.all(f2 >= 0)


@pytest.mark.parametrize(
    ("n", "expected"),
    [(0.8, [547, 866, 1370]), (1.0, [431, 431, 431]), (1.5, [204, 65, 20])],
)
def test_rep2_near_the_goal_matches_spec_figures(n, expected):
    """Spec 11.1: goal 7 m from the surface, l0 = 20, k_rep = 1e5; |F*_rep2| at rho = 0.1, 0.01, 0.001 m."""
    centre, radius = np.zeros((1, 2)), np.array([18.0])
    goal = np.array([25.0, 0.0])
    for rho, value in zip((0.1, 0.01, 0.001), expected, strict=True):
        q = goal + np.array([[0.0, rho]])  # beside the goal, l stays ~7 m
        force = repulsion(q, centre, radius, goal, "iaapf", 1e5, 20.0, n=n)
        n_o, n_g = q / np.linalg.norm(q), np.array([[0.0, -1.0]])
        f1, f2 = rep_components(force, n_o, n_g)[0]
        assert f2 == pytest.approx(value, rel=0.01, abs=0.5)  # spec rounds to integers
        assert abs(f1) < 250 * rho**n  # |F*_rep1| ~ rho^n -> 0


def test_inter_uav_figures_of_spec_11_1():
    """|F2|/|F1| = 0.5 n (1 - l/D) = 0.28 at l = 3, D = 10, n = 0.8; the emergency term at l = 3 m is
    +45 on UAV2 and -45 on UAV1 (k_uav = 1000)."""
    l, d, n = 3.0, 10.0, 0.8
    f1 = (1 / l - 1 / d) * l ** (n - 2)
    f2 = 0.5 * n * (1 / l - 1 / d) ** 2 * l ** (n - 1)
    assert f2 / f1 == pytest.approx(0.28)
    p = np.array([[0.0, 0.0, 10.0], [3.0, 0.0, 10.0]])
    plain, _ = uav(p, p, np.zeros_like(p), 1.0, n, d, SeparationParams(d_emg=0.001), 0.05)
    assert plain[1, 0] == pytest.approx(f1 - f2)  # F1 + F2 of the pair, along e_ji
    force, emergency = uav(p, p, np.zeros_like(p), 1000.0, n, d, SeparationParams(), 0.05)
    assert emergency.all()
    assert force[1, 2] == pytest.approx(45.0, abs=0.05)
    assert force[0, 2] == pytest.approx(-45.0, abs=0.05)
    np.testing.assert_allclose(force[0], -force[1], atol=1e-12)  # equal and opposite pair
    assert force[1, 0] > 0 > force[0, 0]  # and repulsive horizontally


def test_separation_ranges_of_spec_11_4():
    assert d_max_formula(20.0, 0.0, 20.0, 0.0) == pytest.approx(10.0)
    assert d_max_formula(20.0, 0.2, 20.0, 1.0) == pytest.approx(15.0)
    sep = SeparationParams(mode="formula", a_e=20.0, s_s=1.0)  # D_Emg = 20^2 / (2 20) + 1 = 11 m at v_re 20
    vel = np.array([[10.0, 0.0, 0.0], [-10.0, 0.0, 0.0]])
    for gap, inside in ((10.9, True), (11.1, False)):
        p = np.array([[0.0, 0.0, 0.0], [gap, 0.0, 0.0]])
        assert uav(p, p, vel, 1.0, 0.8, 15.0, sep, 0.05)[1].all() == inside
    assert repulsion_range(SeparationParams(), 20.0, 20.0) == 10.0
    assert repulsion_range(SeparationParams(mode="formula"), 20.0, 20.0) == pytest.approx(15.0)


def test_formula_mode_emergency_range_grows_with_closing_speed_and_is_clamped():
    sep = SeparationParams(mode="formula", s_s=1.0, a_e=10.0)
    p = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, 0.0]])
    still = np.zeros_like(p)
    closing = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0]])  # v_re = 10 -> D_Emg = 6 m
    _, emg_still = uav(p, p, still, 1.0, 0.8, 15.0, sep, 0.05)
    _, emg_closing = uav(p, p, closing, 1.0, 0.8, 15.0, sep, 0.05)
    assert not emg_still.any() and emg_closing.all()
    far = np.array([[0.0, 0.0, 0.0], [14.0, 0.0, 0.0]])
    fast = np.array([[50.0, 0.0, 0.0], [-50.0, 0.0, 0.0]])  # D_Emg 501 m, clamped to D_max = 15
    _, emg_far = uav(far, far, fast, 1.0, 0.8, 15.0, sep, 0.05)
    assert emg_far.all()
    apart = np.array([[-2.0, 0.0, 0.0], [16.0, 0.0, 0.0]])  # each 16 m from the other's source
    force, emg = uav(apart, far, fast, 1.0, 0.8, 15.0, sep, 0.05)
    assert not emg.any() and not force.any()  # beyond D_max nothing at all


def test_an_unknown_vehicle_takes_no_pair_away_from_the_others() -> None:
    """Vehicle 2 never reported (src_valid False, far away): vehicles 3 and 4, 5 m apart, still repel each
    other with equal and opposite forces, exactly as when vehicle 2 is known. (A pair whose vehicle index
    equalled its neighbour's place among the known vehicles used to be dropped: 3 did not feel 4.)"""
    p = np.array(
        [[0.0, 0.0, 10.0], [0.0, 100.0, 10.0], [500.0, 500.0, 10.0], [50.0, 0.0, 10.0], [55.0, 0.0, 10.0]]
    )
    sep = SeparationParams()
    known = np.array([True, True, False, True, True])
    force, _ = uav(p, p, np.zeros_like(p), 5e4, 0.8, 10.0, sep, 0.05, src_valid=known)
    all_known, _ = uav(p, p, np.zeros_like(p), 5e4, 0.8, 10.0, sep, 0.05)
    assert force[3, 0] < 0.0 < force[4, 0]  # 3 pushed west, away from 4; 4 pushed east
    np.testing.assert_array_equal(force[3], -force[4])  # 5 m: outside D_Emg, no vertical term
    np.testing.assert_array_equal(force[[0, 1, 3, 4]], all_known[[0, 1, 3, 4]])
