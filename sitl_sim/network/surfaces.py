"""Each persona's MAVLink surface: the handler classes that answer for a vehicle of that persona, and whether
its lone SET_ATTITUDE_TARGET datagrams may take the endpoint's short cut (sitl_sim.network.endpoint)."""

from __future__ import annotations

from typing import NamedTuple

from sitl_sim.autopilot.arducopter import ArduCopter
from sitl_sim.autopilot.persona import Persona
from sitl_sim.autopilot.px4 import Px4
from sitl_sim.network.commands import CommandHandlers
from sitl_sim.network.px4_commands import Px4CommandHandlers, Px4SetpointHandlers
from sitl_sim.network.setpoints import SetpointHandlers


class Surface(NamedTuple):
    """commands: its CommandHandlers class; setpoints: its SetpointHandlers class; attitude_short_cut: its
    setpoint handler's `attitude_target` may take unpacked SET_ATTITUDE_TARGET fields (no further checks)."""

    commands: type[CommandHandlers]
    setpoints: type[SetpointHandlers]
    attitude_short_cut: bool


SURFACES: dict[type[Persona], Surface] = {  # by the persona's class
    ArduCopter: Surface(CommandHandlers, SetpointHandlers, True),
    Px4: Surface(Px4CommandHandlers, Px4SetpointHandlers, False),  # its attitude handler checks more
}
