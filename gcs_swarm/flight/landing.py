"""Landing (LAND every reachable vehicle, wait until they disarm) and the operator's position hold."""

from __future__ import annotations

import numpy as np

from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet

HOLD_LATCH_SPEED = 0.5  # m/s: in hold, a vehicle's position is latched once it has braked below this


def command_landing(fleet: Fleet, events: list[str], ours: np.ndarray) -> None:
    """LAND every reachable vehicle of the (N,) bool mask `ours` (vehicles taken over by an operator are
    left to them); a refusal goes to `events`."""
    rows = [int(i) for i in np.flatnonzero(ours & fleet.alive)]
    if not rows:
        return
    try:
        fleet.land_all(rows)
    except LinkError as exc:
        events.append(f"landing: {exc}")


def land_and_wait(fleet: Fleet, timeout_s: float, events: list[str], ours: np.ndarray) -> None:
    """LAND every reachable vehicle of the (N,) bool mask `ours` and wait up to timeout_s until they disarm
    (auto-disarm after touchdown); a timeout goes to `events`."""
    command_landing(fleet, events, ours)
    try:
        fleet.wait_until(
            lambda: landed(fleet, ours),
            timeout_s=timeout_s,
            what="every vehicle disarmed after landing",
        )
    except LinkError as exc:
        events.append(str(exc))


def landed(fleet: Fleet, ours: np.ndarray) -> bool:
    """No live vehicle of the (N,) bool mask `ours` is armed any more."""
    return not bool((fleet.armed & fleet.alive & ours).any())


class PositionHold:
    """Every vehicle brakes (target: where it is) until slower than HOLD_LATCH_SPEED, then holds that point.

    Re-targeting the current position on every tick would let the autopilot's velocity integrator, wound up
    while braking, drift the vehicle back; a fixed point is held by its position loop."""

    def __init__(self, n: int) -> None:
        self.points = np.full((n, 3), np.nan)  # (N, 3) ENU m, latched in hold; NaN: still braking

    def clear(self) -> None:
        """Forget the latched points (a new hold)."""
        self.points[:] = np.nan

    def tick(self, fleet: Fleet, flown: np.ndarray) -> None:
        """One hold tick: a GUIDED position target to every vehicle of the (N,) bool mask `flown` (live, not
        taken over) with a finite position."""
        pos, vel, yaw = fleet.pos, fleet.vel, fleet.att[:, 2]
        for i in np.flatnonzero(flown & np.isfinite(pos).all(axis=1)):
            latched = bool(np.isfinite(self.points[i]).all())
            if not latched and np.linalg.norm(vel[i]) < HOLD_LATCH_SPEED:
                self.points[i], latched = pos[i], True
            target = self.points[i] if latched else pos[i]
            fleet.vehicle(int(i)).setpoints.send_position_target(
                target, yaw=float(yaw[i]) if np.isfinite(yaw[i]) else None
            )
