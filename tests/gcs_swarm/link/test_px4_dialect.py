"""The PX4 dialect against PX4's own numbers (px4_custom_mode.h, commander_params.c, mavlink_parameters.cpp),
worked out here by hand, not read back from the dialect."""

from __future__ import annotations

import math
import struct
from collections import deque

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots import ARDUPILOT, PX4, dialect_for, dialect_named
from gcs_swarm.link.autopilots.failsafe import FailsafeSettings
from gcs_swarm.link.autopilots.px4 import float_bits_as_int32, int32_bits_as_float
from gcs_swarm.link.channel import LinkStats
from gcs_swarm.link.telemetry import TelemetryState, VehicleTelemetry

# px4_custom_mode.h: PX4_CUSTOM_MAIN_MODE_AUTO 4, _OFFBOARD 6, _POSCTL 3; AUTO sub modes TAKEOFF 2, LOITER 3,
# RTL 5, LAND 6; custom_mode = main << 16 | sub << 24
CUSTOM_MODES = {
    "OFFBOARD": 6 * 65536,
    "POSCTL": 3 * 65536,
    "TAKEOFF": 4 * 65536 + 2 * 16777216,
    "LOITER": 4 * 65536 + 3 * 16777216,
    "RTL": 4 * 65536 + 5 * 16777216,
    "LAND": 4 * 65536 + 6 * 16777216,
}


@pytest.mark.parametrize(("name", "number"), CUSTOM_MODES.items())
def test_mode_numbers_are_px4s(name: str, number: int) -> None:
    assert PX4.mode_number(name) == number
    assert PX4.mode_number(name.lower()) == number
    assert PX4.mode_name(number) == name
    main, sub = number >> 16 & 0xFF, number >> 24
    assert PX4.set_mode_params(number) == (float(mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), main, sub)


def test_qgc_style_auto_names_and_unknowns() -> None:
    assert PX4.mode_number("AUTO.LOITER") == CUSTOM_MODES["LOITER"]
    with pytest.raises(ValueError, match="unknown PX4 mode 'GUIDED'"):
        PX4.mode_number("GUIDED")  # ArduCopter's; PX4 has no such mode
    assert PX4.mode_name(-1) == "UNKNOWN"
    assert PX4.mode_name(0x12345678).startswith("MODE_0x")


def test_registry_and_mission_names() -> None:
    assert dialect_for(mavlink2.MAV_AUTOPILOT_PX4) is PX4
    assert dialect_for(mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA) is ARDUPILOT
    assert dialect_named("px4") is PX4 and dialect_named("ardupilot") is ARDUPILOT
    with pytest.raises(ValueError, match="unknown autopilot 'inav'"):
        dialect_named("inav")


def test_int_parameters_travel_as_their_bytes() -> None:
    """NAV_DLL_ACT = 3 goes out as the float whose bytes are 03 00 00 00 (a denormal, ~4.2e-45), and comes
    back as 3; MPC_THR_HOVER, a float, as itself."""
    wire = PX4.encode_param(3, mavlink2.MAV_PARAM_TYPE_INT32)
    assert struct.pack("<f", wire) == b"\x03\x00\x00\x00"
    assert 0.0 < wire < 1e-44
    assert PX4.decode_param(wire, mavlink2.MAV_PARAM_TYPE_INT32) == 3.0
    assert PX4.encode_param(0.45, mavlink2.MAV_PARAM_TYPE_REAL32) == 0.45
    assert PX4.decode_param(0.45, mavlink2.MAV_PARAM_TYPE_REAL32) == 0.45
    # -1 is all ones: a quiet NaN as a float, still -1 after the round trip
    assert math.isnan(int32_bits_as_float(-1))
    assert PX4.decode_param(int32_bits_as_float(-1), mavlink2.MAV_PARAM_TYPE_INT32) == -1.0
    with pytest.raises(ValueError, match="not an int32"):
        PX4.encode_param(2.5, mavlink2.MAV_PARAM_TYPE_INT32)
    # ArduPilot sends the value itself whatever the type
    assert ARDUPILOT.encode_param(3, mavlink2.MAV_PARAM_TYPE_INT32) == 3.0


def _signalling_nan_bits(value: int) -> bool:
    """The int32's bits are a float32 signalling NaN (exponent all ones, quiet bit clear, mantissa not 0)."""
    bits = value & 0x7FFFFFFF
    return 0x7F800001 <= bits <= 0x7FBFFFFF


