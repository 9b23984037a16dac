"""flight.json's `jit_after_arming` (gcs_swarm.flight.jit_watch): numba's work after start()."""

from __future__ import annotations

from numba import njit

from gcs_swarm.flight.jit_watch import JitWatch


def test_counts_only_what_is_compiled_after_start() -> None:
    @njit  # no cache: compiled in this test, whatever ran before
    def before(x: float) -> float:
        return x + 1.0

    @njit
    def after(x: float) -> float:
        return x * 2.0

    watch = JitWatch()
    before(1.0)
    assert watch.figures() == {"holds": 0, "wall_s": 0.0, "compiled": []}  # not started: nothing counts
    watch.start()
    before(2.0)  # already compiled for float: no JIT work
    assert watch.figures() == {"holds": 0, "wall_s": 0.0, "compiled": []}
    after(3.0)
    figures = watch.figures()
    assert figures["holds"] >= 1 and figures["wall_s"] > 0.0
    assert figures["compiled"] == [f"{__name__}.test_counts_only_what_is_compiled_after_start.<locals>.after"]
