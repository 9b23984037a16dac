"""Vehicles found armed or flying when the run starts (a ground station that crashed left them in the air):
stop the drifting ones at once, describe what was found, and take them back into their formation mode
(`gcs-swarm run --airborne`, docs/reliability.md)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.flight.preflight import PreflightError
from gcs_swarm.flight.takeover import TakeoverWatch
from gcs_swarm.link.autopilots import formation_mode, hold_mode
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet

AIRBORNE_CHOICES = ("finish", "land")  # fly the mission on from where they are, or land them there


def stop_unflown(
    fleet: Fleet, events: list[str], progress: Callable[[str], None], modes: TakeoverWatch
) -> None:
    """Vehicles found armed in their formation mode (GUIDED, OFFBOARD) and not known to be on the ground fly
    targets nobody sends any more (a ground station died and its GCS failsafe has not fired yet, and our
    heartbeats now keep it from firing): ArduCopter levels them and lets them drift on. Put them in their
    hold mode (BRAKE, LOITER) at once, before the minutes of preflight, and say so (recorded in `modes` as
    the ground station's own); what happens next is the run's `airborne` choice."""
    guided = fleet.in_mode(formation_mode)
    on_ground = fleet.landed_state == mavlink2.MAV_LANDED_STATE_ON_GROUND
    drifting = fleet.armed & fleet.alive & guided & ~on_ground
    if not drifting.any():
        return
    names = [fleet.names[i] for i in np.flatnonzero(drifting)]
    progress(f"{', '.join(names)} armed in their formation mode with nobody flying them: stopping them")
    events.append(f"found armed in their formation mode, stopped in their hold mode: {', '.join(names)}")
    modes.commanded(hold_mode, [int(i) for i in np.flatnonzero(drifting)])
    try:
        fleet.set_mode_all(hold_mode, names)
    except LinkError as exc:
        raise PreflightError(f"cannot stop the drifting vehicles: {exc}") from exc


def flying(fleet: Fleet) -> np.ndarray:
    """(N,) bool: vehicles that are armed and not on the ground (EXTENDED_SYS_STATE), e.g. holding where a
    crashed ground station left them."""
    on_ground = np.isin(fleet.landed_state, (mavlink2.MAV_LANDED_STATE_ON_GROUND,))
    return fleet.armed & fleet.alive & ~on_ground


def describe_flying(fleet: Fleet, flying: np.ndarray, home: np.ndarray) -> str:
    """One clause per flying vehicle of the (N,) mask: its name, mode, height (above `home` (N, 3) ENU m
    where known) and speed."""
    parts = []
    for i in np.flatnonzero(flying):
        mode = fleet.vehicle(int(i)).mode_name()
        height = (
            float(fleet.pos[i, 2]) - float(home[i, 2]) if np.isfinite(home[i, 2]) else float(fleet.pos[i, 2])
        )
        parts.append(
            f"{fleet.names[i]} {mode} at {height:.1f} m, {float(np.linalg.norm(fleet.vel[i])):.1f} m/s"
        )
    return "; ".join(parts)


def check_airborne_choice(fleet: Fleet, flying: np.ndarray, airborne: str | None, found: str) -> None:
    """PreflightError unless `airborne` (one of AIRBORNE_CHOICES, None: not chosen) can handle the vehicles
    found flying ((N,) mask, described by `found`): "finish" needs every vehicle in the air."""
    if not flying.all() and airborne == "finish":
        on_ground = ", ".join(n for n, f in zip(fleet.names, flying, strict=True) if not f)
        raise PreflightError(f"some vehicles fly and some are on the ground ({on_ground}): land them first")
    if airborne not in AIRBORNE_CHOICES:
        raise PreflightError(
            f"vehicles already flying: {found}. Say --airborne finish to fly the mission on from where "
            "they are, or --airborne land to land them where they are"
        )


def take_back(fleet: Fleet, modes: TakeoverWatch) -> None:
    """Every vehicle into its formation mode (recorded in `modes` as the ground station's own), so that the
    formation flight commands them from where they are."""
    modes.commanded(formation_mode)
    try:
        fleet.take_control_all()
    except LinkError as exc:
        raise PreflightError(f"cannot take the vehicles back: {exc}") from exc
