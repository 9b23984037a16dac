"""select_spinning: polls without blocking for the spin, yields between polls, then blocks for the rest."""

from __future__ import annotations

import selectors
import socket
from typing import Any

import pytest

from swarm_common import spin_wait
from swarm_common.spin_wait import select_spinning

STEP_S = 10e-6  # the fake clock advances this much per reading


class FakeSelector(selectors.BaseSelector):
    """Ready (one event) from the `ready_on`-th select call on (1-based; None: never); records timeouts."""

    def __init__(self, ready_on: int | None) -> None:
        self.ready_on = ready_on
        self.timeouts: list[float | None] = []

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        self.timeouts.append(timeout)
        if self.ready_on is not None and len(self.timeouts) >= self.ready_on:
            key = selectors.SelectorKey(fileobj=0, fd=0, events=selectors.EVENT_READ, data=None)
            return [(key, selectors.EVENT_READ)]
        return []

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        raise NotImplementedError

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        raise NotImplementedError

    def get_map(self) -> Any:
        return {}


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> dict[str, float]:
    """A fake monotonic clock (STEP_S per reading) and a count of sched_yield calls."""
    state = {"t": 100.0, "yields": 0}

    def monotonic() -> float:
        state["t"] += STEP_S
        return state["t"]

    def sched_yield() -> None:
        state["yields"] += 1

    monkeypatch.setattr(spin_wait.time, "monotonic", monotonic)
    monkeypatch.setattr(spin_wait.os, "sched_yield", sched_yield)
    return state


def test_no_spin_is_one_plain_select(clock: dict[str, float]) -> None:
    sel = FakeSelector(ready_on=None)
    assert select_spinning(sel, 0.5, 0.0) == []
    assert sel.timeouts == [0.5]
    assert clock["yields"] == 0


def test_zero_or_negative_timeout_polls_once(clock: dict[str, float]) -> None:
    for timeout in (0.0, -1.0):
        sel = FakeSelector(ready_on=None)
        assert select_spinning(sel, timeout, 300e-6) == []
        assert sel.timeouts == [0.0]
    assert clock["yields"] == 0


def test_packet_during_the_spin_is_returned_without_blocking(clock: dict[str, float]) -> None:
    sel = FakeSelector(ready_on=3)
    ready = select_spinning(sel, 0.5, 300e-6)
    assert len(ready) == 1
    assert sel.timeouts == [0.0, 0.0, 0.0]  # three polls, no blocking call
    assert clock["yields"] == 2  # the CPU was offered between the polls


def test_after_the_spin_it_blocks_for_the_rest_of_the_timeout(clock: dict[str, float]) -> None:
    sel = FakeSelector(ready_on=None)
    assert select_spinning(sel, 0.5, 300e-6) == []
    polls, final = sel.timeouts[:-1], sel.timeouts[-1]
    assert polls and all(t == 0.0 for t in polls)
    # each poll reads the clock once (STEP_S), plus the start: the spin lasted >= 300 us, about that long
    assert len(polls) == pytest.approx(300e-6 / STEP_S, abs=2)
    assert final is not None and 0.5 - 300e-6 - 3 * STEP_S <= final <= 0.5 - 300e-6


def test_spin_is_capped_by_the_timeout(clock: dict[str, float]) -> None:
    sel = FakeSelector(ready_on=None)
    select_spinning(sel, 50e-6, 1.0)
    assert len(sel.timeouts) <= 50e-6 / STEP_S + 2  # not a second of polls
    assert sel.timeouts[-1] is not None and 0.0 <= sel.timeouts[-1] <= 10e-6


def test_real_socket_already_readable() -> None:
    with (
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx,
    ):
        rx.bind(("127.0.0.1", 0))
        rx.setblocking(False)
        tx.sendto(b"x", rx.getsockname())
        with selectors.DefaultSelector() as sel:
            sel.register(rx, selectors.EVENT_READ, "rx")
            ready = select_spinning(sel, 5.0, 300e-6)
            assert [key.data for key, _ in ready] == ["rx"]
            assert rx.recv(10) == b"x"
            assert select_spinning(sel, 0.01, 300e-6) == []  # drained: spins, then blocks 10 ms, nothing
