"""What the network layer needs from the simulator that owns it (sitl_sim.simulator.Simulator provides it).

A Protocol, so that the endpoints and their message handlers depend on this small surface and not on the
simulator module above them (no import cycle).
"""

from __future__ import annotations

from typing import Protocol

from sitl_sim.autopilot.copter import Autopilot
from sitl_sim.autopilot.fence import FenceItem
from sitl_sim.autopilot.params import ParamTable
from sitl_sim.clock import LockstepClients
from sitl_sim.network.streams import Geodesy, StreamSchedule, TelemetryView


class SimulatorServices(Protocol):
    """The fleet-wide state and services an endpoint and its handlers use. Times are simulated."""

    lockstep: LockstepClients | None  # the lockstep clients, None when running in (sped-up) real time
    lockstep_started: bool  # whether the lockstep clock has left its boot wait for the clients
    params: ParamTable  # every vehicle's parameters
    autopilot: Autopilot  # the autopilot of the fleet
    streams: StreamSchedule  # the telemetry streams' intervals
    geodesy: Geodesy  # the local ENU frame's geodetic origin

    @property
    def t(self) -> float:
        """Simulated seconds since boot."""

    @property
    def time_us(self) -> int:
        """Simulated microseconds since boot (exact integer)."""

    def telemetry_view(self) -> TelemetryView:
        """The fleet's telemetry at the current instant."""

    def on_new_peer(self, vehicle: int) -> None:
        """A client spoke to `vehicle` for the first time."""

    def set_param(self, i: int, name: str, value: float) -> None:
        """Store a checked parameter value set on vehicle i."""

    def store_fence(self, i: int, items: list[FenceItem]) -> None:
        """Store vehicle i's uploaded fence items."""
