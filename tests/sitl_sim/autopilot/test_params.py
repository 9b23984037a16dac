"""Parameter protocol (list, read by name and index, set round trip, refusals) and the table itself."""

from __future__ import annotations

import math

import pytest

from sitl_sim.autopilot.params import ParamTable, param_specs
from tests.sitl_sim.sim_process import M


def test_param_list_read_and_set_round_trip(sitl, pilot_for):
    sim = sitl("--speedup", "5")
    pilot = pilot_for(sim, lockstep=False)
    v = pilot[0]
    v.mav.param_request_list_send(1, 1)
    count = len(param_specs(0.4))
    pilot.spin(lambda: len(v.params) == count, 5.0)
    assert {p.param_count for p in v.params.values()} == {count}
    assert sorted(p.param_index for p in v.params.values()) == list(range(count))
    assert v.params["MAV_SYSID"].param_value == 1
    assert v.params["MOT_THST_HOVER"].param_value == pytest.approx(0.4, abs=1e-6)
    assert v.params["ANGLE_MAX"].param_type == M.MAV_PARAM_TYPE_INT16
    assert v.params["GUID_TIMEOUT"].param_type == M.MAV_PARAM_TYPE_REAL32

    v.params.clear()
    v.mav.param_request_read_send(1, 1, b"RTL_ALT", -1)
    v.mav.param_request_read_send(1, 1, b"", 0)
    pilot.spin(lambda: "RTL_ALT" in v.params and len(v.params) == 2, 5.0)
    first = min(v.params.values(), key=lambda p: p.param_index)
    assert first.param_index == 0 and first.param_id == "ANGLE_MAX"

    assert pilot.set_param(0, "WPNAV_SPEED_UP", 300) == 300
    v.params.clear()
    v.mav.param_request_read_send(1, 1, b"WPNAV_SPEED_UP", -1)
    pilot.spin(lambda: "WPNAV_SPEED_UP" in v.params, 5.0)
    assert v.params["WPNAV_SPEED_UP"].param_value == 300


@pytest.mark.parametrize(
    ("name", "value", "echo", "reason"),
    [
        ("ANGLE_MAX", 9000, 3000, "out of range"),
        ("DISARM_DELAY", 2.5, 10, "must be an integer"),
        ("NO_SUCH_PARAM", 1, None, "unknown parameter"),
        ("FS_GCS_TIMEOUT", math.nan, 5, "not finite"),
    ],
)
def test_param_set_refusals_say_why_and_echo_the_value(sitl, pilot_for, name, value, echo, reason):
    sim = sitl("--speedup", "5")
    pilot = pilot_for(sim, lockstep=False)
    v = pilot[0]
    v.mav.param_set_send(1, 1, name.encode(), value, M.MAV_PARAM_TYPE_REAL32)
    pilot.spin(lambda: any(reason in text for text in v.texts), 5.0)
    if echo is not None:
        pilot.spin(lambda: name in v.params, 5.0)
        assert v.params[name].param_value == echo


def test_table_checks_and_world_params_apply_to_every_vehicle():
    table = ParamTable(3, param_specs(0.4))
    assert table.check("ANGLE_MAX", 4500) is None
    assert "out of range" in table.check("ANGLE_MAX", 100)
    assert "integer" in table.check("RTL_ALT", 1500.5)
    assert table.check("NOPE", 1) == "unknown parameter NOPE"
    assert table.set(1, "ANGLE_MAX", 4500) == [1]
    assert list(table.column("ANGLE_MAX")) == [3000, 4500, 3000]
    assert table.set(2, "SIM_WIND_SPD", 7) == [0, 1, 2]
    assert list(table.column("SIM_WIND_SPD")) == [7, 7, 7]
    assert all(len(spec.name) <= 16 for spec in table.specs)
    assert [spec.name for spec in table.specs] == sorted(spec.name for spec in table.specs)


def test_parameter_names_of_either_release_but_never_both(sitl, pilot_for):
    """4.7 names by default, 4.6 names with --param-names 4.6: a vehicle answers to one spelling only, as a
    real one does (ArduCopter/Parameters.cpp converts the old names on upgrade)."""
    for release, shown, absent in (
        ("4.7", "MAV_SYSID", "SYSID_THISMAV"),
        ("4.6", "SYSID_THISMAV", "MAV_SYSID"),
    ):
        sim = sitl("--lockstep", "--ready-delay", "1", "--param-names", release)
        pilot = pilot_for(sim)
        assert pilot.param(0, shown) == 1
        v = pilot[0]
        v.params.clear()
        v.mav.param_request_read_send(v.sysid, 1, absent.encode(), -1)
        pilot.spin(lambda v=v: v.t > 1.0, 5.0)
        assert absent not in v.params
        sim.stop()
