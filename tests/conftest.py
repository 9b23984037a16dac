"""Markers given by where a test runs, so that the subsets of the README select by cost:

- `e2e`: every test under tests/e2e: flies the ground station and the simulator as real processes;
- `sim`: starts a sitl-sim process on loopback for one component (the fixtures below, or marked by hand);
- `quick`: every other test: no simulator process (`pytest -m quick`, under a minute).
"""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

import pytest
from hypothesis import settings

# no time limit per example: a first call that loads or compiles a numba kernel (a fresh checkout has no
# kernel cache) takes longer than hypothesis' default 200 ms deadline, which is a timed assertion
settings.register_profile("untimed", deadline=None)
settings.load_profile("untimed")

# fixtures that start sitl-sim processes (tests/gcs_swarm/link/conftest.py, tests/sitl_sim/conftest.py, and in
# test modules: console/test_session.py, link/test_fence_link.py, test_forward.py, test_signing_inbound.py);
# a quick test that starts one anyway fails (below), so this list cannot silently fall behind
SIMULATOR_FIXTURES = frozenset(
    {"launcher", "simulator", "lead", "sitl", "pilot_for", "vehicles", "sim_fleet", "rig", "signed_fleet"}
)


E2E = Path(__file__).parent / "e2e"


@pytest.hookimpl(tryfirst=True)  # before `-m` selects by these markers
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if E2E in Path(str(item.path)).parents:
            item.add_marker(pytest.mark.e2e)
        if SIMULATOR_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.sim)
        if item.get_closest_marker("e2e") is None and item.get_closest_marker("sim") is None:
            item.add_marker(pytest.mark.quick)


@pytest.fixture(autouse=True)
def _quick_tests_start_no_simulator(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> None:
    """Keeps the `quick` promise: a quick test that starts sitl-sim fails, naming the fixture rule above."""
    if request.node.get_closest_marker("quick") is None:
        return
    start = subprocess.Popen.__init__

    def refuse_simulator(self: subprocess.Popen[Any], args: Any, *rest: Any, **options: Any) -> None:
        words = [str(a) for a in args] if isinstance(args, (list, tuple)) else str(args).split()
        as_module = any(a == "-m" and b == "sitl_sim" for a, b in zip(words, words[1:], strict=False))
        if as_module or any(Path(w).name == "sitl-sim" for w in words):
            raise AssertionError("a quick test started sitl-sim: mark it `sim` (tests/conftest.py)")
        start(self, args, *rest, **options)

    monkeypatch.setattr(subprocess.Popen, "__init__", refuse_simulator)
