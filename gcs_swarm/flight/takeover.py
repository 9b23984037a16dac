"""Operator takeover: a vehicle that leaves the flight mode the ground station last commanded for it.

Someone else switched it (QGroundControl, MAVProxy, an RC mode switch) or its own failsafe did (GCS or
fence failsafe: RTL, LAND, BRAKE). The ground station then stops commanding it at once, never switches it
back by itself (no mode fight), and flies the others around it as a moving obstacle; the console's
`rejoin NAME` hands it back (docs/console.md, docs/reliability.md "Operator takeover").

The rule (`newly_taken`): a live vehicle whose HEARTBEAT shows a mode other than the one the ground station
last commanded for it, or than the one that command passes through on its own (PX4's NAV_TAKEOFF: TAKEOFF,
then back in LOITER), is taken over. The ground station's own mode changes (each autopilot's launch mode
and formation mode (GUIDED; LOITER, OFFBOARD), its hold mode for vehicles found drifting, LAND at the end,
the console's `mode`/`land`/`rtl`) are recorded with `TakeoverWatch.commanded` *before* they are sent, so
they never count as a takeover; a vehicle whose commanded mode is unknown (never commanded) is never taken.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.flight.result import FlightResult
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.link.autopilots import ModeChoice, formation_mode
from gcs_swarm.link.fleet import Fleet

UNKNOWN_MODE = -1  # custom_mode before a HEARTBEAT, or a vehicle the ground station never commanded
_NO_CENTRES = np.zeros((0, 3))  # `place` without a vehicle taken over (read-only, shared)
_NO_RADII = np.zeros(0)
_NO_CENTRES.flags.writeable = _NO_RADII.flags.writeable = False


def newly_taken(
    mode: NDArray[np.int64],
    commanded: NDArray[np.int64],
    alive: NDArray[np.bool_],
    taken: NDArray[np.bool_],
    passing: NDArray[np.int64] | None = None,
) -> NDArray[np.bool_]:
    """(N,) bool: vehicles taken over now. `mode` (N,) each vehicle's custom_mode from its latest HEARTBEAT
    (UNKNOWN_MODE before one), `commanded` (N,) the custom_mode the ground station last commanded
    (UNKNOWN_MODE: never), `alive` (N,) heard recently, `taken` (N,) already taken over, `passing` (N,) a
    mode the last command passes through on its own (UNKNOWN_MODE: none; None: none for any vehicle)."""
    known = (mode != UNKNOWN_MODE) & (commanded != UNKNOWN_MODE)
    ours = mode == commanded
    if passing is not None:
        ours |= mode == passing
    return alive & known & ~ours & ~taken


@dataclass(frozen=True)
class Takeover:
    """One vehicle leaving the ground station's control: vehicle time `t_s` (s), its `vehicle` name, the
    `mode` it went to, and `by`: "someone else" (another ground station, an RC switch, its own failsafe) or
    "console" (the operator's own `mode`/`land`/`rtl` through our console)."""

    t_s: float
    vehicle: str
    mode: str
    by: str

    def as_json(self) -> dict[str, object]:
        return {"t_s": round(self.t_s, 3), "vehicle": self.vehicle, "mode": self.mode, "by": self.by}


class TakeoverWatch:
    """Which mode the ground station last commanded for each vehicle, and which vehicles are taken over.

    `result.events` and `progress` receive one line per takeover and per rejoin; `result.taken_over` keeps
    every takeover, `result.left_to_operator` the vehicles taken over now (both in flight.json)."""

    def __init__(self, fleet: Fleet, result: FlightResult, progress: Callable[[str], None]) -> None:
        n = len(fleet.names)
        self.fleet = fleet
        self.result = result
        self.events = result.events
        self.progress = progress
        self.commanded_mode = np.full(n, UNKNOWN_MODE, dtype=np.int64)  # (N,) custom_mode we last commanded
        self.passing_mode = np.full(n, UNKNOWN_MODE, dtype=np.int64)  # (N,) one it passes through on its own
        self.taken = np.zeros(n, dtype=bool)  # (N,) taken over: not commanded by the ground station
        self.mode_seen = np.full(n, UNKNOWN_MODE, dtype=np.int64)  # (N,) of taken vehicles, last reported

    def commanded(
        self, mode: ModeChoice, rows: Iterable[int] | None = None, passing: ModeChoice | None = None
    ) -> None:
        """The ground station is about to command `mode` (named in each vehicle's dialect, or a ModeChoice
        function of it) to `rows` (default every vehicle): from now on that mode is its own, and so is
        `passing`, a mode the vehicle switches to by itself on the way (PX4's TAKEOFF after NAV_TAKEOFF)."""
        for i in range(len(self.taken)) if rows is None else rows:
            self.commanded_mode[i] = self.fleet.mode_number(int(i), mode)
            self.passing_mode[i] = (
                UNKNOWN_MODE if passing is None else self.fleet.mode_number(int(i), passing)
            )

    def commanded_landing(self, rows: NDArray[np.bool_]) -> None:
        """The ground station is about to land the vehicles of the (N,) bool mask `rows` (each dialect's
        landing mode)."""
        for i in np.flatnonzero(rows):
            dialect = self.fleet.vehicle(int(i)).channel.autopilot
            self.commanded_mode[i] = dialect.mode_number(dialect.land_mode)
            self.passing_mode[i] = UNKNOWN_MODE

    @property
    def flown(self) -> NDArray[np.bool_]:
        """(N,) vehicles the ground station may command: alive and not taken over."""
        return self.fleet.alive & ~self.taken

    def detect(self, t: float) -> list[int]:
        """Rows taken over since the last call (vehicle time t s): marked taken, each told to `events` and
        `progress`. A taken vehicle switched on to yet another mode is told too (still taken)."""
        fleet = self.fleet
        mode = fleet.mode
        if not self.taken.any() and bool((mode == self.commanded_mode).all()):
            return []  # every vehicle in the mode we commanded: nobody taken, nobody moved on
        taken_now = newly_taken(mode, self.commanded_mode, fleet.alive, self.taken, self.passing_mode)
        rows = [int(i) for i in np.flatnonzero(taken_now)]
        for i in rows:
            self._take(i, t, fleet.vehicle(i).mode_name(), "someone else")
        moved = self.taken & fleet.alive & (mode != self.mode_seen) & (mode != UNKNOWN_MODE)
        for k in np.flatnonzero(moved):
            self.mode_seen[k] = mode[k]
            text = f"{fleet.names[k]} (taken over) now in {fleet.vehicle(int(k)).mode_name()}"
            self.events.append(f"t={t:.2f} s {text}")
            self.progress(f"! {text}")
        return rows

    def release(self, i: int, mode: str, t: float) -> None:
        """The operator put vehicle i in `mode` through our console while the mission flies: ours to record
        (no takeover by someone else), but no longer flown by the formation unless `mode` is its formation
        mode (GUIDED, OFFBOARD)."""
        self.commanded(mode, [i])
        if self.commanded_mode[i] != self.fleet.mode_number(i, formation_mode) and not self.taken[i]:
            self._take(i, t, mode.strip().upper(), "console")
            self.mode_seen[i] = self.commanded_mode[i]  # the mode the console asked for is not news

    def rejoined(self, i: int, t: float) -> None:
        """Vehicle i is back in its formation mode on the operator's request (`rejoin`): flown again."""
        self.taken[i] = False
        self.mode_seen[i] = UNKNOWN_MODE
        self.result.left_to_operator = self.left_to_operator()
        text = (
            f"{self.fleet.names[i]} rejoined: back in {self.fleet.vehicle(i).mode_name()}, flying to its slot"
        )
        self.events.append(f"t={t:.2f} s {text}")
        self.progress(f"! {text}")

    def place(self, controller: FleetController, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Taken vehicles still heard, as moving obstacles at their measured state: (K, 3) ENU m centres and
        (K,) m radii (`radius` each); each also repels the others from where it is now (told to
        `controller`, as a lost vehicle's predicted position is)."""
        if not self.taken.any():
            return _NO_CENTRES, _NO_RADII
        fleet = self.fleet
        pos, vel = fleet.pos, fleet.vel
        rows = np.flatnonzero(self.taken & fleet.alive & np.isfinite(pos).all(axis=1))
        for i in rows:
            controller.place_uncommanded(int(i), pos[i], np.nan_to_num(vel[i]))
        return pos[rows].reshape(-1, 3), np.full(len(rows), radius)

    def left_to_operator(self) -> list[str]:
        """Names of the vehicles still taken over (the ground station leaves them to their operator)."""
        return [self.fleet.names[i] for i in np.flatnonzero(self.taken)]

    def _take(self, i: int, t: float, mode: str, by: str) -> None:
        self.taken[i] = True
        self.mode_seen[i] = self.fleet.mode[i]
        self.result.taken_over.append(Takeover(t, self.fleet.names[i], mode, by).as_json())
        self.result.left_to_operator = self.left_to_operator()
        name = self.fleet.names[i]
        if by == "console":
            text = f"{name} handed to the operator (mode {mode} from the console): no longer flown"
        else:
            text = f"{name} taken over: now in {mode}, not commanded any more (rejoin {name} hands it back)"
        self.events.append(f"t={t:.2f} s {text}")
        self.progress(f"! {text}")
