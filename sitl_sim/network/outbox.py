"""The messages one vehicle endpoint has queued for its peers, and the replies every handler sends."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.params import INT_TYPES, ParamTable, int32_as_float
from sitl_sim.network.streams import Framer


class Outbox:
    """Framed MAVLink 2 packets of one vehicle waiting for the endpoint's next flush, in order."""

    def __init__(self, framer: Framer) -> None:
        self.framer = framer
        self.tx = framer.mav  # pymavlink encoder of this vehicle's messages
        self.packets: list[bytes] = []

    def send(self, msg: mavlink2.MAVLink_message) -> None:
        """Queue a message for every live peer."""
        self.packets.append(self.framer.pack(msg))

    def append(self, packet: bytes) -> None:
        """Queue an already framed packet."""
        self.packets.append(packet)

    def take(self) -> list[bytes]:
        """Everything queued, oldest first; the outbox is empty afterwards (`packets` stays the same list, so
        the simulator can watch every outbox with one any())."""
        packets = self.packets.copy()
        self.packets.clear()
        return packets

    def ack(self, command: int, result: int, msg: mavlink2.MAVLink_message) -> None:
        """COMMAND_ACK addressed to the sender of msg."""
        self.send(
            self.tx.command_ack_encode(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        )

    def send_param(self, params: ParamTable, vehicle: int, j: int, bytewise: bool = False) -> None:
        """PARAM_VALUE of column j of `vehicle`, param_index/param_count counted over what it shows.

        bytewise: integer parameters travel as their int32 bytes reinterpreted as the float (PX4,
        mavlink_parameters.cpp); otherwise integers are sent as float values (ArduPilot, PARAM_FLOAT)."""
        spec = params.specs[j]
        value = float(params.values[vehicle, j])
        if bytewise and spec.type in INT_TYPES:
            value = int32_as_float(int(value))
        listing = params.listing(vehicle)
        index = listing.index(j) if j in listing else 65535
        self.send(self.tx.param_value_encode(spec.name.encode(), value, spec.type, len(listing), index))
