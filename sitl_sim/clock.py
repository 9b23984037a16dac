"""Pacing of simulated time against the wall clock: real time, --speedup X, and --lockstep bookkeeping.

Lockstep rule (docs/sitl.md): simulated time advances in frames of 1/--lockstep-hz. At each frame end the
simulator emits the telemetry due, then waits until every lockstep client has answered the frame: a client
(one peer address of one vehicle endpoint) answers by sending that vehicle a SYSTEM_TIME, SET_ATTITUDE_TARGET,
SET_POSITION_TARGET_LOCAL_NED or SET_POSITION_TARGET_GLOBAL_INT whose time_boot_ms >= the frame's. Sending
such a message with time_boot_ms > 0 makes a peer a lockstep client; one that stays silent for
--lockstep-timeout wall seconds is dropped until it answers again. With --lockstep-delay 1 (pipelined) a
frame end waits for the answers to the previous frame instead, and holds its own telemetry until then.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

MAX_LAG_S = 0.25  # wall seconds a paced run may fall behind before it stops trying to catch up


LATE_S = 0.02  # wall seconds behind schedule that count as late: one frame of the 50 Hz telemetry streams


@dataclass
class PacingLag:
    """How far behind the wall clock a paced run fell: `worst_s` (wall s, the largest lag seen), `late_ticks`
    (ticks that started more than LATE_S behind schedule) of `paced_ticks`. A simulator that falls behind
    sends the frames it owes in a burst, which a real-time client sees as frames replaced before it could
    use them: its missed frames are then the simulator's, not its own."""

    worst_s: float = 0.0
    late_ticks: int = 0
    paced_ticks: int = 0

    def summary(self) -> str:
        """One line for the simulator's exit report."""
        return (
            f"real-time pacing: worst lag {self.worst_s * 1000:.1f} ms, {self.late_ticks} of "
            f"{self.paced_ticks} ticks more than {LATE_S * 1000:g} ms behind"
        )


class RealTimePacer:
    """Maps simulated seconds to wall deadlines at `speedup` x real time; forgives lags above MAX_LAG_S and
    keeps the lags it saw in `lag` (a PacingLag, shared with a pacer that takes over, e.g. when orphaned)."""

    def __init__(self, speedup: float, lag: PacingLag | None = None) -> None:
        self.speedup = speedup
        self.wall0: float | None = None
        self.sim0 = 0.0
        self.lag = PacingLag() if lag is None else lag

    def restart(self, sim_t: float, wall_now: float) -> None:
        """Anchor: simulated time sim_t corresponds to wall_now."""
        self.sim0 = sim_t
        self.wall0 = wall_now

    def deadline(self, sim_t: float, wall_now: float) -> float:
        """Wall time at which sim_t is due (re-anchored first if the run is more than MAX_LAG_S behind);
        `wall_now` for an unpaced run (speedup inf: as fast as it can, never behind)."""
        if math.isinf(self.speedup):
            return wall_now
        if self.wall0 is None:
            self.restart(sim_t, wall_now)
        assert self.wall0 is not None
        due = self.wall0 + (sim_t - self.sim0) / self.speedup
        behind = wall_now - due
        lag = self.lag
        lag.paced_ticks += 1
        if behind > LATE_S:
            lag.late_ticks += 1
        lag.worst_s = max(lag.worst_s, behind)
        if behind > MAX_LAG_S:
            self.restart(sim_t, wall_now)
            due = wall_now
        return due


@dataclass
class LockstepClient:
    """One lockstep client: the latest time_boot_ms it echoed, whether it was dropped for silence."""

    answered_ms: int
    dropped: bool = False


