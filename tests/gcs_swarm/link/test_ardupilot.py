"""ArduCopter facts the ground station relies on (gcs_swarm/link/autopilots/ardupilot.py), and the registry
that hands the link its dialect (gcs_swarm/link/autopilots/__init__.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots import DEFAULT_DIALECT, ardupilot, dialect_for
from gcs_swarm.link.autopilots.ardupilot import ARDUPILOT


@pytest.mark.parametrize(
    ("old", "new"),
    [("SYSID_THISMAV", "MAV_SYSID"), ("SYSID_MYGCS", "MAV_GCS_SYSID"), ("SR0_EXTRA1", "MAV1_EXTRA1"),
     ("SR2_POSITION", "MAV3_POSITION")],
)  # fmt: skip
def test_renamed_parameters_map_both_ways(old: str, new: str) -> None:
    assert ARDUPILOT.other_param_name(old) == new
    assert ARDUPILOT.other_param_name(new) == old


def test_parameters_that_kept_their_name_have_no_other_spelling() -> None:
    for name in ("GUID_OPTIONS", "MAV_OPTIONS", "MAV0_EXTRA1", "FS_GCS_ENABLE"):
        assert ARDUPILOT.other_param_name(name) is None


def test_the_boost_is_taken_out_for_boosting_vehicles_only() -> None:
    """ArduCopter multiplies by 1/cos(lean) (floored at cos 0.1); sending thrust * cos(lean) makes the two
    cancel: at 30 deg roll and 20 deg pitch cos(lean) = cos 30 cos 20 = 0.8138. Hover 0.5, 12 m/s^2."""
    g = 9.8
    sent = ARDUPILOT.thrust(
        np.array([12.0, 12.0]),
        np.radians([30.0, 30.0]),
        np.radians([20.0, 20.0]),
        np.array([0.5, 0.5]),
        np.array([True, False]),
        g,
    )
    cos_lean = math.cos(math.radians(30)) * math.cos(math.radians(20))
    assert sent[0] == pytest.approx(0.5 * 12.0 * cos_lean / g)
    assert sent[1] == pytest.approx(0.5 * 12.0 / g)
    boosted_again = sent[0] / min(max(cos_lean, 0.1), 1.0)  # AC_AttitudeControl_Multi::get_throttle_boosted
    assert boosted_again == pytest.approx(0.5 * 12.0 / g)


def test_a_missing_boost_value_counts_as_on() -> None:
    boost_on = ardupilot.ARDUPILOT.is_angle_boost_on
    assert boost_on(1.0) and boost_on(math.nan) and not boost_on(0.0)


def test_ekf_reasons_name_what_is_missing() -> None:
    required = mavlink2.EKF_ATTITUDE | mavlink2.EKF_VELOCITY_HORIZ
    horizontal = mavlink2.EKF_POS_HORIZ_ABS
    forbidden = mavlink2.EKF_CONST_POS_MODE
    why = ARDUPILOT.ekf_missing(
        mavlink2.EKF_ATTITUDE | mavlink2.EKF_CONST_POS_MODE, required, horizontal, forbidden
    )
    assert why == "no horizontal velocity, absolute horizontal position; constant-position mode (no GPS)"
    assert ARDUPILOT.gps_fix_name(3) == "3D fix" and ARDUPILOT.gps_fix_name(9) == "fix type 9"


def test_the_registry_picks_the_dialect_by_heartbeat_autopilot() -> None:
    assert dialect_for(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA) is ARDUPILOT
    # an autopilot without a dialect of its own is spoken to as the default (ArduPilot, as before dialects)
    assert dialect_for(mavlink2.MAV_AUTOPILOT_GENERIC) is DEFAULT_DIALECT


def test_modes_by_name_and_number() -> None:
    """ArduCopter's custom_mode numbers (ArduCopter/mode.h: STABILIZE 0, GUIDED 4, LAND 9, BRAKE 17)."""
    names = ("stabilize", " Guided ", "LAND", "BRAKE", 4)
    assert [ARDUPILOT.mode_number(m) for m in names] == [0, 4, 9, 17, 4]
    assert ARDUPILOT.mode_name(4) == "GUIDED" and ARDUPILOT.mode_name(-1) == "UNKNOWN"
    assert ARDUPILOT.mode_name(99) == "MODE_99"
    with pytest.raises(ValueError, match="unknown ArduCopter mode 'HOVER'"):
        ARDUPILOT.mode_number("HOVER")
    with pytest.raises(ValueError, match="unknown ArduCopter mode 99"):
        ARDUPILOT.mode_number(99)
