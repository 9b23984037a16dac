"""The live page of a flight (`--web` on `gcs-swarm run` and `console`, docs/replay.md).

The flight thread never builds a message. After each tick, once its commands are out (MissionRunner.on_tick),
`LiveFeed.offer` copies what the page shows into an immutable `LiveSnapshot` (numpy copies), at most RATE_HZ
times a second, and puts it in a one-slot `Handoff` (latest wins). During the blocking waits of a run (the
climb, the landing, a console command), when no tick has offered for a while, the fleet's pump hook offers
instead. The server (`LiveServer`: its own thread, its own asyncio loop, server.py's app) wakes on each new
snapshot, turns it into one frame (messages.py) and sends it to every page.

Operator actions from the page (`--web-token`): `action_refusal` decides whether one may be tried (a token
given on the command line and the same token from the page, one of ACTION_VERBS); the `Operator` the console
gives (gcs_swarm.console.page_actions) runs it through the console's own parsing, refusals and handlers.
"""

from __future__ import annotations

import asyncio
import contextlib
import hmac
import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from aiohttp import WSMsgType, web

from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.autopilots import AutopilotDialect
from gcs_swarm.mission import Mission
from gcs_swarm.web.messages import frame_message, live_frame_message, scene_message, view_bounds
from gcs_swarm.web.replay import event_entry
from gcs_swarm.web.server import make_app, parse_address, serve

RATE_HZ = 20.0  # snapshots (and frames) a second at most
WAITING_S = 0.1  # s without a tick's offer after which the pump hook offers (a blocking wait)
ACTION_VERBS = ("land", "rtl", "hold", "rejoin", "leader")  # the console's verbs a page may send
ACTION_WAIT_S = 60.0  # s a page's action may take on the flight thread before the page is told it is pending
START_S = 30.0  # s the server may take to listen


@dataclass(frozen=True)
class LiveSnapshot:
    """What the page shows of one moment, copied on the flight thread. stamp: s since 1970 (wall clock) of
    the copy; t: vehicle time s; pos (N, 3) m ENU; yaw (N,) rad ENU; slots (N, 2) m ENU (NaN rows: no slot);
    modes (N,) custom_mode numbers and the dialect naming each; alive, taken (N,) bool; link (N, 2) bytes/s
    up, down; budget bytes/s or None; leader index; goal (3,) m ENU (the last waypoint); formation_rms m;
    formation_s: s since formation flight began (None before); events: the flight's event sentences; the
    mission flown (frozen: shared, not copied)."""

    mission: Mission
    stamp: float
    t: float
    phase: str
    pos: np.ndarray
    yaw: np.ndarray
    slots: np.ndarray
    modes: np.ndarray
    dialects: tuple[AutopilotDialect, ...]
    alive: np.ndarray
    taken: np.ndarray
    link: np.ndarray
    budget: float | None
    leader: int
    goal: np.ndarray
    formation_rms: float
    formation_s: float | None
    events: tuple[str, ...]

    def __post_init__(self) -> None:
        for name in ("pos", "yaw", "slots", "modes", "alive", "taken", "link", "goal"):
            getattr(self, name).flags.writeable = False  # copies the server only reads


def take_snapshot(runner: MissionRunner, events: tuple[str, ...]) -> LiveSnapshot:
    """The copy of `runner`'s state the page needs, now; `events`: the flight's event sentences as a tuple
    (LiveFeed keeps it, rebuilt only when the list grew)."""
    fleet, ctl = runner.fleet, runner.controller
    cmd = runner.last_command if runner.phase.in_formation else None
    slots = np.full((len(fleet.links), 2), np.nan) if cmd is None else cmd.slots[:, :2].copy()
    has_time = bool((fleet.state.time_ms >= 0).any())
    t = runner.vehicle_time() if has_time else 0.0
    start = runner.result.t_formation_start
    return LiveSnapshot(
        mission=runner.mission,
        stamp=time.time(),
        t=t,
        phase=str(runner.phase),
        pos=fleet.pos.copy(),
        yaw=fleet.att[:, 2].copy(),
        slots=slots,
        modes=fleet.state.mode.copy(),
        dialects=tuple(fleet.dialects),
        alive=fleet.alive.copy(),
        taken=runner.takeover.taken.copy(),
        link=fleet.link_use.rate.copy(),
        budget=fleet.link_use.budget_B_s,
        leader=int(ctl.leader),
        goal=np.array(ctl.waypoints[-1], dtype=float),
        formation_rms=float(runner.formation_rms),
        formation_s=None if start is None else t - start,
        events=events,
    )


