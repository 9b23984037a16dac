"""Start and stop `sitl-sim` as a separate process for a mission (the embedded simulator).

The ground station never imports the simulator: it launches `python -m sitl_sim` with the mission's world,
matching ports and time mode, waits for its READY line and terminates it afterwards. The simulator's stdin is
a pipe from this process: if the ground station dies in any way, the pipe closes and the simulator flies its
vehicles on their own failsafes until all are down, then exits (`sitl-sim --exit-with-parent`).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path

from gcs_swarm.mission import Mission


class SimulatorError(Exception):
    """The embedded simulator could not be started (one-sentence message)."""


class EmbeddedSimulator:
    """A `sitl-sim` child process serving `mission`'s vehicles on 127.0.0.1:base_port+i."""

    def __init__(
        self,
        mission: Mission,
        base_port: int,
        truth_log: Path | None,
        time_mode: str,
        speedup: float = 1.0,
        seed: int = 0,
        extra_args: list[str] | None = None,
        signing_key_file: Path | None = None,
    ) -> None:
        self.mission = mission
        self.base_port = base_port
        self.truth_log = truth_log
        self.args = [
            sys.executable,
            "-m",
            "sitl_sim",
            "--mission",
            str(mission.path),
            "--base-port",
            str(base_port),
            "--bind",
            "127.0.0.1",
            "--seed",
            str(seed),
            "--rate-hz",
            f"{mission.run.simulator.rate_hz:g}",
            "--exit-with-parent",  # stdin is our pipe: if we die, the simulator lands its vehicles and exits
        ]
        if time_mode == "lockstep":
            self.args += ["--lockstep", "--lockstep-hz", f"{mission.run.control_rate_hz:g}"]
            self.args += ["--lockstep-delay", str(mission.run.simulator.lockstep_delay_frames)]
            self.args += ["--lockstep-spin-us", f"{mission.run.simulator.lockstep_spin_us:g}"]
        elif time_mode == "speedup":
            self.args += ["--speedup", f"{speedup:g}"]
        if truth_log is not None:
            self.args += ["--truth-log", str(truth_log)]
        if signing_key_file is not None:
            self.args += ["--signing-key", str(signing_key_file)]
        self.args += extra_args or []
        self.proc: subprocess.Popen[str] | None = None
        self.output: deque[str] = deque(maxlen=200)
        self._reader: threading.Thread | None = None

    def start(self, timeout_s: float = 60.0, while_starting: Callable[[], None] | None = None) -> None:
        """Launch and wait for the simulator's READY line; SimulatorError if it dies or times out.
        `while_starting` runs after the launch, before the wait (work of this process that can overlap the
        simulator's start); if it raises, the simulator is stopped and the error passes on."""
        self.proc = subprocess.Popen(
            self.args,
            stdin=subprocess.PIPE,  # never written; closed by the kernel whenever this process ends
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        ready = threading.Event()

        def read() -> None:
            assert self.proc is not None and self.proc.stdout is not None
            for line in self.proc.stdout:
                self.output.append(line.rstrip())
                if line.strip() == "READY":
                    ready.set()

        self._reader = threading.Thread(target=read, name="sitl-sim-output", daemon=True)
        self._reader.start()
        if while_starting is not None:
            try:
                while_starting()
            except BaseException:
                self.stop()
                raise
        deadline = time.monotonic() + timeout_s
        while not ready.wait(0.1):
            if self.proc.poll() is not None:
                tail = " | ".join(list(self.output)[-3:])
                raise SimulatorError(
                    f"the embedded simulator exited with status {self.proc.returncode}: {tail}"
                )
            if time.monotonic() > deadline:
                self.stop()
                raise SimulatorError(f"the embedded simulator did not report READY within {timeout_s:g} s")

    def stop(self, timeout_s: float = 10.0) -> int | None:
        """SIGTERM (then SIGKILL) the simulator; returns its exit status."""
        if self.proc is None:
            return None
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout_s)
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        if self._reader is not None:
            self._reader.join(timeout=2.0)
        return self.proc.returncode

    def __enter__(self) -> EmbeddedSimulator:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
