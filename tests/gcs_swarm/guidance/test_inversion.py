"""The thrust/attitude inversion (spec 5): round trips, unit rows, the order of the limits, Eq 36."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance.inversion import invert, limited_thrust, thrust_vector
from gcs_swarm.guidance.params import G, Limits


@pytest.mark.parametrize("yaw_deg", [-179.0, -135.0, -90.0, -30.0, 0.0, 45.0, 90.0, 150.0, 180.0])
def test_inversion_round_trip_in_every_quadrant(yaw_deg):
    rng = np.random.default_rng(int(yaw_deg) + 200)
    n = 200
    lim = Limits(tilt_max_deg=60.0)
    roll = rng.uniform(-0.6, 0.6, n)
    pitch = rng.uniform(-0.6, 0.6, n)
    yaw = np.full(n, math.radians(yaw_deg))
    thrust = rng.uniform(0.5 * G, 1.9 * G, n)
    u = thrust_vector(roll, pitch, yaw, thrust)
    cmd = invert(u, yaw, lim)
    np.testing.assert_allclose(cmd.roll, roll, atol=1e-12)
    np.testing.assert_allclose(cmd.pitch, pitch, atol=1e-12)
    np.testing.assert_allclose(cmd.thrust_acc, thrust, rtol=1e-12)
    np.testing.assert_allclose(thrust_vector(cmd.roll, cmd.pitch, yaw, cmd.thrust_acc), u, atol=1e-12)
    measured = invert(u, yaw, lim, G, roll, pitch)  # Eq 36 with the measured = desired angles: same thrust
    np.testing.assert_allclose(measured.thrust_acc, thrust, rtol=1e-12)


def test_thrust_vector_rows_are_unit_vectors():
    """The corrected y row (cos psi, not sin psi) keeps R e3 a unit vector (spec 5 [fix])."""
    rng = np.random.default_rng(2)
    a = rng.uniform(-math.pi, math.pi, (3, 500))
    np.testing.assert_allclose(np.linalg.norm(thrust_vector(*a, np.ones(500)), axis=1), 1.0, atol=1e-12)


def test_limits_apply_in_order():
    lim = Limits()
    tan = math.tan(lim.tilt_max)
    # 1. U_z floor first, then 2. the tilt limit shortens U_xy (direction kept) against the floored U_z.
    floor = lim.uz_min_g * G
    u = limited_thrust(30.0, 40.0, -5.0, floor, tan)
    assert u[2] == pytest.approx(0.3 * G)
    assert np.hypot(u[0], u[1]) == pytest.approx(0.3 * G * tan)
    assert u[1] / u[0] == pytest.approx(40.0 / 30.0)
    np.testing.assert_array_equal(invert(np.array([[30.0, 40.0, -5.0]]), np.zeros(1), lim).u_limited[0], u)
    # inside the cone nothing changes
    assert limited_thrust(1.0, -1.0, G, floor, tan) == (1.0, -1.0, G)
    # 3. thrust cap last: direction (angles) kept, magnitude 2 g
    cmd = invert(np.array([[0.0, 5.0, 40.0]]), np.zeros(1), lim)
    assert cmd.thrust_acc[0] == pytest.approx(2 * G)
    assert cmd.roll[0] == pytest.approx(-math.atan2(5.0, 40.0))


def test_measured_angle_thrust_floors_the_tilt_compensation():
    """Eq 36 divides by cos(phi)cos(theta) of the measured attitude, never by less than cos(tilt_max)."""
    lim = Limits(thrust_max_g=10.0)
    u = np.array([[0.0, 0.0, G]])
    tilted = invert(u, np.zeros(1), lim, G, np.array([0.2]), np.array([0.1]))
    assert tilted.thrust_acc[0] == pytest.approx(G / (math.cos(0.2) * math.cos(0.1)))
    flipped = invert(u, np.zeros(1), lim, G, np.array([3.0]), np.array([0.0]))
    assert flipped.thrust_acc[0] == pytest.approx(G / math.cos(lim.tilt_max))
