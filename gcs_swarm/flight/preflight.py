"""Preflight: wait until every vehicle is ready, set the parameters the flight needs (attitude-target thrust,
GCS failsafe, guided timeout), install the geofence, and read back what the guidance must know of each
vehicle (hover thrust, angle boost, how a lost vehicle flies home)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gcs_swarm.flight.geofence import install_fence
from gcs_swarm.link.autopilots import ardupilot
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.flight_params import FlightParams
from gcs_swarm.mission import Mission

# ArduCopter FS_GCS_ENABLE values (events.cpp failsafe_gcs_on_event): 1 RTL, 5 Land, 7 Brake or Land
FS_GCS_ENABLE = {"off": 0, "rtl": 1, "land": 5, "brake": 7}
GUID_OPTIONS_THRUST = 8  # bit 3: SET_ATTITUDE_TARGET thrust is normalised collective thrust (not climb rate)
FAILSAFE_PARAMS = ("FS_GCS_TIMEOUT", "WPNAV_SPEED", "RTL_ALT")  # s, cm/s, cm: how a lost vehicle flies home


class PreflightError(Exception):
    """The fleet cannot be launched (one sentence naming the vehicle and why); nothing has flown."""


@dataclass(frozen=True)
class VehicleSetup:
    """What preflight read from each vehicle, one row per vehicle (N)."""

    hover: np.ndarray  # (N,) MOT_THST_HOVER, normalised thrust that holds a hover
    angle_boost: np.ndarray  # (N,) bool, ATC_ANGLE_BOOST on (the autopilot adds 1/cos(tilt) to thrust)
    failsafe_params: np.ndarray  # (N, 3) FAILSAFE_PARAMS as read: s, cm/s, cm

    @classmethod
    def assumed(cls, n: int) -> VehicleSetup:
        """What the run assumes of n vehicles before preflight has read them."""
        return cls(
            hover=np.full(n, 0.5),
            angle_boost=np.zeros(n, dtype=bool),
            failsafe_params=np.tile([5.0, 1000.0, 1500.0], (n, 1)),
        )


def preflight_fleet(
    fleet: Fleet,
    mission: Mission,
    flight_params: FlightParams,
    events: list[str],
    progress: Callable[[str], None],
) -> VehicleSetup:
    """Wait for position estimates and pre-arm health; set and verify the flight's parameters (through
    `flight_params`, which restores them at the end); install the fence (notes to `events` and `progress`);
    read hover thrust, angle boost and failsafe parameters. PreflightError (one sentence) if the fleet cannot
    fly."""
    run = mission.run
    try:
        fleet.wait_ready(timeout_s=run.preflight_timeout_s, progress=progress)
        safety = mission.safety
        flight_params.set_all("GUID_OPTIONS", GUID_OPTIONS_THRUST)
        flight_params.set_all("FS_GCS_ENABLE", FS_GCS_ENABLE[safety.gcs_failsafe])
        flight_params.set_all("FS_GCS_TIMEOUT", float(safety.dead_gcs.failsafe_timeout_s or 0.0))
        flight_params.set_all("GUID_TIMEOUT", safety.dead_gcs.guided_timeout_s)
        # the autopilots' own geofence around the obstacles (flight.geofence, docs/reliability.md)
        install_fence(fleet, flight_params, mission, events, progress)
        hover = fleet.param_get_all("MOT_THST_HOVER")
        angle_boost = np.array([ardupilot.is_boost_on(v) for v in fleet.param_get_all("ATC_ANGLE_BOOST")])
        failsafe = np.column_stack([fleet.param_get_all(name) for name in FAILSAFE_PARAMS])
    except LinkError as exc:
        raise PreflightError(f"preflight failed: {exc}") from exc
    bad = [name for name, h in zip(fleet.names, hover, strict=True) if not 0.05 < h < 0.95]
    if bad:
        raise PreflightError(f"MOT_THST_HOVER of {', '.join(bad)} is outside 0.05..0.95")
    return VehicleSetup(hover=hover, angle_boost=angle_boost, failsafe_params=failsafe)
