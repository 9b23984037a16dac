"""Mission file -> `Mission`: YAML with lines (yaml_tree), the schema (pydantic, schema.py), the rules across
keys (checks.py), and the defaults one key takes from another.

Every mistake a user can make ends in one `MissionError` naming file, line and field; nothing else escapes.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np

from gcs_swarm.guidance.params import STOP_SHAPING
from gcs_swarm.mission import checks
from gcs_swarm.mission.model import (
    FormationSpec,
    LinkSpec,
    Mission,
    Obstacle,
    OutageSpec,
    PlannerSpec,
    RunSpec,
    SafetySpec,
    StartState,
    VehicleSpec,
    World,
    frozen_vector,
)
from gcs_swarm.mission.schema import (
    MissionFile,
    PlannerSection,
    RunSection,
    SafetySection,
    VehicleEntry,
    describe,
    validate_file,
)
from gcs_swarm.mission.yaml_tree import MissionError, parse_yaml


def load_mission(path: str | Path) -> Mission:
    """Read and validate a mission file; MissionError (one sentence, file:line: field) on any mistake."""
    source = str(path)
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise MissionError(f"{source}: mission file not found") from None
    except IsADirectoryError:
        raise MissionError(f"{source}: is a directory, not a mission file") from None
    except OSError as exc:
        raise MissionError(f"{source}: cannot read the mission file ({exc.strerror or exc})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MissionError(
            f"{source}:{line}: the file is not UTF-8 text (bad byte at offset {exc.start})"
        ) from None
    return parse_mission(text, source)


def load_world(path: str | Path) -> World:
    """What the simulator needs from a mission file, with the same validation as `load_mission`."""
    return load_mission(path).world()


def parse_mission(text: str, source: str = "<string>") -> Mission:
    """Validate mission YAML given as text; `source` names it in error messages."""
    root = parse_yaml(text, source)
    if not isinstance(root.value, dict):
        raise root.error(
            f"the top level must be a mapping of sections (vehicles, goal, ...), not {describe(root.value)}"
        )
    file = validate_file(root)
    checks.check_file(file, root)
    mission = _mission(file, source)
    checks.check_mission(mission, root)
    return mission


def _mission(file: MissionFile, source: str) -> Mission:
    """The validated file as a `Mission`, with the defaults that come from other keys filled in."""
    run = _run(file.run, source)
    names = [vehicle.name or f"uav{i + 1}" for i, vehicle in enumerate(file.vehicles)]
    link = file.world.link
    waypoints = file.waypoints if "waypoints" in file.model_fields_set else [file.goal]
    route = tuple(frozen_vector(point) for point in waypoints)
    adjacency = None
    if file.formation.adjacency is not None:
        adjacency = np.array(file.formation.adjacency, dtype=int)
        adjacency.flags.writeable = False
    return Mission(
        name=file.mission.name or _stem_name(source),
        description=file.mission.description,
        path=Path(source),
        origin=(file.origin.lat, file.origin.lon, file.origin.alt),
        vehicles=tuple(_vehicle(vehicle, names[i], i, run) for i, vehicle in enumerate(file.vehicles)),
        formation=FormationSpec(**file.formation.model_dump(exclude={"adjacency"}), adjacency=adjacency),
        goal=route[-1],
        waypoints=route,
        obstacles=tuple(
            Obstacle(frozen_vector(o.center), o.radius, frozen_vector(o.velocity))
            for o in file.world.obstacles or ()
        ),
        wind=file.world.wind,
        link=LinkSpec(
            **link.model_dump(exclude={"outages"}),
            outages=tuple(
                OutageSpec(
                    None if "vehicle" not in outage.model_fields_set else names.index(outage.vehicle),
                    outage.start_s,
                    outage.duration_s,
                )
                for outage in link.outages or ()
            ),
        ),
        field=file.guidance,
        reference=file.reference,
        reshape=file.reshape,
        controller=file.control.controller,
        smc=file.control.smc,
        pid=file.control.pid,
        limits=file.limits,
        safety=_safety(file.safety),
        run=run,
        planner=_planner(file.planner, file.limits.v_xy_leader),
    )


def _stem_name(source: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(source).stem)[:64].lstrip("_.-")
    return stem or "mission"


def _vehicle(vehicle: VehicleEntry, name: str, index: int, run: RunSpec) -> VehicleSpec:
    start = vehicle.start
    return VehicleSpec(
        name=name,
        connection=vehicle.connection or f"udpout:127.0.0.1:{run.simulator.base_port + index}",
        role=vehicle.role,
        sysid=vehicle.sysid or None,
        slot=None if vehicle.slot is None else frozen_vector(vehicle.slot),
        start=StartState(frozen_vector(start.position), frozen_vector(start.velocity), start.yaw_deg),
        target=None if vehicle.target is None else frozen_vector(vehicle.target),
        autopilot=vehicle.autopilot,
    )


def _run(run: RunSection, source: str) -> RunSpec:
    return RunSpec(
        **run.model_dump(exclude={"simulator", "signing_key_file", "forward"}),
        simulator=run.simulator,
        forward=tuple(run.forward),
        signing_key_file=_signing_key_file(run.signing_key_file, source),
    )


def _signing_key_file(written: str, source: str) -> Path | None:
    """run.signing_key_file: a path, relative to the mission file's folder (read at flight time)."""
    if not written:
        return None
    path = Path(written).expanduser()
    if not path.is_absolute() and not source.startswith("<"):
        path = Path(source).parent / path
    return path


def _safety(safety: SafetySection) -> SafetySpec:
    """The failsafe timeout defaults to telemetry.lost_s (at least 2 s), the stop shaping to the failsafe
    action's (STOP_SHAPING); checks.check_file has made sure both are valid."""
    dead_gcs = safety.dead_gcs
    stop_accel, stop_jerk = STOP_SHAPING[safety.gcs_failsafe]
    dead_gcs = dataclasses.replace(
        dead_gcs,
        failsafe_timeout_s=checks.failsafe_timeout(safety),
        brake_accel=stop_accel if dead_gcs.brake_accel is None else dead_gcs.brake_accel,
        brake_jerk=stop_jerk if dead_gcs.brake_jerk is None else dead_gcs.brake_jerk,
    )
    return SafetySpec(
        separation=safety.separation,
        min_altitude=safety.min_altitude,
        geofence_radius=safety.geofence.radius,
        geofence_max_alt=safety.geofence.max_alt,
        collision_radius=safety.collision_radius,
        gcs_failsafe=safety.gcs_failsafe,
        telemetry=safety.telemetry,
        dead_gcs=dead_gcs,
    )


def _planner(planner: PlannerSection, leader_speed: float) -> PlannerSpec:
    return PlannerSpec(
        **planner.model_dump(exclude={"speed", "start"}),
        speed=planner.speed or leader_speed,
        start=None if planner.start is None else frozen_vector(planner.start),
    )
