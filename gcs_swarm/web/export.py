"""The page's top view drawn into an animation file with matplotlib (the `plot` extra) and nothing else: a
GIF through Pillow (matplotlib's own dependency), an MP4 through ffmpeg when it is installed. The frames are
the page's own frames (Replay.frame), so the file shows what the page shows."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm.evaluation.site_drawing import FENCE_COLOUR, draw_site
from gcs_swarm.mission import Mission
from gcs_swarm.web.replay import Replay

TRAIL_S = 30.0  # s of track behind each vehicle, as the page (static/app.js)
COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2")


class ExportError(Exception):
    """An animation that cannot be written; str(e) is one sentence."""


def export_times(replay: Replay, speed: float, fps: float) -> np.ndarray:
    """The replay times s of the animation's frames: every speed/fps s from the first sample, and the last."""
    t0, t1 = replay.t_span
    times = np.arange(t0, t1, speed / fps)
    return np.append(times, t1) if len(times) == 0 or times[-1] < t1 else times


def _site(ax: Any, scene: dict[str, Any], mission: Mission) -> None:
    """The static site: the geofence circle, the mission's fence, zones, buildings and trees
    (evaluation.site_drawing, as on report.png), waypoints, goal."""
    from matplotlib.patches import Circle

    ax.add_patch(Circle((0, 0), scene["fence"]["radius"], fill=False, ls="--", ec=FENCE_COLOUR))
    draw_site(ax, mission)
    waypoints = np.array(scene["waypoints"])
    ax.plot(waypoints[:, 0], waypoints[:, 1], ":o", color="#2c7", ms=3)
    ax.plot(*scene["goal"], marker="P", color="#1a7f37", ms=12)


def write_animation(replay: Replay, out: Path, speed: float, fps: int = 10) -> int:
    """Write the top view of the whole replay to `out` (.gif, or .mp4 with ffmpeg), at `speed` replay s per
    s of animation; the number of frames written. ExportError when it cannot."""
    suffix = out.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise ExportError(f"{out}: the export is a .gif or an .mp4")
    if not speed > 0 or not fps > 0:
        raise ExportError("--speed and the frame rate must be > 0")
    try:
        from matplotlib import animation
        from matplotlib.figure import Figure
        from matplotlib.patches import Circle
    except ImportError:
        raise ExportError("matplotlib is not installed (pip install 'swarm-gcs[plot]')") from None
    if suffix == ".mp4" and not animation.writers.is_available("ffmpeg"):
        raise ExportError(f"{out}: an .mp4 needs ffmpeg, which is not installed; write a .gif instead")
    if not out.parent.is_dir():
        raise ExportError(f"{out.parent}: no such folder")

    scene = replay.scene()
    names = scene["vehicles"]
    x0, y0, x1, y1 = scene["bounds"]
    height = min(max(8.0 * (y1 - y0) / (x1 - x0), 3.0), 12.0)  # in: the view's aspect, within reason
    fig = Figure(figsize=(8.0, height), dpi=80)
    ax = fig.add_subplot()
    ax.set(xlim=(x0, x1), ylim=(y0, y1), aspect="equal", xlabel="x east (m)", ylabel="y north (m)")
    ax.grid(True, color="#eee")
    _site(ax, scene, replay.mission)
    obstacles = [
        Circle((o["x"], o["y"]), o["r"], fc=(0.35, 0.35, 0.35, 0.45), ec="#444") for o in scene["obstacles"]
    ]
    for patch in obstacles:
        ax.add_patch(patch)
    colours = [COLOURS[i % len(COLOURS)] for i in range(len(names))]
    trails = [
        ax.plot([], [], color=c, alpha=0.5, label=name)[0] for c, name in zip(colours, names, strict=True)
    ]
    ax.legend(loc="upper left", fontsize="small")
    slots = ax.scatter([], [], marker="s", facecolors="none", edgecolors=[], s=40)
    leader = ax.scatter([], [], marker="o", facecolors="none", edgecolors="#e6a700", s=400, linewidths=2)
    arrows = ax.quiver(
        np.zeros(len(names)),
        np.zeros(len(names)),
        np.ones(len(names)),
        np.zeros(len(names)),
        color=colours,
        angles="xy",
        scale_units="inches",
        scale=3.0,
        width=0.008,
        pivot="middle",
    )
    title = ax.set_title("")
    times = export_times(replay, speed, fps)
    k_trail = int(np.ceil(TRAIL_S * fps / speed))  # frames a trail spans
    tracks = np.full((len(times), len(names), 2), np.nan)

    def draw(j: int) -> list[Any]:
        frame = replay.frame(replay.index_at(float(times[j])))
        vehicles = frame["vehicles"]
        xy = np.array(
            [[np.nan if v["x"] is None else v["x"], np.nan if v["y"] is None else v["y"]] for v in vehicles]
        )
        yaw = np.array([0.0 if v["yaw"] is None else v["yaw"] for v in vehicles])
        tracks[j] = xy
        for i, line in enumerate(trails):
            line.set_data(
                tracks[max(j - k_trail, 0) : j + 1, i, 0], tracks[max(j - k_trail, 0) : j + 1, i, 1]
            )
        arrows.set_offsets(np.nan_to_num(xy, nan=-1e9))
        arrows.set_UVC(np.cos(yaw), np.sin(yaw))
        with_slot = [(v["slot"], colours[i]) for i, v in enumerate(vehicles) if v["slot"]]
        slots.set_offsets(np.array([s for s, _ in with_slot]).reshape(-1, 2))
        slots.set_edgecolor([c for _, c in with_slot])
        leader.set_offsets(xy[frame["leader"] : frame["leader"] + 1])
        for patch, centre in zip(obstacles, frame.get("obstacles") or [], strict=False):
            patch.set_center(centre)
        state = "  ".join(p for p in (frame["phase"], frame["formation"]) if p)
        title.set_text(f"{scene['mission']}  t = {frame['t']:.1f} s  {state}")
        return [*trails, arrows, slots, leader, title, *obstacles]

    movie = animation.FuncAnimation(fig, draw, frames=len(times), blit=False)
    writer = animation.PillowWriter(fps=fps) if suffix == ".gif" else animation.FFMpegWriter(fps=fps)
    try:
        movie.save(str(out), writer=writer)
    except OSError as exc:
        raise ExportError(f"{out}: cannot write it ({exc.strerror or exc})") from None
    return len(times)
