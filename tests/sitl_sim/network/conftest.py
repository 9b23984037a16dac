"""Fixture of the endpoint intake tests: one in-process simulator (no process, no pacing) per module."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import in_process_config


@pytest.fixture(scope="module")
def sim() -> Iterator[Simulator]:
    """One vehicle airborne at 10 m in GUIDED, on free 127.0.0.1 ports; closed after the module."""
    simulator = Simulator(in_process_config([[0.0, 0.0, 10.0]]))
    yield simulator
    simulator.close()
