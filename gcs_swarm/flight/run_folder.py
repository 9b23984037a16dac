"""The files of a run folder (runs/<time>-<mission>/), written by the flight and read by the evaluation."""

TRUTH_FILE = "truth.csv"  # the simulator's ground truth, one row per vehicle per truth sample
RECORD_FILE = "record.csv"  # the ground station's own record, one row per vehicle per control tick
FLIGHT_FILE = "flight.json"  # how the flight went: phases, events, offsets, tick latencies
