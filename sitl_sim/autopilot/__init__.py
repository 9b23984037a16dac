"""The ArduCopter persona of the simulated vehicles: flight modes, arming and pre-arm checks, guided targets,
takeoff and landing, failsafes, parameters and geofences, over the vehicle model. No MAVLink I/O here (the
network layer turns messages into these calls); MAVLink constants only for the values ArduCopter reports."""
