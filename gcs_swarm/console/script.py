"""Plain mode: commands from a script file or stdin, output as plain lines (for automation and tests).

Each command is echoed as `[    t] > command` (t = vehicle time), then waits for its outcome before the next
line runs; events (replies, refusals with their reason, STATUSTEXT, phase changes, lost/regained links) are
printed as they arrive, and the fleet table every `table_period_s` of vehicle time while the mission flies.
`wait SECONDS` and `wait phase NAME [SECONDS]` pace a script. At `quit` or the end of the input, airborne
vehicles are landed first. Exit status: 0 every command succeeded, 1 some command failed.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable

from gcs_swarm.console.commands import CommandError, Request, help_lines, parse, vocabulary_for
from gcs_swarm.console.session import FlightSession
from gcs_swarm.console.snapshot import FLYING_PHASES, Snapshot
from gcs_swarm.console.view import event_line, fleet_table, plain, status_lines
from gcs_swarm.mission import Mission

EXIT_OK, EXIT_FAILED, EXIT_USER_ERROR = 0, 1, 2
STALL_S = 10.0  # wall s without vehicle time advancing before a wait gives up
_POLL_S = 0.05


class PlainConsole:
    """Runs `lines` against `session`; `write` prints one output line."""

    def __init__(
        self,
        session: FlightSession,
        mission: Mission,
        lines: Iterable[str],
        yes: bool = False,
        write: Callable[[str], None] = print,
        table_period_s: float = 10.0,
    ) -> None:
        self.session = session
        self.mission = mission
        self.yes = yes
        self.write = write
        self.table_period_s = table_period_s
        self.failures = 0
        self._seq = 0
        self._last_table_t = -float("inf")
        self._lines: queue.Queue[str | None] = queue.Queue()
        threading.Thread(target=self._read, args=(lines,), name="script-input", daemon=True).start()

    def _read(self, lines: Iterable[str]) -> None:
        try:
            for line in lines:
                self._lines.put(line)
        finally:
            self._lines.put(None)

    def run(self) -> int:
        """Run every line (until quit); EXIT_USER_ERROR when the vehicles never connected."""
        try:
            if not self._wait_connected():
                return EXIT_USER_ERROR
            while True:
                line = self._next_line()
                if line is None or not self._run_line(line):
                    break
            self._quit()
        except KeyboardInterrupt:
            self.write("interrupted: landing airborne vehicles before quitting (Ctrl-C again to leave now)")
            self._quit()
        return EXIT_OK if self.failures == 0 else EXIT_FAILED

    # ------------------------------------------------------------------ lines

    def _next_line(self) -> str | None:
        while True:
            self._pump()
            try:
                return self._lines.get(timeout=_POLL_S)
            except queue.Empty:
                if not self.session.running:
                    return None

    def _run_line(self, line: str) -> bool:
        """Run one line; False at quit."""
        snapshot = self.session.snapshot()
        try:
            request = parse(line, vocabulary_for(self.mission, snapshot))
        except CommandError as exc:
            self._echo(line, snapshot)
            self._fail(str(exc))
            return True
        if request is None:
            return True
        self._echo(line, snapshot)
        if request.verb == "quit":
            return False
        if request.verb == "help":
            for text in help_lines(request.name or None):
                self.write(text)
        elif request.verb == "status":
            self._print_status(self.session.snapshot())
        elif request.verb == "wait":
            self._wait_seconds(request.value or 0.0)
        elif request.verb == "wait_phase":
            self._wait_phase(request.name, request.value)
        elif request.needs_confirmation and not self.yes:
            self._fail(
                f"{request.verb} arms or launches vehicles: run the console with --yes to allow it here"
            )
        else:
            self._submit(request)
        return True

    def _echo(self, line: str, snapshot: Snapshot) -> None:
        self.write(f"[{snapshot.mission.vehicle_time:8.2f}] > {line.strip()}")

    def _fail(self, text: str) -> None:
        self.failures += 1
        self.write(f"error: {text}")

    def _submit(self, request: Request) -> None:
        ticket = self.session.submit(request)
        while not ticket.wait(_POLL_S):
            self._pump()
        self._pump()
        if not ticket.ok:
            self.failures += 1

    # ------------------------------------------------------------------ waits

    def _wait_connected(self) -> bool:
        while self.session.snapshot().state == "connecting" and self.session.running:
            self._pump()
            time.sleep(_POLL_S)
        self._pump()
        snapshot = self.session.snapshot()
        if snapshot.state != "ready":
            if not snapshot.error:  # a failure's reason was printed as an event already
                self.write("error: the flight session ended")
            return False
        self._print_table(snapshot)
        return True

    def _wait_seconds(self, seconds: float) -> None:
        t_end = self.session.snapshot().mission.vehicle_time + seconds
        self._wait_until(lambda s: s.mission.vehicle_time >= t_end, f"{seconds:g} s of vehicle time")

    def _wait_phase(self, phase: str, limit_s: float | None) -> None:
        start = self.session.snapshot()
        first = len(start.phases) - 1  # the current phase counts
        t_end = start.mission.vehicle_time + (limit_s if limit_s is not None else float("inf"))

        def reached(s: Snapshot) -> bool:
            if phase in s.phases[first:]:
                return True
            if s.mission.phase not in FLYING_PHASES:
                raise _WaitError(
                    f"the mission is not flying (phase {s.mission.phase}); phase {phase} will not come"
                )
            if s.mission.vehicle_time > t_end:
                raise _WaitError(f"phase {phase} did not come within {limit_s:g} s (phase {s.mission.phase})")
            return False

        self._wait_until(reached, f"phase {phase}")

    def _wait_until(self, done: Callable[[Snapshot], bool], what: str) -> bool:
        last_t, last_change = self.session.snapshot().mission.vehicle_time, time.monotonic()
        try:
            while True:
                self._pump()
                snapshot = self.session.snapshot()
                if done(snapshot):
                    return True
                if not self.session.running:
                    raise _WaitError(f"waiting for {what}: the flight session ended")
                if snapshot.mission.vehicle_time != last_t:
                    last_t, last_change = snapshot.mission.vehicle_time, time.monotonic()
                elif time.monotonic() - last_change > STALL_S:
                    raise _WaitError(f"waiting for {what}: vehicle time stopped for {STALL_S:g} s")
                time.sleep(_POLL_S)
        except _WaitError as exc:
            self._pump()
            self._fail(str(exc))
            return False

    # ------------------------------------------------------------------ output

    def _pump(self) -> None:
        """Print new events, and the fleet table when it is due."""
        for event in self.session.events_after(self._seq):
            self._seq = event.seq
            self.write(plain(event_line(event)))
        snapshot = self.session.snapshot()
        t = snapshot.mission.vehicle_time
        if snapshot.mission.phase in FLYING_PHASES and t - self._last_table_t >= self.table_period_s:
            self._print_table(snapshot)

    def _print_table(self, snapshot: Snapshot) -> None:
        self._last_table_t = snapshot.mission.vehicle_time
        for line in fleet_table(snapshot):
            self.write(plain(line))

    def _print_status(self, snapshot: Snapshot) -> None:
        for text in status_lines(snapshot):
            self.write(text)
        self._print_table(snapshot)

    # ------------------------------------------------------------------ quit

    def _quit(self) -> None:
        """Land airborne vehicles (abort), waiting until every one is down and disarmed; vehicles taken over
        are left to their operator (said so)."""
        snapshot = self.session.snapshot()
        taken = [r.name for r in snapshot.rows if r.taken and r.airborne]
        if snapshot.state == "ready" and taken:
            self.write(f"quit: {', '.join(taken)} taken over: left to their operator")
        airborne = [r.name for r in snapshot.rows if r.airborne and not r.taken]
        if snapshot.state != "ready" or not (airborne or snapshot.mission.phase in FLYING_PHASES):
            return
        names = ", ".join(airborne) or "the fleet"
        self.write(f"quit: {names} still flying: landing before quitting")
        self._submit(Request("abort", "abort"))
        self._wait_until(lambda s: s.settled, "every vehicle landed and disarmed")


class _WaitError(Exception):
    """A script wait that cannot finish (its message says why)."""