@given(st.integers(-(2**31), 2**31 - 1).filter(lambda v: not _signalling_nan_bits(v)))
def test_int32_round_trip_through_a_pymavlink_param_set(value: int) -> None:
    """Every int32 whose bits are not a signalling NaN crosses PARAM_SET bit-exact (the bytes on the wire are
    the int's, little-endian) and decodes back."""
    mav = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    msg = mav.param_set_encode(
        1, 1, b"NAV_DLL_ACT", PX4.encode_param(value, 6), mavlink2.MAV_PARAM_TYPE_INT32
    )
    packet = msg.pack(mav)
    payload = packet[10 : 10 + 23]  # MAVLink 2 header is 10 bytes; param_value is the first field
    assert payload[:4] == struct.pack("<i", value)
    decoded = mavlink2.MAVLink(None).parse_char(packet)
    assert float_bits_as_int32(decoded.param_value) == value
    assert PX4.decode_param(decoded.param_value, decoded.param_type) == float(value)


def test_takeoff_altitude_is_amsl_and_yaw_position_left_to_the_vehicle() -> None:
    params = PX4.takeoff_params(10.0, 584.25)
    assert params[6] == 594.25  # param7: metres AMSL
    assert all(math.isnan(p) for p in params[3:6])  # yaw, latitude, longitude: as it stands
    assert ARDUPILOT.takeoff_params(10.0, 584.25) == (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 10.0)  # above home


@pytest.mark.parametrize(
    ("failsafe", "offboard_loss", "gcs_loss"),
    [("brake", 5, 1), ("land", 4, 3), ("rtl", 3, 2), ("off", 5, 0)],  # Hold / Land / Return; NAV_DLL_ACT
)
def test_failsafe_parameters(failsafe: str, offboard_loss: int, gcs_loss: int) -> None:
    """COM_OBL_RC_ACT: 3 Return, 4 Land, 5 Hold; NAV_DLL_ACT: 0 off, 1 Hold, 2 Return, 3 Land. The last
    OFFBOARD target is flown for offboard_loss_s; both timeouts keep PX4's ranges (0..60 s, 5..300 s)."""
    settings = FailsafeSettings(failsafe, gcs_loss_s=2.0, guided_timeout_s=0.5, offboard_loss_s=1.0)
    wanted = dict(PX4.flight_params(settings))
    assert wanted == {
        "COM_OF_LOSS_T": 1.0,
        "COM_OBL_RC_ACT": offboard_loss,
        "NAV_DLL_ACT": gcs_loss,
        "COM_DL_LOSS_T": 5.0,
    }
    longer = FailsafeSettings(failsafe, gcs_loss_s=12.0, guided_timeout_s=0.5, offboard_loss_s=90.0)
    assert dict(PX4.flight_params(longer)).items() >= {"COM_DL_LOSS_T": 12.0, "COM_OF_LOSS_T": 60.0}.items()
    # COM_DL_LOSS_T is an INT32 on PX4 (commander_params.c; read off a real PX4 1.17 SITL): whole seconds, up
    fractional = FailsafeSettings(failsafe, gcs_loss_s=6.2, guided_timeout_s=0.5, offboard_loss_s=1.0)
    assert dict(PX4.flight_params(fractional))["COM_DL_LOSS_T"] == 7.0


def _sys_status(present: int, enabled: int, health: int) -> mavlink2.MAVLink_sys_status_message:
    return mavlink2.MAVLink_sys_status_message(present, enabled, health, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)


@pytest.mark.parametrize(("gated", "health", "prearm"), [(False, 0x1320C83F, 1), (False, 0x0321C83F, 0)])
def test_px4_pre_arm_bit_is_read_from_health_alone(gated: bool, health: int, prearm: int) -> None:
    """Real PX4 SITL (1.17-dev) never sets PREARM_CHECK (0x10000000) in present or enabled (0x0300402f,
    0x0301402f), only in health once its checks pass: 0x1320c83f ready, 0x0321c83f (at boot) not. Read as
    ArduPilot reads it (bit counted only when enabled), the second would count as ready."""
    state = TelemetryState(1, (47.397742, 8.545594, 489.4))
    state.prearm_gated[0] = gated
    telemetry = VehicleTelemetry(0, "lead", state, deque(), LinkStats(), lambda *_: None, lambda: None)
    telemetry.handlers["SYS_STATUS"](_sys_status(0x0300402F, 0x0301402F, health))
    assert state.prearm[0] == prearm
    state.prearm_gated[0] = True  # ArduPilot's reading of the same words: not enabled, so never checked
    telemetry.handlers["SYS_STATUS"](_sys_status(0x0300402F, 0x0301402F, 0x0321C83F))
    assert state.prearm[0] == 1


@pytest.mark.parametrize(("action", "expected"), [("report", 1), ("brake", 2), ("rtl", 3), ("land", 5)])
def test_the_fence_action_is_gf_action(action: str, expected: int) -> None:
    # src/modules/navigator/geofence_params.c: 1 Warning, 2 Hold mode, 3 Return mode, 5 Land mode
    assert PX4.fence_params(action) == [("GF_ACTION", float(expected))]
