"""Fixtures of the simulator tests (helpers in tests/sitl_sim/sim_process.py): factories that start real
simulator processes and scripted ground stations, all stopped or closed at teardown."""

from __future__ import annotations

import signal
from collections.abc import Callable, Iterator

import pytest

from tests.sitl_sim.sim_process import Pilot, SimProcess, start_sim


@pytest.fixture
def sitl() -> Iterator[Callable[..., SimProcess]]:
    """Factory fixture: sitl(*args, vehicles=N) starts a simulator; all are stopped at teardown."""
    started: list[SimProcess] = []

    def factory(*args: str, vehicles: int = 1) -> SimProcess:
        sim = start_sim(*args, vehicles=vehicles)
        started.append(sim)
        return sim

    yield factory
    for sim in started:
        sim.stop(signal.SIGKILL if sim.proc.poll() is None else signal.SIGTERM, timeout_s=5.0)


@pytest.fixture
def pilot_for() -> Iterator[Callable[..., Pilot]]:
    """Factory fixture: pilot_for(sim, lockstep=True) -> Pilot; closed at teardown."""
    pilots: list[Pilot] = []

    def factory(sim: SimProcess, lockstep: bool = True, sysid_base: int = 1) -> Pilot:
        pilot = Pilot(sim, lockstep, sysid_base)
        pilots.append(pilot)
        return pilot

    yield factory
    for pilot in pilots:
        pilot.close()
