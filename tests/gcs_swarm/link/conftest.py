"""Fixtures: real simulated vehicles (simulated_vehicles.py), wire taps in front of them, fleets over the
taps; every process, socket and fleet cleaned up."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig, VehicleLink
from tests.gcs_swarm.link.simulated_vehicles import ORIGIN, Launcher, SimulatedVehicles
from tests.gcs_swarm.link.wire_tap import WireTap


@pytest.fixture(scope="session")
def launcher() -> Iterator[Launcher]:
    """Starts the tests' simulators; reaps them all at the end of the session."""
    sims = Launcher()
    try:
        yield sims
    finally:
        sims.close()


@pytest.fixture
def simulator(launcher: Launcher) -> Iterator[Callable[..., SimulatedVehicles]]:
    """Factory: simulator(count=1, *args, sysid_base=1) -> a running sitl_sim (args default: LOCKSTEP: ready
    at once), stopped with its taps at teardown."""
    started: list[SimulatedVehicles] = []

    def make(count: int = 1, *args: str, sysid_base: int = 1) -> SimulatedVehicles:
        started.append(launcher.start(count, *args, sysid_base=sysid_base))
        return started[-1]

    yield make
    for vehicles in started:
        launcher.stop(vehicles)


@pytest.fixture
def fleet_of() -> Iterator[Callable[..., Fleet]]:
    """Factory: fleet_of(*taps, names=, sysids=, **fleet options) -> unconnected Fleet, closed after."""
    fleets: list[Fleet] = []

    def make(
        *taps: WireTap,
        names: list[str] | None = None,
        sysids: list[int | None] | None = None,
        **options: object,
    ) -> Fleet:
        names = names or [f"v{k}" for k in range(len(taps))]
        sysids = sysids or [None] * len(taps)
        configs = [VehicleConfig(n, t.connection, s) for n, t, s in zip(names, taps, sysids, strict=True)]
        fleet = Fleet(configs, ORIGIN, **options)  # type: ignore[arg-type]
        fleets.append(fleet)
        return fleet

    yield make
    for fleet in fleets:
        fleet.close()


@pytest.fixture
def lead(
    simulator: Callable[..., SimulatedVehicles], fleet_of: Callable[..., Fleet]
) -> Callable[..., tuple[Fleet, VehicleLink, WireTap]]:
    """Factory: lead(**fleet options) -> (fleet, link, tap): one simulated vehicle (lockstep, ready at once)
    named lead, connected through a wire tap, after a parameter round trip (so the vehicle has handled
    connect's requests)."""

    def make(**options: object) -> tuple[Fleet, VehicleLink, WireTap]:
        wire = simulator(1).tap(0)
        fleet = fleet_of(wire, names=["lead"], **options)
        fleet.connect(timeout_s=10.0)
        link = fleet.vehicle("lead")
        fleet.run([link.parameters.op_get("GUID_OPTIONS")])
        return fleet, link, wire

    return make
