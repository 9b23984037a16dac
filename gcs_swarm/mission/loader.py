"""Mission file -> `Mission`: YAML with lines (yaml_tree), the schema (pydantic, schema.py), the rules across
keys (checks.py), and the defaults one key takes from another.

Every mistake a user can make ends in one `MissionError` naming file, line and field; nothing else escapes.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from gcs_swarm.guidance.params import STOP_SHAPING
from gcs_swarm.link.command_mode import StepDown
from gcs_swarm.mission import checks
from gcs_swarm.mission.geodesy import Origin, ground_enu, implied_origin, position_enu, vertex_enu
from gcs_swarm.mission.imports import with_imports
from gcs_swarm.mission.model import (
    Cylinder,
    Fence,
    FormationSpec,
    Leg,
    LinkSpec,
    Mission,
    Obstacle,
    OutageSpec,
    PlannerSpec,
    Prism,
    RunSpec,
    SafetySpec,
    StartState,
    VehicleSpec,
    World,
    Zone,
    frozen_vector,
)
from gcs_swarm.mission.schema import (
    DEFAULT_ORIGIN,
    GeoPoint,
    MissionFile,
    PlannerSection,
    RunSection,
    SafetySection,
    VehicleEntry,
    describe,
    validate_file,
)
from gcs_swarm.mission.yaml_tree import MissionError, Node, parse_yaml


def load_mission(path: str | Path, *, to_fly: bool = True) -> Mission:
    """Read and validate a mission file; MissionError (one sentence, file:line: field) on any mistake.
    `to_fly` False: also a mission the flight refuses (checks.flight_refusal: legs near the site fence)."""
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
    return parse_mission(text, source, to_fly=to_fly)


def load_world(path: str | Path) -> World:
    """What the simulator needs from a mission file, with the same validation as `load_mission`."""
    return load_mission(path).world()


def parse_mission(text: str, source: str = "<string>", *, to_fly: bool = True) -> Mission:
    """Validate mission YAML given as text; `source` names it in error messages (and is the folder
    world.import paths are relative to). `to_fly`: as `load_mission`."""
    root = parse_yaml(text, source)
    if not isinstance(root.value, dict):
        raise root.error(
            f"the top level must be a mapping of sections (vehicles, goal, ...), not {describe(root.value)}"
        )
    file = validate_file(root)
    if file.world.imports:
        root = with_imports(root, file.world.imports, source)
        file = validate_file(root)
    checks.check_file(file, root)
    mission = _mission(file, source, root)
    checks.check_mission(mission, root)
    if to_fly:
        refusal = checks.flight_refusal(mission, root)
        if refusal is not None:
            raise refusal
    return mission


def _origin(file: MissionFile, root: Node) -> Origin:
    """The origin as written or implied (geodesy.implied_origin); a MissionError when geographic positions
    are given but none of the places the origin may be taken from is geographic."""
    origin, _ = implied_origin(file)
    if "origin" in file.model_fields_set or origin != DEFAULT_ORIGIN:
        return origin
    geographic = _first_geographic(root)
    if geographic is not None:
        raise geographic.error(
            "a position in latitude/longitude needs an origin: give 'origin', or write the fence polygon, "
            "the first vehicle's start or the first waypoint in latitude/longitude"
        )
    return origin


def _first_geographic(node: Node) -> Node | None:
    """The first mapping with `lat` and `lon` below `node` (outside `origin`), or None."""
    value = node.value
    if isinstance(value, dict):
        if "lat" in value and "lon" in value and node.path != "origin":
            return node
        children = [child for key, child in value.items() if not (node.path == "" and key == "origin")]
    elif isinstance(value, list):
        children = value
    else:
        return None
    for child in children:
        found = _first_geographic(child)
        if found is not None:
            return found
    return None


def _mission(file: MissionFile, source: str, root: Node) -> Mission:
    """The validated file as a `Mission`, with the defaults that come from other keys filled in and every
    position in ENU metres about the origin (geodesy.py)."""
    origin = _origin(file, root)

    def enu(value: list[float] | GeoPoint, loc: tuple[str | int, ...]) -> np.ndarray:
        point = position_enu(value, origin)
        if point is None:
            raise root.at(loc).error(
                "give the height: alt (m above the origin) or amsl (m above mean sea level)"
            )
        return frozen_vector(point)

    def vertices(values: list) -> np.ndarray:
        return frozen_vector([vertex_enu(v, origin) for v in values]).reshape(-1, 2)

    run = _run(file.run, source)
    names = [vehicle.name or f"uav{i + 1}" for i, vehicle in enumerate(file.vehicles)]
    link = file.world.link
    legs = _legs(file, enu)
    if legs:
        route = tuple(point for leg in legs for point in leg[1])
    elif "waypoints" in file.model_fields_set:
        route = tuple(enu(point, ("waypoints", k)) for k, point in enumerate(file.waypoints))
    else:
        route = (enu(file.goal, ("goal",)),)
    formation = file.formation.model_dump(exclude={"adjacency"})
    if legs:  # the first leg's formation is flown from the start
        formation.update(shape=legs[0][0].shape, spacing=legs[0][0].spacing)
    adjacency = None
    if file.formation.adjacency is not None:
        adjacency = np.array(file.formation.adjacency, dtype=int)
        adjacency.flags.writeable = False
    return Mission(
        name=file.mission.name or _stem_name(source),
        description=file.mission.description,
        path=Path(source),
        origin=origin,
        vehicles=tuple(
            _vehicle(vehicle, names[i], i, run, origin, enu) for i, vehicle in enumerate(file.vehicles)
        ),
        formation=FormationSpec(**formation, adjacency=adjacency),
        goal=route[-1],
        waypoints=route,
        obstacles=tuple(
            Obstacle(enu(o.center, ("world", "obstacles", k, "center")), o.radius, frozen_vector(o.velocity))
            for k, o in enumerate(file.world.obstacles or ())
        ),
        wind=file.world.wind,
        link=LinkSpec(
            **link.model_dump(exclude={"outages", "step_down"}),
            step_down=StepDown(**link.step_down.model_dump()),
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
        pace=file.pace,
        controller=file.control.controller,
        smc=file.control.smc,
        pid=file.control.pid,
        limits=file.limits,
        safety=_safety(file.safety),
        run=run,
        planner=_planner(
            file.planner,
            file.limits.v_xy_leader,
            None if file.planner.start is None else enu(file.planner.start, ("planner", "start")),
        ),
        fence=Fence(
            polygon=None if file.safety.geofence.polygon is None else vertices(file.safety.geofence.polygon),
            exclusions=tuple(
                Zone(
                    zone.name or f"safety.geofence.exclusions[{k}]",
                    None if zone.polygon is None else vertices(zone.polygon),
                    None if zone.center is None else frozen_vector(vertex_enu(zone.center, origin)),
                    zone.radius or 0.0,
                )
                for k, zone in enumerate(file.safety.geofence.exclusions or ())
            ),
            upload=file.safety.geofence.upload,
        ),
        prisms=tuple(
            Prism(p.name or f"world.prisms[{k}]", vertices(p.polygon), p.bottom, p.top)
            for k, p in enumerate(file.world.prisms or ())
        ),
        cylinders=tuple(
            Cylinder(
                c.name or f"world.cylinders[{k}]",
                frozen_vector(vertex_enu(c.center, origin)),
                c.radius,
                c.bottom,
                c.top,
            )
            for k, c in enumerate(file.world.cylinders or ())
        ),
        rally=tuple(enu(point, ("safety", "rally", k)) for k, point in enumerate(file.safety.rally or ())),
        legs=tuple(leg for leg, _ in legs),
    )


def _legs(
    file: MissionFile, enu: Callable[[list[float] | GeoPoint, tuple[str | int, ...]], np.ndarray]
) -> list[tuple[Leg, tuple[np.ndarray, ...]]]:
    """The file's legs, each resolved (a field not set is the leg before's; the first leg's defaults are the
    mission's formation and leader speed cap), with its waypoints in ENU m (at the leg's altitude where it
    sets one). Empty when the route is not written as legs."""
    out: list[tuple[Leg, tuple[np.ndarray, ...]]] = []
    shape, spacing, speed = file.formation.shape, file.formation.spacing, file.limits.v_xy_leader
    first = 0
    for j, entry in enumerate(file.legs):
        shape = entry.formation.shape or shape
        spacing = entry.formation.spacing or spacing
        speed = entry.speed or speed
        points = []
        for k, point in enumerate(entry.waypoints):
            loc = ("legs", j, "waypoints", k)
            if entry.altitude is not None and not isinstance(point, list):
                point = point.model_copy(update={"alt": entry.altitude})
            points.append(enu(point, loc))
        leg = Leg(entry.name or f"legs[{j}]", first, shape, spacing, speed, entry.altitude)
        out.append((leg, tuple(points)))
        first += len(points)
    return out


def _stem_name(source: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(source).stem)[:64].lstrip("_.-")
    return stem or "mission"


def _vehicle(
    vehicle: VehicleEntry,
    name: str,
    index: int,
    run: RunSpec,
    origin: Origin,
    enu: Callable[[Any, tuple[str | int, ...]], np.ndarray],
) -> VehicleSpec:
    """One vehicle; its start position in ENU (a geographic start without a height stands on the ground),
    its target through `enu` (value, key path)."""
    start = vehicle.start
    return VehicleSpec(
        name=name,
        connection=vehicle.connection or f"udpout:127.0.0.1:{run.simulator.base_port + index}",
        role=vehicle.role,
        sysid=vehicle.sysid or None,
        slot=None if vehicle.slot is None else frozen_vector(vehicle.slot),
        start=StartState(
            frozen_vector(ground_enu(start.position, origin)), frozen_vector(start.velocity), start.yaw_deg
        ),
        target=None if vehicle.target is None else enu(vehicle.target, ("vehicles", index, "target")),
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


def _planner(planner: PlannerSection, leader_speed: float, start: np.ndarray | None) -> PlannerSpec:
    return PlannerSpec(
        **planner.model_dump(exclude={"speed", "start"}),
        speed=planner.speed or leader_speed,
        start=start,
    )
