"""`gcs-swarm replay --export`: an animation of the hand-written run folder (t 0..2 s) with matplotlib."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from PIL import Image

from gcs_swarm.cli import main
from gcs_swarm.web.export import ExportError, export_times, write_animation
from gcs_swarm.web.replay import load_replay


def test_the_frames_fall_every_speed_over_fps_seconds_and_end_on_the_last_sample(run_dir: Path) -> None:
    replay = load_replay(run_dir)
    # 2 s at 1x and 10 frames per s: 0.0, 0.1, ..., 1.9, then 2.0: 21 frames
    assert export_times(replay, 1.0, 10) == pytest.approx([k / 10 for k in range(21)])
    assert export_times(replay, 4.0, 10) == pytest.approx([0.0, 0.4, 0.8, 1.2, 1.6, 2.0])


def test_a_gif_of_the_run(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run.gif"
    assert main(["replay", str(run_dir), "--export", str(out), "--speed", "1"]) == 0
    assert capsys.readouterr().out == f"{out}: 21 frames at 10 per s, 1x\n"
    with Image.open(out) as gif:
        assert gif.format == "GIF"
        # Pillow merges identical consecutive frames; the three samples differ, so at least three remain
        assert getattr(gif, "n_frames", 1) >= 3


@pytest.mark.parametrize(
    ("name", "says"),
    [("run.avi", "a .gif or an .mp4"), ("missing/run.gif", "no such folder")],
)
def test_an_export_that_cannot_be_written_is_one_error(
    run_dir: Path, tmp_path: Path, name: str, says: str
) -> None:
    with pytest.raises(ExportError, match=says):
        write_animation(load_replay(run_dir), tmp_path / name, 1.0)


@pytest.mark.skipif(shutil.which("ffmpeg") is not None, reason="ffmpeg is installed: an mp4 can be written")
def test_an_mp4_without_ffmpeg_says_so(run_dir: Path, tmp_path: Path) -> None:
    with pytest.raises(ExportError, match="needs ffmpeg"):
        write_animation(load_replay(run_dir), tmp_path / "run.mp4", 1.0)


def test_a_bad_speed_is_refused(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(run_dir), "--export", str(tmp_path / "a.gif"), "--speed", "0"]) == 2
    assert capsys.readouterr().out == "error: --speed must be > 0\n"
