"""A child process's output lines, read on a thread, and a wait for one of them that fails at once, with what
the process printed, when the process exits first (tests that start the simulator or the ground station)."""

from __future__ import annotations

import queue
import subprocess
import threading
import time
from collections.abc import Callable

import pytest

POLL_S = 0.2  # s between checks that the process still runs while no line comes


class OutputLines:
    """Every line the text-mode `proc` prints on stdout, in `seen` (stripped of the line end) as it comes."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.seen: list[str] = []
        self._lines: queue.Queue[str] = queue.Queue()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout or ():
            self._lines.put(line.rstrip("\n"))

    def wait_for(self, wanted: Callable[[str], bool], timeout_s: float, what: str) -> str:
        """The first line from now on for which `wanted` is true; the test fails when the process exits, or
        `timeout_s` s pass, before it comes (`what` names the line in the message)."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                line = self._lines.get(timeout=POLL_S)
            except queue.Empty:
                if self.proc.poll() is not None:
                    self.reader.join(timeout=POLL_S)  # the lines it printed before it exited
                    if self._lines.empty():
                        status = self.proc.returncode
                        pytest.fail(f"the process exited with status {status} before {what}: {self.seen}")
                if time.monotonic() > deadline:
                    pytest.fail(f"no {what} within {timeout_s:g} s: {self.seen}")
                continue
            self.seen.append(line)
            if wanted(line):
                return line

    def everything(self, timeout_s: float) -> str:
        """All the process printed, once its output has closed (waited for up to `timeout_s` s), one line
        per line."""
        self.reader.join(timeout=timeout_s)
        while not self._lines.empty():
            self.seen.append(self._lines.get_nowait())
        return "\n".join(self.seen)
