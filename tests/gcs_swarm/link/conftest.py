"""Fixtures: fake vehicles (threads on 127.0.0.1 free ports) and fleets over them, always cleaned up."""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest

from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig, VehicleLink
from tests.gcs_swarm.link.fake_vehicle import ORIGIN, FakeVehicle


@pytest.fixture
def fake() -> Iterator[Callable[..., FakeVehicle]]:
    """Factory: fake(sysid, **options) -> a started FakeVehicle, stopped at teardown."""
    started: list[FakeVehicle] = []

    def make(sysid: int = 1, **options: object) -> FakeVehicle:
        vehicle = FakeVehicle(sysid, **options).start()  # type: ignore[arg-type]
        started.append(vehicle)
        return vehicle

    yield make
    for vehicle in started:
        vehicle.stop()


@pytest.fixture
def fleet_of() -> Iterator[Callable[..., Fleet]]:
    """Factory: fleet_of(*fakes, names=, sysids=, **fleet options) -> unconnected Fleet, closed after."""
    fleets: list[Fleet] = []

    def make(
        *fakes: FakeVehicle,
        names: list[str] | None = None,
        sysids: list[int | None] | None = None,
        **options: object,
    ) -> Fleet:
        names = names or [f"v{k}" for k in range(len(fakes))]
        sysids = sysids or [None] * len(fakes)
        configs = [VehicleConfig(n, f.connection, s) for n, f, s in zip(names, fakes, sysids, strict=True)]
        fleet = Fleet(configs, ORIGIN, **options)  # type: ignore[arg-type]
        fleets.append(fleet)
        return fleet

    yield make
    for fleet in fleets:
        fleet.close()


@pytest.fixture
def lead(
    fake: Callable[..., FakeVehicle], fleet_of: Callable[..., Fleet]
) -> Callable[..., tuple[Fleet, VehicleLink, FakeVehicle]]:
    """Factory: lead(**fake options) -> (fleet, link, fake) with one connected lockstep vehicle named lead."""

    def make(**options: object) -> tuple[Fleet, VehicleLink, FakeVehicle]:
        vehicle = fake(1, lockstep=True, **options)
        fleet = fleet_of(vehicle, names=["lead"])
        fleet.connect(timeout_s=3.0)
        link = fleet.vehicle("lead")
        fleet.run(
            [link.parameters.op_get("SYSID_THISMAV")]
        )  # a round trip: the vehicle has now handled connect's requests
        return fleet, link, vehicle

    return make
