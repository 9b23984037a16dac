"""The swarm in a browser (docs/replay.md): one page, every asset in `static/`, fed over a WebSocket.

`messages.py` is what the page reads (a scene once, then frames), `replay.py` turns a run folder into those
messages, `player.py` plays them (play, pause, speed, seek), `server.py` serves the page and the socket
(aiohttp), `export.py` draws the same top view into a GIF or MP4 with matplotlib.
"""
