"""The page's web server (aiohttp): GET / is the page, /static/* its assets (all in the package: the page
works offline), /ws the WebSocket a session (player.ReplaySession now, a live flight later) feeds. Binds to
loopback unless told otherwise."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from pathlib import Path

from aiohttp import web

STATIC = Path(__file__).parent / "static"
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765

Session = Callable[[web.WebSocketResponse], Awaitable[None]]


def make_app(session: Session) -> web.Application:
    """The page, its assets and its socket; `session` serves each page that connects."""

    async def page(_request: web.Request) -> web.FileResponse:
        return web.FileResponse(STATIC / "index.html")

    async def socket(request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=20.0)
        await ws.prepare(request)
        await session(ws)
        await ws.close()
        return ws

    app = web.Application()
    app.router.add_get("/", page)
    app.router.add_get("/ws", socket)
    app.router.add_static("/static", STATIC)
    return app


async def serve(app: web.Application, host: str, port: int, ready: Callable[[str], None]) -> None:
    """Serve `app` on host:port (port 0: one the system picks) until cancelled; `ready` gets the page's URL
    once the socket listens. OSError if the address cannot be bound."""
    runner = web.AppRunner(app)
    await runner.setup()
    try:
        site = web.TCPSite(runner, host, port)
        await site.start()
        bound = runner.addresses[0][1]  # (host, port, ...) of the first listening socket
        shown = f"[{host}]" if ":" in host else host
        ready(f"http://{shown}:{bound}/")
        await asyncio.Event().wait()
    finally:
        await runner.cleanup()


def parse_address(text: str) -> tuple[str, int]:
    """`--web`'s HOST:PORT, HOST, :PORT or PORT (IPv6 as [HOST]:PORT) -> (host, port), DEFAULT_HOST and
    DEFAULT_PORT where left out; ValueError (one sentence) otherwise."""
    host, port = text.strip(), ""
    if host.startswith("["):  # [::1]:8765
        host, _, rest = host[1:].partition("]")
        port = rest.removeprefix(":")
    elif host.isdigit():
        host, port = "", host
    elif host.count(":") == 1:
        host, port = host.split(":")
    if port and not (port.isdigit() and 0 <= int(port) <= 65535):
        raise ValueError(f"{text!r}: the port must be a number 0..65535 (0: any free one)")
    return host or DEFAULT_HOST, int(port) if port else DEFAULT_PORT
