"""Which autopilot each simulated vehicle impersonates on the wire: the names, and parsing them.

The physics, the attitude controller and the shared outer loop (sitl_sim.autopilot.copter) are the same for
every vehicle; what differs per autopilot (modes, arming rules, failsafes, parameter names and encoding,
default telemetry) lives in one module per persona: ArduCopter's in copter.py / modes.py / params.py, PX4's in
px4.py. Code elsewhere asks `Autopilot.persona(i)`, never compares names itself.
"""

from __future__ import annotations

ARDUPILOT, PX4 = "ardupilot", "px4"
AUTOPILOTS = (ARDUPILOT, PX4)


def parse_autopilots(text: str, vehicles: int) -> tuple[str, ...]:
    """`--autopilot` text -> one name per vehicle: a single name applies to all, a comma list gives one per
    vehicle. Raises ValueError (a one-line reason) for an unknown name or a wrong count."""
    names = tuple(part.strip().lower() for part in text.split(","))
    for name in names:
        if name not in AUTOPILOTS:
            raise ValueError(f"--autopilot {name!r} is not one of {', '.join(AUTOPILOTS)}")
    if len(names) == 1:
        return names * vehicles
    if len(names) != vehicles:
        raise ValueError(f"--autopilot lists {len(names)} autopilots for {vehicles} vehicles")
    return names
