"""The console's command language: parsing, validation, completion, help; bad input gives one clear
CommandError and nothing else."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gcs_swarm.console.commands import (
    COMMANDS,
    KNOWN_PARAMS,
    CommandError,
    Request,
    Vocabulary,
    complete,
    help_lines,
    parse,
)

VOCAB = Vocabulary(
    names=("lead", "right", "left"),
    sysids=(1, 2, 3),
    min_altitude=2.0,
    max_altitude=300.0,
    geofence_radius=2000.0,
    obstacles=((60.0, 47.0, 10.0, 4.0),),
)


def ok(line: str) -> Request:
    request = parse(line, VOCAB)
    assert request is not None
    return request


def refused(line: str) -> str:
    with pytest.raises(CommandError) as info:
        parse(line, VOCAB)
    message = str(info.value)
    assert message and "\n" not in message
    return message


def test_blank_lines_and_comments_are_nothing() -> None:
    assert parse("", VOCAB) is None
    assert parse("   ", VOCAB) is None
    assert parse("# a comment", VOCAB) is None


@pytest.mark.parametrize("verb", ["start", "hold", "resume", "abort", "status", "quit"])
def test_plain_commands(verb: str) -> None:
    assert ok(verb).verb == verb
    assert ok(f"  {verb.upper()}  ").verb == verb
    assert verb in refused(f"{verb} now")


def test_aliases() -> None:
    assert ok("exit").verb == "quit"
    assert ok("stop").verb == "abort"


def test_targets_all_name_and_sysid() -> None:
    everyone = ok("arm")
    assert everyone.vehicles == (0, 1, 2) and everyone.every
    assert ok("arm all").vehicles == (0, 1, 2)
    assert ok("land right").vehicles == (1,) and not ok("land right").every
    assert ok("rtl 3").vehicles == (2,)
    message = refused("disarm banana")
    assert "banana" in message and "lead (1)" in message
    assert "'9'" in refused("arm 9")


def test_mavproxy_forms() -> None:
    assert ok("arm throttle").verb == "arm"
    assert ok("arm throttle left").vehicles == (2,)
    request = ok("mode GUIDED")
    assert (request.verb, request.name, request.every) == ("mode", "GUIDED", True)
    assert ok("mode loiter 2").name == "LOITER"
    alone = ok("guided lead")
    assert (alone.verb, alone.name, alone.vehicles) == ("mode", "GUIDED", (0,))
    assert "did you mean GUIDED" in refused("mode GUIDD")


def test_takeoff_altitude_checked() -> None:
    request = ok("takeoff 10 lead")
    assert (request.value, request.vehicles) == (10.0, (0,))
    assert request.needs_confirmation
    assert "outside 0..300" in refused("takeoff -5")
    assert "outside 0..300" in refused("takeoff 500")
    assert "must be a number" in refused("takeoff high")
    assert "finite" in refused("takeoff nan")
    assert "usage" in refused("takeoff")


def test_goal_checked_against_the_envelope() -> None:
    assert ok("goal 40 -30 10").point == (40.0, -30.0, 10.0)
    assert "usage: goal X Y Z" in refused("goal 1 2")
    assert "altitude band" in refused("goal 1 2 1")
    assert "geofence" in refused("goal 3000 0 10")
    assert "inside obstacle 0" in refused("goal 60 47 11")
    assert "goal y must be a number" in refused("goal 1 north 10")


def test_formation() -> None:
    request = ok("formation line 12")
    assert (request.name, request.value) == ("line", 12.0)
    assert ok("formation V").value is None
    assert "unknown formation shape" in refused("formation hexagon")
    assert "> 0 m" in refused("formation v -1")


def test_param_forms() -> None:
    got = ok("param get mot_thst_hover lead")
    assert (got.verb, got.name, got.vehicles) == ("param_get", "MOT_THST_HOVER", (0,))
    assert ok("param show RTL_ALT").verb == "param_get"
    put = ok("param set GUID_OPTIONS 8 2")
    assert (put.verb, put.name, put.value, put.vehicles) == ("param_set", "GUID_OPTIONS", 8.0, (1,))
    assert ok("param fetch").verb == "param_fetch"
    assert "usage: param" in refused("param")
    assert "usage: param" in refused("param set RTL_ALT")
    assert "1-16" in refused("param get THIS_NAME_IS_FAR_TOO_LONG")
    assert "must be a number" in refused("param set RTL_ALT x")


def test_wait_forms() -> None:
    assert ok("wait 2.5").value == 2.5
    phase = ok("wait phase formation 30")
    assert (phase.verb, phase.name, phase.value) == ("wait_phase", "formation", 30.0)
    assert "unknown phase" in refused("wait phase cruising")
    assert ">= 0" in refused("wait -1")


def test_help() -> None:
    assert ok("help").name == ""
    assert ok("help goal").name == "goal"
    assert "no help" in refused("help flying")
    everything = "\n".join(help_lines())
    for verb in COMMANDS:
        assert verb in everything
    assert any("GUIDED" in line for line in help_lines("mode"))


def test_unknown_commands_and_unreadable_lines() -> None:
    assert "unknown command 'fly'" in refused("fly away")
    assert "did you mean start" in refused("strat")
    assert "cannot read" in refused('goal "1 2 3')


def test_confirmation_needed_for_arming_and_launching() -> None:
    assert {v for v in ("start", "arm", "takeoff 5", "hold", "land") if ok(v).needs_confirmation} == {
        "start",
        "arm",
        "takeoff 5",
    }


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=60))
def test_any_text_parses_or_gives_a_command_error(line: str) -> None:
    try:
        parse(line, VOCAB)
    except CommandError as exc:
        assert str(exc)


@settings(max_examples=200, deadline=None)
@given(
    st.sampled_from([*COMMANDS, "param", "mode", "guided"]),
    st.lists(
        st.sampled_from(["all", "lead", "7", "-3", "1e400", "x", "get", "set", "phase", "v", ""]), max_size=4
    ),
)
def test_command_words_with_any_arguments_parse_or_refuse(verb: str, args: list[str]) -> None:
    line = " ".join([verb, *args])
    try:
        parse(line, VOCAB)
    except CommandError:
        pass
    assert isinstance(complete(line, VOCAB), list)


def test_completion_of_commands_and_arguments() -> None:
    assert complete("", VOCAB)[: len(COMMANDS)] == list(COMMANDS)
    assert complete("st", VOCAB) == ["start", "status", "stabilize", "stabilized"]  # ArduCopter, PX4
    assert complete("arm ", VOCAB) == ["throttle", "all", "lead", "right", "left", "1", "2", "3"]
    assert complete("arm throttle l", VOCAB) == ["lead", "left"]
    assert complete("mode gu", VOCAB) == ["GUIDED", "GUIDED_NOGPS"]
    assert complete("mode GUIDED r", VOCAB) == ["right"]
    assert complete("param ", VOCAB) == ["get", "set", "fetch", "show"]
    assert complete("param get MOT", VOCAB) == ["MOT_THST_HOVER"]
    assert complete("param set RTL_ALT 15 ", VOCAB)[:2] == ["all", "lead"]
    assert complete("formation ", VOCAB) == ["line", "v", "column", "grid"]
    assert complete("wait phase f", VOCAB) == ["formation"]
    assert complete("help go", VOCAB) == ["goal"]
    assert complete("goal 1 ", VOCAB) == []


def test_completion_uses_fetched_parameter_names() -> None:
    fetched = Vocabulary(names=("a",), sysids=(1,), params=("ZZ_ONE", "ZZ_TWO"))
    assert complete("param get ZZ", fetched) == ["ZZ_ONE", "ZZ_TWO"]
    assert complete("param get ZZ", VOCAB) == []
    assert "RTL_ALT" in KNOWN_PARAMS