class Handoff:
    """One slot between the flight thread and the server: `put` replaces what it holds (latest wins) and
    calls the waker the server set; `latest` reads it. Thread-safe by construction: one reference is written
    and read whole."""

    def __init__(self) -> None:
        self._slot: LiveSnapshot | None = None
        self._wake: Callable[[], None] | None = None

    def put(self, snapshot: LiveSnapshot) -> None:
        self._slot = snapshot
        wake = self._wake
        if wake is not None:
            wake()

    def latest(self) -> LiveSnapshot | None:
        return self._slot

    def on_put(self, wake: Callable[[], None] | None) -> None:
        """Call `wake` (from the putting thread) after each put; None: nobody to wake."""
        self._wake = wake


class LiveFeed:
    """The flight thread's side: offers a snapshot of the runner to `handoff` at most RATE_HZ times a
    second, after ticks (`attach` sets MissionRunner.on_tick) and inside blocking waits (Fleet.on_pump,
    chained after the hook already there) when no tick has offered for WAITING_S."""

    def __init__(self, runner: MissionRunner, handoff: Handoff, rate_hz: float = RATE_HZ) -> None:
        self.runner = runner
        self.handoff = handoff
        self.period_s = 1.0 / rate_hz
        self._last_copy = -np.inf  # time.monotonic() of the last snapshot
        self._last_tick = -np.inf  # time.monotonic() of the last offer after a tick
        self._events: tuple[str, ...] = ()

    def attach(self) -> None:
        """Hook the feed into the runner's ticks and its fleet's pump."""
        self.runner.on_tick = self.after_tick
        previous = self.runner.fleet.on_pump

        def while_waiting() -> None:
            if previous is not None:
                previous()
            self.while_waiting()

        self.runner.fleet.on_pump = while_waiting

    def after_tick(self) -> None:
        self._last_tick = time.monotonic()
        self._offer(self._last_tick)

    def while_waiting(self) -> None:
        now = time.monotonic()
        if now - self._last_tick >= WAITING_S:
            self._offer(now)

    def _offer(self, now: float) -> None:
        if now - self._last_copy < self.period_s:
            return
        self._last_copy = now
        events = self.runner.result.events
        if len(events) != len(self._events):
            self._events = tuple(events)
        self.handoff.put(take_snapshot(self.runner, self._events))


class Operator(Protocol):
    """Whoever carries out the page's actions (the console: gcs_swarm.console.page_actions)."""

    def act(self, line: str) -> tuple[bool, list[str]]:
        """Run one command line as the console would; (obeyed, the sentences saying what happened or why
        not). Blocks until the flight thread has run it."""
        ...


def action_refusal(message: dict[str, Any], token: str | None, operator: Operator | None) -> str | None:
    """Why the page's action `message` ({"cmd": "action", "line": ..., "token": ...}) may not be tried, or
    None: an operator to carry it out, a token given with --web-token and the same one in the message, a
    line whose first word is one of ACTION_VERBS. The console then refuses or obeys it as typed."""
    if operator is None:
        return "gcs-swarm run takes no operator commands: fly with gcs-swarm console --web --web-token TOKEN"
    if token is None:
        return "this page is read-only: start the console with --web-token TOKEN to allow actions"
    given = message.get("token")
    if not isinstance(given, str) or not hmac.compare_digest(given.encode(), token.encode()):
        return "wrong or missing token: actions need the token given with --web-token"
    line = message.get("line")
    words = line.split() if isinstance(line, str) else []
    if not words or words[0].lower() not in ACTION_VERBS:
        return f"the page's actions are {', '.join(ACTION_VERBS)} (a line such as 'land left')"
    return None


