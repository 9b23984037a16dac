"""The send step of a formation tick (gcs_swarm.link.attitude_commands): each vehicle's thrust made by its
autopilot dialect, worked by hand, then the final guard; and for every kind of row, garbage included, what
goes out stays within the limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_swarm.link import attitude_commands as commands
from gcs_swarm.link.autopilots import ARDUPILOT, PX4
from gcs_swarm.link.command_limits import TILT_SLACK, CommandLimits

G = 9.80665
LIMITS = CommandLimits(
    tilt_max=0.6, thrust_max_g=2.0, min_altitude=2.0, geofence_radius=100.0, geofence_max_alt=50.0
)


def send(thrust_acc, att, boost, dialects, hover=0.4, roll=None, pitch=None, pos=None):
    n = len(thrust_acc)
    zeros = np.zeros(n)
    att = np.asarray(att, dtype=float)
    return commands.attitude_commands(
        zeros if roll is None else np.asarray(roll, dtype=float),
        zeros if pitch is None else np.asarray(pitch, dtype=float),
        att[:, 2], np.asarray(thrust_acc, dtype=float), att,
        np.array([[0.0, 0.0, 10.0]] * n) if pos is None else np.asarray(pos, dtype=float),
        np.zeros((n, 3)), np.full(n, hover), np.asarray(boost, dtype=bool), G, LIMITS, dialects,
    )  # fmt: skip


def test_ardupilot_thrust_is_hover_times_g_ratio_with_the_boost_taken_out() -> None:
    """Hover 0.4 holds 1 g. Vehicle 0 is level and asks for 1 g: 0.4. Vehicle 1 leans 60 deg (cos 0.5) with
    ATC_ANGLE_BOOST on and asks for 1.5 g: ArduCopter divides by cos again, so half of 1.5 * 0.4 = 0.3 goes
    out. Vehicle 2 is the same without the boost: 0.6. None is changed by the guard."""
    att = [[0.0, 0.0, 0.1], [math.pi / 3, 0.0, 0.2], [math.pi / 3, 0.0, 0.3]]
    out = send([G, 1.5 * G, 1.5 * G], att, [True, True, False], [ARDUPILOT] * 3)
    assert out.thrust == pytest.approx([0.4, 0.3, 0.6], abs=1e-12)
    assert out.yaw.tolist() == [0.1, 0.2, 0.3] and not out.changed.any()


def test_the_boost_floor_and_an_unknown_lean() -> None:
    """ArduCopter floors cos(lean) at 0.1 (AC_AttitudeControl_Multi::get_throttle_boosted); a NaN attitude
    counts as level."""
    att = [[1.5, 0.0, 0.0], [math.nan, 0.0, 0.0]]
    out = send([G, G], att, [True, True], [ARDUPILOT] * 2)
    assert out.thrust == pytest.approx([0.04, 0.4], abs=1e-12)


def test_px4_flies_thrust_as_given_whatever_the_lean() -> None:
    """PX4's OFFBOARD takes thrust along body z with no tilt compensation: the same 1.5 g at 60 deg lean is
    0.6, boost flag or not."""
    att = [[math.pi / 3, 0.0, 0.2], [math.pi / 3, 0.0, 0.3]]
    out = send([1.5 * G, 1.5 * G], att, [True, False], [PX4] * 2)
    assert out.thrust == pytest.approx([0.6, 0.6], abs=1e-12)


def test_a_mixed_fleet_gets_each_vehicle_its_own_dialect() -> None:
    att = [[math.pi / 3, 0.0, 0.0]] * 4
    out = send([1.5 * G] * 4, att, [True] * 4, [ARDUPILOT, PX4, ARDUPILOT, PX4])
    assert out.thrust == pytest.approx([0.3, 0.6, 0.3, 0.6], abs=1e-12)


@pytest.mark.parametrize(("acc", "thrust"), [(math.nan, 0.0), (math.inf, 1.0), (-math.inf, 0.0), (-3.0, 0.0)])
def test_unusable_accelerations(acc: float, thrust: float) -> None:
    """NaN: no thrust; +inf: full (then the guard's thrust_max_g * hover = 0.8); -inf or negative: none."""
    for dialect in (ARDUPILOT, PX4):
        out = send([acc], [[0.0, 0.0, 0.0]], [True], [dialect])
        assert out.thrust[0] == min(thrust, 0.8)


SPECIAL = [0.0, -0.0, math.nan, math.inf, -math.inf, 1e308, -1e-320]
angles = st.one_of(st.floats(-1.2, 1.2), st.sampled_from([0.6, -0.6, 0.6 + 1e-9, math.pi, *SPECIAL]))
accelerations = st.one_of(st.floats(-5.0, 40.0), st.sampled_from([G, *SPECIAL]))
coordinates = st.one_of(st.floats(-150.0, 150.0), st.sampled_from([100.0, -100.0, 50.0, 2.0, *SPECIAL]))


@st.composite
def fleets(draw: st.DrawFn) -> tuple:
    n = draw(st.integers(1, 9))

    def column(values: st.SearchStrategy[float], width: int = 0) -> np.ndarray:
        flat = draw(st.lists(values, min_size=n * max(width, 1), max_size=n * max(width, 1)))
        return np.array(flat).reshape((n, width) if width else (n,))

    hover = np.array(draw(st.lists(st.floats(0.1, 0.9), min_size=n, max_size=n)))
    boost = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    dialects = draw(st.lists(st.sampled_from([ARDUPILOT, PX4]), min_size=n, max_size=n))
    return (
        column(angles), column(angles), column(angles), column(accelerations), column(angles, 3),
        column(coordinates, 3), column(coordinates, 3), hover, boost, G, LIMITS, dialects,
    )  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(args=fleets())
def test_what_goes_out_is_finite_and_within_the_limits(args: tuple) -> None:
    roll, pitch, yaw, _, att, pos, _, hover, *_ = args
    with np.errstate(all="ignore"):
        out = commands.attitude_commands(*args)
    for values in (out.roll, out.pitch, out.thrust):
        assert np.isfinite(values).all()
    assert np.isfinite(out.yaw[np.isfinite(att[:, 2]) | np.isfinite(yaw)]).all()
    assert ((out.thrust >= 0.0) & (out.thrust <= np.minimum(1.0, hover * LIMITS.thrust_max_g))).all()
    tilt = np.arccos(np.clip(np.cos(out.roll) * np.cos(out.pitch), -1.0, 1.0))
    assert (tilt <= LIMITS.tilt_max + TILT_SLACK + 1e-12).all()
    below = pos[:, 2] <= LIMITS.min_altitude
    assert (out.thrust[below] >= np.minimum(hover[below], np.minimum(1.0, 2.0 * hover[below]))).all()
    unchanged = ~out.changed
    assert (out.roll[unchanged] == roll[unchanged]).all() and (out.pitch[unchanged] == pitch[unchanged]).all()
