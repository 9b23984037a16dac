"""The page's server on a real loopback socket (port 0: the system picks a free one): the page and its
assets over HTTP, and a WebSocket client that reads the scene and frames, pauses, seeks and is refused.
Receives are bounded (RECEIVE_S) so that a broken server fails the test instead of hanging it; no assertion
is about time."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import aiohttp

from gcs_swarm.web.player import ReplaySession
from gcs_swarm.web.replay import load_replay
from gcs_swarm.web.server import STATIC, make_app, serve

RECEIVE_S = 60.0  # s: a hang guard only


async def _next(ws: aiohttp.ClientWebSocketResponse, kind: str) -> dict[str, Any]:
    """The next message of type `kind` (others skipped)."""
    while True:
        message = await ws.receive_json(timeout=RECEIVE_S)
        if message["type"] == kind:
            return message


async def _session(run_dir: Path) -> dict[str, Any]:
    app = make_app(ReplaySession(load_replay(run_dir), speed=1.0))
    urls: asyncio.Queue[str] = asyncio.Queue()
    server = asyncio.create_task(serve(app, "127.0.0.1", 0, urls.put_nowait))
    seen: dict[str, Any] = {}
    try:
        url = await asyncio.wait_for(urls.get(), RECEIVE_S)
        async with aiohttp.ClientSession() as http:
            async with http.get(url) as page:
                seen["page"] = (page.status, await page.text())
            async with http.get(url + "static/app.js") as script:
                seen["script"] = (script.status, await script.text())
            async with http.ws_connect(url + "ws") as ws:
                seen["scene"] = await _next(ws, "scene")
                seen["first_status"] = await _next(ws, "status")
                frames: list[dict[str, Any]] = []
                statuses: list[dict[str, Any]] = []
                while not (frames and frames[-1]["t"] == 2.0 and statuses):  # playing at 1x to the end
                    message = await ws.receive_json(timeout=RECEIVE_S)
                    {"frame": frames, "status": statuses}[message["type"]].append(message)
                seen["played"] = [f["t"] for f in frames]
                seen["end_status"] = statuses[-1]
                await ws.send_json({"cmd": "seek", "t": 1.4})
                seen["seek_status"] = await _next(ws, "status")
                seen["seek_frame"] = await _next(ws, "frame")
                await ws.send_json({"cmd": "speed", "value": -2})
                seen["refusal"] = await _next(ws, "error")
                await ws.send_str("not json")
                seen["refusal_text"] = await _next(ws, "error")
                await ws.send_json({"cmd": "play"})
                seen["play_status"] = await _next(ws, "status")
                await ws.send_json({"cmd": "pause"})
                seen["pause_status"] = await _next(ws, "status")
    finally:
        server.cancel()
        await asyncio.gather(server, return_exceptions=True)
    return seen


def test_the_page_its_assets_and_the_socket_over_loopback(run_dir: Path) -> None:
    seen = asyncio.run(_session(run_dir))
    assert seen["page"][0] == 200 and seen["page"][1] == (STATIC / "index.html").read_text()
    assert seen["script"][0] == 200 and "window.swarmState" in seen["script"][1]
    assert seen["scene"]["vehicles"] == ["lead", "right", "left"]
    assert seen["first_status"]["playing"] is True
    played = seen["played"]
    assert played[0] == 0.0 and played[-1] == 2.0 and played == sorted(played)
    assert set(played) == {0.0, 1.0, 2.0}  # every sample shown, none invented
    assert seen["end_status"] == {"type": "status", "playing": False, "speed": 1.0, "t": 2.0}
    assert seen["seek_status"]["t"] == 1.4 and seen["seek_frame"]["t"] == 1.0  # the sample at or before 1.4 s
    assert "speed" in seen["refusal"]["text"] and "JSON object" in seen["refusal_text"]["text"]
    assert seen["play_status"]["playing"] is True
    assert seen["pause_status"]["playing"] is False


def test_a_busy_port_is_one_error(run_dir: Path, capsys: Any) -> None:
    import socket

    from gcs_swarm.cli import main

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["replay", str(run_dir), "--port", str(port)]) == 2
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith(f"error: cannot serve on 127.0.0.1:{port}")
