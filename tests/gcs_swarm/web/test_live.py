"""The live page without a browser or a flight: the one-slot handoff, the token check, `--web`'s address,
and the server on a loopback socket (port 0) fed hand-made snapshots of quickstart's three vehicles, with a
stand-in operator. Receives are bounded (RECEIVE_S) so that a broken server fails instead of hanging; no
assertion is about time."""

from __future__ import annotations

import asyncio
import math
from pathlib import Path
from typing import Any

import aiohttp
import numpy as np
import pytest

from gcs_swarm.link.autopilots import dialect_named
from gcs_swarm.mission import load_mission
from gcs_swarm.web.live import ACTION_VERBS, Handoff, LiveServer, LiveSnapshot, action_refusal
from gcs_swarm.web.server import DEFAULT_HOST, DEFAULT_PORT, parse_address
from tests.gcs_swarm.web.conftest import ROOT

RECEIVE_S = 60.0  # s: a hang guard only
ARDUCOPTER = dialect_named("ardupilot")
GUIDED, LAND = 4, 9  # ArduCopter custom_mode numbers (ArduCopter mode.h: GUIDED = 4, LAND = 9)


def snapshot(t: float, events: tuple[str, ...] = (), stamp: float = 0.0) -> LiveSnapshot:
    """quickstart's three vehicles at t s: vehicle i at (t + i, 2 t, 10) m, yaw 0.1 i rad, GUIDED but the
    third in LAND; a slot beside each; the third lost; 100 B/s up and 2000 down each."""
    mission = load_mission(ROOT / "missions" / "quickstart.yaml", to_fly=False)
    n = 3
    return LiveSnapshot(
        mission=mission,
        stamp=stamp,
        t=t,
        phase="formation",
        pos=np.array([[t + i, 2 * t, 10.0] for i in range(n)]),
        yaw=0.1 * np.arange(n),
        slots=np.array([[t + i + 1, 2 * t] for i in range(n)]),
        modes=np.array([GUIDED, GUIDED, LAND]),
        dialects=(ARDUCOPTER,) * n,
        alive=np.array([True, True, False]),
        taken=np.array([False, True, False]),
        link=np.tile([100.0, 2000.0], (n, 1)),
        budget=None,
        leader=0,
        goal=np.array([t + 3.0, 2 * t + 4.0, 10.0]),  # 5 m from the leader at (t, 2 t, 10): 3-4-5
        formation_rms=0.5,
        formation_s=t - 1.0,
        events=events,
    )


def test_the_handoff_keeps_the_latest_and_wakes_on_each_put() -> None:
    handoff = Handoff()
    assert handoff.latest() is None
    woken: list[int] = []
    handoff.on_put(lambda: woken.append(1))
    first, second = snapshot(1.0), snapshot(2.0)
    handoff.put(first)
    handoff.put(second)
    assert handoff.latest() is second and len(woken) == 2  # the first is overwritten: latest wins
    handoff.on_put(None)
    handoff.put(first)
    assert handoff.latest() is first and len(woken) == 2


class _Operator:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def act(self, line: str) -> tuple[bool, list[str]]:
        self.lines.append(line)
        return True, [f"console: {line} done"]


def test_actions_need_an_operator_a_token_and_the_same_token() -> None:
    operator = _Operator()
    ok = {"cmd": "action", "line": "land left", "token": "s3cret"}
    assert "gcs-swarm run takes no operator commands" in str(action_refusal(ok, "s3cret", None))
    assert "read-only" in str(action_refusal(ok, None, operator))
    for token in ("wrong", "", None, 7, "s3cre", "s3cret "):
        refused = action_refusal({**ok, "token": token}, "s3cret", operator)
        assert refused is not None and "token" in refused
    for line in ("arm lead", "start", "", "   ", None, "param set X 1 lead", "mode LAND lead"):
        refused = action_refusal({**ok, "line": line}, "s3cret", operator)
        assert refused is not None and "actions are land, rtl, hold, rejoin, leader" in refused
    for verb in ACTION_VERBS:
        assert action_refusal({**ok, "line": f"{verb} left"}, "s3cret", operator) is None
    assert operator.lines == []  # deciding never acts


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("127.0.0.1:8000", ("127.0.0.1", 8000)),
        ("0.0.0.0:0", ("0.0.0.0", 0)),
        ("9000", (DEFAULT_HOST, 9000)),
        (":9000", (DEFAULT_HOST, 9000)),
        ("example.local", ("example.local", DEFAULT_PORT)),
        ("[::1]:9001", ("::1", 9001)),
        ("[::1]", ("::1", DEFAULT_PORT)),
    ],
)
def test_web_addresses(text: str, expected: tuple[str, int]) -> None:
    assert parse_address(text) == expected


