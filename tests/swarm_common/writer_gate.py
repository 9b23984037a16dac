"""Holding a BackgroundWriter's thread, so that a test can change values after writing them and before the
thread formats them."""

from __future__ import annotations

import threading

from swarm_common.background_writer import BackgroundWriter


def hold_writer_thread(writer: BackgroundWriter) -> threading.Event:
    """Keep `writer`'s thread busy (on a chunk that renders to nothing) until the returned event is set, at
    most 10 s. Call it before anything is batched: the chunk goes to the thread at once."""
    gate = threading.Event()
    writer.chunks_per_hand_over = 1
    writer.write(lambda: b"" if gate.wait(10.0) else b"")
    return gate
