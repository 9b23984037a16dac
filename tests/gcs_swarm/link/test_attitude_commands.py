"""The send step of a formation tick (gcs_swarm.link.attitude_commands): the compiled loop gives numpy's
bits, for every kind of row the guard has a rule for and for garbage; and two worked cases of the thrust."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_swarm.link import attitude_commands as commands
from gcs_swarm.link.command_limits import CommandLimits
from tests.gcs_swarm.link.test_frames import assert_same_bits

pytest.importorskip("numba")

G = 9.80665
LIMITS = CommandLimits(
    tilt_max=0.6, thrust_max_g=2.0, min_altitude=2.0, geofence_radius=100.0, geofence_max_alt=50.0
)

SPECIAL = [0.0, -0.0, math.nan, -math.nan, math.inf, -math.inf, 1e308, -1e-320]
angles = st.one_of(st.floats(-1.2, 1.2), st.sampled_from([0.6, -0.6, 0.6 + 1e-9, math.pi, *SPECIAL]))
accelerations = st.one_of(st.floats(-5.0, 40.0), st.sampled_from([G, *SPECIAL]))
# positions inside and outside the 100 m fence, above its 50 m ceiling, below the 2 m floor, on each limit
coordinates = st.one_of(st.floats(-150.0, 150.0), st.sampled_from([100.0, -100.0, 50.0, 2.0, *SPECIAL]))
velocities = st.one_of(st.floats(-15.0, 15.0), st.sampled_from(SPECIAL))
hovers = st.one_of(st.floats(0.1, 0.9), st.sampled_from([0.5, 0.0, -0.0, math.nan, math.inf]))


@st.composite
def send_steps(draw: st.DrawFn) -> tuple[np.ndarray, ...]:
    n = draw(st.integers(1, 9))

    def column(values: st.SearchStrategy[float], width: int = 0) -> np.ndarray:
        flat = draw(st.lists(values, min_size=n * max(width, 1), max_size=n * max(width, 1)))
        return np.array(flat).reshape((n, width) if width else (n,))

    boost = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    return (
        column(angles), column(angles), column(angles), column(accelerations), column(angles, 3),
        column(coordinates, 3), column(velocities, 3), column(hovers), boost,
    )  # fmt: skip


@settings(max_examples=400, deadline=None)
@given(step=send_steps())
def test_the_compiled_send_step_gives_numpys_bits(step: tuple[np.ndarray, ...]) -> None:
    expected = commands.attitude_commands_numpy(*step, G, LIMITS)
    got = commands.attitude_commands(*step, G, LIMITS)
    for name in ("roll", "pitch", "yaw", "thrust"):
        assert_same_bits(getattr(got, name), getattr(expected, name))
    assert got.changed.tolist() == expected.changed.tolist()


@pytest.mark.parametrize("send_step", [commands.attitude_commands_numpy, commands.attitude_commands])
def test_thrust_is_hover_times_g_ratio_with_the_boost_taken_out(send_step) -> None:
    """Worked by hand: hover 0.4 holds 1 g. Vehicle 0 is level and asks for 1 g: 0.4. Vehicle 1 leans 60 deg
    (cos 0.5) with ATC_ANGLE_BOOST on and asks for 1.5 g: ArduCopter divides by cos again, so half of
    1.5 * 0.4 = 0.3 goes out. Vehicle 2 is the same without the boost: 0.6. None is changed by the guard
    (inside the fence, between floor and ceiling, level commands)."""
    n = 3
    zeros = np.zeros(n)
    att = np.array([[0.0, 0.0, 0.1], [math.pi / 3, 0.0, 0.2], [math.pi / 3, 0.0, 0.3]])
    pos = np.array([[0.0, 0.0, 10.0]] * n)
    out = send_step(
        zeros, zeros, att[:, 2], np.array([G, 1.5 * G, 1.5 * G]), att, pos, np.zeros((n, 3)),
        np.full(n, 0.4), np.array([True, True, False]), G, LIMITS,
    )  # fmt: skip
    assert out.thrust == pytest.approx([0.4, 0.3, 0.6], abs=1e-12)
    assert out.yaw.tolist() == [0.1, 0.2, 0.3] and not out.changed.any()