@pytest.mark.parametrize("text", ["host:port", "host:70000", "h:-1", "[::1]:x"])
def test_bad_web_addresses_are_one_sentence(text: str) -> None:
    with pytest.raises(ValueError, match="the port must be a number 0..65535"):
        parse_address(text)


async def _next(ws: aiohttp.ClientWebSocketResponse, kind: str) -> dict[str, Any]:
    while True:
        message = await ws.receive_json(timeout=RECEIVE_S)
        if message["type"] == kind:
            return message


async def _page(url: str, handoff: Handoff, send: list[dict[str, Any]]) -> dict[str, Any]:
    seen: dict[str, Any] = {"replies": []}
    async with aiohttp.ClientSession() as http, http.ws_connect(url + "ws") as ws:
        handoff.put(snapshot(2.0, ("command mode: attitude targets", "t=1.50 s formation narrows: column")))
        seen["scene"] = await _next(ws, "scene")
        seen["first"] = await _next(ws, "frame")
        handoff.put(
            snapshot(3.0, ("command mode: attitude targets", "t=1.50 s formation narrows: column", "x"))
        )
        seen["second"] = await _next(ws, "frame")
        for message in send:
            await ws.send_json(message)
            seen["replies"].append(await _next(ws, "action"))
    return seen


def _serve(token: str | None, operator: _Operator | None, send: list[dict[str, Any]]) -> dict[str, Any]:
    handoff = Handoff()
    server = LiveServer(handoff, "127.0.0.1", 0, token)
    if operator is not None:
        server.serve_actions(operator)
    url = server.start()
    try:
        return asyncio.run(_page(url, handoff, send))
    finally:
        server.stop()


def test_a_page_gets_the_scene_then_each_snapshot_as_a_frame() -> None:
    seen = _serve(None, None, [])
    scene, first, second = seen["scene"], seen["first"], seen["second"]
    assert scene["vehicles"] == ["lead", "right", "left"] and scene["replay"] is False
    assert scene["actions"] is False
    assert [e["kind"] for e in scene["events"]] == ["note", "reshape"] and scene["events"][1]["t"] == 1.5
    # the frame carries the events new when it was built (0 and 1), which the scene has too: the page skips
    # those below its count (app.js onLive)
    assert first["t"] == 2.0 and first["first_event"] == 0 and first["events"] == scene["events"]
    v = first["vehicles"]
    assert [(u["x"], u["y"], u["z"]) for u in v] == [(2.0, 4.0, 10.0), (3.0, 4.0, 10.0), (4.0, 4.0, 10.0)]
    assert [u["mode"] for u in v] == ["GUIDED", "GUIDED", "LAND"]
    assert [u["lost"] for u in v] == [False, False, True] and [u["taken"] for u in v] == [False, True, False]
    assert v[1]["slot"] == [4.0, 4.0] and (v[0]["up"], v[0]["down"]) == (100.0, 2000.0)
    assert first["formation"] == "formation narrows: column"  # the latest reshape event's text
    assert first["progress"] == {"leader_to_goal_m": 5.0, "formation_rms_m": 0.5, "formation_s": 1.0}
    assert second["t"] == 3.0 and second["first_event"] == 2 and second["events"][0]["text"] == "x"
    assert math.isfinite(second["stamp"])


