"""The leader's path predicted for the reshape's look-ahead (gcs_swarm.guidance.leader_path): it is the path
the leader's own reference then flies, and the look-ahead uses it; compiled and interpreted
(NUMBA_DISABLE_JIT=1) predictions are the same bits."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gcs_swarm.evaluation.flight_quality import CUSP_WINDOW_S
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.leader_path import (
    PREDICT_DT_S,
    leader_aim,
    leader_stalls,
    leader_steps,
    predict_leader_path,
    resample,
    switch_radius,
)
from gcs_swarm.guidance.params import FieldParams, ReferenceParams, ReshapeParams
from swarm_common.obstacle_shapes import pack_shapes
from tests.gcs_swarm.guidance.interpreted import interpreted_arrays

GOAL = np.array([[200.0, 0.0, 10.0]])
OBSTACLE_C = np.array([[60.0, 2.0, 10.0]])  # 2 m left of the leader's straight line, in its way
OBSTACLE_R = np.array([4.0])


def _controller(
    n: int = 1,
    reshape: ReshapeParams | None = None,
    field: FieldParams | None = None,
    reference: ReferenceParams | None = None,
) -> FleetController:
    offsets = np.zeros((n, 3))
    if n > 1:
        offsets[1:] = formation_offsets("v", n - 1, 10.0)
    ctl = FleetController(n, 0, offsets, GOAL, reshape=reshape, z_min=1.0, field=field, reference=reference)
    pos = offsets + [0.0, 0.0, 10.0]
    ctl.reset(pos, np.zeros((n, 3)), np.zeros(n))
    return ctl


def _fly_reference(ctl: FleetController, seconds: float) -> np.ndarray:
    """The leader's reference positions (T, 3) over `seconds` of ticks, each vehicle exactly where its
    reference is (perfect tracking: the leash never acts)."""
    dt = ctl.control_dt
    n, track = ctl.n, [ctl.generator.p[0].copy()]
    for k in range(round(seconds / dt)):
        pos, vel = ctl.generator.p.copy(), ctl.generator.v.copy()
        ctl.tick(k * dt, pos, vel, np.zeros((n, 3)), OBSTACLE_C, OBSTACLE_R, np.ones(n, dtype=bool))
        track.append(ctl.generator.p[0].copy())
    return np.array(track)


def _distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Horizontal distance (P,) m from each point (P, 3) to the polyline through line (T, 3)."""
    a, b = line[:-1, None, :2], line[1:, None, :2]
    ab = b - a
    t = np.clip(
        np.sum((points[None, :, :2] - a) * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-12), 0, 1
    )
    nearest = a + t[..., None] * ab
    return np.min(np.linalg.norm(points[None, :, :2] - nearest, axis=-1), axis=0)


def test_predicted_path_is_the_path_the_leader_flies() -> None:
    # The prediction steps the same reference (10 Hz) that the controller ticks (50 Hz): round an obstacle
    # in its way the leader swerves metres off its straight line, and the prediction goes with it.
    ctl = _controller()
    model, gen = ctl.leader_model, ctl.generator
    assert ctl.heading is not None
    points, headings, along = predict_leader_path(
        model, gen.p[0], gen.v[0], gen.a[0], ctl.heading, GOAL, 10.0, 120.0, 2.0, OBSTACLE_C, OBSTACLE_R
    )
    flown = _fly_reference(ctl, 16.0)
    swerve = np.max(np.abs(flown[(flown[:, 0] > 40) & (flown[:, 0] < 80), 1]))
    assert swerve > 5.0  # the straight line would be wrong by this much
    assert np.max(_distance_to_polyline(points, flown)) < 0.5
    assert along[-1] == 120.0 and np.allclose(np.diff(along), 2.0)
    # travel is horizontal arc length: consecutive points 2 m apart up to the bends' chords
    chords = np.hypot(*np.diff(points[:, :2], axis=0).T)
    assert np.all(chords <= 2.0 + 1e-9) and np.all(chords > 1.9)
    # psi_L steers to the waypoint (heading_from_route), not along the swerve
    bearing = np.arctan2(GOAL[0, 1] - points[:, 1], GOAL[0, 0] - points[:, 0])
    assert np.max(np.abs(headings - bearing)) < math.radians(3.0)


