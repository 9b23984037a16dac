"""Launch: each autopilot's launch mode (ArduCopter GUIDED, PX4 LOITER), arm and take off to the formation
altitude (each vehicle plus its slot's dz)."""

from __future__ import annotations

import numpy as np

from gcs_swarm.flight.preflight import PreflightError
from gcs_swarm.link.autopilots import launch_mode
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.mission import Mission
from gcs_swarm.mission.geometry import mission_offsets


def takeoff_altitudes(mission: Mission) -> np.ndarray:
    """(N,) m: the formation altitude plus each vehicle's slot dz."""
    return mission.formation.altitude + mission_offsets(mission)[:, 2]


def launched(fleet: Fleet, mission: Mission, ours: np.ndarray) -> bool:
    """Every vehicle of the (N,) bool mask `ours` (those not taken over by an operator) is within 0.5 m of
    its takeoff altitude (always, for an airborne start)."""
    if mission.run.airborne_start:
        return True
    return bool((fleet.pos[:, 2] >= takeoff_altitudes(mission) - 0.5)[ours].all())


def home_positions(fleet: Fleet, mission: Mission) -> np.ndarray:
    """(N, 3) ENU m, the failsafe's home of each vehicle: where it stands before takeoff (an airborne start's
    home is the ground below it)."""
    home = fleet.pos
    if mission.run.airborne_start:
        home[:, 2] = 0.0
    return home


def command_launch(fleet: Fleet, mission: Mission) -> None:
    """Launch mode, arm and take off (each acknowledged); for an airborne start only the formation mode
    (Fleet.take_control_all). The climb itself is not awaited. PreflightError if a vehicle refuses."""
    try:
        if mission.run.airborne_start:
            fleet.take_control_all()
            return
        fleet.set_mode_all(launch_mode)
        fleet.arm_all()
        fleet.takeoff_all(takeoff_altitudes(mission))
    except LinkError as exc:
        raise PreflightError(f"launch refused: {exc}") from exc
