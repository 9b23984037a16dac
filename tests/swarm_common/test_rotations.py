"""swarm_common.rotations: ZYX Euler angles <-> quaternions against independently built rotation matrices, and
the angle wrap."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from swarm_common import rotations
from tests.swarm_common.rotation_matrices import quaternion_rotation, rotation

angles = st.tuples(
    st.floats(-math.pi, math.pi),
    st.floats(-1.5, 1.5),  # away from the pitch singularity of ZYX Euler angles
    st.floats(-math.pi, math.pi),
)


@given(angles)
def test_euler_quaternion_round_trip(euler: tuple[float, float, float]) -> None:
    q = rotations.euler_to_quaternion(euler)
    np.testing.assert_allclose(quaternion_rotation(q), rotation(euler), atol=1e-12)
    np.testing.assert_allclose(
        quaternion_rotation(rotations.euler_to_quaternion(rotations.quaternion_to_euler(q))),
        rotation(euler),
        atol=1e-9,
    )


def test_vectorised_shapes() -> None:
    euler = np.zeros((5, 3))
    euler[:, 2] = np.linspace(-3, 3, 5)
    assert rotations.quaternion_to_euler(rotations.euler_to_quaternion(euler)).shape == (5, 3)


def test_wrap_pi() -> None:
    # [-pi, pi): 3 pi and -pi wrap to -pi, pi / 2 stays
    np.testing.assert_allclose(
        rotations.wrap_pi([3 * math.pi, -math.pi, math.pi / 2]), [-math.pi, -math.pi, math.pi / 2]
    )
