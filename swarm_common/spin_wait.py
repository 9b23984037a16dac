"""Wait for readable sockets by polling briefly before blocking (two-phase waiting), for both ends of a
lockstep exchange.

In lockstep the simulator and the ground station hand each frame to each other many times a millisecond of
wall time, and a process woken from a blocking `select` takes long to run again compared with that; waking a
blocked peer also costs the sender far more than a `sendto` to an awake one (measured by
benchmarks/bench_wakeup.py, figures in docs/benchmarks-archive.md). `select_spinning` polls first, for at most
`spin_s`, giving the CPU to any other runnable thread or process between two polls (`os.sched_yield`), and
only then blocks for the rest of the timeout.

The yield is what keeps the spin harmless when the cores are shared: measured with two Monte Carlo flights at
once on two cores, the yielding spin helped and a spin that does not yield hurt (docs/benchmarks-archive.md).
"""

from __future__ import annotations

import os
import selectors
import time


def select_spinning(
    selector: selectors.BaseSelector, timeout_s: float, spin_s: float
) -> list[tuple[selectors.SelectorKey, int]]:
    """`selector.select(timeout_s)`, but polled without blocking for the first min(spin_s, timeout_s) s.

    timeout_s, spin_s: wall s (>= 0); spin_s 0 is a plain select. Returns as soon as something is readable,
    and otherwise after timeout_s (what select returns then: nothing, or what became readable at the end).
    """
    if spin_s <= 0.0 or timeout_s <= 0.0:
        return selector.select(max(timeout_s, 0.0))
    start = time.monotonic()
    spin = min(spin_s, timeout_s)
    while True:
        ready = selector.select(0.0)
        if ready:
            return ready
        waited = time.monotonic() - start
        if waited >= spin:
            return selector.select(max(timeout_s - waited, 0.0))
        os.sched_yield()
