"""What the console shows, as immutable values the flight thread publishes and the UI thread renders.

The figures are derived from the fleet's telemetry arrays and the runner's last guidance command; nothing
here decides anything about the flight. Units: metres, m/s, seconds (vehicle time unless said otherwise).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.flight.phase import Phase

MAV_STATE_CRITICAL = 5  # HEARTBEAT system_status in a failsafe (ArduCopter)
MAV_STATE_EMERGENCY = 6  # ... crashed / lost control
LANDED_IN_AIR = (2, 3, 4)  # MAV_LANDED_STATE in air, taking off, landing
FLYING_PHASES = frozenset({Phase.LAUNCH, Phase.FORMATION, Phase.HOLD, Phase.LAND})
"""Runner phases in which `runner.step()` drives the vehicles."""
STALE_AFTER_S = 1.0  # wall seconds without any packet before a vehicle's telemetry counts as stale


@dataclass(frozen=True)
class VehicleRow:
    """One vehicle as the operator sees it. NaN / None where not known yet."""

    name: str
    sysid: int | None
    alive: bool
    age_s: float  # wall s since its last packet
    loss: float | None  # fraction of its position messages missing lately (None: rate not known)
    mode: str
    armed: bool
    airborne: bool
    position: tuple[float, float, float]  # ENU m
    speed: float  # m/s
    slot_error: float | None  # m to its formation slot; None for the leader and outside formation flight
    obstacle: float | None  # m from the nearest obstacle surface; None without obstacles
    neighbour: float | None  # m to the nearest other vehicle; None when alone
    warnings: tuple[str, ...]
    rtt_ms: float = math.nan  # wall ms of the latest TIMESYNC round trip
    taken: bool = False  # taken over by another controller: left to its operator (never landed at quit)
    # MAVLink bytes/s to (up) and from (down) the vehicle over the latest second of vehicle time, and the
    # budget of its link in bytes/s, up and down together (None: none given) (link.link_use)
    up_B_s: float = math.nan
    down_B_s: float = math.nan
    budget_B_s: float | None = None

    @property
    def over_budget(self) -> bool:
        """The latest second's up + down went over the link budget."""
        return self.budget_B_s is not None and self.up_B_s + self.down_B_s > self.budget_B_s

    @property
    def altitude(self) -> float:
        return self.position[2]


@dataclass(frozen=True)
class MissionLine:
    """The mission at a glance."""

    phase: Phase
    started: bool
    vehicle_time: float  # s since the vehicles booted
    leader_goal_distance: float  # m from the leader to the final goal
    goal: tuple[float, float, float]  # ENU m
    formation_rms: float  # m, followers' RMS distance to their slots (NaN before formation flight)
    min_separation: float  # m, smallest distance between two vehicles since connecting
    busy: str  # the blocking command the flight thread is running, or ""
    busy_s: float = 0.0  # wall s that command has been running


@dataclass(frozen=True)
class Snapshot:
    """Everything the UI renders, published after each flight-thread tick."""

    state: str  # "connecting" | "ready" | "failed" | "stopped"
    rows: tuple[VehicleRow, ...]
    mission: MissionLine
    phases: tuple[str, ...]  # every phase the runner entered, in order
    params: tuple[str, ...]  # parameter names the vehicles have reported
    error: str = ""  # why the session failed

    @property
    def airborne(self) -> tuple[str, ...]:
        """Names of the vehicles that are (or were, when last heard) flying."""
        return tuple(r.name for r in self.rows if r.airborne)

    @property
    def armed(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.rows if r.armed)

    @property
    def settled(self) -> bool:
        """The mission is not flying and no reachable vehicle is armed (safe to quit); vehicles taken over
        are their operator's, not waited for."""
        return self.mission.phase not in FLYING_PHASES and not any(
            r.armed and r.alive and not r.taken for r in self.rows
        )