def test_the_aim_turns_at_most_its_rate_toward_the_waypoint() -> None:
    p, goal = np.array([0.0, 0.0, 10.0]), np.array([0.0, 30.0, 12.0])  # due North, 30 m away, 2 m up
    step = math.radians(1.0)
    aim, bearing = leader_aim(p, goal, 0.0, step, 10.0)  # the aim was East: it turns 1 deg toward North
    assert math.isclose(bearing, step)  # (wrapped into [-pi, pi): equal to rounding)
    assert np.allclose(aim, [30.0 * math.cos(step), 30.0 * math.sin(step), 12.0])  # same distance and height
    aim, bearing = leader_aim(p, goal, math.radians(89.5), step, 10.0)  # within one step: the waypoint,
    assert bearing == math.pi / 2 and np.array_equal(aim, goal)  # exactly (not p + 30 m along pi / 2)
    aim, bearing = leader_aim(p, goal, math.radians(-170.0), step, 10.0)  # the short way round: clockwise
    assert math.isclose(bearing, math.radians(-171.0))
    for held in (
        leader_aim(p, goal, 0.0, step, 30.5),  # within the hold distance: the waypoint itself
        leader_aim(p, goal, math.nan, step, 10.0),  # no bearing yet
        leader_aim(p, goal, 0.0, 0.0, 10.0),  # off
    ):
        assert np.array_equal(held[0], goal) and held[1] == math.pi / 2


def test_the_switch_radius_is_where_an_arc_at_the_aims_rate_meets_the_next_leg() -> None:
    # a corner of 90 deg at (100, 0), then North; at 5 m/s and 0.5 rad/s the arc's radius is 10 m, and its
    # tangent length 10 tan(45 deg) = 10 m; at 60 deg, 10 tan(30 deg)
    route = np.array([[100.0, 0.0, 10.0], [100.0, 100.0, 10.0]])
    assert math.isclose(switch_radius(route, 0, 5.0, 0.0, 5.0, 0.5, 20.0), 10.0)
    sixty = np.array([[100.0, 0.0, 10.0], [150.0, 50.0 * math.sqrt(3.0), 10.0]])
    assert math.isclose(switch_radius(sixty, 0, 5.0, 0.0, 5.0, 0.5, 20.0), 10.0 * math.tan(math.radians(30)))
    assert math.isclose(switch_radius(route, 0, 5.0, 0.0, 5.0, 0.5, 8.0), 8.0)  # at most `most`
    assert switch_radius(route, 0, 2.0, 0.0, 5.0, 0.5, 20.0) == 5.0  # 4 m: never under the radius
    assert switch_radius(route, 0, 5.0, 0.0, 5.0, 0.0, 20.0) == 5.0  # the aim does not turn: the radius
    assert switch_radius(route, 1, 5.0, 0.0, 5.0, 0.5, 20.0) == 5.0  # the last waypoint
    assert switch_radius(route, 0, 0.0, 0.0, 5.0, 0.5, 20.0) == 5.0  # at rest


def test_a_negative_aim_turn_rate_is_refused() -> None:
    with pytest.raises(ValueError, match="aim_turn_rate_deg must be >= 0"):
        ReferenceParams(aim_turn_rate_deg=-1.0)


def _corner_flight(
    aim_turn_rate_deg: float, turn_wait_deg: float = 20.0
) -> tuple[np.ndarray, np.ndarray, FleetController]:
    """The leader alone, tracking its reference perfectly, along a route that turns right by 90 deg at
    (60, 0): its reference positions and velocities (T, 3) every tick for 14 s, and the controller at the
    start (for a prediction)."""
    route = np.array([[60.0, 0.0, 10.0], [60.0, -80.0, 10.0]])
    reference = ReferenceParams(aim_turn_rate_deg=aim_turn_rate_deg, turn_wait_deg=turn_wait_deg)
    ctl = FleetController(1, 0, np.zeros((1, 3)), route, z_min=1.0, reference=reference)
    ctl.reset(np.array([[0.0, 0.0, 10.0]]), np.zeros((1, 3)), np.zeros(1))
    start = FleetController(1, 0, np.zeros((1, 3)), route, z_min=1.0, reference=reference)
    start.reset(np.array([[0.0, 0.0, 10.0]]), np.zeros((1, 3)), np.zeros(1))
    positions, velocities = [], []
    for k in range(round(14.0 / ctl.control_dt)):
        pos, vel = ctl.generator.p.copy(), ctl.generator.v.copy()
        no_obstacles = (np.zeros((0, 3)), np.zeros(0))
        ctl.tick(k * ctl.control_dt, pos, vel, np.zeros((1, 3)), *no_obstacles, np.ones(1, bool))
        positions.append(ctl.generator.p[0].copy())
        velocities.append(ctl.generator.v[0].copy())
    return np.array(positions), np.array(velocities), start


