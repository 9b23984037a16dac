"""The flight thread: the only thread that touches the Fleet and the MissionRunner.

It loops: run the requests the UI queued, then one tick (`runner.step()` while the mission flies: climb,
formation, hold, landing; `runner.idle()` before `start` and after landing, so a lockstep simulator keeps
running), then publish a `Snapshot` and the new events. The UI thread only calls `submit`, `snapshot` and
`events_after`, which are thread-safe. Blocking fleet operations (preflight, arm, mode, takeoff, param) run
here; their outcome comes back as events that name the vehicle and, on refusal, its reason. While one runs,
the fleet's pump hook (`Fleet.on_pump`, called from inside every blocking wait, still on this thread) keeps
publishing snapshots, so the table stays live.

Everything that flies is the runner's; the session only dispatches operator commands and reports.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm.console.commands import Request
from gcs_swarm.console.snapshot import (
    FLYING_PHASES,
    MissionLine,
    Snapshot,
    StreamLoss,
    VehicleRow,
    empty_snapshot,
    is_airborne,
    nearest_neighbour,
    obstacle_clearance,
    vehicle_warnings,
)
from gcs_swarm.evaluation.error_log import log_exception, traceback_note
from gcs_swarm.flight.phase import Phase
from gcs_swarm.flight.preflight import PreflightError
from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.link_use import DOWN, UP
from gcs_swarm.link.streams import telemetry_rates
from gcs_swarm.link.telemetry import Event
from gcs_swarm.link.vehicle import VehicleLink

_PUBLISH_PERIOD_S = 0.05  # wall s between snapshots (the UI renders a few times a second)
_MAX_LAG_S = 0.5  # real-time pacing: vehicle time this far behind the wall clock is not caught up
_SEVERITY_LEVEL = {0: "error", 1: "error", 2: "error", 3: "error", 4: "warning"}  # MAV_SEVERITY -> level


@dataclass(frozen=True)
class ConsoleEvent:
    """A line of the event log. `time_s` is vehicle time; level is "info", "warning" or "error"."""

    seq: int
    time_s: float
    source: str  # a vehicle name, "mission" or "console"
    text: str
    level: str = "info"


class Ticket:
    """The pending outcome of a submitted request; `wait()` until the flight thread has run it."""

    def __init__(self, request: Request) -> None:
        self.request = request
        self.ok = False
        self._done = threading.Event()

    def finish(self, ok: bool) -> None:
        self.ok = ok
        self._done.set()

    def wait(self, timeout_s: float | None = None) -> bool:
        return self._done.wait(timeout_s)


class FlightSession:
    """Owns `runner` (and its fleet) on a background thread; see the module doc.

    realtime: pace vehicle time to the wall clock (a lockstep simulator otherwise runs as fast as it can;
    real vehicles are paced by nature). connect_timeout_s: for every vehicle's first HEARTBEAT. run_dir: the
    run folder, whose errors.log receives the traceback of an unexpected exception (a bug) in the flight
    thread; the event log then names that file in one line.
    """

    def __init__(
        self,
        runner: MissionRunner,
        run_dir: Path,
        realtime: bool = False,
        connect_timeout_s: float = 30.0,
    ) -> None:
        self.runner = runner
        self.run_dir = run_dir
        self.fleet = runner.fleet
        self.mission = runner.mission
        self.realtime = realtime
        self.connect_timeout_s = connect_timeout_s
        runner.progress = self._on_progress
        runner.leader_takeover_timeout_s = None  # a leader taken over: hold until the operator decides
        self.fleet.on_pump = self._refresh
        n = len(self.mission.vehicles)
        self._requests: queue.Queue[Ticket] = queue.Queue()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._main, name="flight", daemon=True)
        self._lock = threading.Lock()
        self._events: deque[ConsoleEvent] = deque(maxlen=2000)
        self._seq = 0
        self._snapshot = empty_snapshot([v.name for v in self.mission.vehicles])
        self._state = "connecting"
        self._error = ""
        self._busy = ""
        self._busy_since = 0.0  # time.monotonic() when the running request began
        self._serving: Ticket | None = None  # the request being run, finished on the way out if it raised
        self._started = False
        self._phases: list[str] = [Phase.CONNECT]
        self._min_separation = math.inf
        self._crashed = np.zeros(n, dtype=bool)
        self._loss = StreamLoss(n)
        self._last_publish = -math.inf
        self._pace_anchor: tuple[float, float] | None = None
        self._last_tick_error = ""
        self._obstacle_radii = np.array([o.radius for o in self.mission.obstacles], dtype=float)

    # ------------------------------------------------------------------ UI thread API

    def start(self) -> None:
        self._thread.start()

    def submit(self, request: Request) -> Ticket:
        """Queue a request for the flight thread (thread-safe); its replies arrive as events."""
        ticket = Ticket(request)
        if not self._thread.is_alive():
            self._event("console", f"{request.verb}: the flight session is not running", "error")
            ticket.finish(False)
        else:
            self._requests.put(ticket)
        return ticket

    def snapshot(self) -> Snapshot:
        return self._snapshot

    def events_after(self, seq: int) -> list[ConsoleEvent]:
        """Events with a sequence number above `seq`, oldest first."""
        with self._lock:
            return [e for e in self._events if e.seq > seq]

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def stop(self, timeout_s: float = 15.0) -> None:
        """End the flight thread (vehicles keep whatever they were doing) and wait for it."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout_s)

    # ------------------------------------------------------------------ flight thread

    def _main(self) -> None:
        try:
            self._connect()
            while not self._stop.is_set():
                self._serve_requests()
                self._tick()
                self._observe()
                self._publish()
                self._pace()
        except LinkError as exc:
            self._fail(str(exc))
        except Exception as exc:  # noqa: BLE001 - the UI must learn why the flight thread ended
            logged = log_exception(self.run_dir, "internal error in the console's flight thread")
            self._fail(
                f"internal error in the flight thread: {type(exc).__name__}: {exc}{traceback_note(logged)}"
            )
        finally:
            if self._state != "failed":
                self._restore_params()
            self.fleet.on_pump = None
            if self._state != "failed":
                self._state = "stopped"
            self._cancel_pending()
            self._publish(force=True)

    def _connect(self) -> None:
        """Connect, then ask for telemetry at the control rate so the table is live before `start`."""
        self._publish(force=True)
        self.runner.connect(self.connect_timeout_s)
        rate = self.mission.run.control_rate_hz
        rates = telemetry_rates(rate)
        results = self.fleet.run(
            (link.streams.op_request_streams(rates) for link in self.fleet.links), strict=False
        )
        for link, result in zip(self.fleet.links, results, strict=True):
            if isinstance(result, LinkError):
                self._event(link.name, f"telemetry rates not set: {result}", "warning", self._vt())
            else:
                self._loss.set_interval(link.index, 1000.0 / rate)
        self._state = "ready"
        names = ", ".join(f"{link.name} (sysid {link.sysid})" for link in self.fleet.links)
        self._event("mission", f"connected to {names}", time_s=self._vt())

    def _restore_params(self) -> None:
        """Leaving: put back what the run changed on grounded vehicles (MissionRunner.restore_params)."""
        try:
            self.runner.restore_params()
        except LinkError as exc:
            self._event("console", f"parameters not restored: {exc}", "warning")
            return
        except Exception as exc:  # noqa: BLE001 - best effort on the way out; say why
            logged = log_exception(self.run_dir, "parameters not restored")
            self._event("console", f"parameters not restored: {exc}{traceback_note(logged)}", "warning")
            return
        for change in self.runner.result.params_changed:
            if change["restored"]:
                self._event(str(change["vehicle"]), f"{change['name']} restored to {change['original']:g}")

    def _fail(self, message: str) -> None:
        self._state, self._error = "failed", message
        self._event("console", message, "error")

    def _cancel_pending(self) -> None:
        if self._serving is not None:  # its handler raised: the event log already says why
            self._serving.finish(False)
            self._serving = None
        while True:
            try:
                ticket = self._requests.get_nowait()
            except queue.Empty:
                return
            self._event(
                "console", f"{ticket.request.line or ticket.request.verb}: not run, stopping", "error"
            )
            ticket.finish(False)

    def _tick(self) -> None:
        runner = self.runner
        if runner.phase not in FLYING_PHASES:
            runner.idle(0.02)
            return
        try:
            runner.step(timeout_s=0.5)
        except (LinkError, ValueError, RuntimeError) as exc:
            if str(exc) != self._last_tick_error:  # the same failure on every tick is reported once
                self._event("mission", f"flight tick failed: {exc}", "error", self._vt())
            self._last_tick_error = str(exc)
            if runner.phase.airborne:
                self._event("mission", "landing every vehicle", "error", self._vt())
                runner.abort()

    def _observe(self) -> None:
        """Forward the fleet's events (STATUSTEXT, link lost/regained) and track the minimum separation."""
        self._forward_vehicle_events()
        pos = self.fleet.pos
        known = self.fleet.alive & np.isfinite(pos).all(axis=1)
        if known.sum() >= 2:
            nearest = nearest_neighbour(pos[known])
            self._min_separation = min(self._min_separation, float(np.nanmin(nearest)))
        self._loss.update(self.fleet.state.position_ms, self.fleet.state.position_count)

    def _refresh(self) -> None:
        """Fleet pump hook: observe and publish from inside blocking waits (a command's round trips,
        preflight, a landing command), at most once per publish period of wall time; inside a command, keep
        real-time pacing too. Never pumps."""
        if self._state == "ready" and time.monotonic() - self._last_publish >= _PUBLISH_PERIOD_S:
            self._observe()
            self._publish()
        if self._busy:
            self._pace()

    def _forward_vehicle_events(self) -> None:
        while self.fleet.events:
            event: Event = self.fleet.events.popleft()
            if event.text.startswith("Crash"):  # ArduCopter's crash check: "Crash: Disarming ..."
                self._crashed[self.fleet.names.index(event.vehicle)] = True
            level = _SEVERITY_LEVEL.get(event.severity, "info")
            self._event(event.vehicle, event.text, level, event.time_s)

    def _vt(self) -> float:
        """Vehicle time now (flight thread only), 0 before any telemetry."""
        return self.runner.vehicle_time() if bool((self.fleet.state.time_ms >= 0).any()) else 0.0

    def _on_progress(self, message: str) -> None:
        phase = self.runner.phase
        if phase != self._phases[-1]:
            self._phases.append(phase)
        level = "warning" if message.startswith("!") else "info"
        self._event("mission", message.lstrip("! "), level, self._vt())
        self._publish(force=True)

    def _pace(self) -> None:
        """Real-time pacing: sleep while vehicle time runs ahead of the wall clock."""
        if not self.realtime or self._state != "ready":
            return
        t, now = self.runner.vehicle_time(), time.monotonic()
        if self._pace_anchor is None or t <= 0:
            self._pace_anchor = (t, now)
            return
        ahead = (t - self._pace_anchor[0]) - (now - self._pace_anchor[1])
        if ahead > 0:
            time.sleep(min(ahead, 0.05))
        elif ahead < -_MAX_LAG_S:
            self._pace_anchor = (t, now)

    # ------------------------------------------------------------------ events and snapshots

    def _event(self, source: str, text: str, level: str = "info", time_s: float | None = None) -> None:
        if time_s is None:
            time_s = self._snapshot.mission.vehicle_time
        with self._lock:
            self._seq += 1
            self._events.append(ConsoleEvent(self._seq, time_s, source, text, level))

    def _publish(self, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last_publish < _PUBLISH_PERIOD_S:
            return
        self._last_publish = now
        self._snapshot = self._build_snapshot(now)

    def _build_snapshot(self, now: float) -> Snapshot:
        fleet, runner, mission = self.fleet, self.runner, self.mission
        st = fleet.state
        pos, vel, alive = fleet.pos, fleet.vel, fleet.alive
        has_time = bool((st.time_ms >= 0).any())
        t = runner.vehicle_time() if has_time else 0.0
        cmd = runner.last_command if runner.phase.in_formation else None
        centres = np.array([o.center_at(t) for o in mission.obstacles]).reshape(-1, 3)
        clearance = obstacle_clearance(pos, centres, self._obstacle_radii)
        neighbour = nearest_neighbour(pos)
        leader = runner.controller.leader  # the lead may have passed on (lost, taken over, `leader`)
        rows = []
        for link in fleet.links:
            i = link.index
            slot_error = None
            if cmd is not None and i != leader and np.isfinite(cmd.slots[i]).all():
                slot_error = float(np.linalg.norm(pos[i] - cmd.slots[i]))
            emergency = cmd is not None and runner.phase is Phase.FORMATION and bool(cmd.emergency[i])
            age = now - link.telemetry.last_rx_wall
            rows.append(
                VehicleRow(
                    name=link.name,
                    sysid=link.sysid,
                    alive=bool(alive[i]),
                    age_s=age,
                    loss=self._loss.fraction(i),
                    mode=link.mode_name(),
                    armed=bool(st.armed[i]),
                    airborne=is_airborne(bool(st.armed[i]), int(st.landed_state[i]), float(pos[i, 2])),
                    position=(float(pos[i, 0]), float(pos[i, 1]), float(pos[i, 2])),
                    speed=float(np.linalg.norm(vel[i])),
                    slot_error=slot_error,
                    obstacle=_optional(clearance[i]),
                    neighbour=_optional(neighbour[i]),
                    warnings=vehicle_warnings(
                        bool(alive[i]),
                        age,
                        int(st.system_status[i]),
                        bool(self._crashed[i]),
                        emergency,
                        taken=bool(runner.takeover.taken[i]),
                    ),
                    rtt_ms=float(st.rtt_ms[i]),
                    taken=bool(runner.takeover.taken[i]),
                    up_B_s=float(fleet.link_use.rate[i, UP]),
                    down_B_s=float(fleet.link_use.rate[i, DOWN]),
                    budget_B_s=fleet.link_use.budget_B_s,
                )
            )
        goal = runner.controller.waypoints[-1]
        line = MissionLine(
            phase=runner.phase,
            started=self._started,
            vehicle_time=t,
            leader_goal_distance=float(np.linalg.norm(pos[leader] - goal)),
            goal=(float(goal[0]), float(goal[1]), float(goal[2])),
            formation_rms=runner.formation_rms,
            min_separation=self._min_separation,
            busy=self._busy,
            busy_s=now - self._busy_since if self._busy else 0.0,
        )
        params = sorted({name for link in fleet.links for name in link.parameters.values})
        return Snapshot(self._state, tuple(rows), line, tuple(self._phases), tuple(params), self._error)

    # ------------------------------------------------------------------ requests

    def _serve_requests(self) -> None:
        while True:
            try:
                ticket = self._requests.get_nowait()
            except queue.Empty:
                return
            request = ticket.request
            self._serving = ticket
            handler = _HANDLERS.get(request.verb)
            self._busy, self._busy_since = request.line or request.verb, time.monotonic()
            self._publish(force=True)
            try:
                ok = (
                    handler(self, request)
                    if handler is not None
                    else self._refuse(f"{request.verb}: not here")
                )
            except (LinkError, PreflightError, ValueError, RuntimeError) as exc:
                ok = self._refuse(str(exc))
            finally:
                self._busy = ""
            self._publish(force=True)  # before the ticket: whoever waits on it then sees the outcome
            self._serving = None
            ticket.finish(ok)

    def _reply(self, text: str, source: str = "console") -> bool:
        self._forward_vehicle_events()  # the vehicles' own messages about a command come before its outcome
        self._event(source, text, "info", self._vt())
        return True

    def _refuse(self, text: str) -> bool:
        self._forward_vehicle_events()
        self._event("console", text, "error", self._vt())
        return False

    def _flying(self) -> bool:
        return self.runner.phase in FLYING_PHASES

    def _start(self, request: Request) -> bool:
        runner = self.runner
        if runner.result.t_formation_start is not None or self._flying():
            return self._refuse(f"the mission has already been started (phase {runner.phase})")
        self._started = True
        try:
            runner.begin()
        except (PreflightError, LinkError) as exc:
            self._refuse(f"start failed: {exc}")
            if runner.phase is Phase.LAUNCH:
                self._event("mission", "landing (disarming) the vehicles that were launched", "warning")
                runner.abort()
            return False
        return self._reply("started: taking off, then formation flight")

    def _hold(self, request: Request) -> bool:
        phase = self.runner.phase
        if phase is Phase.HOLD:
            return self._reply("already holding")
        if phase is not Phase.FORMATION:
            return self._refuse(f"hold needs formation flight; the mission is in phase {phase}")
        self.runner.hold()
        return self._reply("holding: every vehicle brakes and holds its position (resume to go on)")

    def _resume(self, request: Request) -> bool:
        phase = self.runner.phase
        if phase is not Phase.HOLD:
            return self._refuse(f"resume needs phase hold; the mission is in phase {phase}")
        self.runner.resume()
        return self._reply("resumed formation flight")

    def _abort(self, request: Request) -> bool:
        runner = self.runner
        if runner.phase.airborne:
            runner.abort()
            return self._reply("aborting: every vehicle lands now")
        if runner.phase is Phase.LAND:
            return self._reply("already landing")
        taken = runner.takeover.taken  # left to their operator: never landed by the console's abort
        armed = [
            link for link in self.fleet.links if self.fleet.state.armed[link.index] and not taken[link.index]
        ]
        if not armed:
            return self._reply("nothing to abort: no vehicle is armed")
        return self._vehicle_ops(armed, lambda link: link.commands.op_land(), "landing (mode LAND)")

    def _goal(self, request: Request) -> bool:
        if self.runner.phase in (Phase.LAND, Phase.DONE):
            return self._refuse(f"the mission is in phase {self.runner.phase}; the goal can no longer change")
        assert request.point is not None
        self.runner.set_goal(np.array(request.point, dtype=float))
        note = " (resume to fly there)" if self.runner.phase is Phase.HOLD else ""
        return self._reply(f"goal set to {_xyz(request.point)}{note}")

    def _formation(self, request: Request) -> bool:
        if self.runner.phase in (Phase.LAND, Phase.DONE):
            return self._refuse(
                f"the mission is in phase {self.runner.phase}; the formation can no longer change"
            )
        self.runner.set_formation(request.name, request.value)
        spacing = "" if request.value is None else f", spacing {request.value:g} m"
        return self._reply(f"formation {request.name}{spacing}")

    def _rejoin(self, request: Request) -> bool:
        """rejoin VEHICLE: hand a vehicle taken over back to the formation (GUIDED, then to its slot)."""
        (row,) = request.vehicles
        self.runner.rejoin(row)
        return self._reply("back in GUIDED: flying to its slot", self.fleet.names[row])

    def _leader(self, request: Request) -> bool:
        """leader VEHICLE: the lead passes to this vehicle (on to the same goal)."""
        (row,) = request.vehicles
        self.runner.promote(row)
        return self._reply(f"{self.fleet.names[row]} leads the formation (phase {self.runner.phase})")

    def _manual(self, request: Request) -> bool:
        """arm / disarm / mode / takeoff / land / rtl on the chosen vehicles, straight over their links."""
        verb, runner = request.verb, self.runner
        if request.every and self._flying():
            if verb == "land":
                if runner.phase is not Phase.LAND:
                    runner.abort()
                return self._reply("landing every vehicle (the mission is aborted)")
            return self._refuse(
                f"the mission is flying (phase {runner.phase}): use hold, resume or abort, "
                f"or give {verb} one vehicle"
            )
        links = [self.fleet.links[i] for i in request.vehicles]
        mode = {"land": "LAND", "rtl": "RTL", "mode": request.name}.get(verb)
        if mode is not None:
            for link in links:  # our own mode change, never a takeover; away from GUIDED in flight: released
                runner.release(link.index, mode)
            return self._vehicle_ops(links, lambda link: link.commands.op_set_mode(mode), f"mode {mode}")
        if verb == "takeoff":
            alt = request.value if request.value is not None else math.nan
            return self._vehicle_ops(
                links, lambda link: link.commands.op_takeoff(alt), f"taking off to {alt:g} m"
            )
        if verb == "arm":
            return self._vehicle_ops(links, lambda link: link.commands.op_arm(), "armed")
        return self._vehicle_ops(links, lambda link: link.commands.op_disarm(), "disarmed")

    def _param_get(self, request: Request) -> bool:
        links = [self.fleet.links[i] for i in request.vehicles]
        return self._vehicle_ops(
            links,
            lambda link: link.parameters.op_get(request.name),
            lambda value: f"{request.name} = {value:g}",
        )

    def _param_set(self, request: Request) -> bool:
        links = [self.fleet.links[i] for i in request.vehicles]
        value = request.value if request.value is not None else math.nan
        return self._vehicle_ops(
            links, lambda link: link.parameters.op_set(request.name, value), f"{request.name} = {value:g}"
        )

    def _param_fetch(self, request: Request) -> bool:
        if self._flying():
            return self._refuse(
                "param fetch pauses the formation controller for seconds: not while the mission flies"
            )
        links = [self.fleet.links[i] for i in request.vehicles]
        return self._vehicle_ops(
            links, lambda link: link.parameters.op_all(), lambda values: f"{len(values)} parameters"
        )

    def _vehicle_ops(
        self,
        links: list[VehicleLink],
        make: Callable[[VehicleLink], Any],
        done: str | Callable[[Any], str],
    ) -> bool:
        """Run one operation per vehicle together; one line per vehicle: `done` (or `done` of the
        operation's result), or why it refused."""
        results = self.fleet.run((make(link) for link in links), strict=False)
        ok = True
        for link, result in zip(links, results, strict=True):
            if isinstance(result, LinkError):
                ok = self._refuse(str(result))
            else:
                self._reply(done if isinstance(done, str) else done(result), link.name)
        return ok


_HANDLERS: dict[str, Callable[[FlightSession, Request], bool]] = {
    "start": FlightSession._start,
    "hold": FlightSession._hold,
    "resume": FlightSession._resume,
    "abort": FlightSession._abort,
    "goal": FlightSession._goal,
    "rejoin": FlightSession._rejoin,
    "leader": FlightSession._leader,
    "formation": FlightSession._formation,
    "arm": FlightSession._manual,
    "disarm": FlightSession._manual,
    "mode": FlightSession._manual,
    "takeoff": FlightSession._manual,
    "land": FlightSession._manual,
    "rtl": FlightSession._manual,
    "param_get": FlightSession._param_get,
    "param_set": FlightSession._param_set,
    "param_fetch": FlightSession._param_fetch,
}


def _optional(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _xyz(point: tuple[float, float, float]) -> str:
    return "(" + ", ".join(f"{c:g}" for c in point) + ")"
