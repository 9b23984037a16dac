"""Personas as objects: the registry, one parameter table for a mixed fleet, the mirrors of PX4 parameters
into the shared loop's columns, and the landing descent each persona hands the shared outer loop as data."""

from __future__ import annotations

import numpy as np
import pytest

from sitl_sim.autopilot.arducopter import ArduCopter
from sitl_sim.autopilot.copter import Autopilot
from sitl_sim.autopilot.outer_loop import DESCENT_INTERPOLATED, DESCENT_TWO_SPEED, interpolated_land_speed
from sitl_sim.autopilot.params import param_specs
from sitl_sim.autopilot.px4 import Px4
from sitl_sim.autopilot.registry import fleet_params, fleet_personas, parse_autopilots, persona_named
from sitl_sim.vehicle_model.dynamics import FleetDynamics, FleetState

HOVER = 0.4


def mixed_table():
    personas = (ArduCopter, Px4)
    return fleet_params(param_specs(HOVER), HOVER, personas), personas


def test_registry_knows_both_personas_and_refuses_any_other_name():
    assert persona_named("ardupilot") is ArduCopter and persona_named("px4") is Px4
    assert parse_autopilots("px4", 3) == ("px4",) * 3
    assert parse_autopilots("ardupilot, PX4", 2) == ("ardupilot", "px4")
    with pytest.raises(ValueError, match="'inav' is not one of ardupilot, px4"):
        parse_autopilots("ardupilot,inav", 2)
    with pytest.raises(ValueError, match="lists 2 autopilots for 3 vehicles"):
        parse_autopilots("ardupilot,px4", 3)
    assert fleet_personas((), 2) == (ArduCopter, ArduCopter)  # the default persona, named explicitly


def test_each_vehicle_lists_its_personas_names_and_the_simulators():
    table, _ = mixed_table()
    names = [{table.specs[j].name for j in table.listing(i)} for i in range(2)]
    assert {"WPNAV_SPEED", "GUID_TIMEOUT", "SIM_WIND_SPD"} <= names[0]
    assert not any(name.startswith(("MPC_", "COM_")) for name in names[0])
    assert {"MPC_XY_CRUISE", "COM_OF_LOSS_T", "SIM_WIND_SPD"} <= names[1]
    assert not names[1] & {"WPNAV_SPEED", "GUID_TIMEOUT", "LAND_SPEED"}


def test_px4_parameters_drive_the_shared_columns_in_arducopter_units():
    table, personas = mixed_table()
    # MPC_XY_CRUISE default 5 m/s -> WPNAV_SPEED 500 cm/s; MPC_TILTMAX_AIR 45 deg -> ANGLE_MAX 4500 cdeg
    assert table.value(1, "WPNAV_SPEED") == 500.0 and table.value(1, "ANGLE_MAX") == 4500.0
    assert table.value(1, "GUID_TIMEOUT") == 1e9  # PX4 has none: offboard loss is its own rule
    assert table.value(0, "WPNAV_SPEED") == next(
        s.default for s in param_specs(HOVER) if s.name == "WPNAV_SPEED"
    )
    table.set(1, "MPC_XY_CRUISE", 8.0)
    personas[1].parameter_set(table, 1, "MPC_XY_CRUISE")
    assert table.value(1, "WPNAV_SPEED") == 800.0
    assert table.value(0, "WPNAV_SPEED") != 800.0  # the other vehicle's column is its own


def test_interpolated_land_speed_by_hand():
    # PX4's defaults: fast above 10 m, slow below 5 m, crawl below 1 m (range finder up to 100 m), cap 1.5
    def speed(height, range_max=100.0, cap=1.5):
        return interpolated_land_speed(height, 10.0, 5.0, 1.0, 0.7, 0.3, 1.5, cap, range_max)

    assert speed(20.0) == 1.5
    assert speed(10.0) == pytest.approx(1.5)
    assert speed(7.5) == pytest.approx(1.1)  # half way between 0.7 at 5 m and 1.5 at 10 m
    assert speed(5.0) == 0.7 and speed(3.0) == 0.7
    assert speed(1.0) == 0.3 and speed(0.2) == 0.3
    assert speed(0.5, range_max=0.2) == 0.7  # beyond the range finder's reach no crawl
    assert speed(20.0, cap=1.0) == 1.0


def test_the_autopilot_hands_each_vehicles_descent_to_the_loop_as_data():
    table, personas = mixed_table()
    dyn = FleetDynamics(2, state=FleetState.at_rest(np.zeros((2, 3)), np.zeros(2)))
    zeros = np.zeros((2, 3))
    ap = Autopilot(dyn, table, zeros, zeros, np.zeros(2, dtype=bool), zeros, 0.0, personas)
    assert isinstance(ap.persona(0), ArduCopter) and isinstance(ap.persona(1), Px4)
    assert (
        ap.persona(1).heartbeat(1)[0] != ap.persona(0).heartbeat(0)[0]
    )  # MAV_AUTOPILOT_PX4 vs ARDUPILOTMEGA
    descent = ap._descent
    assert descent.profile.tolist() == [DESCENT_TWO_SPEED, DESCENT_INTERPOLATED]
    read = [table.specs[j].name for j in descent.columns[1]]
    assert read == list(Px4.descent_params) and read[0] == "MPC_LAND_ALT1" and read[-1] == "MPC_JERK_AUTO"