def _largest_turn_in_a_window(velocities: np.ndarray, dt: float) -> float:
    """deg: the most the horizontal course of velocities (T, 3), one row every dt s, turns within
    CUSP_WINDOW_S (the cusp count's window)."""
    course = np.unwrap(np.arctan2(velocities[:, 1], velocities[:, 0]))
    span = round(CUSP_WINDOW_S / dt)
    return float(np.degrees(np.max(np.abs(course[span:] - course[:-span]))))


def test_a_turning_aim_takes_the_corner_on_a_curve() -> None:
    # Aim off: the leader brakes into the corner along its stopping curve and its course turns 90 deg at
    # the bottom of the braking, fast. Aim at 30 deg/s: the attraction turns no faster than that, so the
    # course does not either, bar the reference's lag catching up, and the leader, which began to turn
    # before braking down to the corner, is never as slow in the turn.
    sharp, sharp_v, _ = _corner_flight(0.0)
    curve, curve_v, _ = _corner_flight(30.0)
    dt = FleetController(1, 0, np.zeros((1, 3)), GOAL).control_dt
    assert _largest_turn_in_a_window(curve_v, dt) <= 1.5 * 30.0 < _largest_turn_in_a_window(sharp_v, dt)
    turning = np.abs(np.arctan2(curve_v[:, 1], curve_v[:, 0])) > math.radians(5.0)
    turning &= np.arctan2(curve_v[:, 1], curve_v[:, 0]) > math.radians(-85.0)
    slowest_sharp = np.min(np.hypot(*sharp_v[(sharp[:, 0] > 50.0) & (sharp[:, 1] > -10.0), :2].T))
    assert np.min(np.hypot(*curve_v[turning, :2].T)) > slowest_sharp
    # Aim off, the leader moves on within the switch radius of the corner (60, 0) and turns there. With it,
    # the leader moves on where an arc at its speed and the aim's rate meets the next leg, at most d_g
    # (10 m) short of the corner, and turns inside the corner: never beyond it, nor farther inside than the
    # chord from (50, 0) to (60, -10), 10 / sqrt(2) m from it.
    corner = np.array([60.0, 0.0])
    assert np.min(np.hypot(*(sharp[:, :2] - corner).T)) < ReferenceParams().waypoint_radius
    assert curve[:, 0].max() < 60.0 + 0.1
    assert 1.0 < np.min(np.hypot(*(curve[:, :2] - corner).T)) < 10.0 / math.sqrt(2.0)


def test_the_prediction_turns_its_aim_as_the_leader_does() -> None:
    # (without the turn wait, which slows the leader in the turn and which the prediction does not fly)
    flown, _, start = _corner_flight(30.0, turn_wait_deg=0.0)
    gen = start.generator
    assert start.heading is not None
    travel = float(np.sum(np.hypot(*np.diff(flown[:, :2], axis=0).T)))
    points, _, _ = predict_leader_path(
        start.leader_model, gen.p[0], gen.v[0], gen.a[0], start.heading, start.waypoints, 10.0, travel, 2.0,
        np.zeros((0, 3)), np.zeros(0), aim_bearing=start.aim_bearing,
    )  # fmt: skip
    assert points[:, 1].min() < -20.0  # round the corner
    # it moves on to the next leg at a step of its own (PREDICT_DT_S), up to one step's travel at the speed
    # cap after the ticks did
    assert np.max(_distance_to_polyline(points, flown)) < PREDICT_DT_S * 10.0


def test_prediction_ends_where_the_leader_stops() -> None:
    # no obstacle: a straight line to the goal 200 m east, and no farther however much is asked
    ctl = _controller()
    gen = ctl.generator
    assert ctl.heading is not None
    points, headings, along = predict_leader_path(
        ctl.leader_model, gen.p[0], gen.v[0], gen.a[0], ctl.heading, GOAL, 10.0, 500.0, 2.0,
        np.zeros((0, 3)), np.zeros(0),
    )  # fmt: skip
    assert np.allclose(points[:, 1], 0.0) and np.allclose(points[:, 2], 10.0) and np.allclose(headings, 0.0)
    assert 195.0 < along[-1] <= 200.5 and abs(points[-1, 0] - along[-1]) < 1e-9