class LiveSource:
    """The server's side, on its loop: the latest snapshot as the page's messages, built once per snapshot
    (`frame_text`) for every page; the scene for a page that connects."""

    def __init__(self, handoff: Handoff) -> None:
        self.handoff = handoff
        self.version = 0  # snapshots turned into frames so far
        self.frame_text = ""
        self.snapshot: LiveSnapshot | None = None  # the one frame_text shows
        self.changed = asyncio.Condition()
        self._events: list[dict[str, Any]] = []
        self._formation: str | None = None  # the latest reshape's text

    def scene(self, snapshot: LiveSnapshot) -> dict[str, Any]:
        """The scene of the flight `snapshot` is from, with the events so far, viewing the start positions,
        the vehicles where they are and the site."""
        mission = snapshot.mission
        starts = np.array([v.start.position[:2] for v in mission.vehicles]).reshape(-1, 2)
        tracks = np.vstack([starts, snapshot.pos[:, :2]])
        return scene_message(mission, list(self._events), None, view_bounds(mission, tracks))

    async def run(self) -> None:
        """Turn each new snapshot into `frame_text` and wake the pages, until cancelled."""
        loop = asyncio.get_running_loop()
        woken = asyncio.Event()

        def wake() -> None:
            with contextlib.suppress(RuntimeError):  # the loop closed: the server is stopping
                loop.call_soon_threadsafe(woken.set)

        self.handoff.on_put(wake)
        try:
            seen: LiveSnapshot | None = None
            while True:
                await woken.wait()
                woken.clear()
                snapshot = self.handoff.latest()
                if snapshot is None or snapshot is seen:
                    continue
                seen = snapshot
                self.frame_text = json.dumps(self.frame(snapshot))
                self.snapshot = snapshot
                async with self.changed:
                    self.version += 1
                    self.changed.notify_all()
        finally:
            self.handoff.on_put(None)

    def frame(self, s: LiveSnapshot) -> dict[str, Any]:
        """The live frame of snapshot s (messages.live_frame_message); new events join the scene's list."""
        first = len(self._events)
        new = [event_entry(sentence) for sentence in s.events[first:]]
        self._events += new
        for event in new:
            if event["kind"] == "reshape":
                self._formation = event["text"]
        modes: list[str | None] = [d.mode_name(int(m)) for d, m in zip(s.dialects, s.modes, strict=True)]
        frame = frame_message(
            s.t, s.pos, s.yaw, s.slots, modes, ~s.alive, np.zeros(len(s.pos), dtype=bool), s.leader,
            s.phase, self._formation, None,
        )  # fmt: skip
        progress = {
            "leader_to_goal_m": float(np.linalg.norm(s.pos[s.leader] - s.goal)),
            "formation_rms_m": s.formation_rms,
            "formation_s": s.formation_s,
        }
        return live_frame_message(frame, s.stamp, s.taken, s.link, s.budget, progress, new, first)


class LiveSession:
    """Serves one page a live flight: the scene, the latest frame, then every new one; the page's actions
    checked (action_refusal) and carried out by the operator, each answered with an `action` message."""

    def __init__(self, source: LiveSource, operator: Operator | None, token: str | None) -> None:
        self.source = source
        self.operator = operator
        self.token = token
        self.pages: set[web.WebSocketResponse] = set()

    async def __call__(self, ws: web.WebSocketResponse) -> None:
        self.pages.add(ws)
        reader = asyncio.create_task(self._read(ws))
        source = self.source
        try:
            sent = 0  # frames sent: the scene goes with the first (the flight's, once it has begun)
            while True:
                async with source.changed:
                    while source.version == sent and not ws.closed and not reader.done():
                        await source.changed.wait()
                if ws.closed or reader.done():
                    break
                if sent == 0:
                    snapshot = source.snapshot
                    assert snapshot is not None
                    scene = source.scene(snapshot)
                    scene["actions"] = self.operator is not None and self.token is not None
                    await ws.send_json(scene)
                sent = source.version
                await ws.send_str(source.frame_text)
        except ConnectionResetError:
            pass  # the page went away mid-send
        finally:
            self.pages.discard(ws)
            reader.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await reader

    async def _read(self, ws: web.WebSocketResponse) -> None:
        """The page's messages until its socket closes (then its session is woken to end)."""
        try:
            await self._answer(ws)
        finally:
            async with self.source.changed:
                self.source.changed.notify_all()

    async def _answer(self, ws: web.WebSocketResponse) -> None:
        """The page's actions answered one at a time; anything else refused."""
        async for msg in ws:
            if msg.type != WSMsgType.TEXT:
                continue
            try:
                message = json.loads(msg.data)
            except json.JSONDecodeError:
                message = None
            if not isinstance(message, dict) or message.get("cmd") != "action":
                await ws.send_json({"type": "error", "text": 'a live page sends {"cmd": "action", ...} only'})
                continue
            line = str(message.get("line") or "")
            refused = action_refusal(message, self.token, self.operator)
            if refused is not None or self.operator is None:
                reply = {"type": "action", "line": line, "ok": False, "text": refused}
            else:
                loop = asyncio.get_running_loop()
                ok, texts = await loop.run_in_executor(None, self.operator.act, line)
                reply = {"type": "action", "line": line, "ok": ok, "text": "; ".join(texts)}
            await ws.send_json(reply)

    async def close_pages(self, _app: web.Application | None = None) -> None:
        """Close every page's socket (server shutdown): their sessions then end."""
        for ws in list(self.pages):
            await ws.close()


