"""A first flight on a fresh machine (issue 35): with an empty numba cache, every compiled law of the ground
station is compiled before the vehicles arm, so that no formation tick waits for the JIT while the vehicles
fly on their last setpoint. The simulator compiles its own kernels before it says READY.

The run's flight.json counts numba's compiles and cache loads from the launch on (`jit_after_arming`,
gcs_swarm.flight.jit_watch); the mixed fleet flies both autopilot dialects (ArduCopter GUIDED, PX4 OFFBOARD
after its setpoint stream), so every kernel a formation flight needs is met.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from tests.e2e.flights import MISSIONS, SHORT_BOOT, fly


def test_a_cold_numba_cache_is_filled_before_the_vehicles_arm(tmp_path: Path) -> None:
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    outcome = fly(
        MISSIONS / "mixed_fleet.yaml", tmp_path / "run", timeout_s=900.0, extra=[SHORT_BOOT], env=env
    )
    assert outcome.status == 0, outcome.output
    assert any(cache.rglob("*.nbi")), "the flight did not use the empty cache it was given"
    flight = json.loads((outcome.run_dir / "flight.json").read_text())
    assert flight["jit_after_arming"] == {"holds": 0, "wall_s": 0.0, "compiled": []}