def test_prediction_leaves_the_heading_it_was_given_alone() -> None:
    ctl = _controller()
    gen = ctl.generator
    assert ctl.heading is not None
    ctl.heading.psi = 0.5  # the formation faces away from the goal: the prediction turns it back
    before = (ctl.heading.psi, ctl.heading.rate, ctl.heading.v_filtered)
    _, headings, _ = predict_leader_path(
        ctl.leader_model, gen.p[0], gen.v[0], gen.a[0], ctl.heading, GOAL, 10.0, 60.0, 2.0, np.zeros((0, 3)),
        np.zeros(0),
    )  # fmt: skip
    assert headings[0] == 0.5 and abs(headings[-1]) < 0.01
    assert (ctl.heading.psi, ctl.heading.rate, ctl.heading.v_filtered) == before


def test_resample_interpolates_by_travel() -> None:
    track = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0]])
    courses = np.array([0.0, 0.0, math.pi / 2])
    points, headings, along = resample(track, courses, np.array([0.0, 1.0, 3.0]), 3.0, 1.0)
    assert np.allclose(along, [0, 1, 2, 3])
    assert np.allclose(points, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [1, 2, 0]])
    assert np.allclose(headings, [0, 0, math.pi / 4, math.pi / 2])


def test_look_ahead_on_the_predicted_path_changes_shape_sooner() -> None:
    # A V of 4 (10 m spacing) flies at an obstacle on its leader's line. Along the straight route every
    # candidate puts a slot (the column: all) through the obstacle, so none fits and the shape is kept until
    # the obstacle is close; along the predicted swerve a narrower shape fits, and it is taken as soon as the
    # obstacle comes into the look-ahead.
    first_change = {}
    for predict in (True, False):
        ctl = _controller(5, ReshapeParams(predict_path=predict))
        dt = ctl.control_dt
        for k in range(round(8.0 / dt)):
            pos, vel = ctl.generator.p.copy(), ctl.generator.v.copy()
            ctl.tick(k * dt, pos, vel, np.zeros((5, 3)), OBSTACLE_C, OBSTACLE_R, np.ones(5, dtype=bool))
            if ctl.drain_shape_changes():
                first_change[predict] = float(ctl.generator.p[0, 0])
                break
    assert first_change[True] < 10.0  # m east of the start: at once (the look-ahead covers the obstacle)
    assert first_change.get(False, math.inf) > first_change[True] + 20.0


def test_a_leader_stalled_in_front_of_a_gap_is_looked_past():
    # Two spheres of 8.5 m with 8.2 m between their surfaces across the leader's line: attraction and
    # repulsion balance in front of the gap, and the leader's reference stops there (the paper's local
    # minimum). The look-ahead still covers the length asked, along the straight route through the gap, so a
    # formation narrowed for the gap does not widen in front of it.
    centres = np.array([[60.0, 12.6, 10.0], [60.0, -12.6, 10.0]])
    radii = np.array([8.5, 8.5])
    ctl = _controller()
    gen = ctl.generator
    assert ctl.heading is not None
    points, headings, along = predict_leader_path(
        ctl.leader_model, gen.p[0], gen.v[0], gen.a[0], ctl.heading, GOAL, 10.0, 150.0, 2.0, centres, radii
    )
    dt = ctl.control_dt
    for k in range(round(30.0 / dt)):  # the leader's own reference, flown: it stalls short of the gap
        pos = ctl.generator.p.copy()
        ctl.tick(
            k * dt, pos, ctl.generator.v.copy(), np.zeros((1, 3)), centres, radii, np.ones(1, dtype=bool)
        )
    stall = float(ctl.generator.p[0, 0])
    assert stall < 60.0 - 8.5 and float(np.hypot(*ctl.generator.v[0, :2])) < 0.1
    assert along[-1] >= 150.0 - 2.0 and points[:, 0].max() > 60.0 + 8.5  # through the gap and beyond
    beyond = points[:, 0] > stall + 1.0
    assert np.allclose(points[beyond, 1], 0.0, atol=1e-6) and np.allclose(headings[beyond], 0.0, atol=1e-6)


