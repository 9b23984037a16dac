"""The vehicles' MAVLink side: one UDP endpoint per vehicle, the message handlers (commands, parameters,
guided setpoints, the fence mission protocol), telemetry streams, signing and the faulty radio link. Uses the
simulator only through network.services.SimulatorServices."""
