"""One vehicle's parameters over the MAVLink parameter protocol (PARAM_REQUEST_READ / _LIST, PARAM_SET,
PARAM_VALUE), as `Operation`s timed in vehicle time with resends (gcs_swarm.link.operations). Parameters an
autopilot renamed between releases are read and set under whichever spelling the vehicle has (its dialect's
`other_param_name`)."""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import LinkError, MAVLinkMessage
from gcs_swarm.link.operations import COMMAND_RETRIES, Operation, Timeout, require_alive
from gcs_swarm.link.telemetry import VehicleTelemetry


class Parameters:
    """The parameters of the vehicle behind `channel`: `values` (name -> value) as last reported."""

    def __init__(self, channel: Channel, telemetry: VehicleTelemetry) -> None:
        self.channel = channel
        self.telemetry = telemetry
        self.name = channel.name
        self.values: dict[str, float] = {}
        self.types: dict[str, int] = {}  # name -> MAV_PARAM_TYPE
        self.count: int | None = None  # PARAM_VALUE.param_count (None before the first)
        self._updates: dict[str, int] = {}  # name -> PARAM_VALUEs received for it
        self._listing: dict[int, str] = {}  # param_index -> name, of the listing under way
        self._received = 0  # PARAM_VALUE messages received

    def on_param_value(self, m: MAVLinkMessage) -> None:
        """A PARAM_VALUE: remember the value, decoded in the autopilot's dialect (PX4 sends integers as their
        bytes); a non-finite value is counted invalid and ignored."""
        value = self.channel.autopilot.decode_param(m.param_value, m.param_type)
        if not math.isfinite(value):
            self.channel.stats.invalid += 1
            return
        name = m.param_id
        self.values[name] = value
        self.types[name] = m.param_type
        self.count = m.param_count
        self._updates[name] = self._updates.get(name, 0) + 1
        if 0 <= m.param_index < m.param_count:
            self._listing[m.param_index] = name
        self._received += 1

    def spelling(self, name: str) -> str:
        """The spelling of parameter `name` this vehicle answers to (its dialect's `other_param_name`: e.g.
        ArduCopter 4.7 renamed some), as learned from its PARAM_VALUEs; `name` until known."""
        other = self.channel.autopilot.other_param_name(name)
        if name not in self.values and other is not None and other in self.values:
            return other
        return name

    def op_get(self, name: str, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0) -> Operation[float]:
        """PARAM_REQUEST_READ by name until its PARAM_VALUE arrives, resent after each silent `timeout_s` of
        vehicle time; returns the value. A renamed parameter (SYSID_THISMAV / MAV_SYSID, ...) is read under
        whichever name the vehicle has: one quick try of the given name, then the other spelling."""
        other = self.channel.autopilot.other_param_name(name)
        name = self.spelling(name)
        if other is None or name in self.values or other in self.values:
            return (yield from self._op_get(name, retries, timeout_s))
        try:
            return (yield from self._op_get(name, 0, timeout_s))
        except LinkError:
            pass
        try:
            return (yield from self._op_get(other, retries, timeout_s))
        except LinkError:
            return (yield from self._op_get(name, retries, timeout_s))

    def _op_get(self, name: str, retries: int, timeout_s: float) -> Operation[float]:
        param_id = self._param_id(name)
        require_alive(self.channel, self.telemetry)
        ch = self.channel
        timeout = Timeout(timeout_s, self.telemetry.vehicle_clock)
        for _ in range(retries + 1):
            seen = self._updates.get(name, 0)
            ch.send(ch.mav.param_request_read_encode(ch.target_sysid, ch.compid, param_id, -1))
            timeout.restart()
            while not timeout.expired():
                yield
                if self._updates.get(name, 0) > seen:
                    return self.values[name]
        raise LinkError(
            f"{self.name} did not report parameter {name} ({retries + 1} requests; does it exist?)"
        )

    def op_set(
        self, name: str, value: float, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> Operation[float]:
        """PARAM_SET, verified by the PARAM_VALUE echo (float32 equality); resent up to `retries` times, after
        each silent `timeout_s` of vehicle time (a repeat is harmless: the same value is set again). A
        renamed parameter is read first, so that it is set under the vehicle's own spelling; so is any
        parameter of an autopilot that encodes by type (PX4 ignores a PARAM_SET of the wrong type)."""
        dialect = self.channel.autopilot
        renamed = dialect.other_param_name(name) is not None
        if (renamed or dialect.typed_params) and self.spelling(name) not in self.values:
            yield from self.op_get(name, retries, timeout_s)
        name = self.spelling(name)
        param_id = self._param_id(name)
        if not math.isfinite(value):
            raise LinkError(f"{self.name}: parameter {name} needs a finite value, not {value}")
        require_alive(self.channel, self.telemetry)
        ch = self.channel
        wanted = np.float32(value)
        echo: float | None = None
        timeout = Timeout(timeout_s, self.telemetry.vehicle_clock)
        for _ in range(retries + 1):
            seen = self._updates.get(name, 0)
            param_type = self.types.get(name, mavlink2.MAV_PARAM_TYPE_REAL32)
            try:
                wire = dialect.encode_param(value, param_type)
            except ValueError as err:
                raise LinkError(f"{self.name}: parameter {name}: {err}") from None
            ch.send(ch.mav.param_set_encode(ch.target_sysid, ch.compid, param_id, wire, param_type))
            timeout.restart()
            while not timeout.expired():
                yield
                if self._updates.get(name, 0) > seen:
                    echo = self.values[name]
                    if np.float32(echo) == wanted:
                        return echo
                    break
        if echo is None:
            raise LinkError(
                f"{self.name} did not confirm parameter {name} ({retries + 1} attempts; does it exist?)"
            )
        raise LinkError(f"{self.name} did not accept {name} = {value:g}: it reads back {echo:g}")

    def op_all(self, timeout_s: float = 60.0, gap_s: float = 0.5) -> Operation[dict[str, float]]:
        """PARAM_REQUEST_LIST; after `gap_s` without a PARAM_VALUE, missing indices are read one by one (both
        seconds of vehicle time). Returns name -> value of every parameter listed."""
        require_alive(self.channel, self.telemetry)
        ch = self.channel
        self._listing = {}
        ch.send(ch.mav.param_request_list_encode(ch.target_sysid, ch.compid))
        clock = self.telemetry.vehicle_clock
        timeout, gap = Timeout(timeout_s, clock), Timeout(gap_s, clock)
        received = self._received
        while self.count is None or len(self._listing) < self.count:
            yield
            if timeout.expired():
                raise LinkError(
                    f"{self.name} sent {len(self._listing)} of {self.count or '?'} parameters "
                    f"in {timeout_s:g} s"
                )
            if self._received != received:
                received = self._received
                gap.restart()
                continue
            if not gap.expired():
                continue
            gap.restart()
            if self.count is None:
                ch.send(ch.mav.param_request_list_encode(ch.target_sysid, ch.compid))
                continue
            missing = [k for k in range(self.count) if k not in self._listing]
            for index in missing[:32]:
                ch.send(ch.mav.param_request_read_encode(ch.target_sysid, ch.compid, b"", index))
        return {name: self.values[name] for name in self._listing.values()}

    def _param_id(self, name: str) -> bytes:
        if not name or len(name) > 16 or not name.isascii():
            raise LinkError(f"{self.name}: parameter name {name!r} must be 1-16 ASCII characters")
        return name.encode()
