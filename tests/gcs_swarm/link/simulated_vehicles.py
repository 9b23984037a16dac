"""The vehicles of the link tests: a real `python -m sitl_sim` on free loopback ports (started with
tests.sitl_sim.sim_process.start_sim, its stderr collected), and wire taps in front of its vehicles.

Tests get a fresh simulator each: a lockstep simulator waits for every client it has heard (docs/sitl.md,
lockstep rule 2), so a vehicle shared with a test that has finished would stall the next one for
--lockstep-timeout. A start costs about half a second (numba kernels come from the cache), so `Launcher`
keeps the next simulator of the most common kind (one vehicle, LOCKSTEP) booting while a test runs, and
stopped simulators are reaped at the end of the session.
"""

from __future__ import annotations

import concurrent.futures
import subprocess
import threading
from dataclasses import dataclass, field

from tests.gcs_swarm.link.wire_tap import WireTap
from tests.sitl_sim.sim_process import SimProcess, start_sim

ORIGIN = (47.397742, 8.545594, 488.0)  # the simulator's --home: the mission origin of every link test
SPACING_M = 5.0  # docs/sitl.md: without --mission vehicle i stands at x = 5 i m (ENU), facing north
LOCKSTEP = ("--lockstep", "--ready-delay", "0", "--lockstep-timeout", "1")  # ready at once


@dataclass
class SimulatedVehicles:
    """A running simulator (vehicle i: sysid sysid_base + i), its stderr so far, the taps opened on it."""

    sim: SimProcess
    sysid_base: int
    log: list[str] = field(default_factory=list)
    taps: list[WireTap] = field(default_factory=list)

    def sysid(self, index: int) -> int:
        return self.sysid_base + index

    def tap(self, index: int = 0, gcs_address: tuple[str, int] | None = None) -> WireTap:
        """A started WireTap in front of vehicle `index`, closed by `stop`."""
        self.taps.append(WireTap(self.sim.port(index), self.sysid(index), gcs_address).start())
        return self.taps[-1]

    def dropped(self, tap: WireTap) -> list[str]:
        """The simulator's stderr lines saying it stopped waiting for `tap`'s client (lockstep timeout)."""
        host, port = tap.client_address
        return [line for line in list(self.log) if f"{host}:{port} of vehicle" in line and "dropped" in line]

    def close_taps(self) -> None:
        """Close every tap opened so far."""
        for opened in self.taps:
            opened.close()
        self.taps.clear()


def reap(procs: list[subprocess.Popen[str]]) -> None:
    """Wait for terminated simulators (killed if one does not exit within 10 s)."""
    for proc in procs:
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


class Launcher:
    """Starts simulators for a test session; keeps one (1 vehicle, LOCKSTEP) booting ahead in a thread."""

    def __init__(self) -> None:
        self._ahead: concurrent.futures.Future[SimulatedVehicles] | None = None
        self._pool = concurrent.futures.ThreadPoolExecutor(max_workers=1, thread_name_prefix="sim-launcher")
        self._stopped: list[subprocess.Popen[str]] = []

    def start(self, count: int = 1, *args: str, sysid_base: int = 1) -> SimulatedVehicles:
        """A running simulator (args default: LOCKSTEP)."""
        args = args or LOCKSTEP
        if (count, args, sysid_base) != (1, LOCKSTEP, 1):
            return start_vehicles(count, *args, sysid_base=sysid_base)
        ahead = self._ahead or self._pool.submit(start_vehicles, 1, *LOCKSTEP)
        self._ahead = self._pool.submit(start_vehicles, 1, *LOCKSTEP)
        return ahead.result()

    def stop(self, vehicles: SimulatedVehicles) -> None:
        """Close its taps and terminate it (reaped in `close`)."""
        vehicles.close_taps()
        vehicles.sim.proc.terminate()
        self._stopped.append(vehicles.sim.proc)

    def close(self) -> None:
        """Stop the simulator booting ahead and reap every stopped one."""
        if self._ahead is not None:
            self.stop(self._ahead.result())
        self._pool.shutdown()
        reap(self._stopped)


def start_vehicles(count: int, *args: str, sysid_base: int = 1) -> SimulatedVehicles:
    """Start the simulator with `count` vehicles, ORIGIN as home, sysids from sysid_base, and `args`."""
    home = ",".join(f"{v:.7f}" for v in ORIGIN)
    sim = start_sim(f"--home={home}", "--sysid-base", str(sysid_base), *args, vehicles=count)
    vehicles = SimulatedVehicles(sim, sysid_base)
    assert sim.proc.stderr is not None
    stderr = sim.proc.stderr

    def read_log() -> None:
        for line in stderr:
            vehicles.log.append(line.strip())

    threading.Thread(target=read_log, daemon=True).start()
    return vehicles