class LockstepClients:
    """Lockstep clients of each vehicle, keyed by peer address."""

    def __init__(self, n: int, timeout_s: float) -> None:
        self.n = n
        self.timeout_s = timeout_s
        self.by_vehicle: list[dict[tuple[str, int], LockstepClient]] = [{} for _ in range(n)]
        self.first_seen_wall: float | None = None

    def answer(self, vehicle: int, addr: tuple[str, int], time_boot_ms: int, wall_now: float) -> None:
        """A qualifying message with time_boot_ms came from addr to vehicle (0 never registers a client)."""
        clients = self.by_vehicle[vehicle]
        client = clients.get(addr)
        if client is None:
            if time_boot_ms <= 0:
                return
            client = clients[addr] = LockstepClient(time_boot_ms)
            if self.first_seen_wall is None:
                self.first_seen_wall = wall_now
        client.answered_ms = max(client.answered_ms, time_boot_ms)
        if time_boot_ms > 0:
            client.dropped = False

    def any_active(self) -> bool:
        """Some client is not dropped."""
        return any(not c.dropped for clients in self.by_vehicle for c in clients.values())

    def pending(self, frame_ms: int) -> list[tuple[int, tuple[str, int]]]:
        """(vehicle, address) of the active clients that have not answered frame_ms yet."""
        return [
            (vehicle, addr)
            for vehicle, clients in enumerate(self.by_vehicle)
            for addr, c in clients.items()
            if not c.dropped and c.answered_ms < frame_ms
        ]

    def drop(self, keys: list[tuple[int, tuple[str, int]]]) -> None:
        """Stop waiting for these clients until they answer again."""
        for vehicle, addr in keys:
            self.by_vehicle[vehicle][addr].dropped = True

    def vehicle_answered(self, vehicle: int, frame_ms: int) -> bool:
        """The vehicle has active lockstep clients and all of them answered frame_ms."""
        answered = False
        for client in self.by_vehicle[vehicle].values():
            if not client.dropped:
                if client.answered_ms < frame_ms:
                    return False
                answered = True
        return answered

    def every_vehicle_has_client(self) -> bool:
        """Each vehicle endpoint has at least one active lockstep client."""
        return all(any(not c.dropped for c in clients.values()) for clients in self.by_vehicle)


@dataclass(frozen=True)
class Timing:
    """Integer step counts that tie the loops together (all in physics steps of 1/rate_hz)."""

    rate_hz: float
    steps_per_tick: int  # physics steps per autopilot tick
    ticks_per_frame: int  # autopilot ticks per lockstep frame (1 when not in lockstep)
    steps_per_truth: int  # physics steps between truth-log samples

    @property
    def tick_s(self) -> float:
        """Autopilot tick length, s."""
        return self.steps_per_tick / self.rate_hz


def plan_timing(rate_hz: float, outer_hz: float, lockstep_hz: float | None, truth_rate_hz: float) -> Timing:
    """Choose the step counts; ValueError (one sentence naming the option) when the rates do not fit together.

    The autopilot tick is rate_hz/outer_hz physics steps; in lockstep it is shortened, if needed, to the
    largest divisor of the frame so that frames hold a whole number of ticks.
    """

    def steps(per_hz: float, option: str) -> int:
        ratio = rate_hz / per_hz
        if ratio < 1 - 1e-9 or abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(f"--rate-hz ({rate_hz:g}) must be a whole multiple of {option} ({per_hz:g})")
        return round(ratio)

    steps_per_tick = steps(outer_hz, "--outer-hz")
    ticks_per_frame = 1
    if lockstep_hz is not None:
        frame = steps(lockstep_hz, "--lockstep-hz")
        steps_per_tick = max(d for d in range(1, min(steps_per_tick, frame) + 1) if frame % d == 0)
        ticks_per_frame = frame // steps_per_tick
    steps_per_truth = steps(truth_rate_hz, "--truth-rate-hz")
    if steps_per_truth % steps_per_tick:
        raise ValueError(
            f"--truth-rate-hz ({truth_rate_hz:g}) must divide the autopilot rate "
            f"({rate_hz / steps_per_tick:g} Hz)"
        )
    return Timing(rate_hz, steps_per_tick, ticks_per_frame, steps_per_truth)
