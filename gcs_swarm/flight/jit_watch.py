"""Whether numba compiled or loaded machine code while the vehicles flew: flight.json's `jit_after_arming`.

Every compiled law is compiled, or loaded from numba's cache, before the vehicles arm (the guidance's
`prepare_kernels`, the link's warm-up at connect). A kernel met for the first time in the air would stall the
control loop for as long as numba takes, while the vehicles fly on their last setpoint; this watch makes
such a stall visible in every run folder instead of only in a profiler.

It listens to numba's event API (numba.core.event): every compile and every cache load holds numba's global
compiler lock, so the outermost holds of that lock after `start()` are the JIT work done in flight; the
"numba:compile" events name what was compiled (a cache load names nothing).
"""

from __future__ import annotations

import time

from numba.core import event

LOCK_EVENT = "numba:compiler_lock"
COMPILE_EVENT = "numba:compile"


class _LockHolds(event.Listener):
    """Outermost holds of numba's compiler lock in this process: how many, and their total wall s."""

    def __init__(self) -> None:
        self.depth = 0
        self.holds = 0
        self.wall_s = 0.0
        self._since = 0.0

    def on_start(self, ev: event.Event) -> None:
        if self.depth == 0:
            self._since = time.perf_counter()
        self.depth += 1

    def on_end(self, ev: event.Event) -> None:
        self.depth = max(self.depth - 1, 0)
        if self.depth == 0:
            self.holds += 1
            self.wall_s += time.perf_counter() - self._since


class _Compiles(event.Listener):
    """Qualified names of the Python functions numba compiled in this process, in order."""

    def __init__(self) -> None:
        self.names: list[str] = []

    def on_start(self, ev: event.Event) -> None:
        function = ev.data["dispatcher"].py_func
        self.names.append(f"{function.__module__}.{function.__qualname__}")

    def on_end(self, ev: event.Event) -> None:
        pass


_HOLDS = _LockHolds()
_COMPILES = _Compiles()
event.register(LOCK_EVENT, _HOLDS)  # once per process, at import: the listeners only count
event.register(COMPILE_EVENT, _COMPILES)


class JitWatch:
    """numba's JIT work in this process from `start()` (the launch) on; `figures()` for flight.json."""

    def __init__(self) -> None:
        self._holds = 0
        self._wall_s = 0.0
        self._compiled = 0
        self.started = False

    def start(self) -> None:
        """Count from now on (the vehicles are about to arm, or were found flying)."""
        self._holds, self._wall_s, self._compiled = _HOLDS.holds, _HOLDS.wall_s, len(_COMPILES.names)
        self.started = True

    def figures(self) -> dict[str, object]:
        """`holds`: compiles and cache loads since start(); `wall_s`: their total wall time; `compiled`: the
        functions compiled (not loaded from the cache), in order. All zero/empty before start()."""
        if not self.started:
            return {"holds": 0, "wall_s": 0.0, "compiled": []}
        return {
            "holds": _HOLDS.holds - self._holds,
            "wall_s": round(_HOLDS.wall_s - self._wall_s, 4),
            "compiled": _COMPILES.names[self._compiled :],
        }
