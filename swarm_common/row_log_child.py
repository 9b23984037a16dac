"""The formatting process of swarm_common.row_log_process: `python -m swarm_common.row_log_child PATH`
writes the rows its stdin brings into PATH (created or truncated). Standard library only, so that it starts
in a few tens of milliseconds.

Messages on stdin, one after another: a kind byte, a little-endian u32 payload length (`HEAD`), the payload.
`H` bytes written as they are (a header); `T` a u32 column count (`WIDTH`) and the UTF-8 printf-style row
template for the rows that follow; `R` rows of that many float64 columns, each written as `template % row`;
`F` a flush: one byte answered on stdout once everything before it is written. The end of stdin ends the
file; anything malformed ends the process with a message on stderr and exit status 1. It runs below its
owner (`run_below_the_control_loops`): when the cores are busy, the rows wait in the pipe (1 MB, a thousand
6-vehicle ticks) rather than the control loop.
"""

from __future__ import annotations

import os
import struct
import sys
from array import array
from pathlib import Path
from typing import BinaryIO

HEAD = struct.Struct("<cI")  # kind, payload length
WIDTH = struct.Struct("<I")  # columns of the rows that follow a template
NICENESS = 10  # below the control loops it serves: on a busy machine the log waits, the loops do not


def serve(path: Path, stream: BinaryIO, acks: BinaryIO) -> None:
    """Messages from `stream` into the file at `path`; flush answers on `acks`."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        template, width = "", 1
        while True:
            head = stream.read(HEAD.size)
            if not head:
                return
            kind, size = HEAD.unpack(head + _read_exactly(stream, HEAD.size - len(head)))
            payload = _read_exactly(stream, size)
            if kind == b"H":
                _write_all(fd, payload)
            elif kind == b"T":
                (width,) = WIDTH.unpack_from(payload)
                template = payload[WIDTH.size :].decode()
            elif kind == b"R":
                values = array("d", payload).tolist()
                text = "".join(template % tuple(values[k : k + width]) for k in range(0, len(values), width))
                _write_all(fd, text.encode())
            elif kind == b"F":
                acks.write(b"F")
                acks.flush()
            else:
                raise ValueError(f"unknown message kind {kind!r}")
    finally:
        os.close(fd)


def _read_exactly(stream: BinaryIO, size: int) -> bytes:
    data = stream.read(size) if size else b""
    if len(data) != size:
        raise EOFError(f"the pipe ended inside a message ({len(data)} of {size} bytes)")
    return data


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def run_below_the_control_loops() -> None:
    """Lower this process's priority: nice NICENESS, and on Linux the SCHED_IDLE policy, under which a waking
    formatter never preempts a control loop (with nice alone it did: docs/benchmarks-archive.md 2026-11-27
    22:00). It
    only gets idle time then: its owner takes it back to the normal policy if it falls behind
    (swarm_common.row_log_process)."""
    os.nice(NICENESS)
    if hasattr(os, "SCHED_IDLE"):
        try:
            os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
        except OSError:  # not allowed here (a container's seccomp policy): nice alone
            pass


def main() -> None:
    run_below_the_control_loops()
    try:
        serve(Path(sys.argv[1]), sys.stdin.buffer, sys.stdout.buffer)
    except Exception as error:  # reported to the owner, which raises RowLogError with it
        print(f"{type(error).__name__}: {error}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