def test_the_leader_flown_forward_keeps_to_its_speed_cap_and_stops_at_its_goal() -> None:
    ctl = _controller()
    gen = ctl.generator
    assert ctl.heading is not None
    flight = leader_steps(
        ctl.leader_model, gen.p[0], gen.v[0], gen.a[0], ctl.heading, GOAL, 6.0, 1000, math.inf, OBSTACLE_C,
        OBSTACLE_R,
    )  # fmt: skip
    assert 0 < len(flight.speeds) < 1000  # stopped at the goal, before the steps ran out
    assert np.all(flight.speeds <= 6.0 + 1e-9) and flight.speeds.max() > 5.9
    assert np.all(flight.waypoints == 0) and flight.distances[-1] < ctl.leader_model.d_g
    steps = np.hypot(*np.diff(np.vstack([gen.p[:1], flight.positions])[:, :2], axis=0).T)
    assert np.array_equal(flight.travel, np.cumsum(steps))


def predictions() -> dict[str, np.ndarray]:
    """Every array the prediction gives on scenes that take each branch: spheres and packed shapes, the IAAPF
    and the APF, psi_L's low-pass and angle shaping on and off, the leader's aim turning and not, a waypoint
    switch, a stop at the goal, a
    stall in front of a gap (leader_stalls) and a straight continuation past it."""
    shapes = pack_shapes(
        cylinders=[((110.0, 14.0), 3.0, 0.0, 30.0)],
        prisms=[([(140.0, 4.0), (150.0, 4.0), (150.0, 20.0), (140.0, 20.0)], 0.0, 25.0)],
    )
    gap_c, gap_r = np.array([[60.0, 12.6, 10.0], [60.0, -12.6, 10.0]]), np.array([8.5, 8.5])
    route = np.array([[80.0, 30.0, 12.0], [200.0, 0.0, 10.0]])
    out: dict[str, np.ndarray] = {}
    scenes = [
        ("iaapf", FieldParams(), ReferenceParams(heading_filter_s=0.5, aim_turn_rate_deg=30.0)),
        (
            "apf",
            FieldParams(method="apf"),
            ReferenceParams(heading_accel_max_deg=0.0, heading_from_route=False),
        ),
    ]
    for name, field, reference in scenes:
        ctl = _controller(field=field, reference=reference)
        for k in range(15):  # a moving start, with a low-passed course
            pos, vel = ctl.generator.p.copy(), ctl.generator.v.copy()
            ctl.tick(k * ctl.control_dt, pos, vel, np.zeros((1, 3)), OBSTACLE_C, OBSTACLE_R, np.ones(1, bool))
        gen, model, heading = ctl.generator, ctl.leader_model, ctl.heading
        assert heading is not None
        flight = leader_steps(
            model, gen.p[0], gen.v[0], gen.a[0], heading, route, 9.0, 600, math.inf, OBSTACLE_C, OBSTACLE_R,
            shapes, ctl.aim_bearing,
        )  # fmt: skip
        for field_name, values in flight._asdict().items():
            out[f"{name} steps {field_name}"] = values
        for label, centres, radii in (("obstacles", OBSTACLE_C, OBSTACLE_R), ("gap", gap_c, gap_r)):
            path = predict_leader_path(
                model, gen.p[0], gen.v[0], gen.a[0], heading, GOAL, 10.0, 150.0, 2.0, centres, radii, shapes
            )
            for part, values in zip(("points", "headings", "travel"), path, strict=True):
                out[f"{name} {label} {part}"] = values
        stalls = [leader_stalls(model, gen.p[0], gen.v[0], gen.a[0], heading, GOAL[0], 10.0, gap_c, gap_r)]
        out[f"{name} stalls"] = np.array(stalls)
    return out


def test_compiled_and_interpreted_predictions_are_the_same_bits(tmp_path: Path) -> None:
    """The prediction's kernel and the laws it calls, compiled here and run as plain Python in a subprocess
    with NUMBA_DISABLE_JIT=1 (as test_interpreted_tick.py does for the tick), give the same arrays."""
    compiled = predictions()
    for name in ("iaapf", "apf"):  # the branches are met: a waypoint switch, a stop at the goal
        waypoints = compiled[f"{name} steps waypoints"]
        assert waypoints[0] == 0 and waypoints[-1] == 1 and len(waypoints) < 600
    assert compiled["iaapf stalls"][0]  # and a stall in front of the gap
    module = "tests.gcs_swarm.guidance.test_leader_path"
    interpreted = interpreted_arrays(module, "predictions()", tmp_path / "interpreted.npz", 300)
    assert sorted(interpreted.files) == sorted(compiled)
    for key, values in compiled.items():
        assert values.dtype == interpreted[key].dtype and values.tobytes() == interpreted[key].tobytes(), key
