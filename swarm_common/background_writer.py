"""A log file written by a thread of its own, so that a control loop never waits on the disk.

A write() system call can block for tens of milliseconds when the kernel throttles a process that has many
dirty pages (a 200-vehicle real-time flight writes about 6 MB/s of truth log, tlog and run record; one tick
of such a flight spent 28 ms in its run-record phase, whose formatting takes 1.6 ms, BENCHMARKS.md
2026-11-27). The owner hands over chunks of bytes (`write`, a queue put) and goes on; the thread writes
them, in order, straight to the OS (no user-space buffer), so what was handed over is in the file within
moments and a killed process loses at most what is still queued. The write system call releases the GIL,
so the owner keeps running while the thread waits.

`flush` waits until everything handed over so far is written; `close` does that, then closes the file. An
error the thread meets (disk full) is raised by the owner's next write, flush or close, and nothing more is
written after it.
"""

from __future__ import annotations

import queue
import threading
from pathlib import Path
from types import TracebackType

_STOP = None  # queued by close: the thread's last item


class BackgroundWriter:
    """Writes the byte chunks handed to `write` to `path` (created or truncated) from a thread named
    `name`."""

    def __init__(self, path: Path, name: str) -> None:
        self.path = Path(path)
        self._file = open(self.path, "wb", buffering=0)  # noqa: SIM115 - the thread owns it; close() closes it
        self._queue: queue.SimpleQueue[bytes | threading.Event | None] = queue.SimpleQueue()
        self._error: OSError | None = None
        self.closed = False
        self._thread = threading.Thread(target=self._run, name=f"writer {name}", daemon=True)
        self._thread.start()

    def write(self, data: bytes) -> None:
        """Hand `data` over to be written after everything handed over before."""
        self._raise_error()
        if self.closed:
            raise ValueError(f"{self.path.name}: write after close")
        self._queue.put(data)

    def flush(self) -> None:
        """Return once everything handed over so far is written to the OS."""
        self._raise_error()
        if self.closed:
            return
        done = threading.Event()
        self._queue.put(done)
        done.wait()
        self._raise_error()

    def close(self) -> None:
        """Write everything handed over, stop the thread and close the file (idempotent)."""
        if self.closed:
            return
        self.closed = True
        self._queue.put(_STOP)
        self._thread.join()
        self._file.close()
        self._raise_error()

    def _raise_error(self) -> None:
        if self._error is not None:
            error, self._error = self._error, None
            raise error

    def _run(self) -> None:
        failed = False
        while True:
            item = self._queue.get()
            if item is _STOP:
                return
            if isinstance(item, threading.Event):
                item.set()
                continue
            if failed:
                continue
            try:
                self._write_all(item)
            except OSError as err:
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
