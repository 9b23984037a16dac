"""What the embedded simulator does when the ground station that started it dies.

`gcs-swarm` starts `sitl-sim --exit-with-parent` with a pipe on its stdin and never writes to it; the kernel
closes that pipe however the ground station ends (exit, crash, SIGKILL, out-of-memory kill), so end of file
on stdin means the parent is gone. PR_SET_PDEATHSIG is not used on purpose: it would kill the simulator at
once, with its vehicles in the air, while a real vehicle flies on into its failsafes.

From then on the simulator is an orphan (docs/sitl.md "When the ground station dies"): it stops waiting for
lockstep answers and runs free (`orphan_speedup` x real time, `inf` = as fast as it can), keeps flying every
vehicle on its own autopilot (GUID_TIMEOUT, then the GCS failsafe), records it all in the truth log, and
exits once every vehicle is landed and disarmed (or crashed), or after `grace_s` simulated seconds.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable


class ParentWatch:
    """A daemon thread that reads the file descriptor `fd` (the stdin pipe from the parent) until end of file,
    then calls `on_gone()` once. Anything the parent writes is ignored.

    It reads the raw descriptor (os.read), not sys.stdin's buffered reader: a daemon thread blocked inside a
    BufferedReader holds its lock, and the interpreter aborts at exit ("Fatal Python error:
    _enter_buffered_busy") when it tries to flush that reader."""

    def __init__(self, fd: int, on_gone: Callable[[], None]) -> None:
        self._fd = fd
        self._on_gone = on_gone
        self._thread = threading.Thread(target=self._watch, name="parent-watch", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _watch(self) -> None:
        try:
            while os.read(self._fd, 4096):
                pass
        except OSError:
            pass  # a closed or broken pipe means the same: the parent is gone
        self._on_gone()


def detach_output(log_path: str | None) -> None:
    """Point stdout and stderr (the dead parent's pipe: writing there would raise BrokenPipeError) at
    `log_path` (appended), or at os.devnull."""
    target = os.open(log_path or os.devnull, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
        os.dup2(target, stream.fileno())
    os.close(target)
