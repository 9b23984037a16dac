"""Play, pause, speed and seek of one page (ReplayPlayer) over the hand-written run folder (t 0..2 s)."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_swarm.web.player import ReplayPlayer
from gcs_swarm.web.replay import load_replay


@pytest.fixture
def player(run_dir: Path) -> ReplayPlayer:
    return ReplayPlayer(load_replay(run_dir), speed=2.0)


def test_playing_moves_speed_times_the_wall_time_and_stops_at_the_end(player: ReplayPlayer) -> None:
    assert (player.t, player.playing) == (0.0, True)
    player.advance(0.3)  # 0.3 s of wall time at 2x: 0.6 s
    assert player.t == pytest.approx(0.6) and player.index() == 0
    player.advance(0.25)  # 1.1 s: the sample of 1.0 s
    assert player.t == pytest.approx(1.1) and player.index() == 1
    player.advance(10.0)
    assert (player.t, player.playing, player.index()) == (2.0, False, 2)
    assert player.command({"cmd": "play"}) is None  # at the end: from the start again
    assert (player.t, player.playing) == (0.0, True)


def test_pause_holds_and_seek_clamps_to_the_run(player: ReplayPlayer) -> None:
    assert player.command({"cmd": "pause"}) is None
    player.advance(5.0)
    assert (player.t, player.playing) == (0.0, False)
    assert player.command({"cmd": "seek", "t": 1.7}) is None
    assert (player.t, player.index()) == (1.7, 1)
    assert player.command({"cmd": "seek", "t": -3}) is None and player.t == 0.0
    assert player.command({"cmd": "seek", "t": 30}) is None and player.t == 2.0
    assert player.command({"cmd": "speed", "value": 0.5}) is None and player.speed == 0.5
    assert player.status() == {"type": "status", "playing": False, "speed": 0.5, "t": 2.0}


@pytest.mark.parametrize(
    "command",
    [
        None,
        "play",
        [],
        {},
        {"cmd": "rewind"},
        {"cmd": "speed"},
        {"cmd": "speed", "value": 0},
        {"cmd": "speed", "value": -1},
        {"cmd": "speed", "value": 1e9},
        {"cmd": "speed", "value": True},
        {"cmd": "seek", "t": "1"},
        {"cmd": "seek", "t": float("nan")},
        {"cmd": 3},
    ],
)
def test_a_bad_command_is_refused_in_a_sentence_and_changes_nothing(
    player: ReplayPlayer, command: object
) -> None:
    before = player.status()
    refusal = player.command(command)
    assert isinstance(refusal, str) and refusal
    assert player.status() == before
