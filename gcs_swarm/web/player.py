"""Playing a recorded run to one page: play, pause, speed and seek over a `Replay` (replay.py), and the
WebSocket session that sends its messages (messages.py) and obeys the page's commands."""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
from typing import Any

from aiohttp import WSMsgType, web

from gcs_swarm.web.replay import Replay

UPDATE_S = 0.05  # s of wall time between frames while playing: 20 updates a second
MAX_SPEED = 1000.0  # replay s per wall s


class ReplayPlayer:
    """Where one page is in a replay: t (replay time, s), playing, speed (replay s per wall s)."""

    def __init__(self, replay: Replay, speed: float, playing: bool = True) -> None:
        self.replay = replay
        self.t0, self.t1 = replay.t_span
        self.t = self.t0
        self.speed = speed
        self.playing = playing and self.t1 > self.t0

    def advance(self, wall_s: float) -> None:
        """Move on by wall_s of wall time when playing; stop at the end."""
        if not self.playing:
            return
        self.t = min(self.t + wall_s * self.speed, self.t1)
        if self.t >= self.t1:
            self.playing = False

    def command(self, message: Any) -> str | None:
        """Obey one page command ({"cmd": "play" | "pause" | "speed" + "value" | "seek" + "t"}); the
        sentence why not when it is refused (the state unchanged)."""
        if not isinstance(message, dict) or not isinstance(message.get("cmd"), str):
            return 'a command is a JSON object with "cmd"'
        cmd = message["cmd"]
        if cmd == "play":
            if self.t >= self.t1:
                self.t = self.t0  # play at the end: from the start again
            self.playing = self.t1 > self.t0
        elif cmd == "pause":
            self.playing = False
        elif cmd in ("speed", "seek"):
            key = "value" if cmd == "speed" else "t"
            value = message.get(key)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                return f'"{cmd}" needs a number "{key}"'
            if cmd == "speed":
                if not 0 < value <= MAX_SPEED:
                    return f"speed must be > 0 and <= {MAX_SPEED:g}"
                self.speed = float(value)
            else:
                self.t = min(max(float(value), self.t0), self.t1)
        else:
            return f"unknown command {cmd!r} (play, pause, speed, seek)"
        return None

    def status(self) -> dict[str, Any]:
        return {"type": "status", "playing": self.playing, "speed": self.speed, "t": round(self.t, 3)}

    def index(self) -> int:
        return self.replay.index_at(self.t)


_CLOSED = object()  # the page's socket closed
_NOTHING = object()  # no command within UPDATE_S: time passes


async def _read_commands(ws: web.WebSocketResponse, inbox: asyncio.Queue[Any]) -> None:
    """Every text message of the page into `inbox`, parsed (text that is not JSON goes in as text, which
    ReplayPlayer.command refuses); _CLOSED when the socket closes."""
    async for msg in ws:
        if msg.type == WSMsgType.TEXT:
            try:
                await inbox.put(json.loads(msg.data))
            except json.JSONDecodeError:
                await inbox.put(msg.data)
    await inbox.put(_CLOSED)


class ReplaySession:
    """Serves one page a replay: the scene, then frames as the player moves; a status and the frame after
    each command obeyed, a status when playing stops at the end, an error for each command refused."""

    def __init__(self, replay: Replay, speed: float) -> None:
        self.replay = replay
        self.speed = speed
        self._scene = replay.scene()  # the same for every page

    async def __call__(self, ws: web.WebSocketResponse) -> None:
        player = ReplayPlayer(self.replay, self.speed)
        loop = asyncio.get_running_loop()
        inbox: asyncio.Queue[Any] = asyncio.Queue()
        reader = asyncio.create_task(_read_commands(ws, inbox))
        try:
            await ws.send_json(self._scene)
            await ws.send_json(player.status())
            sent = player.index()
            await ws.send_json(self.replay.frame(sent))
            last = loop.time()
            while not ws.closed:
                try:
                    message = await asyncio.wait_for(inbox.get(), UPDATE_S)
                except TimeoutError:
                    message = _NOTHING
                if message is _CLOSED:
                    break
                now = loop.time()
                was_playing = player.playing
                player.advance(now - last)
                last = now
                refused = None if message is _NOTHING else player.command(message)
                if refused:
                    await ws.send_json({"type": "error", "text": refused})
                obeyed = message is not _NOTHING and not refused
                if obeyed or player.playing != was_playing:
                    await ws.send_json(player.status())
                if player.index() != sent or obeyed:
                    sent = player.index()
                    await ws.send_json(self.replay.frame(sent))
        except ConnectionResetError:
            pass  # the page went away mid-send
        finally:
            reader.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await reader
