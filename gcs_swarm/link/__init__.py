"""The ground station's MAVLink link: the only place where bytes become state and commands become bytes.

Packets in: connection.py (endpoints) -> network.py (routing, binding) -> intake.py (the one way in: the
plain 50 Hz telemetry taken by a compiled walk, the rest decoded by pymavlink) -> the law of
intake_kernel.py and telemetry.py -> TelemetryState arrays. Commands out: attitude_commands.py (each
autopilot dialect's thrust, then command_limits.py's guard) -> setpoints.py / fleet.py -> channel.py.
fleet.py drives N vehicle.py links in one event loop; autopilots/ holds everything autopilot-specific.
docs/architecture.md describes each module.
"""
