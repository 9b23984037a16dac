"""world.link.step_down (docs/command-modes.md "In flight"): what a valid file gives the command-mode watch,
the defaults when it is left out, and one error per mistake naming the file, the line and the key."""

from __future__ import annotations

from pathlib import Path

import pytest

from gcs_swarm.flight.fly import mission_fleet
from gcs_swarm.link.command_mode import StepDown
from gcs_swarm.mission import parse_mission
from tests.gcs_swarm.mission.test_mission import MINIMAL, error_of


def test_left_out_the_watch_keeps_the_defaults_of_the_flights_before() -> None:
    """The defaults are the thresholds the watch had as constants: 0.15 s of queueing, 2 windows of 1 s."""
    step_down = parse_mission(MINIMAL).link.step_down
    assert step_down == StepDown(enabled=True, queue_age_s=0.15, after_s=2)
    assert step_down.windows == 2
    assert parse_mission(MINIMAL + "world: {link: {step_down: }}\n").link.step_down == step_down


def test_the_keys_reach_the_mission_as_written() -> None:
    text = MINIMAL + "world:\n  link:\n    step_down: {enabled: false, queue_age_s: 0.4, after_s: 3}\n"
    step_down = parse_mission(text).link.step_down
    assert step_down == StepDown(enabled=False, queue_age_s=0.4, after_s=3)
    assert step_down.windows == 3  # 3 s of 1 s windows
    assert parse_mission(
        MINIMAL + "world: {link: {step_down: {queue_age_s: 1}}}\n"
    ).link.step_down == StepDown(queue_age_s=1.0)


def test_the_mission_s_keys_reach_the_fleet_s_watch(tmp_path: Path) -> None:
    """`gcs-swarm run` and the console build their fleet with mission_fleet: its CommandModeWatch judges
    with the mission's keys."""
    mission = parse_mission(MINIMAL + "world: {link: {step_down: {enabled: false, after_s: 4}}}\n")
    fleet = mission_fleet(mission, None, tmp_path, None)
    try:
        assert fleet.command_watch.step_down == StepDown(enabled=False, after_s=4)
    finally:
        fleet.close()


@pytest.mark.parametrize(
    ("text", "field", "fragment"),
    [
        (MINIMAL + "world: {link: {step_down: {queue_age_s: 0}}}  # <-\n", "queue_age_s", "must be > 0 s"),
        (MINIMAL + "world: {link: {step_down: {queue_age_s: 9}}}  # <-\n", "queue_age_s", "must be <= 5 s"),
        (MINIMAL + "world: {link: {step_down: {queue_age_s: '0.2'}}}  # <-\n", "queue_age_s", "number"),
        (MINIMAL + "world: {link: {step_down: {after_s: 0}}}  # <-\n", "after_s", "must be >= 1 s"),
        (MINIMAL + "world: {link: {step_down: {after_s: 61}}}  # <-\n", "after_s", "must be <= 60 s"),
        (MINIMAL + "world: {link: {step_down: {after_s: 1.5}}}  # <-\n", "after_s", "whole"),
        (MINIMAL + "world: {link: {step_down: {enabled: 0}}}  # <-\n", "enabled", "true or"),
        (MINIMAL + "world: {link: {step_down: {after: 3}}}  # <-\n", "after", "did you mean 'after_s'?"),
        (MINIMAL + "world: {link: {step_down: false}}  # <-\n", "", "expected a mapping"),
    ],
)
def test_each_step_down_mistake_names_file_line_and_key(text: str, field: str, fragment: str) -> None:
    line = next(i for i, content in enumerate(text.splitlines(), 1) if "# <-" in content)
    message = error_of(text, "missions/bad.yaml")
    key = "world.link.step_down" + (f".{field}" if field else "")
    assert message.startswith(f"missions/bad.yaml:{line}: {key}: "), message
    assert fragment in message, message
    assert "\n" not in message.strip()  # one sentence, one line
