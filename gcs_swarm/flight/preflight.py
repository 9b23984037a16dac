"""Preflight: wait until every vehicle is ready, set the parameters the flight needs (each autopilot's own:
attitude-target thrust, GCS failsafe, command timeout), install the geofence, and read back what the guidance
must know of each vehicle (hover thrust, angle boost, how a lost vehicle flies home)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gcs_swarm.flight.geofence import install_fence
from gcs_swarm.link.autopilots import AutopilotDialect, launch_mode
from gcs_swarm.link.autopilots.failsafe import FailsafeSettings
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.flight_params import FlightParams
from gcs_swarm.mission import Mission


class PreflightError(Exception):
    """The fleet cannot be launched (one sentence naming the vehicle and why); nothing has flown."""


@dataclass(frozen=True)
class VehicleSetup:
    """What preflight read from each vehicle, one row per vehicle (N)."""

    hover: np.ndarray  # (N,) normalised thrust that holds a hover (MOT_THST_HOVER, MPC_THR_HOVER)
    angle_boost: (
        np.ndarray
    )  # (N,) bool, the autopilot adds 1/cos(tilt) to thrust (ArduCopter ATC_ANGLE_BOOST)
    # (N, 3) how a vehicle that lost its ground station flies: failsafe timeout s, Return speed m/s, Return
    # altitude m (each dialect's `failsafe_params`, converted to SI)
    failsafe_params: np.ndarray

    @classmethod
    def assumed(cls, n: int) -> VehicleSetup:
        """What the run assumes of n vehicles before preflight has read them."""
        return cls(
            hover=np.full(n, 0.5),
            angle_boost=np.zeros(n, dtype=bool),
            failsafe_params=np.tile([5.0, 10.0, 15.0], (n, 1)),
        )


def by_dialect(fleet: Fleet) -> dict[AutopilotDialect, list[int]]:
    """The live vehicles' rows grouped by autopilot dialect (a mixed fleet has several groups)."""
    groups: dict[AutopilotDialect, list[int]] = defaultdict(list)
    for i, dialect in enumerate(fleet.dialects):
        if fleet.alive[i]:
            groups[dialect].append(i)
    return dict(groups)


def into_launch_mode(fleet: Fleet, events: list[str]) -> None:
    """Disarmed vehicles whose pre-arm checks judge the selected mode (PX4) and that sit in another mode than
    their launch mode (PX4 after a previous flight: OFFBOARD, whose checks never pass without setpoints) are
    put in their launch mode first, so that their checks can pass."""
    rows = [
        i
        for i, dialect in enumerate(fleet.dialects)
        if dialect.arm_checks_follow_mode
        and fleet.alive[i]
        and not fleet.armed[i]
        and fleet.mode[i] >= 0
        and fleet.mode[i] != fleet.mode_number(i, launch_mode)
    ]
    if rows:
        events.append(f"preflight: {', '.join(fleet.names[i] for i in rows)} put in their launch mode first")
        fleet.set_mode_all(launch_mode, rows)


def preflight_fleet(
    fleet: Fleet,
    mission: Mission,
    flight_params: FlightParams,
    events: list[str],
    progress: Callable[[str], None],
) -> VehicleSetup:
    """Wait for position estimates and pre-arm health; set and verify each autopilot's flight parameters
    (through `flight_params`, which restores them at the end); install the fence (notes to `events` and
    `progress`); read hover thrust, angle boost and failsafe parameters. PreflightError (one sentence) if the
    fleet cannot fly."""
    run, safety = mission.run, mission.safety
    n = len(fleet.names)
    setup = VehicleSetup.assumed(n)
    hover, boost, lost_flight = setup.hover.copy(), setup.angle_boost.copy(), setup.failsafe_params.copy()
    try:
        into_launch_mode(fleet, events)
        fleet.wait_ready(timeout_s=run.preflight_timeout_s, progress=progress)
        groups = by_dialect(fleet)
        dead_gcs = safety.dead_gcs
        failsafe = FailsafeSettings(
            action=safety.gcs_failsafe,
            gcs_loss_s=float(dead_gcs.failsafe_timeout_s or 0.0),
            guided_timeout_s=dead_gcs.guided_timeout_s,
            offboard_loss_s=dead_gcs.offboard_loss_timeout_s,
        )
        for dialect, rows in groups.items():
            for name, value in dialect.flight_params(failsafe):
                flight_params.set_all(name, value, rows)
        # the autopilots' own geofence around the obstacles (flight.geofence, docs/reliability.md)
        install_fence(fleet, flight_params, mission, events, progress)
        for dialect, rows in groups.items():
            hover[rows] = fleet.param_get_all(dialect.hover_param, rows)
            if dialect.angle_boost_param is not None:
                read = fleet.param_get_all(dialect.angle_boost_param, rows)
                boost[rows] = [dialect.is_angle_boost_on(v) for v in read]
            for k, (name, to_si) in enumerate(dialect.failsafe_params):
                lost_flight[rows, k] = fleet.param_get_all(name, rows) * to_si
    except LinkError as exc:
        raise PreflightError(f"preflight failed: {exc}") from exc
    bad = [
        f"{fleet.dialects[i].hover_param} of {name}"
        for i, (name, h) in enumerate(zip(fleet.names, hover, strict=True))
        if not 0.05 < h < 0.95
    ]
    if bad:
        raise PreflightError(f"{', '.join(bad)} outside 0.05..0.95")
    return VehicleSetup(hover=hover, angle_boost=boost, failsafe_params=lost_flight)
