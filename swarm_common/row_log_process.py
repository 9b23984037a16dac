"""A CSV log of numeric rows formatted by a process of its own, so that neither the control loop nor its
process's GIL pays for turning numbers into text.

The owner (`RowLogProcess`) sends rows as float64 bytes with the printf-style row template they fill
("%.6g,%d,...\\r\\n", one conversion per column; integer columns take their float values); the child (`python
-m swarm_common.row_log_child PATH`, standard library only) writes `template % row` for each row, in order,
straight to the file. In a small lockstep flight the formatting is a noticeable share of the ground station's
tick; a writer thread cannot take it off the tick, since it needs the GIL the tick holds
(swarm_common.background_writer), a process runs it on the other core. The run record and the simulator's
truth log (its two files) use it. The child runs below the control loops (Linux SCHED_IDLE,
`row_log_child.run_below_the_control_loops`): with nice alone, the simulator's waking formatters preempted the
ground station's tick and slowed formation flight; under SCHED_IDLE formation is as fast as without them (A/Bs
in docs/benchmarks-archive.md, 2026-11-27 17:00 and 22:00). A SCHED_IDLE child only gets the cores' idle time:
where other programs keep them busy it could fall behind until its pipe is full and its owner waits, so the
owner takes it back to the normal policy (niced) once its pipe is half full (`RowLogProcess.promoted`).

Rows reach the child in batches, like background_writer's: about ROWS_PER_HAND_OVER rows and at most
MAX_CHUNKS_PER_HAND_OVER chunks (ticks) per hand-over, and whatever waits once HAND_OVER_PERIOD_S (wall) has
passed since the last hand-over, checked at each write. If the owner dies (even by SIGKILL), the child reads
the end of its pipe, writes everything it was handed and exits: a killed ground station's log is complete up
to its last hand-over. Nothing is left running.

Wire format on the child's stdin, one message after another: a kind byte, a little-endian u32 payload length,
the payload (swarm_common.row_log_child).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path
from typing import IO

import numpy as np

from swarm_common.background_writer import HAND_OVER_PERIOD_S, chunks_for_rows
from swarm_common.row_log_child import HEAD, WIDTH

_PIPE_BYTES = 1 << 20  # a 200-vehicle tick is 50 kB of rows; the default 64 kB pipe would block the owner
_CLOSE_TIMEOUT_S = 60.0


def _pipe_capacity(fd: int) -> int:
    """Bytes the pipe `fd` holds (Linux F_GETPIPE_SZ; elsewhere the classic 64 kB)."""
    try:
        return int(fcntl.fcntl(fd, getattr(fcntl, "F_GETPIPE_SZ", 1032)))
    except OSError:
        return 1 << 16


class RowLogError(RuntimeError):
    """The formatting process failed (its own words), or is gone."""


class RowLogProcess:
    """Owner side: starts the child writing `path` (created or truncated); `name` names it in errors."""

    def __init__(self, path: Path, name: str) -> None:
        self.path = Path(path)
        self.name = name
        self._child = subprocess.Popen(
            [sys.executable, "-m", "swarm_common.row_log_child", str(self.path)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,  # a Ctrl-C or a signal to the owner's group must not cut the log short
        )
        assert self._child.stdin is not None and self._child.stdout is not None
        self._stdin: IO[bytes] = self._child.stdin
        self._acks: IO[bytes] = self._child.stdout
        with contextlib.suppress(OSError):  # Linux: a larger pipe; elsewhere the default
            fcntl.fcntl(self._stdin.fileno(), getattr(fcntl, "F_SETPIPE_SZ", 1031), _PIPE_BYTES)
        self._pipe_bytes = _pipe_capacity(self._stdin.fileno())
        self.promoted = False  # the child was taken out of SCHED_IDLE (`_keep_up`)
        self._pending = bytearray()
        self._chunks = 0  # chunks pending
        self._chunks_per_hand_over = 1
        self._template: str | None = None
        self._handed_at = time.monotonic()
        self.closed = False

    def write(self, data: bytes) -> None:
        """Write `data` as it is, after everything written before."""
        self._append(b"H", data)
        self._chunk_done(1)

    def write_rows(self, template: str, rows: np.ndarray) -> None:
        """Write one chunk of rows: `template % tuple(row)` for each row of the (n, columns) `rows`, whose
        values go as float64 (`template` has one conversion per column)."""
        table = np.ascontiguousarray(rows, dtype=np.float64)
        if table.ndim != 2:
            raise ValueError(f"rows must be a 2-D table, got shape {table.shape}")
        if template != self._template:
            self._append(b"T", WIDTH.pack(table.shape[1]) + template.encode())
            self._template = template
        self._append(b"R", table.tobytes())
        self._chunk_done(len(table))

    def flush(self) -> None:
        """Return once everything written so far is in the file."""
        if self.closed:
            return
        self._append(b"F", b"")
        self._hand_over()
        if self._acks.read(1) != b"F":
            self._fail("stopped before a flush")

    def close(self) -> None:
        """Write everything written so far, let the child finish and close the file (idempotent)."""
        if self.closed:
            return
        try:
            self._hand_over()
        finally:
            self._end("failed")

    def _append(self, kind: bytes, payload: bytes) -> None:
        if self.closed:
            raise ValueError(f"{self.path.name}: write after close")
        self._pending += HEAD.pack(kind, len(payload))
        self._pending += payload

    def _chunk_done(self, rows: int) -> None:
        self._chunks += 1
        self._chunks_per_hand_over = chunks_for_rows(rows)
        if (
            self._chunks >= self._chunks_per_hand_over
            or time.monotonic() - self._handed_at >= HAND_OVER_PERIOD_S
        ):
            self._hand_over()

    def _hand_over(self) -> None:
        self._handed_at = time.monotonic()
        if not self._pending:
            return
        data, self._pending, self._chunks = bytes(self._pending), bytearray(), 0
        self._keep_up(len(data))
        try:
            self._stdin.write(data)
            self._stdin.flush()
        except (BrokenPipeError, ValueError):
            self._fail("is gone")

    def _keep_up(self, incoming: int) -> None:
        """Take the child out of SCHED_IDLE (back to the normal policy, still niced) once its pipe would be
        more than half full: a formatter starved by other programs' load must not make its owner, a control
        loop, wait on a full pipe. Once, for good; where the pipe's fill or the policy cannot be read or
        changed, nothing."""
        if self.promoted or not hasattr(os, "SCHED_IDLE"):
            return
        try:
            queued = struct.unpack("i", fcntl.ioctl(self._stdin.fileno(), termios.FIONREAD, b"\0\0\0\0"))[0]
            if queued + incoming <= self._pipe_bytes // 2:
                return
            os.sched_setscheduler(self._child.pid, os.SCHED_OTHER, os.sched_param(0))
        except OSError:
            return
        self.promoted = True

    def _fail(self, what: str) -> None:
        self._end(what)
        raise RowLogError(f"{self.name}: the formatting process {what} (exit {self._child.returncode})")

    def _end(self, what: str) -> None:
        """Close the child's input, wait for it (killed after _CLOSE_TIMEOUT_S), close its pipes; RowLogError
        "the formatting process {what}" with its own words when it did not exit cleanly."""
        self.closed = True
        with contextlib.suppress(OSError):
            self._stdin.close()
        try:
            self._child.wait(timeout=_CLOSE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self._child.kill()
            self._child.wait()
        stderr = self._child.stderr.read() if self._child.stderr is not None else b""
        for pipe in (self._acks, self._child.stderr):
            if pipe is not None:
                pipe.close()
        if self._child.returncode != 0:
            raise RowLogError(
                f"{self.name}: the formatting process {what} (exit {self._child.returncode}): "
                f"{stderr.decode(errors='replace').strip()}"
            )
