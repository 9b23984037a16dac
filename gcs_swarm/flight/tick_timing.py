"""Where the ground station's formation ticks spend their wall time, and which telemetry frames it never
answered: the figures behind flight.json's `worst_tick`, `tick_phases_ms` and `frames_missed`.

A formation tick's cycle runs from the start of `MissionRunner.step` (waiting for the frame) to its end (the
lockstep answers sent). It splits into waiting (the link blocked in select for packets, `Fleet.pump_wait_s`)
and work, the work into phases (`TICK_PHASES`):

    receive   decoding the packets that completed the frame, and the link's housekeeping in `Fleet.pump`
              (heartbeats, loss checks, stream watchdog; `Fleet.pump_work_s`)
    assess    stale-telemetry assessment, lost and taken-over vehicles placed as obstacles
    guidance  FleetController.tick
    send      thrust from acceleration, the final command guard, SET_ATTITUDE_TARGET packed and sent
    record    the run record's row
    rest      everything else: wait_tick's frame checks, lost-vehicle and takeover checks, progress line,
              lockstep answers

Each phase is a few time.perf_counter() calls (`TickTiming.mark`). The first formation tick
(`MissionRunner.start_formation`) is timed too, its guidance set-up (`_enter_formation`) in `rest`; it is
not in `tick_latency_ms`.

Frames missed: a vehicle's GLOBAL_POSITION_INT replaced by a newer one before a tick or a lockstep answer
consumed it (counted per vehicle by the link, TelemetryState.frames_missed); `MissedFramesByPhase` splits the
count by the mission phase during which it happened.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.flight.phase import Phase

TICK_PHASES = ("receive", "assess", "guidance", "send", "record", "rest")
RECEIVE, ASSESS, GUIDANCE, SEND, RECORD, REST = range(len(TICK_PHASES))


class PumpClock(Protocol):
    """What the link reports of its own time (gcs_swarm.link.fleet.Fleet): cumulative wall s."""

    pump_wait_s: float  # blocked in select, waiting for packets
    pump_work_s: float  # decoding what arrived and the link's housekeeping


class TickTiming:
    """Per formation tick: vehicle time, wall s waiting and working, and the work per phase (`TICK_PHASES`).

    `rows` holds one (t_s, wait_s, work_s, *phase_s) tuple per tick timed; `clock` is the wall clock (s);
    `first_at` and `last_at` the clock when the first and the last tick timed began their work (`at`).
    """

    def __init__(self, clock: Callable[[], float] = time.perf_counter) -> None:
        self.clock = clock
        self.rows: list[tuple[float, ...]] = []
        self._last = 0.0  # clock at the previous mark
        self._link_wait0 = self._link_work0 = 0.0
        self._spent = [0.0] * len(TICK_PHASES)
        self._t_s: float | None = None  # vehicle time of the formation tick in this cycle (None: none yet)
        self._at_wall = 0.0  # clock at `at` in this cycle
        self.first_at = self.last_at = 0.0

    def begin(self, link: PumpClock) -> None:
        """A step starts: it will wait for the frame on `link`."""
        self._last = self.clock()
        self._link_wait0, self._link_work0 = link.pump_wait_s, link.pump_work_s
        self._spent = [0.0] * len(TICK_PHASES)
        self._t_s = None

    def at(self, t_s: float) -> None:
        """The step is a formation tick at vehicle time `t_s` (s); what came before it is `rest`."""
        self._t_s = t_s
        self.mark(REST)
        self._at_wall = self._last

    def mark(self, phase: int) -> None:
        """The wall time since the previous mark was spent in `phase` (an index into TICK_PHASES)."""
        now = self.clock()
        self._spent[phase] += now - self._last
        self._last = now

    def end(self, link: PumpClock) -> None:
        """The step is over: keep its row if it was a formation tick. The link's waiting and receiving
        happened inside the first `rest` span (wait_tick), so they are taken out of it."""
        if self._t_s is None:
            return
        self.mark(REST)
        wait = link.pump_wait_s - self._link_wait0
        spent = self._spent
        spent[RECEIVE] = link.pump_work_s - self._link_work0
        spent[REST] = max(0.0, spent[REST] - wait - spent[RECEIVE])
        self.rows.append((self._t_s, wait, sum(spent), *spent))
        self._t_s = None
        self.last_at = self._at_wall
        if len(self.rows) == 1:
            self.first_at = self._at_wall

    def summary(self) -> dict[str, object]:
        """flight.json entries (ms): `worst_tick` (the tick with the most work: its vehicle time, wait, work
        and work per phase) and `tick_phases_ms` (median, p99 and max of wait, work and each phase over
        the ticks; `vehicle_s` and `wall_s` from the first tick timed to the last, each when its work
        began: their ratio is how fast the vehicles' clock ran, 1 in real time); empty without a timed
        tick."""
        if not self.rows:
            return {}
        ms = np.asarray(self.rows)[:, 1:] * 1000.0  # (ticks, 2 + phases): wait, work, phases
        names = ("wait", "work", *TICK_PHASES)
        worst = int(np.argmax(ms[:, 1]))
        stats = {
            "median": np.median(ms, axis=0),
            "p99": np.percentile(ms, 99, axis=0),
            "max": ms.max(axis=0),
        }
        return {
            "worst_tick": {
                "t_s": round(self.rows[worst][0], 3),
                "wait_ms": round(float(ms[worst, 0]), 4),
                "work_ms": round(float(ms[worst, 1]), 4),
                "phases_ms": {p: round(float(v), 4) for p, v in zip(TICK_PHASES, ms[worst, 2:], strict=True)},
            },
            "tick_phases_ms": {
                "ticks": len(self.rows),
                "vehicle_s": round(self.rows[-1][0] - self.rows[0][0], 3),
                "wall_s": round(self.last_at - self.first_at, 3),
                **{
                    stat: {n: round(float(v), 4) for n, v in zip(names, values, strict=True)}
                    for stat, values in stats.items()
                },
            },
        }


class MissedFramesByPhase:
    """The link's per-vehicle count of frames missed (`counts`, (N,) int, cumulative, updated in place by
    the link) split by the mission phase during which each was missed."""

    def __init__(self, names: Sequence[str], counts: NDArray[np.int64]) -> None:
        self.names = list(names)
        self.counts = counts
        self._phase: Phase | None = None
        self._since = counts.copy()
        self._by_phase: dict[Phase, NDArray[np.int64]] = {}

    def enter(self, phase: Phase) -> None:
        """The mission enters `phase`: what was missed since the last change belongs to the previous one."""
        self._by_phase = self._with_current()
        self._phase = phase
        self._since = self.counts.copy()

    def _with_current(self) -> dict[Phase, NDArray[np.int64]]:
        by_phase = dict(self._by_phase)
        if self._phase is not None:
            before = by_phase.get(self._phase, np.zeros_like(self.counts))
            by_phase[self._phase] = before + (self.counts - self._since)
        return by_phase

    def summary(self) -> dict[str, object]:
        """flight.json `frames_missed`: the total, and per phase its total and the vehicles that missed any
        (name -> frames; vehicles that missed none are left out)."""
        by_phase = self._with_current()
        return {
            "total": int(sum(int(c.sum()) for c in by_phase.values())),
            "by_phase": {
                phase: {
                    "total": int(c.sum()),
                    "by_vehicle": {self.names[i]: int(c[i]) for i in np.flatnonzero(c)},
                }
                for phase, c in by_phase.items()
            },
        }
