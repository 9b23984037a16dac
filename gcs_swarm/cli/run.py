"""`gcs-swarm run MISSION.yaml`: fly a mission (against the embedded simulator or running vehicles), write
the run folder (telemetry.tlog, truth.csv, record.csv, flight.json, report.json/md/png), print a summary and
return the exit status: 0 flown and every vehicle reached its goal with no collision (with `--airborne land`:
every vehicle landed and disarmed); 1 flown but failed; 2 user error.
"""

from __future__ import annotations

from gcs_swarm.evaluation.flights import fly_and_report
from gcs_swarm.flight.fly import RunOptions


def run_command(mission_path: str, options: RunOptions) -> int:
    """The whole `run` command; prints progress and a summary."""
    say = (lambda _msg: None) if options.quiet else (lambda msg: print(msg, flush=True))
    status, flown, report = fly_and_report(mission_path, options, say)
    if flown.error is not None:
        print(f"error: {flown.error}")
    if report is None:
        return status
    say(
        f"reached={report['reached']} time_to_goal={report['time_to_goal_s']} s "
        f"collisions={report['collisions']} "
        f"min_separation={report['min_separation_m']} m min_clearance={report['min_obstacle_clearance_m']} m "
        f"formation_rms={report['formation_rms_m']} m (from {report['source']})"
    )
    whole = report.get("whole_flight") or {}
    say(
        f"whole flight: slot error rms {whole.get('slot_error_rms_m')} m, "
        f"max {whole.get('slot_error_max_m')} m, "
        f"cusps {whole.get('cusps_total')}, max tilt-command rate {whole.get('max_tilt_command_rate_rad_s')} "
        f"rad/s, min altitude {whole.get('min_altitude_in_formation_m')} m"
    )
    for taken in report.get("taken_over", []):
        say(f"TAKEN OVER: {taken['vehicle']} at t={taken['t_s']} s into {taken['mode']} (by {taken['by']})")
    for event in report.get("safety_events", []):
        say(f"SAFETY EVENT: {event}")
    assert flown.run_dir is not None
    say(f"report: {flown.run_dir / 'report.md'}")
    return status
