"""Stale telemetry: predict briefly, then slow down and widen, then hold [add] (docs/reliability.md).

A vehicle's telemetry age is its newest time_boot_ms minus the time_boot_ms of its latest position report
(both from the vehicle's own clock, so the rule is the same in real time and in lockstep). With the
`TelemetryParams` ages predict_s < hold_s < lost_s:

- age <= hold_s: the vehicle is flown on its constant-velocity prediction pos + vel * age;
- any live vehicle older than predict_s puts the fleet in degraded mode (speed caps x degraded_speed,
  formation spacing and separation ranges x degraded_spacing) until every live vehicle has stayed within
  predict_s for recover_s;
- age > hold_s: the vehicle is held: it brakes and hovers on its own autopilot (which has fresh data) until
  its telemetry is within predict_s again; a held leader holds the whole fleet (the followers' slots hang
  on it);
- no packet for lost_s: the link layer declares the vehicle lost (gcs_swarm.link) and the runner re-forms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gcs_swarm.guidance.params import TelemetryParams
from swarm_common.jit import kernel
from swarm_common.numpy_rules import clip


@dataclass(frozen=True)
class TelemetryAssessment:
    """One tick's verdict. age (N,) s (inf before the first position), pos (N, 3) ENU m predicted to now,
    held (N,) vehicles to brake instead of command, degraded: the fleet flies slower and wider, by the
    factors speed_scale (on the speed caps) and spacing_scale (on spacing and separation ranges)."""

    age: np.ndarray
    pos: np.ndarray
    held: np.ndarray
    degraded: bool
    speed_scale: float
    spacing_scale: float


class StaleTelemetryMonitor:
    """Keeps the degraded-mode timer across ticks for one fleet."""

    def __init__(self, params: TelemetryParams) -> None:
        self.params = params
        self.degraded_until = -np.inf  # vehicle time s until which the fleet stays degraded
        self.stale_held: np.ndarray | None = None  # (N,) held for their own telemetry, until within predict_s

    def reset(self) -> None:
        """Forget the degraded-mode timer and the holds (a new flight)."""
        self.degraded_until = -np.inf
        self.stale_held = None

    def assess(
        self, t: float, pos: np.ndarray, vel: np.ndarray, age: np.ndarray, alive: np.ndarray, leader: int
    ) -> TelemetryAssessment:
        """Verdict at vehicle time t (s) from measured pos/vel (N, 3), telemetry ages (N,) s, the (N,) mask
        of live vehicles and the leader's index."""
        p = self.params
        age = np.asarray(age, dtype=float)
        alive = np.asarray(alive, dtype=bool)
        was = np.zeros(len(age), dtype=bool) if self.stale_held is None else self.stale_held
        pos, vel = np.asarray(pos, dtype=float), np.asarray(vel, dtype=float)
        held, self.stale_held, late, predicted = stale_verdict(
            age, alive, was, pos, vel, int(leader), float(p.hold_s), float(p.predict_s)
        )
        if late:
            self.degraded_until = t + p.recover_s
        degraded = late or t < self.degraded_until
        return TelemetryAssessment(
            age=age,
            pos=predicted,
            held=held,
            degraded=degraded,
            speed_scale=p.degraded_speed if degraded else 1.0,
            spacing_scale=p.degraded_spacing if degraded else 1.0,
        )


@kernel
def stale_verdict(
    age: np.ndarray,
    alive: np.ndarray,
    was: np.ndarray,
    pos: np.ndarray,
    vel: np.ndarray,
    leader: int,
    hold_s: float,
    predict_s: float,
) -> tuple[np.ndarray, np.ndarray, bool, np.ndarray]:
    """The rule of the module doc for one tick, from ages (N,) s, the (N,) masks of live vehicles and of those
    held for their own telemetry at the previous tick (`was`), pos (N, 3) ENU m, vel (N, 3) m/s and the
    leader's index: (held (N,), held for their own telemetry (N,), any live vehicle older than predict_s,
    positions predicted to now (N, 3)). NaN and inf ages count as old and predict nothing."""
    n = age.shape[0]
    own = np.empty(n, dtype=np.bool_)
    late = False
    for i in range(n):
        own[i] = alive[i] and (not age[i] <= hold_s or (was[i] and not age[i] <= predict_s))
        late = late or (alive[i] and not age[i] <= predict_s)
    held = alive.copy() if own[leader] else own.copy()
    predicted = np.empty((n, 3))
    for i in range(n):
        horizon = 0.0 if held[i] else clip(age[i] if math.isfinite(age[i]) else 0.0, 0.0, hold_s)
        for k in range(3):
            predicted[i, k] = pos[i, k] + vel[i, k] * horizon
    return held, own, late, predicted
