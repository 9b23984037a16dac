"""Whether numba compiled or loaded machine code while the vehicles flew: flight.json's `jit_after_arming`.

Every compiled law is compiled, or loaded from numba's cache, before the vehicles arm (the guidance's
`prepare_kernels`, the link's warm-up at connect, eager signatures). A kernel met for the first time in the
air would stall the control loop while the vehicles fly on their last setpoint; this watch makes such a stall
visible in every run folder instead of only in a profiler.

It listens to numba's event API (numba.core.event): every compile and every cache load holds numba's global
compiler lock, so the outermost holds of that lock are the JIT work; the "numba:compile" events name what was
compiled (a cache load names nothing).
"""

from __future__ import annotations

import time

from numba.core import event


class _JitWork(event.Listener):
    """This process's outermost holds of numba's compiler lock (`holds`, their `wall_s`) and the qualified
    names of the functions it compiled (`compiled`), counted from import on."""

    def __init__(self) -> None:
        self.depth = self.holds = 0
        self.wall_s = self._since = 0.0
        self.compiled: list[str] = []

    def on_start(self, ev: event.Event) -> None:
        if ev.kind == "numba:compile":
            function = ev.data["dispatcher"].py_func
            self.compiled.append(f"{function.__module__}.{function.__qualname__}")
            return
        if self.depth == 0:
            self._since = time.perf_counter()
        self.depth += 1

    def on_end(self, ev: event.Event) -> None:
        if ev.kind == "numba:compile":
            return
        self.depth = max(self.depth - 1, 0)
        if self.depth == 0:
            self.holds += 1
            self.wall_s += time.perf_counter() - self._since


_WORK = _JitWork()
event.register("numba:compiler_lock", _WORK)  # once per process, at import: the listener only counts
event.register("numba:compile", _WORK)


class JitWatch:
    """numba's JIT work in this process from `start()` (the launch) on; `figures()` for flight.json."""

    def __init__(self) -> None:
        self._start: tuple[int, float, int] | None = None

    def start(self) -> None:
        """Count from now on (the vehicles are about to arm, or were found flying)."""
        self._start = (_WORK.holds, _WORK.wall_s, len(_WORK.compiled))

    def figures(self) -> dict[str, object]:
        """`holds`: compiles and cache loads since start(); `wall_s`: their total wall time; `compiled`: the
        functions compiled (not loaded from the cache), in order. All zero/empty before start()."""
        holds, wall_s, compiled = self._start or (_WORK.holds, _WORK.wall_s, len(_WORK.compiled))
        return {
            "holds": _WORK.holds - holds,
            "wall_s": round(_WORK.wall_s - wall_s, 4),
            "compiled": _WORK.compiled[compiled:],
        }
