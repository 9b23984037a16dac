"""Flying one derived mission for an experiment: free UDP ports, `run_command` (a real lockstep flight through
MAVLink against the embedded simulator) and the figures of its report.json as one flat result.
"""

from __future__ import annotations

import json
import random
import socket
from pathlib import Path
from typing import Any

from gcs_swarm.report import SUMMARY_KEYS
from gcs_swarm.run_command import EXIT_USER_ERROR, RunOptions, run_command

PORT_RANGE = (20000, 60000)
PORT_TRIES = 200
FLIGHT_TRIES = 3  # a port taken between the probe and the simulator's bind: try again on other ports
RESULT_KEYS = SUMMARY_KEYS  # the report figures each campaign result line carries
WHOLE_FLIGHT_RESULT_KEYS = (  # ... and these of report.json's whole_flight (docs/metrics.md)
    "slot_error_rms_m",
    "slot_error_max_m",
    "cusps_total",
    "max_tilt_command_rate_rad_s",
    "pitch_command_chatter_max_rad",
    "min_separation_whole_flight_m",
    "min_altitude_in_formation_m",
)


def free_udp_base(count: int) -> int:
    """A base port with base..base+count-1 free on 127.0.0.1, probed from a random start so that concurrent
    workers rarely pick the same block. RuntimeError when none is found."""
    rng = random.Random()
    for _ in range(PORT_TRIES):
        base = rng.randrange(PORT_RANGE[0], PORT_RANGE[1] - count)
        socks: list[socket.socket] = []
        try:
            for i in range(count):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", base + i))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError(f"no block of {count} free UDP ports found")


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
        status = run_command(str(mission_path), options)
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
