"""The guidance tick in closed loop (tick_replay): reproducible bit for bit, and what it sends obeys the
rules every tick, in every situation of the replay (inactive and NaN rows, vehicles close together,
degraded scales, a tick gap, new goals and offsets, the guard's fence and altitude rules).

The same replay, run against the code before the overhead rewrite of issue 16, gave byte-identical records
(every output and internal state, 12 scenarios x 400 ticks); so did the compiled tick against the code before
it (the numpy steps of commit 88c7f1a: 16 scenarios x 400 ticks, the 7 bundled missions x 2500 ticks); those
comparisons need the old tree and live outside the repository. Here the compiled steps are compared with the
numpy steps of this tree, which stay the reference.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from gcs_swarm.guidance import fleet_controller, reference
from tests.gcs_swarm.guidance.tick_replay import SCENARIOS, replay

TICKS = 120


@pytest.mark.parametrize("name", ["paper_static_6", "grid_3_plain", "grid_6_formula", "grid_9_pid"])
def test_the_replay_is_reproducible_bit_for_bit(name: str) -> None:
    """Two fresh controllers fed the same inputs give the same bytes in every output and internal state
    (no state leaks between controllers through caches)."""
    for first, second in zip(replay(name, TICKS), replay(name, TICKS), strict=True):
        assert first.keys() == second.keys()
        for key in first:
            assert first[key].tobytes() == second[key].tobytes(), key


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_tick_sends_only_what_the_rules_allow(name: str) -> None:
    """Inactive rows are NaN and are flagged nowhere; active rows are finite; after the guard the tilt
    acos(cos r cos p) is within the limit and the thrust within [0, min(1, hover thrust_max_g)]."""
    for record in replay(name, TICKS):
        active = record["active"]
        for key in ("roll_d", "pitch_d", "yaw_d", "thrust_acc", "clearance"):
            assert np.isnan(record[key][~active]).all(), key
        for key in ("roll_d", "pitch_d", "yaw_d", "thrust_acc"):
            assert np.isfinite(record[key][active]).all(), key
        assert not (record["emergency"] & ~active).any() and not (record["collision"] & ~active).any()
        tilt = np.arccos(np.cos(record["guard_roll"]) * np.cos(record["guard_pitch"]))
        assert (tilt <= math.radians(35.0) + 1e-9).all()
        assert ((record["guard_thrust"] >= 0.0) & (record["guard_thrust"] <= 1.0)).all()
        assert np.isfinite(record["guard_yaw"]).all()


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_the_compiled_shaping_flies_the_numpy_bits(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The replay with step 4 compiled (shaping_kernels) and with the numpy reference gives the same bytes
    in every output and internal state, tick by tick (the numba path is used when numba is installed)."""
    kernel = pytest.importorskip("gcs_swarm.guidance.shaping_kernels").shape_reference_acceleration
    calls = []

    def counted(*args: object) -> np.ndarray:
        calls.append(1)
        return kernel(*args)

    monkeypatch.setattr(fleet_controller, "compiled_steps", None)  # the numpy steps, which call step 4
    monkeypatch.setattr(reference, "compiled_shaping", counted)
    compiled = list(replay(name, TICKS))
    monkeypatch.setattr(reference, "compiled_shaping", None)
    for first, second in zip(compiled, replay(name, TICKS), strict=True):
        assert first.keys() == second.keys()
        for key in first:
            assert first[key].tobytes() == second[key].tobytes(), key
    assert len(calls) == (0 if name == "grid_3_plain" else TICKS)  # "plain": jerk_max 0, first-order step 4


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_the_compiled_tick_flies_the_numpy_bits(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The replay with steps 1-7 compiled (compiled_tick) and with the numpy steps gives the same bytes in
    every output and internal state, tick by tick: every bundled mission, grid fleets of 1 to 230 (the hash
    grid above 200), obstacles, emergencies, the dead-GCS speed caps, relay topology, PID, paper_literal,
    degraded scales, inactive and returning vehicles."""
    compiled = pytest.importorskip("gcs_swarm.guidance.compiled_tick").CompiledTick
    assert fleet_controller.compiled_steps is compiled
    calls = []
    original = compiled.__call__

    def counted(self: object, *args: object) -> object:
        calls.append(1)
        return original(self, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(compiled, "__call__", counted)
    fast = list(replay(name, TICKS))
    monkeypatch.setattr(fleet_controller, "compiled_steps", None)
    for first, second in zip(fast, replay(name, TICKS), strict=True):
        assert first.keys() == second.keys()
        for key in first:
            assert first[key].tobytes() == second[key].tobytes(), key
    assert len(calls) == TICKS
