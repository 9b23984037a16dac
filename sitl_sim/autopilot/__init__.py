"""The simulated autopilot over the vehicle model: one shared autopilot (copter.py: ArduCopter-numbered modes,
arming, guided targets, takeoff and landing, geofences, the compiled outer loop of outer_loop.py) and the
personas that give each vehicle an autopilot's face and rules (persona.py: the base class and registry;
arducopter.py: ArduCopter 4.7; px4.py: PX4), with the parameter table (params.py). No MAVLink I/O here (the
network layer turns messages into these calls); MAVLink constants only for the values the personas report."""