def empty_snapshot(names: list[str]) -> Snapshot:
    """What there is to show before the vehicles have connected."""
    nan3 = (math.nan, math.nan, math.nan)
    rows = tuple(
        VehicleRow(
            n, None, False, math.inf, None, "UNKNOWN", False, False, nan3, math.nan, None, None, None, ()
        )
        for n in names
    )
    mission = MissionLine(Phase.CONNECT, False, 0.0, math.nan, nan3, math.nan, math.nan, "")
    return Snapshot("connecting", rows, mission, (Phase.CONNECT,), ())


def nearest_neighbour(pos: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N,) distance m from each vehicle to the nearest other one with a known position (NaN if none)."""
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    np.fill_diagonal(d, np.nan)
    d[~np.isfinite(d)] = np.inf
    out = d.min(axis=1) if len(pos) > 1 else np.full(len(pos), np.inf)
    return np.where(np.isfinite(out), out, np.nan)


def obstacle_clearance(
    pos: NDArray[np.float64], centres: NDArray[np.float64], radii: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(N,) m from each position (N, 3) to the nearest sphere surface, centres (K, 3), radii (K,)."""
    if len(radii) == 0:
        return np.full(len(pos), np.nan)
    return (np.linalg.norm(pos[:, None, :] - centres[None, :, :], axis=-1) - radii[None, :]).min(axis=1)


def vehicle_warnings(
    alive: bool, age_s: float, system_status: int, crashed: bool, emergency: bool, taken: bool = False
) -> tuple[str, ...]:
    """The warning words of one vehicle, most severe first: LOST or STALE, TAKEN (taken over by another
    controller: not flown by the formation until `rejoin`), CRASHED, FAILSAFE, EMERGENCY."""
    words = []
    if not alive:
        words.append("LOST")
    elif age_s > STALE_AFTER_S:
        words.append("STALE")
    if taken:
        words.append("TAKEN")
    if crashed or system_status == MAV_STATE_EMERGENCY:
        words.append("CRASHED")
    if system_status == MAV_STATE_CRITICAL:
        words.append("FAILSAFE")
    if emergency:
        words.append("EMERGENCY")
    return tuple(words)


def is_airborne(armed: bool, landed_state: int, altitude: float) -> bool:
    """Armed and in the air by EXTENDED_SYS_STATE, or above 0.5 m when the vehicle does not report it."""
    if not armed:
        return False
    if landed_state in LANDED_IN_AIR:
        return True
    return landed_state == 0 and bool(altitude > 0.5)


class StreamLoss:
    """Fraction of position messages (GLOBAL_POSITION_INT) missing over the last `window_s` of each vehicle's
    own time, from their time_boot_ms stamps and the requested interval."""

    def __init__(self, n: int, window_s: float = 3.0) -> None:
        self.window_ms = window_s * 1000.0
        self.interval_ms: list[float | None] = [None] * n
        self._samples: list[deque[tuple[int, int]]] = [deque() for _ in range(n)]

    def set_interval(self, index: int, interval_ms: float | None) -> None:
        self.interval_ms[index] = interval_ms
        self._samples[index].clear()

    def update(self, position_ms: NDArray[np.int64], position_count: NDArray[np.int64]) -> None:
        """Record each vehicle's latest position stamp (ms) and message count."""
        for i, samples in enumerate(self._samples):
            t, c = int(position_ms[i]), int(position_count[i])
            if t < 0 or (samples and samples[-1][0] == t):
                continue
            if samples and t < samples[-1][0]:  # rebooted
                samples.clear()
            samples.append((t, c))
            while t - samples[0][0] > self.window_ms:
                samples.popleft()

    def fraction(self, index: int) -> float | None:
        """Missing fraction 0..1, or None without a known interval or half a second of samples."""
        interval, samples = self.interval_ms[index], self._samples[index]
        if interval is None or len(samples) < 2:
            return None
        (t0, c0), (t1, c1) = samples[0], samples[-1]
        if t1 - t0 < 500:
            return None
        expected = (t1 - t0) / interval
        return min(max(1.0 - (c1 - c0) / expected, 0.0), 1.0)
