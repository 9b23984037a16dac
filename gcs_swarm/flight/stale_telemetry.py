"""Stale telemetry in formation flight: the tick's verdict (predict, degrade or hold, from
gcs_swarm.guidance.degradation), with an event and a progress line on every change and the flight's
figures (degraded time, holds, oldest telemetry) in the FlightResult."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from gcs_swarm.flight.result import FlightResult
from gcs_swarm.guidance.degradation import StaleTelemetryMonitor, TelemetryAssessment
from gcs_swarm.guidance.params import TelemetryParams
from gcs_swarm.link.fleet import Fleet


def telemetry_age(fleet: Fleet) -> np.ndarray:
    """(N,) s: each vehicle's newest time_boot_ms minus that of its latest position (inf before one)."""
    st = fleet.state
    age = (st.time_ms - st.position_ms).astype(float) / 1000.0
    return np.where(st.position_ms >= 0, age, np.inf)


class StaleTelemetryWatch:
    """The stale-telemetry monitor of one flight, reporting into `result` and `progress`."""

    def __init__(
        self, params: TelemetryParams, n: int, result: FlightResult, progress: Callable[[str], None]
    ) -> None:
        self.params = params
        self.monitor = StaleTelemetryMonitor(params)
        self.result = result
        self.progress = progress
        self.held = np.zeros(n, dtype=bool)  # (N,) held at the previous tick
        self.degraded = False  # degraded at the previous tick
        self.last_tick_t: float | None = None  # vehicle s of the previous tick

    def reset(self) -> None:
        """A new formation flight: nothing held, not degraded, no previous tick."""
        self.monitor.reset()
        self.held[:], self.degraded, self.last_tick_t = False, False, None

    def assess(
        self, fleet: Fleet, t: float, pos: np.ndarray, vel: np.ndarray, leader: int
    ) -> TelemetryAssessment:
        """The verdict at vehicle time t (s) from measured pos/vel (N, 3); events on changes."""
        alive, names = fleet.alive, fleet.names
        verdict = self.monitor.assess(t, pos, vel, telemetry_age(fleet), alive, leader)
        dt = 0.0 if self.last_tick_t is None else max(0.0, t - self.last_tick_t)
        self.last_tick_t = t
        ages = verdict.age[alive & np.isfinite(verdict.age)]
        if ages.size:
            self.result.max_telemetry_age_s = max(self.result.max_telemetry_age_s, float(ages.max()))
        if verdict.degraded:
            self.result.degraded_s += dt
        if verdict.degraded != self.degraded:
            p = self.params
            scales = f"speed x{p.degraded_speed:g}, spacing x{p.degraded_spacing:g}"
            text = (
                f"stale telemetry: degraded flight ({scales})"
                if verdict.degraded
                else "telemetry fresh again: normal flight"
            )
            self.result.events.append(f"t={t:.2f} s {text}")
            self.progress(f"! {text}")
        for i in np.flatnonzero(verdict.held != self.held):
            if verdict.held[i]:
                self.result.holds += 1
                old = not verdict.age[i] <= self.params.hold_s
                why = f"telemetry {verdict.age[i]:.2f} s old" if old else "the leader's telemetry is stale"
                text = f"{names[i]} held: {why}"
            elif alive[i]:
                text = f"{names[i]} rejoins: telemetry fresh again"
            else:
                continue  # lost: the re-form event tells
            self.result.events.append(f"t={t:.2f} s {text}")
            self.progress(f"! {text}")
        self.degraded, self.held = verdict.degraded, verdict.held.copy()
        return verdict
