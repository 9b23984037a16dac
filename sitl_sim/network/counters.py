"""What one vehicle endpoint received and what it threw away, by reason."""

from __future__ import annotations

from dataclasses import dataclass, fields


@dataclass
class LinkCounters:
    """Per-endpoint message counters (the simulator prints them at exit, one line per vehicle).

    `invalid` and `refused` are decisions of the handlers, taken explicitly as ArduCopter takes them;
    `handler_errors` are exceptions escaping a handler: a bug of the simulator, never a property of the input
    (logged with its traceback; the fuzz tests require it to stay 0).
    """

    received: int = 0  # valid MAVLink messages addressed to this vehicle
    bad_frames: int = 0  # garbage bytes, bad CRC, unknown ids, truncated frames
    foreign: int = 0  # messages for another system/component
    invalid: int = 0  # NaN/inf/absurd fields, unsupported frames, malformed requests
    refused: int = 0  # well-formed commands/targets the autopilot refused (ArduCopter rules)
    unsigned: int = 0  # with a signing key: unsigned, wrongly signed or replayed messages dropped
    handler_errors: int = 0  # exceptions raised while handling a message (simulator bugs)

    def summary(self) -> str:
        """One line "name=value ..." of all counters."""
        return " ".join(f"{f.name}={getattr(self, f.name)}" for f in fields(self))