def test_an_action_is_refused_without_the_token_and_carried_out_with_it() -> None:
    operator = _Operator()
    send = [
        {"cmd": "action", "line": "land left"},
        {"cmd": "action", "line": "land left", "token": "nope"},
        {"cmd": "action", "line": "arm left", "token": "t0k"},
        {"cmd": "action", "line": "land left", "token": "t0k"},
    ]
    seen = _serve("t0k", operator, send)
    assert seen["scene"]["actions"] is True
    refused = seen["replies"][:3]
    assert all(r["ok"] is False for r in refused)
    assert (
        "token" in refused[0]["text"]
        and "token" in refused[1]["text"]
        and "actions are" in refused[2]["text"]
    )
    assert seen["replies"][3] == {
        "type": "action",
        "line": "land left",
        "ok": True,
        "text": "console: land left done",
    }
    assert operator.lines == ["land left"]  # only the one with the token reached the operator


def test_without_a_token_the_page_is_read_only() -> None:
    operator = _Operator()
    seen = _serve(None, operator, [{"cmd": "action", "line": "hold", "token": ""}])
    assert seen["scene"]["actions"] is False
    assert "read-only" in seen["replies"][0]["text"] and operator.lines == []


def test_a_busy_or_bad_address_and_a_token_without_the_page_are_one_error_before_flying(
    tmp_path: Path, capsys: Any
) -> None:
    import socket

    from gcs_swarm.cli import main

    mission = str(ROOT / "missions" / "quickstart.yaml")
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["run", mission, "--out", str(tmp_path / "a"), "--web", f"127.0.0.1:{port}"]) == 2
    assert (
        capsys.readouterr()
        .out.splitlines()[-1]
        .startswith(f"error: cannot serve the live page on 127.0.0.1:{port}")
    )
    assert not (tmp_path / "a").exists()  # nothing flew: no run folder
    assert main(["run", mission, "--web", "127.0.0.1:http"]) == 2
    assert "error: --web '127.0.0.1:http': the port must be a number" in capsys.readouterr().out
    assert main(["console", mission, "--web-token", "x"]) == 2
    assert capsys.readouterr().out.strip() == "error: --web-token needs --web (the page it allows actions on)"
    assert main(["console", mission, "--out", str(tmp_path / "b"), "--web", "--web-token", " "]) == 2
    assert capsys.readouterr().out.strip() == "error: --web-token must not be empty"


class _Fleet:
    def __init__(self) -> None:
        self.on_pump: Any = None


class _Runner:
    """What LiveFeed touches of a MissionRunner: on_tick, fleet.on_pump, result.events."""

    def __init__(self) -> None:
        self.on_tick: Any = None
        self.fleet = _Fleet()
        self.result = type("Result", (), {"events": []})()


def test_the_feed_copies_at_its_rate_after_ticks_and_in_waits_only_when_ticks_stop(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from gcs_swarm.web import live

    clock = [100.0]
    monkeypatch.setattr(live.time, "monotonic", lambda: clock[0])
    taken: list[tuple[str, ...]] = []
    made = snapshot(0.0)

    def take(runner: object, events: tuple[str, ...]) -> LiveSnapshot:
        taken.append(events)
        return made

    monkeypatch.setattr(live, "take_snapshot", take)
    runner, handoff = _Runner(), Handoff()
    pumped: list[int] = []
    runner.fleet.on_pump = lambda: pumped.append(1)  # a hook already there (the console's) still runs
    live.LiveFeed(runner, handoff, rate_hz=20.0).attach()  # type: ignore[arg-type]

    runner.on_tick()  # t = 100 s: the first copy
    clock[0] += 0.02
    runner.on_tick()  # 20 ms later: within the 50 ms period, none
    runner.fleet.on_pump()  # a pump between ticks: ticks are running, none
    assert len(taken) == 1 and pumped == [1]
    clock[0] += 0.04
    runner.result.events.append("t=1.00 s formation narrows: column")
    runner.on_tick()  # 60 ms after the first: a copy, with the new event
    assert taken[-1] == ("t=1.00 s formation narrows: column",)
    clock[0] += live.WAITING_S + 0.01  # no tick for longer than WAITING_S: a blocking wait
    runner.fleet.on_pump()
    assert len(taken) == 3 and pumped == [1, 1]
    assert handoff.latest() is not None and not handoff.latest().pos.flags.writeable  # type: ignore[union-attr]
