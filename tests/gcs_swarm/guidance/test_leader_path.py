"""The leader's path predicted for the reshape's look-ahead (gcs_swarm.guidance.leader_path): it is the path
the leader's own reference then flies, and the look-ahead uses it."""

from __future__ import annotations

import math

import numpy as np

from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.leader_path import predict_leader_path, resample
from gcs_swarm.guidance.params import ReshapeParams

GOAL = np.array([[200.0, 0.0, 10.0]])
OBSTACLE_C = np.array([[60.0, 2.0, 10.0]])  # 2 m left of the leader's straight line, in its way
OBSTACLE_R = np.array([4.0])


def _controller(n: int = 1, reshape: ReshapeParams | None = None) -> FleetController:
    offsets = np.zeros((n, 3))
    if n > 1:
        offsets[1:] = formation_offsets("v", n - 1, 10.0)
    ctl = FleetController(n, 0, offsets, GOAL, reshape=reshape, z_min=1.0)
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
