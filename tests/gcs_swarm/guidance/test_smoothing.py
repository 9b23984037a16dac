"""The [add] smoothing and anticipation around the paper's method: ArduPilot's jerk-limited shaping, the
tilt slew, the leader heading, the braking-path evaluation of the fields, the circulation around an obstacle
ahead, slot assignment and slot push-out. Expected values are worked out by hand in each test."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_swarm.guidance.attitude_slew import slew_step
from gcs_swarm.guidance.field import obstacle_repulsion
from gcs_swarm.guidance.formation import LeaderHeading, assign_slots, formation_offsets, slot_positions
from gcs_swarm.guidance.obstacles import push_out_horizontally
from gcs_swarm.guidance.params import FieldParams, Limits, ReferenceParams, SeparationParams
from gcs_swarm.guidance.reference import ReferenceGenerator
from gcs_swarm.guidance.separation import uav_repulsion
from gcs_swarm.guidance.shaping import shape_vel_accel, shape_vel_accel_xy
from swarm_common.rotations import wrap_pi, wrap_pi_float
from swarm_common.shaping import sqrt_controller

DT = 0.02


def shape_xy(target, feed_forward, vel, accel, accel_max, jerk_max, dt):
    """shape_vel_accel_xy of one vehicle on (2,) vectors, as a (2,) array."""
    return np.array(shape_vel_accel_xy(*target, *feed_forward, *vel, *accel, accel_max, jerk_max, dt))


def field(q, dest, centres, radii, fp, ahead=None):
    """The obstacle repulsion (N, 3), evaluated along q -> ahead (None: at q)."""
    return obstacle_repulsion(q, q if ahead is None else ahead, dest, centres, radii, fp)


def uav(p_at, p_src, vel, sep, at_vel=None, brake_accel=0.0):
    """The inter-UAV force (N, 3) and emergency flags (N,) of k_uav 5e4, n 0.8, D_max 10 m, l_min 0.05 m."""
    fp = FieldParams(k_uav=5e4, n_uav=0.8, l_min=0.05)
    at_vel = np.zeros_like(p_at) if at_vel is None else at_vel
    valid = np.ones(len(p_src), dtype=bool)
    return uav_repulsion(
        p_at, p_src, vel, valid, at_vel, brake_accel, fp, 10.0, False, min(sep.d_emg, 10.0), sep.a_e, sep.s_s
    )


# ----- ArduPilot's sqrt controller and shaping -----


def test_sqrt_controller_is_linear_near_zero_and_a_braking_curve_beyond():
    """p = 2, L = 8: linear up to L / p^2 = 2 (rate 2 e); beyond, sqrt(2 L (e - 1)) (at e = 2 both give 4,
    so the two pieces meet); odd in the error; never more than |e| / dt."""
    rates = [sqrt_controller(e, 2.0, 8.0, 0.0) for e in (0.5, 2.0, 5.0, -5.0)]
    np.testing.assert_allclose(rates, [1.0, 4.0, 8.0, -8.0])
    # p = 100 > 1 / dt: the linear rate 0.1 would overshoot 0.001 within one 20 ms step; capped at 0.05
    assert sqrt_controller(0.001, 100.0, 8.0, 0.02) == pytest.approx(0.001 / 0.02)
    assert sqrt_controller(-3.0, 1.5, 0.0, 0.0) == -4.5  # no second-order limit: linear
    assert sqrt_controller(-3.0, 1.5, -1.0, 0.0) == -4.5
    assert sqrt_controller(4.5, 0.0, 8.0, 0.0) == pytest.approx(math.sqrt(72.0))  # p = 0: sqrt(2 L e)


def test_a_velocity_step_is_shaped_within_accel_and_jerk_without_overshoot():
    """From rest to 10 m/s with A = 4 m/s^2, J = 5 m/s^3: |a| <= A, |da| <= J dt each step, the velocity never
    passes 10 m/s, and it reaches 99 % no sooner than the time-optimal profile dv / A + A / J = 2.5 + 0.8 =
    3.3 s and no later than that plus the sqrt controller's linear tail: inside L / p^2 = J / (J / A)^2 =
    3.2 m/s of error the error decays like exp(-p t), p = J / A = 1.25 1/s, and from 3.2 to 0.1 m/s takes
    ln(32) / 1.25 = 2.77 s."""
    v, a = np.zeros((1, 2)), np.zeros((1, 2))
    target = np.array([[10.0, 0.0]])
    t_reach = None
    for k in range(1, 600):
        a_new = shape_xy(target[0], np.zeros(2), v[0], a[0], 4.0, 5.0, DT)[None, :]
        assert np.linalg.norm(a_new) <= 4.0 + 1e-9
        assert np.linalg.norm(a_new - a) <= 5.0 * DT + 1e-9
        a = a_new
        v = v + a * DT
        assert v[0, 0] <= 10.0 + 1e-9
        if t_reach is None and v[0, 0] >= 9.9:
            t_reach = k * DT
    assert t_reach is not None and 3.3 <= t_reach <= 3.3 + math.log(32.0) / 1.25
    assert v[0, 0] == pytest.approx(10.0, abs=1e-3) and abs(a[0, 0]) < 1e-3


def test_a_turn_keeps_cross_track_acceleration():
    """Velocity (10, 0) asked to become (10, 10) * 0.7071 (a 45 deg turn, same speed): ArduPilot's corner rule
    reserves up to A / sqrt(2) across the demand, so the first accelerations point mostly sideways."""
    v, a = np.array([[10.0, 0.0]]), np.zeros((1, 2))
    target = np.array([[7.0710678, 7.0710678]])
    for _ in range(50):
        a = shape_xy(target[0], np.zeros(2), v[0], a[0], 4.0, 50.0, DT)[None, :]
    unit = target[0] / np.linalg.norm(target[0])
    cross = a[0] - unit * (a[0] @ unit)
    assert np.linalg.norm(cross) > 2.0  # most of A = 4 goes across the new direction
    assert np.linalg.norm(a) <= 4.0 + 1e-9


def test_one_axis_shaping_feeds_forward_and_limits_total():
    """A feed-forward of 1 m/s^2 with no velocity error is passed through (jerk permitting); a huge error
    is capped at +-A in total."""
    a = 0.0
    for _ in range(100):
        a = shape_vel_accel(0.0, 1.0, 0.0, a, 4.0, 5.0, DT)
    assert a == pytest.approx(1.0)
    a = 0.0
    for _ in range(100):
        a = shape_vel_accel(100.0, 1.0, 0.0, a, 4.0, 5.0, DT)
    assert a == pytest.approx(4.0)


def test_the_horizontal_total_saturates_at_accel_max():
    """A huge demand saturates the horizontal acceleration at the limit A, whatever the jerk limit."""
    for accel_max, jerk_max in ((2.0, 5.0), (6.0, 40.0)):
        a = np.zeros(2)
        for _ in range(200):
            a = shape_xy(np.full(2, 50.0), np.zeros(2), np.zeros(2), a, accel_max, jerk_max, DT)
        assert np.linalg.norm(a) == pytest.approx(accel_max)


# ----- the reference generator's shaped mode -----


def test_the_shaped_reference_stops_at_a_fixed_target_without_overshoot():
    """Attraction toward a target 60 m away (the field of spec 8 step 3 at k_att = 100, d_g = 10 m, cruise
    10 m/s): with the stopping curve the reference passes the target by less than 20 cm and settles on it.
    Close in, the curve is K_v d (K_v = 1 1/s) and the shaper tracks it with gain J / A = 1.25 1/s, a loop
    s^2 + 1.25 s + 1.25 with damping 0.56: a small overshoot (a few % of the last metres), well inside the
    1 m goal tolerance. (Without it,
    the demand K_v d falls from 10 m/s at d = 10 m faster than 4 m/s^2 can follow, and the reference
    overshoots: checked below with stop_accel = 0.)"""
    params = ReferenceParams()
    gen = ReferenceGenerator(params, Limits(), k_att=100.0)
    gen.reset(np.zeros((1, 3)), np.zeros((1, 3)))
    target = np.array([[60.0, 0.0, 0.0]])
    d_g = 10.0
    for _ in range(3000):
        d = target - gen.p
        rho = np.linalg.norm(d)
        force = 100.0 * d * min(1.0, d_g / max(rho, 1e-9))
        p, v, a = gen.step(
            force, np.zeros((1, 3)), np.array([10.0]), DT, np.ones(1, dtype=bool), targets=target
        )
        assert p[0, 0] <= 60.2
    assert gen.p[0, 0] == pytest.approx(60.0, abs=0.01)
    assert params.stop_accel > 0.0
    gen = ReferenceGenerator(ReferenceParams(stop_accel=0.0), Limits(), k_att=100.0)
    gen.reset(np.zeros((1, 3)), np.zeros((1, 3)))
    farthest = 0.0
    for _ in range(3000):
        d = target - gen.p
        force = 100.0 * d * min(1.0, d_g / max(float(np.linalg.norm(d)), 1e-9))
        p, _, _ = gen.step(
            force, np.zeros((1, 3)), np.array([10.0]), DT, np.ones(1, dtype=bool), targets=target
        )
        farthest = max(farthest, p[0, 0])
    assert farthest > 60.5


def test_the_braking_point_lies_v_squared_over_2a_ahead():
    far, rows = np.full((1, 3), 100.0), np.zeros(1, dtype=bool)  # rows not selected: no leash
    gen = ReferenceGenerator(ReferenceParams(brake_accel=2.0), Limits(), k_att=100.0)
    gen.reset(np.zeros((1, 3)), np.array([[6.0, 8.0, 0.0]]))  # 10 m/s: 100 / 4 = 25 m ahead
    np.testing.assert_allclose(gen.leash_and_lookahead(far, rows), [[15.0, 20.0, 0.0]])
    gen = ReferenceGenerator(ReferenceParams(brake_accel=0.0), Limits(), k_att=100.0)
    gen.reset(np.zeros((1, 3)), np.array([[6.0, 8.0, 0.0]]))
    np.testing.assert_allclose(gen.leash_and_lookahead(far, rows), [[0.0, 0.0, 0.0]])
    gen.leash_and_lookahead(far, ~rows)  # selected: put back on the 5 m leash sphere round the vehicle
    np.testing.assert_allclose(gen.p, far - 5.0 / math.sqrt(3.0))


# ----- fields along the braking path, circulation, vertical weight -----

PLAIN = {"circulation": 0.0, "obstacle_vertical": 1.0}


def test_obstacle_field_along_the_braking_path():
    """An obstacle 30 m ahead of a point with a 40 m braking path is felt where the path comes nearest to it
    (the same force as at that point, from the plain evaluation); one behind is felt at the point itself;
    a zero-length path is the plain evaluation."""
    fp = FieldParams(k_rep=1e5, l0=20.0, **PLAIN)
    q = np.array([[0.0, 0.0, 10.0]])
    ahead = np.array([[40.0, 0.0, 10.0]])
    dest = np.array([[200.0, 0.0, 10.0]])
    centre, radius = np.array([[30.0, 8.0, 10.0]]), np.array([3.0])
    swept = field(q, dest, centre, radius, fp, ahead=ahead)
    at_nearest = field(np.array([[30.0, 0.0, 10.0]]), dest, centre, radius, fp)
    np.testing.assert_allclose(swept, at_nearest)
    behind = np.array([[-10.0, 5.0, 10.0]])
    swept = field(q, dest, behind, radius, fp, ahead=ahead)
    plain = field(q, dest, behind, radius, fp)
    np.testing.assert_allclose(swept, plain)
    swept = field(q, dest, centre, radius, fp, ahead=q.copy())
    plain = field(q, dest, centre, radius, fp)
    np.testing.assert_allclose(swept, plain)


def test_circulation_turns_a_head_on_push_into_a_way_round():
    """Obstacle dead ahead on the line to the goal (n_o = -x, n_g = +x): the paper's repulsion points straight
    back; the circulation adds gain * |F_rep1| sideways, to the right of the travel (-y), so the sum has a
    lateral part equal to gain times the backward F_rep1 part. Beside the path (n_o across n_g) it adds
    nothing."""
    q = np.array([[0.0, 0.0, 10.0]])
    dest = np.array([[100.0, 0.0, 10.0]])
    centre, radius = np.array([[12.0, 0.0, 10.0]]), np.array([2.0])
    plain = field(q, dest, centre, radius, FieldParams(method="apf", **PLAIN))
    turned = field(q, dest, centre, radius, FieldParams(method="apf", circulation=0.5, obstacle_vertical=1.0))
    assert plain[0, 1] == 0.0 and plain[0, 0] < 0.0
    assert turned[0, 0] == pytest.approx(plain[0, 0])
    assert turned[0, 1] == pytest.approx(0.5 * plain[0, 0])  # |F| sideways = 0.5 |F|, toward -y
    beside = np.array([[0.0, 8.0, 10.0]])
    a = field(q, dest, beside, radius, FieldParams(method="apf", **PLAIN))
    b = field(q, dest, beside, radius, FieldParams(method="apf", circulation=0.5, obstacle_vertical=1.0))
    np.testing.assert_allclose(a, b)


def test_circulation_goes_round_on_the_goal_side():
    """The goal lies up and to the left (+y) of an obstacle ahead: the way round is on the left."""
    q = np.array([[0.0, 0.0, 10.0]])
    dest = np.array([[100.0, 40.0, 10.0]])
    centre, radius = np.array([[12.0, 0.0, 10.0]]), np.array([2.0])
    fp = FieldParams(method="apf", circulation=1.0, obstacle_vertical=1.0)
    turned = field(q, dest, centre, radius, fp)
    assert turned[0, 1] > 0.0


def test_circulation_fades_for_a_goal_nearer_than_the_obstacle():
    """A vehicle 10 m from an obstacle's surface (centre 12 m ahead, radius 2) whose goal lies 4 m ahead, in
    front of the obstacle: the obstacle is not between them (rho 4 < l 10), so there is no way round to take
    and the circulation adds nothing. Its share grows with rho / l - 1: a goal 15 m ahead (beyond the centre,
    rho / l = 1.5) gets half the sideways push of a goal far behind the obstacle (rho / l >= 2), which gets
    gain x the backward part (previous test)."""
    q = np.array([[0.0, 0.0, 10.0]])
    centre, radius = np.array([[12.0, 0.0, 10.0]]), np.array([2.0])
    plain_fp = FieldParams(method="apf", **PLAIN)
    turned_fp = FieldParams(method="apf", circulation=0.5, obstacle_vertical=1.0)
    near = np.array([[4.0, 0.0, 10.0]])
    np.testing.assert_allclose(
        field(q, near, centre, radius, turned_fp), field(q, near, centre, radius, plain_fp)
    )
    half_way = np.array([[15.0, 0.0, 10.0]])
    plain = field(q, half_way, centre, radius, plain_fp)
    turned = field(q, half_way, centre, radius, turned_fp)
    assert turned[0, 1] == pytest.approx(0.5 * 0.5 * plain[0, 0])


def test_vertical_weight_scales_only_z():
    q = np.array([[0.0, 0.0, 6.0]])  # below an obstacle centre at 10 m: pushed down by the 3-D field
    dest = np.array([[100.0, 0.0, 6.0]])
    centre, radius = np.array([[0.0, 9.0, 10.0]]), np.array([3.0])
    full = field(q, dest, centre, radius, FieldParams(**PLAIN))
    weak = field(q, dest, centre, radius, FieldParams(circulation=0.0, obstacle_vertical=0.25))
    assert full[0, 2] < 0.0
    np.testing.assert_allclose(weak[0, :2], full[0, :2])
    assert weak[0, 2] == pytest.approx(0.25 * full[0, 2])


def test_inter_uav_force_along_the_relative_braking_path():
    """Two vehicles 30 m apart closing head-on at 10 m/s with a_b = 1: the relative braking path is
    |w| / (4 a_b) = 2.5 s long, 25 m: they are felt 5 m apart (inside D_max = 10), where the plain
    evaluation at 30 m feels nothing. Offset by 4 m sideways with a_b = 0.5 (a 5 s path, longer than the
    3 s to closest approach), the force points straight sideways: the separation they would pass at. Moving
    apart, the sweep changes nothing."""
    sep = SeparationParams()
    p_at = np.array([[0.0, 0.0, 10.0], [30.0, 0.0, 10.0]])
    vel = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0]])
    plain, _ = uav(p_at, p_at, vel, sep)
    assert not plain.any()
    swept, _ = uav(p_at, p_at, vel, sep, at_vel=vel, brake_accel=1.0)
    five = p_at * [1 / 6, 1, 1]  # the same pair 5 m apart, at rest
    at_five, _ = uav(five, five, np.zeros((2, 3)), sep)
    np.testing.assert_allclose(swept, at_five)
    offset = p_at + [[0.0, 0.0, 0.0], [0.0, 4.0, 0.0]]
    swept, _ = uav(offset, offset, vel, sep, at_vel=vel, brake_accel=0.5)
    assert swept[0, 0] == pytest.approx(0.0, abs=1e-9) and swept[0, 1] < 0.0
    apart = -vel
    swept, _ = uav(p_at * [0.3, 1, 1], p_at * [0.3, 1, 1], apart, sep, at_vel=apart, brake_accel=1.0)
    plain, _ = uav(p_at * [0.3, 1, 1], p_at * [0.3, 1, 1], apart, sep)
    np.testing.assert_allclose(swept, plain)


# ----- tilt slew and leader heading -----


def test_tilt_slew_ramps_a_step_along_its_direction():
    """A step from level to (roll 0.3, pitch 0.4) = 0.5 rad of tilt at 2 rad/s takes 0.25 s (12.5 ticks of
    20 ms): each tick moves 0.04 rad along (0.6, 0.8)."""
    rows = np.ones(1, dtype=bool)
    demand = np.array([0.3]), np.array([0.4])
    roll, pitch = slew_step(*demand, np.zeros(1), np.zeros(1), 2.0 * DT, rows)
    assert roll[0] == pytest.approx(0.024) and pitch[0] == pytest.approx(0.032)
    for _ in range(12):
        roll, pitch = slew_step(*demand, roll, pitch, 2.0 * DT, rows)
    assert roll[0] == pytest.approx(0.3) and pitch[0] == pytest.approx(0.4)
    assert slew_step(*demand, np.zeros(1), np.zeros(1), 0.0, rows)[1][0] == 0.4  # limit 0: no slew
    held = slew_step(*demand, np.full(1, 0.1), np.full(1, 0.2), 2.0 * DT, ~rows)  # rows not commanded
    assert held[0][0] == 0.1 and held[1][0] == 0.2
    fresh = slew_step(*demand, np.full(1, np.nan), np.zeros(1), 2.0 * DT, rows)  # no last command: the demand
    assert fresh[0][0] == 0.3 and fresh[1][0] == 0.4


def test_leader_heading_turn_rate_and_its_change_are_limited():
    """A 90 deg course change: the rate never exceeds 30 deg/s, never changes by more than 20 deg/s^2 * dt,
    and psi ends on the new course without overshooting it by more than a degree."""
    h = LeaderHeading(0.0, 3.0, math.radians(30), 10.0, accel_max=math.radians(20), filter_s=0.0, gain=1.0)
    rates = [0.0]
    for _ in range(1000):
        h.update(np.array([0.0, 10.0]), 100.0, DT)
        rates.append(h.rate)
        assert h.psi <= math.pi / 2 + math.radians(1)
    r = np.array(rates)
    assert np.abs(r).max() <= math.radians(30) + 1e-12
    assert np.abs(np.diff(r)).max() <= math.radians(20) * DT + 1e-12
    assert h.psi == pytest.approx(math.pi / 2, abs=1e-3)


def test_leader_heading_holds_when_slow_and_brakes_its_turn():
    h = LeaderHeading(0.0, 3.0, math.radians(30), 10.0, accel_max=math.radians(20), filter_s=0.0)
    for _ in range(50):
        h.update(np.array([0.0, 10.0]), 100.0, DT)
    turning = h.rate
    assert turning > 0.0
    h.update(np.array([0.0, 1.0]), 100.0, DT)  # slow: no new course, the turn winds down smoothly
    assert 0.0 < h.rate < turning


_ANY_FLOAT = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64),
    st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, math.pi, -math.pi, 2.0 * math.pi]),
)


@settings(max_examples=400, deadline=None)
@given(
    _ANY_FLOAT,
    st.one_of(st.just(0.0), st.floats(0.0, 1e6)),
    st.one_of(st.just(0.0), st.floats(-10.0, 1e6)),
    st.one_of(st.just(0.0), st.floats(0.0, 10.0)),
)
def test_the_sqrt_controller_is_odd_and_never_overshoots(error, p, limit, dt):
    """On every branch (linear, braking curve, no gain, no second-order limit, the 1/dt bound): the rate is
    odd in the error, has the error's sign, and with dt > 0 covers at most the error in one step; NaN in,
    NaN out; in the linear law (no second-order limit, no 1/dt bound) -0 gives -0 (as numpy's p * e)."""
    rate = sqrt_controller(error, p, limit, dt)
    assert sqrt_controller(-error, p, limit, dt) == -rate or math.isnan(rate)
    if limit <= 0.0:
        assert math.copysign(1.0, sqrt_controller(-0.0, p, limit, 0.0)) == -1.0
    assert rate * error >= 0.0 or math.isnan(rate)
    if dt > 0.0 and math.isfinite(rate):
        assert abs(rate) <= abs(error) / dt * (1.0 + 1e-15)
    assert math.isnan(sqrt_controller(math.nan, p, limit, dt))


@given(_ANY_FLOAT)
def test_the_scalar_wrap_gives_the_array_bits(angle):
    assert np.float64(wrap_pi_float(angle)).tobytes() == wrap_pi(angle).tobytes()


# ----- slots -----


def test_slot_assignment_gives_each_swapped_follower_its_nearest_slot():
    """Four followers of a V, each started next to another's slot: every one gets the slot it stands by
    (a move of sqrt(3 x 0.25) m, the shortest possible longest move), the leader's row stays zero, and a
    follower that may not move keeps its slot."""
    offsets = np.zeros((5, 3))
    offsets[1:] = formation_offsets("v", 4, 10.0)
    slots = slot_positions(np.zeros(3), 0.3, offsets)
    pos = slots[[0, 2, 1, 4, 3]] + 0.5  # followers swapped pairwise
    movable = np.array([False, True, True, True, True])
    out, _ = assign_slots(pos, np.zeros(3), 0.3, offsets, movable, 4.0)
    new_slots = slot_positions(np.zeros(3), 0.3, out)
    np.testing.assert_allclose(np.linalg.norm(new_slots[1:] - pos[1:], axis=1), math.sqrt(0.75))
    np.testing.assert_array_equal(out[0], 0.0)
    movable[4] = False
    out, _ = assign_slots(pos, np.zeros(3), 0.3, offsets, movable, 4.0)
    np.testing.assert_array_equal(out[4], offsets[4])


def test_push_out_moves_points_to_the_grown_circle_only():
    """Sphere r = 3 at (0, 0, 10), margin 5: a point 2 m east at the centre's height goes to 8 m east; a point
    2 m below the centre's height goes to sqrt(64 - 4) east; points outside stay."""
    centre, radius = np.array([[0.0, 0.0, 10.0]]), np.array([3.0])
    pts = np.array([[2.0, 0.0, 10.0], [2.0, 0.0, 8.0], [9.0, 0.0, 10.0], [0.0, 0.0, 30.0]])
    out = np.array([[*push_out_horizontally(*pt, centre, radius, 5.0), pt[2]] for pt in pts])
    np.testing.assert_allclose(out[0], [8.0, 0.0, 10.0])
    np.testing.assert_allclose(out[1], [math.sqrt(60.0), 0.0, 8.0])
    np.testing.assert_allclose(out[2:], pts[2:])


@pytest.mark.parametrize("start_vz", [0.0, -8.0])
def test_reference_never_sinks_below_the_altitude_floor(start_vz: float) -> None:
    """A field pushing straight down as hard as it can (an obstacle above, say) from 10 m with a 2 m floor,
    starting at rest or already diving at 8 m/s (what a 4-obstacle world in 4.8 m/s wind produced, driving a
    reference to -4 m and a vehicle into the ground): the jerk-limited reference must stop at the floor and
    not below it, and near the floor descend no faster than its shaping can stop."""
    params = ReferenceParams()
    gen = ReferenceGenerator(params, Limits(), k_att=100.0, z_min=2.0)
    gen.reset(np.array([[0.0, 0.0, 10.0]]), np.array([[0.0, 0.0, start_vz]]))
    down = np.array([[0.0, 0.0, -1e6]])
    lowest, rows, arrival = 10.0, np.array([True]), None
    for _ in range(1500):  # 30 s at 50 Hz
        p, v, _a = gen.step(down, np.zeros((1, 3)), np.array([10.0]), 0.02, rows)
        lowest = min(lowest, float(p[0, 2]))
        if arrival is None and float(p[0, 2]) < 2.2:
            arrival = -float(v[0, 2])  # descent speed on reaching the last 0.2 m
    assert lowest >= 2.0 - 1e-9
    assert arrival is not None
    if (
        start_vz == 0.0
    ):  # from rest the descent near the floor is slow (the shaping could not stop 8 m/s there)
        assert arrival < 1.0, arrival
    assert abs(float(gen.p[0, 2]) - 2.0) < 0.05 and abs(float(gen.v[0, 2])) < 0.05  # resting on the floor
