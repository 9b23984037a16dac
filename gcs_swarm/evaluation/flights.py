"""A flight and its evaluation: `fly_and_report` (the flight, then report.json/md/png from its run folder, and
the exit status of `gcs-swarm run`), and for experiments one derived mission flown on free UDP ports (a real
lockstep flight through MAVLink against the embedded simulator) with the figures of its report as one flat
result.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gcs_swarm.evaluation.report import SUMMARY_KEYS, write_report
from gcs_swarm.flight.fly import EXIT_FAILED, EXIT_OK, EXIT_USER_ERROR, Flown, RunOptions, fly_mission
from swarm_common.ports import free_udp_base

FLIGHT_TRIES = 3  # a port taken between the probe and the simulator's bind: try again on other ports
RESULT_KEYS = SUMMARY_KEYS  # the report figures each campaign result line carries
WHOLE_FLIGHT_RESULT_KEYS = (  # ... and these of report.json's whole_flight (docs/metrics.md)
    "slot_error_rms_m",
    "slot_error_max_m",
    "cusps_total",
    "cusp_times_s",
    "max_tilt_command_rate_rad_s",
    "pitch_command_chatter_max_rad",
    "min_separation_whole_flight_m",
    "min_altitude_in_formation_m",
    "assembly_s",
    "slot_error_assembled_rms_m",
    "slot_error_assembled_max_m",
    "shape_formed_s",
    "leader_path_ratio",
)


def fly_and_report(
    mission_path: str, options: RunOptions, say: Callable[[str], None]
) -> tuple[int, Flown, dict[str, Any] | None]:
    """Fly the mission, then write its report when formation flight began. Returns the exit status of
    `gcs-swarm run` (0 flown and every vehicle reached its goal with no collision, no lost vehicle and no
    safety event; with `--airborne land` every vehicle landed and disarmed; 1 flown but failed; 2 user error),
    the flight and the report (None when none was written)."""
    flown = fly_mission(mission_path, options, say)
    if not flown.report_due:
        return flown.status, flown, None
    assert flown.run_dir is not None and flown.mission is not None
    report = write_report(flown.run_dir, flown.mission)
    ok = (
        report["reached"]
        and report["collisions"] == 0
        and not flown.result.lost
        and not report["safety_events"]
    )
    status = flown.status if flown.status != EXIT_OK else (EXIT_OK if ok else EXIT_FAILED)
    return status, flown, report


def fly(mission_path: Path, run_dir: Path, vehicles: int, link_loss: float = 0.0) -> int:
    """Fly the mission into run_dir with the embedded simulator on free ports, its links losing packets with
    probability link_loss; the run command's exit status (0 reached without collision, 1 failed, 2 could not
    fly). Quiet: only error lines are printed."""
    status = EXIT_USER_ERROR
    # RunOptions.sim_args (the embedded simulator's extra arguments) is only needed for link faults.
    sim_args: tuple[str, ...] = (f"--link-loss={link_loss:g}",) if link_loss > 0 else ()
    for _ in range(FLIGHT_TRIES):
        options = RunOptions(
            out_dir=run_dir, base_port=free_udp_base(vehicles), quiet=True, sim_args=sim_args
        )
        status, flown, _ = fly_and_report(str(mission_path), options, lambda _line: None)
        if flown.error is not None:
            print(f"error: {flown.error}")
        if status != EXIT_USER_ERROR:
            break
    return status


def flight_figures(run_dir: Path, status: int, collision_radius: float) -> dict[str, Any]:
    """The result of one flown run: exit status, success (status 0), collision (a crashed vehicle, an obstacle
    clearance <= collision_radius or two vehicles closer than twice it, spec 10) and the report figures
    (None where the run has no report, e.g. it never reached formation flight)."""
    report_path = run_dir / "report.json"
    report = json.loads(report_path.read_text()) if report_path.exists() else {}
    flight_path = run_dir / "flight.json"
    flight = json.loads(flight_path.read_text()) if flight_path.exists() else {}
    clearance = report.get("min_obstacle_clearance_m")
    separation = report.get("min_separation_m")
    collision = bool(
        report.get("collisions")
        or (clearance is not None and clearance <= collision_radius)
        or (separation is not None and separation <= 2 * collision_radius)
    )
    result: dict[str, Any] = {"status": status, "success": status == 0, "collision": collision}
    result |= {key: report.get(key) for key in RESULT_KEYS}
    whole = report.get("whole_flight") or {}
    result |= {key: whole.get(key) for key in WHOLE_FLIGHT_RESULT_KEYS}
    result["safety_events"] = list(report.get("safety_events", []))
    result["reached"] = bool(report.get("reached", False))
    result["events"] = list(flight.get("events", []))[:10]
    return result