class LiveServer:
    """The page's server on its own thread and asyncio loop, fed by `handoff`. `start` returns the page's
    URL once it listens (OSError when host:port cannot be bound); `serve_actions` lets the page act with
    `token` through `operator`; `stop` closes the pages and ends the thread."""

    def __init__(self, handoff: Handoff, host: str, port: int, token: str | None = None) -> None:
        self.handoff = handoff
        self.source = LiveSource(handoff)
        self.session = LiveSession(self.source, None, token)
        self.host, self.port = host, port
        self.url = ""
        self._ready = threading.Event()
        self._error: OSError | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._main: asyncio.Task[None] | None = None
        self._thread = threading.Thread(target=self._serve, name="web", daemon=True)

    def watch(self, runner: MissionRunner) -> None:
        """Feed the page from `runner` (LiveFeed.attach); call before it flies."""
        LiveFeed(runner, self.handoff).attach()

    def serve_actions(self, operator: Operator) -> None:
        """The page's actions go to `operator` (still only with the token, action_refusal)."""
        self.session.operator = operator

    def start(self) -> str:
        self._thread.start()
        if not self._ready.wait(START_S):
            raise OSError(f"the page's server did not listen within {START_S:g} s")
        if self._error is not None:
            raise self._error
        return self.url

    def stop(self) -> None:
        loop, main = self._loop, self._main
        if loop is not None and main is not None:
            with contextlib.suppress(RuntimeError):  # the loop has already ended
                loop.call_soon_threadsafe(main.cancel)
        self._thread.join(START_S)

    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            self._main = loop.create_task(self._run())
            loop.run_until_complete(self._main)
        except OSError as exc:
            self._error = exc
        except asyncio.CancelledError:
            pass
        finally:
            self._ready.set()
            loop.close()

    async def _run(self) -> None:
        app = make_app(self.session)
        app.on_shutdown.append(self.session.close_pages)
        frames = asyncio.create_task(self.source.run())

        def ready(url: str) -> None:
            self.url = url
            self._ready.set()

        try:
            await serve(app, self.host, self.port, ready)
        finally:
            frames.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await frames


def start_live_page(address: str, token: str | None) -> LiveServer | None:
    """The page's server listening on `address` (HOST:PORT, server.parse_address), actions allowed with
    `token` once an operator is given; None after printing why it cannot be."""
    if token is not None and not token.strip():
        print("error: --web-token must not be empty")
        return None
    try:
        host, port = parse_address(address)
    except ValueError as exc:
        print(f"error: --web {exc}")
        return None
    server = LiveServer(Handoff(), host, port, token)
    try:
        url = server.start()
    except OSError as exc:
        print(f"error: cannot serve the live page on {host}:{port} ({exc.strerror or exc})")
        return None
    print(f"live page at {url}{'' if token is None else ' (actions with the token)'}", flush=True)
    return server
