"""A log file written by a thread of its own, so that a control loop never waits on the disk.

A write() system call can block for much longer than a control tick when the kernel throttles a process that
has many dirty pages (a 200-vehicle real-time flight writes megabytes a second of truth log, tlog and run
record; docs/benchmarks-archive.md 2026-11-27 shows such a stall).
The owner queues chunks of bytes (`write`) and goes on; the thread writes them, in order, straight to the OS
(no user-space buffer). The write system call releases the GIL, so the owner keeps running while the thread
waits. The tlog uses it; logs of numeric rows, which must also be turned into text, go to a formatting process
instead (swarm_common.row_log_process), since a thread would format them under the GIL its owner's control
loop needs.

Chunks reach the thread in batches: every `chunks_per_hand_over` chunks, and whatever waits when the thread
has had nothing for `period_s` (wall; the thread takes it itself). A killed process loses at most the last
`period_s` of chunks and what the thread had not written yet.

Logs of rows (the run record, the truth log) batch about ROWS_PER_HAND_OVER rows per hand-over
(`chunks_for_rows`), at most MAX_CHUNKS_PER_HAND_OVER chunks (ticks): one per tick at 200 vehicles, one per 10
ticks at 6, so that a killed ground station's record still ends within 0.2 s of vehicle time of its death
(tests/e2e/test_gcs_killed.py asks 1.5 s). Each hand-over wakes the reader, which then competes with the
owner for the cores; in a 6-vehicle lockstep flight one hand-over per tick in both processes made whole runs
measurably slower (docs/benchmarks-archive.md 2026-11-27 12:00).

`flush` hands over and waits until everything so far is written; `close` does that, then closes the file. An
error the thread meets (disk full) is raised by the owner's next write, flush or close, and nothing more is
written after it.
"""

from __future__ import annotations

import math
import queue
import threading
from pathlib import Path
from types import TracebackType

ROWS_PER_HAND_OVER = 200  # log rows (vehicles x samples) an owner batches per hand-over (chunks_for_rows)
MAX_CHUNKS_PER_HAND_OVER = 10  # at most this many chunks (ticks, samples) per hand-over: what a kill loses
HAND_OVER_PERIOD_S = 1.0  # wall s without a hand-over after which the thread takes what is pending itself

_STOP = None  # queued by close: the thread's last item


def chunks_for_rows(rows_per_chunk: int) -> int:
    """Chunks per hand-over for chunks of `rows_per_chunk` rows: about ROWS_PER_HAND_OVER rows, at least 1,
    at most MAX_CHUNKS_PER_HAND_OVER."""
    wanted = math.ceil(ROWS_PER_HAND_OVER / max(rows_per_chunk, 1))
    return min(max(1, wanted), MAX_CHUNKS_PER_HAND_OVER)


class BackgroundWriter:
    """Writes the chunks of bytes given to `write` to `path` (created or truncated) from a thread named
    `name`, handed over in batches (see the module doc)."""

    def __init__(
        self, path: Path, name: str, chunks_per_hand_over: int = 1, period_s: float = HAND_OVER_PERIOD_S
    ) -> None:
        if chunks_per_hand_over < 1 or not period_s > 0:
            raise ValueError("chunks_per_hand_over must be >= 1 and period_s > 0")
        self.path = Path(path)
        self.chunks_per_hand_over = chunks_per_hand_over
        self.period_s = period_s
        self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - the thread owns it; close() closes it
        self._pending: list[bytes] = []  # written, not yet handed over
        self._lock = threading.Lock()  # guards _pending and keeps hand-overs in order (owner and thread)
        self._queue: queue.SimpleQueue[list[bytes] | threading.Event | None] = queue.SimpleQueue()
        self._error: Exception | None = None
        self.closed = False
        self._thread = threading.Thread(target=self._run, name=f"writer {name}", daemon=True)
        self._thread.start()

    def write(self, data: bytes) -> None:
        """Queue `data` to be written after everything written before."""
        self._raise_error()
        if self.closed:
            raise ValueError(f"{self.path.name}: write after close")
        with self._lock:
            self._pending.append(data)
            full = len(self._pending) >= self.chunks_per_hand_over
        if full:
            self._hand_over()

    def flush(self) -> None:
        """Return once everything written so far is written to the OS."""
        self._raise_error()
        if self.closed:
            return
        self._hand_over()
        done = threading.Event()
        self._queue.put(done)
        done.wait()
        self._raise_error()

    def close(self) -> None:
        """Write everything written so far, stop the thread and close the file (idempotent)."""
        if self.closed:
            return
        self.closed = True
        self._hand_over()
        self._queue.put(_STOP)
        self._thread.join()
        self._file.close()
        self._raise_error()

    def _hand_over(self) -> None:
        """Queue the pending chunks for the thread (from the owner, or from the thread after a quiet
        period)."""
        with self._lock:
            if self._pending:
                self._queue.put(self._pending)
                self._pending = []

    def _raise_error(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def _run(self) -> None:
        failed = False
        while True:
            try:
                item = self._queue.get(timeout=self.period_s)
            except queue.Empty:
                self._hand_over()  # chunks waiting a whole period: taken in order, after the queued ones
                continue
            if item is _STOP:
                return
            if isinstance(item, threading.Event):
                item.set()
                continue
            if failed:
                continue
            try:
                for chunk in item:
                    self._write_all(chunk)
            except Exception as err:  # noqa: BLE001 - the owner raises it (a disk error)
                self._error, failed = err, True

    def _write_all(self, data: bytes) -> None:
        """A raw file's write may take part of the data: write until all of it is in the file."""
        view = memoryview(data)
        while view:
            view = view[self._file.write(view) :]

    def __enter__(self) -> BackgroundWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
