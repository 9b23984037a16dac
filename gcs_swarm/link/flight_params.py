"""Parameters a run sets on its vehicles for the flight, remembered with their original values and put back
afterwards, so that the next pilot of a vehicle does not inherit a ground station's settings.

A value is restored only on a vehicle that is disarmed (on the ground) when the run ends: giving a flying
vehicle back, say, FS_GCS_ENABLE = 0 as the ground station leaves would take its failsafe away. What was
changed, and whether it was put back, goes to flight.json (`params_changed`) and the report.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.operations import Operation
from gcs_swarm.link.vehicle import VehicleLink


@dataclass
class ParamChange:
    """One parameter of one vehicle: its value before the run, the value flown, whether it was restored."""

    vehicle: str
    name: str
    original: float
    flown: float
    restored: bool = False

    def as_json(self) -> dict[str, object]:
        return asdict(self)


class FlightParams:
    """Sets parameters fleet-wide for the flight and restores them (see the module docstring)."""

    def __init__(self, fleet: Fleet) -> None:
        self.fleet = fleet
        self.changes: list[ParamChange] = []
        # changes that are not parameters (the fence items, gcs_swarm.flight.geofence): name -> the operation
        # that puts the original back on a vehicle
        self.restorers: dict[str, Callable[[VehicleLink, ParamChange], Operation[Any]]] = {}

    def set_all(self, name: str, value: float, vehicles: Iterable[int] | None = None) -> None:
        """Read `name` on every live vehicle (of the rows `vehicles`, default all), then set it to `value`
        (read back); LinkError as the fleet's."""
        fleet = self.fleet
        links = fleet.select(vehicles)
        originals = fleet.param_get_all(name, [link.index for link in links])
        fleet.param_set_all(name, value, [link.index for link in links])
        for link, original in zip(links, originals, strict=True):
            if np.float32(original) != np.float32(value):
                self.changes.append(ParamChange(link.name, name, float(original), float(value)))

    def restore(self) -> list[ParamChange]:
        """Put every changed value back on vehicles that are disarmed and still heard (best effort: a vehicle
        that refuses or does not answer keeps the flown value and is reported so). Returns the changes."""
        fleet = self.fleet
        todo = [c for c in self.changes if not c.restored]
        by_name = {link.name: link for link in fleet.links}
        for change in todo:
            link = by_name[change.vehicle]
            i = link.index
            if not fleet.alive[i] or fleet.armed[i]:
                continue
            restorer = self.restorers.get(change.name)
            try:
                if restorer is not None:
                    fleet.run([restorer(link, change)])
                else:
                    fleet.run([link.parameters.op_set(change.name, change.original)])
                change.restored = True
            except LinkError:
                continue
        return self.changes
