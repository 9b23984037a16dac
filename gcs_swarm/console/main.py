"""`gcs-swarm console MISSION.yaml`: the same wiring as `gcs-swarm run` (embedded simulator or running
vehicles, Fleet, RunRecord, MissionRunner, run folder and report) with the operator in the loop.

Interactive (full-screen prompt_toolkit UI) when stdin and stdout are terminals and no --script is given;
plain line mode otherwise. Exit status: 0 ok; 1 a scripted command failed; 2 user error (mission file,
simulator, vehicles not reachable).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from gcs_swarm.console.page_actions import ConsoleOperator
from gcs_swarm.console.script import PlainConsole
from gcs_swarm.console.session import FlightSession
from gcs_swarm.evaluation.report import write_report
from gcs_swarm.flight.embedded_sim import EmbeddedSimulator, SimulatorError
from gcs_swarm.flight.fly import (
    SetupChoices,
    lockstep_spin_s,
    mission_fleet,
    set_up_run,
    start_embedded_simulator,
    write_flight,
)
from gcs_swarm.flight.result import FlightResult
from gcs_swarm.flight.run_folder import RECORD_FILE
from gcs_swarm.flight.run_record import RunRecord
from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.link.signing import SigningKeyError
from gcs_swarm.mission import MissionError
from gcs_swarm.web.live import start_live_page

EXIT_OK, EXIT_USER_ERROR = 0, 2
HISTORY_FILE = "console_history.txt"


@dataclass(frozen=True)
class ConsoleOptions(SetupChoices):
    """Command-line choices of `gcs-swarm console`."""

    script: Path | None = None
    yes: bool = False
    web: str | None = None  # --web HOST:PORT: the live page (gcs_swarm.web.live)
    web_token: str | None = None  # --web-token: the page's actions allowed with it


def console_command(mission_path: str, options: ConsoleOptions) -> int:
    """The whole `console` command."""
    script = None
    if options.script is not None:
        try:
            script = options.script.read_text().splitlines()
        except (OSError, UnicodeDecodeError) as exc:
            print(f"error: cannot read the script {options.script}: {exc}")
            return EXIT_USER_ERROR
    try:
        setup = set_up_run(mission_path, options)
    except (MissionError, SigningKeyError) as exc:
        print(f"error: {exc}")
        return EXIT_USER_ERROR
    mission, run_dir, base_port = setup.mission, setup.run_dir, setup.base_port
    page = None
    if options.web is not None:
        page = start_live_page(options.web, options.web_token)
        if page is None:
            return EXIT_USER_ERROR
    embedded = base_port is not None
    interactive = script is None and sys.stdin.isatty() and sys.stdout.isatty()
    wall0 = time.monotonic()
    sim: EmbeddedSimulator | None = None
    result = FlightResult()
    latencies: list[float] = []
    limited = 0
    link_stats: dict[str, dict[str, dict[str, int]]] | None = None
    link_use: dict[str, dict[str, object]] | None = None
    status = EXIT_OK
    if not interactive:
        print(f"run folder {run_dir}", flush=True)
    try:
        if base_port is not None:
            sim = start_embedded_simulator(mission, run_dir, base_port, setup.key_file)
        where = (
            f"embedded simulator on 127.0.0.1:{base_port}.." if embedded else "vehicles of the mission file"
        )
        spin_s = lockstep_spin_s(mission, embedded)
        with mission_fleet(mission, base_port, run_dir, setup.key, spin_s) as fleet:
            record = RunRecord(run_dir / RECORD_FILE)
            runner = MissionRunner(
                mission,
                fleet,
                record,
                progress=lambda _line: None,  # FlightSession takes the progress lines into its event log
                progress_period_s=2.0 if script is not None else 1e9,
            )
            # A person typing wants vehicle time at wall-clock pace; a script runs as fast as the link goes.
            session = FlightSession(runner, run_dir, realtime=sys.stdin.isatty() and script is None)
            if page is not None:  # after the session: the page's pump hook follows the session's
                page.watch(runner)
                page.serve_actions(ConsoleOperator(session, mission, options.yes))
            session.start()
            try:
                if interactive:
                    from gcs_swarm.console.app import ConsoleApp

                    title = f"swarm-gcs console: {mission.name}, {len(mission.vehicles)} vehicles, {where}"
                    title += "" if page is None else f", page {page.url}"  # the line printed is hidden
                    app = ConsoleApp(session, mission, title, run_dir / HISTORY_FILE, options.yes)
                    status = app.run()
                else:
                    print(f"connecting to the {where}", flush=True)
                    lines = script if script is not None else sys.stdin
                    status = PlainConsole(session, mission, lines, options.yes, _print).run()
            finally:
                session.stop()
                record.close()
                result = runner.result
                latencies = runner.tick_latency_s
                limited = runner.commands_limited
                timing = runner.timing_summary()
                link_stats = {"vehicles": fleet.stats(), "forwards": fleet.forward_stats()}
                link_use = fleet.link_use.summary()
                result.events.extend(fleet.link_use.events)
    except (SimulatorError, MissionError) as exc:
        print(f"error: {exc}")
        return EXIT_USER_ERROR
    finally:
        if sim is not None:
            sim.stop()
        if page is not None:
            page.stop()
    wall_s = time.monotonic() - wall0
    write_flight(
        run_dir, mission, mission_path, result, wall_s, latencies, limited, link_stats, timing, link_use
    )
    if result.t_formation_start is not None:
        report = write_report(run_dir, mission)
        print(
            f"reached={report['reached']} collisions={report['collisions']} "
            f"min_separation={report['min_separation_m']} m formation_rms={report['formation_rms_m']} m"
        )
    print(f"run folder {run_dir}")
    return status


def _print(line: str) -> None:
    print(line, flush=True)
