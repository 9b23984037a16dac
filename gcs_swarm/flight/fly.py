"""Fly a mission (against the embedded simulator or running vehicles) into a run folder: telemetry.tlog,
truth.csv, record.csv, flight.json. The report is the evaluation's job
(gcs_swarm.evaluation.flights.fly_and_report).
Exit statuses: 0 flown, 1 flown but failed, 2 user error; the sentence that ended a flight early is
returned (`Flown.error`) for the front end to show.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import numpy as np

from gcs_swarm.flight.embedded_sim import EmbeddedSimulator, SimulatorError
from gcs_swarm.flight.phase import Phase
from gcs_swarm.flight.preflight import PreflightError
from gcs_swarm.flight.result import FlightResult
from gcs_swarm.flight.run_folder import FLIGHT_FILE, RECORD_FILE, TRUTH_FILE
from gcs_swarm.flight.run_record import RunRecord
from gcs_swarm.flight.runner import MissionRunner
from gcs_swarm.guidance.fleet_controller import prepare_kernels
from gcs_swarm.link import signing
from gcs_swarm.link.command_mode import CommandModeError, CommandPlan, command_plan, link_budget
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.forward import ForwardConfig
from gcs_swarm.link.vehicle import VehicleConfig
from gcs_swarm.mission import Mission, MissionError, load_mission
from gcs_swarm.mission.geometry import mission_offsets

log = logging.getLogger(__name__)

EXIT_OK, EXIT_FAILED, EXIT_USER_ERROR = 0, 1, 2


@dataclass(frozen=True)
class SetupChoices:
    """The command-line choices every flying command shares (`gcs-swarm run`, `gcs-swarm console`)."""

    out_dir: Path | None = None
    connect_only: bool = False
    base_port: int | None = None
    keep_params: bool = False  # leave the flight parameters as flown (else run.keep_params decides)
    forward: tuple[str, ...] = ()  # other ground stations watching through this one (added to run.forward)
    forward_rw: bool = False  # the forwards may command the vehicles (also run.forward_rw)


@dataclass(frozen=True)
class RunOptions(SetupChoices):
    """Command-line choices of `gcs-swarm run`."""

    time_mode: str | None = None  # override of run.simulator.time_mode
    seed: int | None = None
    quiet: bool = False
    sim_args: tuple[str, ...] = ()  # passed verbatim to the embedded simulator (e.g. --link-loss=0.1)
    crash_at: float | None = None  # vehicle s at which the ground station SIGKILLs itself (a rehearsal)
    airborne: str | None = None  # vehicles found flying: "finish" the mission or "land" them (None: refuse)
    watch: Callable[[MissionRunner], None] | None = None  # given the runner before it flies (`--web`)


@dataclass(frozen=True)
class RunSetup:
    """A mission as the command line amends it (keep_params, forwards), its run folder (created), its signing
    key file and key (None: unsigned), and the embedded simulator's first UDP port (None: the mission's own
    connections, no embedded simulator)."""

    mission: Mission
    run_dir: Path
    key_file: Path | None
    key: bytes | None
    base_port: int | None


def set_up_run(mission_path: str, choices: SetupChoices) -> RunSetup:
    """Load the mission and apply the command line's choices; MissionError or signing.SigningKeyError (one
    sentence) when it cannot fly."""
    mission = load_mission(mission_path)
    if choices.keep_params:
        mission = dataclasses.replace(mission, run=dataclasses.replace(mission.run, keep_params=True))
    mission = with_forwards(mission, choices.forward, choices.forward_rw)
    key_file, key = signing_key(mission)
    run_dir = choices.out_dir or default_run_dir(mission)
    run_dir.mkdir(parents=True, exist_ok=True)
    spec = mission.run.simulator
    embedded = spec.embedded and not choices.connect_only
    return RunSetup(
        mission, run_dir, key_file, key, (choices.base_port or spec.base_port) if embedded else None
    )


def latency_summary(latencies_s: list[float]) -> dict[str, float] | None:
    """Median, p99 and max of per-tick latencies, in ms (None without ticks)."""
    if not latencies_s:
        return None
    ms = np.asarray(latencies_s) * 1000.0
    return {
        k: round(float(v), 4)
        for k, v in (("median", np.median(ms)), ("p99", np.percentile(ms, 99)), ("max", ms.max()))
    }


def write_flight(
    run_dir: Path,
    mission: Mission,
    mission_path: str,
    result: FlightResult,
    wall_s: float,
    tick_latency_s: list[float],
    commands_limited: int,
    link_stats: dict[str, dict[str, dict[str, int]]] | None = None,
    tick_timing: dict[str, object] | None = None,
    link_use: dict[str, dict[str, object]] | None = None,
) -> None:
    """flight.json: what the ground station did (phases, arrival, lost vehicles, events, tick latency, how
    many vehicle-ticks' commands the final guard changed, stale-telemetry figures of docs/reliability.md);
    with the mission path it lets `gcs-swarm report` rebuild the report of a run folder. `tick_timing`: the
    worst formation tick, the time per phase and the frames missed (flight.tick_timing), written as given."""
    flight = {
        "mission": mission.name,
        "mission_path": str(Path(mission_path).resolve()),
        "phase_reached": result.phase_reached,
        "arrived": result.arrived,
        "t_formation_start": result.t_formation_start,
        "t_formation_end": result.t_formation_end,
        "final_targets": None if result.final_targets is None else np.asarray(result.final_targets).tolist(),
        "leader": mission.leader_index if result.leader is None else result.leader,
        "offsets": (mission_offsets(mission) if result.offsets is None else result.offsets).tolist(),
        "lost": result.lost,
        "lost_at_s": result.lost_at,
        "events": result.events,
        "ticks": result.ticks,
        "tick_latency_ms": latency_summary(tick_latency_s),
        **(tick_timing or {}),
        "commands_limited": commands_limited,
        "degraded_s": round(result.degraded_s, 3),
        "holds": result.holds,
        "max_telemetry_age_s": round(result.max_telemetry_age_s, 3),
        "params_changed": result.params_changed,
        "reattached": result.reattached,
        "taken_over": result.taken_over,
        "left_to_operator": result.left_to_operator,
        "autopilots": result.autopilots,
        "reshapes": result.reshapes,  # guidance.reshape.ShapeChange.as_json rows, oldest first
        "legs": result.legs,  # each leg of the route as the leader started it (runner._start_leg)
        "detours": result.detours,  # legs flown round a gap (guidance.route_plan.Detour.as_json)
        "formation_timeline": [
            {
                "t": t,
                "leader": leader,
                "offsets": [None if np.isnan(o).any() else o.tolist() for o in offsets],
                "follows_path": follows,  # the column's slots along the leader's path (spec 6a.9)
            }
            for t, leader, offsets, follows in result.formation_timeline
        ],
        "wall_duration_s": wall_s,
        "link_stats": link_stats,  # {"vehicles": Fleet.stats(), "forwards": Fleet.forward_stats()}
        "link_use": link_use,  # bytes/s each way per vehicle and the budget (link.link_use.LinkUse.summary)
        "command_mode": result.command_mode,  # link.command_mode.CommandPlan.as_json (None: not chosen)
        "command_mode_changes": result.command_mode_changes,  # link.command_mode.change_row rows, in flight
    }
    (run_dir / FLIGHT_FILE).write_text(json.dumps(flight, indent=2) + "\n")


def default_run_dir(mission: Mission) -> Path:
    return Path("runs") / f"{datetime.now().strftime('%Y%m%d-%H%M%S')}-{mission.name}"


def vehicle_configs(mission: Mission, base_port: int | None) -> list[VehicleConfig]:
    """Connection per vehicle: the mission's strings, or 127.0.0.1:base_port+i for the embedded simulator."""
    return [
        VehicleConfig(
            name=v.name,
            connection=v.connection if base_port is None else f"udpout:127.0.0.1:{base_port + i}",
            sysid=v.sysid,
            autopilot=v.autopilot,
        )
        for i, v in enumerate(mission.vehicles)
    ]


def with_forwards(mission: Mission, forward: tuple[str, ...], forward_rw: bool) -> Mission:
    """`mission` with the command line's --forward endpoints added to run.forward (--forward-rw: or-ed)."""
    run = dataclasses.replace(
        mission.run, forward=mission.run.forward + forward, forward_rw=mission.run.forward_rw or forward_rw
    )
    return dataclasses.replace(mission, run=run)


def mission_fleet(
    mission: Mission, base_port: int | None, run_dir: Path, key: bytes | None, spin_s: float = 0.0
) -> Fleet:
    """The (unconnected) Fleet that flies `mission`: its vehicles (see vehicle_configs), the run folder's
    telemetry.tlog, the signing key, safety.telemetry.lost_s as the loss timeout, run.forward, and spin_s
    (wall s each wait for packets polls first, see lockstep_spin_s)."""
    plan = mission_command_plan(mission, signed=key is not None)
    return Fleet(
        vehicle_configs(mission, base_port),
        mission.origin,
        tlog_path=run_dir / "telemetry.tlog",
        signing_key=key,
        loss_timeout_s=mission.safety.telemetry.lost_s,
        stream_rate_hz=mission.run.control_rate_hz,
        forwards=[ForwardConfig(text, mission.run.forward_rw) for text in mission.run.forward],
        spin_s=spin_s,
        # world.link.budget_bps, else the mission's radio's capacity in MAVLink bytes (link.command_mode)
        link_budget_bps=None if plan.budget is None else plan.budget.bytes_per_s * 8.0,
        command_plan=plan,
        step_down=mission.link.step_down,
    )


def mission_command_plan(mission: Mission, signed: bool) -> CommandPlan:
    """The command mode and telemetry rates for the mission's link budget (link.command_mode); MissionError
    (one sentence) when the budget cannot carry even the slowest mode."""
    budget = link_budget(mission.link, len(mission.vehicles))
    try:
        return command_plan(budget, mission.run.control_rate_hz, signed, mission.link.command_mode)
    except CommandModeError as exc:
        raise MissionError(str(exc)) from None


def lockstep_spin_s(mission: Mission, embedded: bool, time_mode: str | None = None) -> float:
    """Wall s the ground station polls for packets before it blocks: run.simulator.lockstep_spin_us when it
    flies its embedded simulator in lockstep (time_mode: the command line's override of the mission's),
    whose next frame comes within a fraction of a millisecond; 0 (block at once) against anything else,
    which sends its next packets milliseconds later."""
    spec = mission.run.simulator
    lockstep = embedded and (time_mode or spec.time_mode) == "lockstep"
    return spec.lockstep_spin_us * 1e-6 if lockstep else 0.0


def signing_key(mission: Mission) -> tuple[Path | None, bytes | None]:
    """The mission's MAVLink 2 signing key file and key (run.signing_key_file or SWARM_GCS_SIGNING_KEY_FILE);
    (None, None) without one. SigningKeyError (one sentence) for an unreadable or malformed file."""
    key_file = signing.key_file(mission.run.signing_key_file)
    return key_file, None if key_file is None else signing.read_key(key_file)


def start_embedded_simulator(
    mission: Mission,
    run_dir: Path,
    base_port: int,
    key_file: Path | None,
    time_mode: str | None = None,
    seed: int | None = None,
    sim_args: tuple[str, ...] = (),
) -> EmbeddedSimulator:
    """Start the mission's simulator (ports base_port+i, truth log in run_dir, the same signing key); the
    time mode and seed default to the mission's."""
    spec = mission.run.simulator
    sim = EmbeddedSimulator(
        mission,
        base_port=base_port,
        truth_log=run_dir / TRUTH_FILE,
        time_mode=time_mode or spec.time_mode,
        speedup=spec.speedup,
        seed=spec.seed if seed is None else seed,
        extra_args=list(sim_args),
        signing_key_file=key_file,
    )
    # the guidance kernels and tables load on this core while the simulator starts on the other (0.3-0.4 s)
    sim.start(while_starting=lambda: prepare_kernels(mission.safety.dead_gcs))
    return sim


@dataclass
class Flown:
    """What a flight left behind: the exit status so far, the mission and run folder (None when the mission
    did not load), the runner's result, whether formation flight began so the run folder can be
    evaluated (`report_due`), and the error to show the user (None: none)."""

    status: int
    result: FlightResult
    mission: Mission | None = None
    run_dir: Path | None = None
    report_due: bool = False
    error: str | None = None  # the one sentence that ended the flight early (a user error, a lost link)


def fly_mission(mission_path: str, options: RunOptions, say: Callable[[str], None]) -> Flown:
    """Load and fly the mission with the command-line choices; progress lines go to `say`, the error that
    ended the flight early to `Flown.error`."""
    try:
        setup = set_up_run(mission_path, options)
    except (MissionError, signing.SigningKeyError) as exc:
        return Flown(EXIT_USER_ERROR, FlightResult(), error=str(exc))
    mission, run_dir, key_file, key, base_port = (
        setup.mission, setup.run_dir, setup.key_file, setup.key, setup.base_port
    )  # fmt: skip
    embedded = base_port is not None
    sim: EmbeddedSimulator | None = None
    wall0 = time.monotonic()
    result = FlightResult()
    runner: MissionRunner | None = None
    status = EXIT_OK
    error: str | None = None
    link_stats: dict[str, dict[str, dict[str, int]]] | None = None
    link_use: dict[str, dict[str, object]] | None = None
    say(f"run folder {run_dir}")
    if key is not None:
        say(f"MAVLink 2 signing with the key in {key_file}")
    for text in mission.run.forward:
        say(f"forwarding to {text} ({'read-write' if mission.run.forward_rw else 'read-only'})")
    try:
        if base_port is not None:
            sim = start_embedded_simulator(
                mission,
                run_dir,
                base_port,
                key_file,
                options.time_mode,
                options.seed,
                tuple(options.sim_args),
            )
            say(f"embedded simulator up: {len(mission.vehicles)} vehicles on 127.0.0.1:{base_port}..")
        spin_s = lockstep_spin_s(mission, embedded, options.time_mode)
        with mission_fleet(mission, base_port, run_dir, key, spin_s) as fleet:
            record = RunRecord(run_dir / RECORD_FILE)
            try:
                runner = MissionRunner(mission, fleet, record, progress=say)
                runner.crash_at_s = options.crash_at
                runner.airborne = options.airborne
                if options.watch is not None:
                    options.watch(runner)
                result = runner.run()
            finally:
                record.close()
                if runner is not None:
                    runner.restore_params()
                    result = runner.result
                link_stats = {"vehicles": fleet.stats(), "forwards": fleet.forward_stats()}
                link_use = fleet.link_use.summary()
                result.events.extend(fleet.link_use.events)
                result.command_mode_changes = fleet.command_watch.changes
                for line in fleet.link_summary():
                    say(line)
    except (MissionError, SimulatorError, PreflightError) as exc:
        error, status = str(exc), EXIT_USER_ERROR
    except LinkError as exc:
        error = str(exc)
        nothing_flew = result.phase_reached in (Phase.CONNECT, Phase.PREFLIGHT, Phase.LAUNCH)
        status = EXIT_USER_ERROR if nothing_flew else EXIT_FAILED
        result.events.append(str(exc))
    except KeyboardInterrupt:
        say("interrupted: stopping")
        log.info("interrupted by the operator during phase %s", result.phase_reached)
        status = EXIT_FAILED
        result.events.append("interrupted by the operator")
    finally:
        if sim is not None:
            sim.stop()
            (run_dir / "simulator.log").write_text("\n".join(sim.output) + "\n")  # incl. its link counters
    latencies = runner.tick_latency_s if runner is not None else []
    limited = runner.commands_limited if runner is not None else 0
    wall_s = time.monotonic() - wall0
    timing = runner.timing_summary() if runner is not None else None
    write_flight(
        run_dir, mission, mission_path, result, wall_s, latencies, limited, link_stats, timing, link_use
    )
    flown = Flown(status, result, mission, run_dir, error=error)
    if status == EXIT_OK and result.reattached == "land":
        say("every vehicle landed and disarmed" if result.landed_all else "not every vehicle disarmed")
        flown.status = EXIT_OK if result.landed_all and not result.lost else EXIT_FAILED
    elif status == EXIT_USER_ERROR or result.t_formation_start is None:
        flown.status = status if status != EXIT_OK else EXIT_FAILED
    else:
        flown.report_due = True
    return flown
