"""Frame conversions at the MAVLink boundary (spec 1.1): geodesy, NED/ENU vectors, FLU/ENU <-> FRD/NED."""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gcs_swarm.link import frames
from swarm_common import rotations
from tests.swarm_common.rotation_matrices import quaternion_rotation, rotation

ORIGIN = (47.397742, 8.545594, 488.0)
ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # also NED -> ENU
FLU_TO_FRD = np.diag([1.0, -1.0, -1.0])  # also FRD -> FLU

angles = st.tuples(
    st.floats(-math.pi, math.pi),
    st.floats(-1.5, 1.5),  # away from the pitch singularity of ZYX Euler angles
    st.floats(-math.pi, math.pi),
)


def test_geodetic_rows_to_enu_match_pymap3d_and_round_trip() -> None:
    lat = np.array([47.397742, 47.398742, 47.396742])
    lon = np.array([8.545594, 8.547594, 8.544594])
    alt = np.array([488.0, 498.5, 470.0])
    enu = frames.geodetic_rows_to_enu(np.column_stack((lat, lon, alt)), ORIGIN)
    assert enu.shape == (3, 3)
    for k in range(3):
        expected = pymap3d.geodetic2enu(lat[k], lon[k], alt[k], *ORIGIN)
        np.testing.assert_allclose(enu[k], expected, atol=1e-9)
    assert enu[1, 1] == pytest.approx(111.2, abs=0.5)  # 0.001 deg of latitude is ~111 m North
    back = frames.enu_to_geodetic(enu, ORIGIN)
    np.testing.assert_allclose(back[0], lat, atol=1e-10)
    np.testing.assert_allclose(back[1], lon, atol=1e-10)
    np.testing.assert_allclose(back[2], alt, atol=1e-6)


def test_the_origin_is_zero() -> None:
    np.testing.assert_allclose(frames.geodetic_rows_to_enu([ORIGIN], ORIGIN), [[0.0, 0.0, 0.0]], atol=1e-9)


def test_ned_enu_vectors() -> None:
    np.testing.assert_array_equal(frames.ned_to_enu([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    np.testing.assert_array_equal(frames.enu_to_ned([2.0, 1.0, -3.0]), [1.0, 2.0, 3.0])
    v = np.arange(12.0).reshape(4, 3)
    np.testing.assert_array_equal(frames.ned_to_enu(v), v @ ENU_TO_NED.T)


@pytest.mark.parametrize(
    ("yaw_enu_deg", "yaw_ned_deg"),
    [(0, 90), (90, 0), (180, -90), (-90, 180), (30, 60), (120, -30), (-60, 150), (-150, -120)],
)
def test_yaw_quadrants(yaw_enu_deg: float, yaw_ned_deg: float) -> None:
    """Level, the target quaternion turns about NED's down axis by the NED yaw: (cos y/2, 0, 0, sin y/2)."""
    q = frames.attitude_target_quaternion([0.0, 0.0, math.radians(yaw_enu_deg)])
    yaw_ned = 2.0 * math.atan2(q[3], q[0])
    assert q[1] == q[2] == 0.0
    assert math.degrees(rotations.wrap_pi(yaw_ned - math.radians(yaw_ned_deg))) == pytest.approx(
        0.0, abs=1e-9
    )


def test_known_cases() -> None:
    # Level, facing North in NED (yaw 0): the MAVLink quaternion is the identity.
    np.testing.assert_allclose(
        frames.attitude_target_quaternion([0.0, 0.0, math.pi / 2]), [1, 0, 0, 0], atol=1e-12
    )


@given(angles)
def test_attitude_conversion_is_the_frame_change(euler: tuple[float, float, float]) -> None:
    """R_NED<-FRD = T * R_ENU<-FLU * B for the converted Euler angles and quaternions."""
    r_enu = rotation(euler)
    r_ned = ENU_TO_NED @ r_enu @ FLU_TO_FRD
    q_ned = frames.attitude_target_quaternion(euler)
    np.testing.assert_allclose(quaternion_rotation(q_ned), r_ned, atol=1e-12)
    q_enu = frames.quaternion_ned_to_enu(q_ned)
    np.testing.assert_allclose(quaternion_rotation(q_enu), r_enu, atol=1e-12)


def test_vectorised_shapes() -> None:
    euler = np.zeros((5, 3))
    euler[:, 2] = np.linspace(-3, 3, 5)
    assert frames.attitude_target_quaternion(euler).shape == (5, 4)


@given(
    st.floats(-89.0, 89.0),
    st.floats(-180.0, 180.0),
    st.floats(-400.0, 5000.0),
    st.integers(0, 2**32 - 1),
    st.integers(0, 9),
    st.floats(0.0, 0.5),
)
def test_geodetic_rows_to_enu_gives_pymap3d_bits(lat0, lon0, h0, seed, n, spread_deg):
    """Every output bit of the rows is pymap3d.geodetic2enu's: fleets of 0 to 9 vehicles, near the
    origin and up to about 50 km away, unknown (NaN) rows included."""
    rng = np.random.default_rng(seed)
    rows = np.column_stack(
        (
            np.clip(lat0 + rng.normal(0.0, spread_deg, n), -90.0, 90.0),
            lon0 + rng.normal(0.0, spread_deg, n),
            h0 + rng.normal(0.0, 300.0, n),
        )
    )
    if n > 2:
        rows[1] = np.nan  # a vehicle not heard from yet
    e, nn, u = pymap3d.geodetic2enu(rows[:, 0], rows[:, 1], rows[:, 2], lat0, lon0, h0)
    expected = np.stack((e, nn, u), axis=-1).astype(float)
    got = frames.geodetic_rows_to_enu(rows, (lat0, lon0, h0))
    assert got.shape == (n, 3)
    assert_same_bits(got, expected)


edge_angles = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, math.pi, -math.pi, 0.5 * math.pi, -0.5 * math.pi, 2.0 * math.pi]),
    st.floats(-10.0, 10.0),
)


@given(st.lists(st.tuples(edge_angles, edge_angles, edge_angles), max_size=9))
def test_attitude_targets_give_the_bits_of_the_euler_formula(rows):
    """A fleet's attitude targets have the bits of swarm_common.rotations.euler_to_quaternion (numpy) of the
    FRD/NED angles (roll, -pitch, wrap_pi(pi/2 - yaw)), NaN, infinities and signed zeros included."""
    euler = np.array(rows, dtype=float).reshape(-1, 3)
    with np.errstate(invalid="ignore"):  # inf % 2 pi
        ned = np.stack((euler[:, 0], -euler[:, 1], rotations.wrap_pi(0.5 * math.pi - euler[:, 2])), axis=-1)
        expected = rotations.euler_to_quaternion(ned)
    got = frames.attitude_target_quaternion(euler)
    assert got.shape == expected.shape == (len(rows), 4)
    assert_same_bits(got, expected)


def assert_same_bits(got: np.ndarray, expected: np.ndarray) -> None:
    """NaN where `expected` has NaN (of either sign: numpy's vector loops and libm set the sign of a NaN
    differently, and no NaN is ever sent or logged); every other element bit for bit, signed zeros too."""
    nan = np.isnan(expected)
    assert (np.isnan(got) == nan).all()
    assert got[~nan].tobytes() == expected[~nan].tobytes()
