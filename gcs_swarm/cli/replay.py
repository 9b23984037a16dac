"""`gcs-swarm replay RUN_DIR`: the page of gcs_swarm.web over a recorded run folder, or `--export` an
animation of its top view (docs/replay.md)."""

from __future__ import annotations

import asyncio
from pathlib import Path

from gcs_swarm.web.replay import RunFolderError, load_replay

EXIT_USER_ERROR = 2
SERVE_SPEED = 1.0  # replay s per wall s on the page unless --speed says otherwise
EXPORT_SPEED = 4.0  # replay s per s of animation unless --speed says otherwise
EXPORT_FPS = 10  # frames per s of animation


def replay_command(
    run_dir: Path,
    mission: Path | None,
    host: str,
    port: int,
    speed: float | None,
    export: Path | None,
) -> int:
    """Serve the replay page until Ctrl-C, or write the export; 2 with one sentence on a bad run folder,
    address or export."""
    if speed is not None and not speed > 0:
        print("error: --speed must be > 0")
        return EXIT_USER_ERROR
    try:
        replay = load_replay(run_dir, mission)
    except RunFolderError as exc:
        print(f"error: {exc}")
        return EXIT_USER_ERROR
    if export is not None:
        from gcs_swarm.web.export import ExportError, write_animation

        try:
            frames = write_animation(replay, export, speed or EXPORT_SPEED, EXPORT_FPS)
        except ExportError as exc:
            print(f"error: {exc}")
            return EXIT_USER_ERROR
        print(f"{export}: {frames} frames at {EXPORT_FPS:g} per s, {speed or EXPORT_SPEED:g}x")
        return 0
    from gcs_swarm.web.player import ReplaySession
    from gcs_swarm.web.server import make_app, serve

    app = make_app(ReplaySession(replay, speed or SERVE_SPEED))
    t0, t1 = replay.t_span
    print(f"{run_dir}: {len(replay.mission.vehicles)} vehicles, t {t0:.1f}..{t1:.1f} s ({replay.source})")

    def ready(url: str) -> None:
        print(f"replay at {url} (Ctrl-C stops)", flush=True)

    try:
        asyncio.run(serve(app, host, port, ready))
    except OSError as exc:
        print(f"error: cannot serve on {host}:{port} ({exc.strerror or exc})")
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        pass
    return 0
