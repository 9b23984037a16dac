"""Mission file -> `Mission`: the schema of docs/mission-schema.md, section by section, then cross-checks.

Every mistake a user can make ends in one `MissionError` naming file, line and field; nothing else escapes.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from pathlib import Path

import numpy as np

from gcs_swarm.guidance.params import (
    STOP_SHAPING,
    DeadGcsParams,
    FieldParams,
    Limits,
    PIDParams,
    ReferenceParams,
    SeparationParams,
    SMCParams,
    TelemetryParams,
)
from gcs_swarm.mission import checks
from gcs_swarm.mission.checks import ParsedVehicle
from gcs_swarm.mission.fields import (
    Section,
    describe,
    integer,
    items,
    number,
    param_fields,
    params,
    text,
    vector,
)
from gcs_swarm.mission.model import (
    FormationSpec,
    LinkSpec,
    Mission,
    Obstacle,
    OutageSpec,
    PlannerSpec,
    RunSpec,
    SafetySpec,
    SimulatorSpec,
    StartState,
    VehicleSpec,
    WindSpec,
    World,
    frozen_vector,
)
from gcs_swarm.mission.yaml_tree import MissionError, Node, parse_yaml

DEFAULT_ORIGIN = (-35.363261, 149.165230, 584.0)  # ArduPilot SITL's CMAC field, Canberra
NAME_PATTERN = r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}"
NAME_HINT = "expected a name of letters, digits, '_', '.' or '-' (at most 64, no spaces)"

TOP_KEYS = (
    "mission",
    "origin",
    "vehicles",
    "formation",
    "goal",
    "waypoints",
    "world",
    "guidance",
    "control",
    "limits",
    "safety",
    "run",
    "planner",
)
MOVED_KEYS = {"obstacles": "world", "wind": "world", "separation": "safety", "simulator": "run"}
VEHICLE_KEYS = ("name", "connection", "role", "sysid", "slot", "start", "target")
START_KEYS = ("position", "velocity", "yaw_deg")
FORMATION_KEYS = ("shape", "spacing", "angle_deg", "altitude", "topology", "adjacency", "assign_slots")
SHAPES = ("v", "line", "column", "grid", "offsets")
RUN_KEYS = (
    "control_rate_hz",
    "time_limit_s",
    "goal_tolerance_m",
    "hold_s",
    "airborne_start",
    "takeoff_timeout_s",
    "preflight_timeout_s",
    "land_timeout_s",
    "simulator",
    "signing_key_file",
    "keep_params",
)
SIMULATOR_KEYS = ("embedded", "time_mode", "speedup", "seed", "rate_hz", "base_port")
SAFETY_KEYS = (
    "separation",
    "min_altitude",
    "geofence",
    "collision_radius",
    "gcs_failsafe",
    "telemetry",
    "dead_gcs",
)
WORLD_KEYS = ("obstacles", "wind", "link")
LINK_PROBABILITIES = ("loss", "dup", "corrupt", "reorder")
LINK_DELAYS = ("delay_ms", "jitter_ms")
LINK_KEYS = (*LINK_PROBABILITIES, *LINK_DELAYS, "from_s", "outages")
OUTAGE_KEYS = ("vehicle", "start_s", "duration_s")
MAX_LINK_DELAY_MS = 10000.0  # the simulator's limit (sitl-sim --link-delay-ms)
PLANNER_KEYS = ("dimensions", "dt", "time_limit_s", "speed", "goal_radius", "step", "start")
ZERO3 = frozen_vector([0.0, 0.0, 0.0])


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
        text_ = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MissionError(
            f"{source}:{line}: the file is not UTF-8 text (bad byte at offset {exc.start})"
        ) from None
    return parse_mission(text_, source)


def load_world(path: str | Path) -> World:
    """What the simulator needs from a mission file, with the same validation as `load_mission`."""
    return load_mission(path).world()


def parse_mission(text_: str, source: str = "<string>") -> Mission:
    """Validate mission YAML given as text; `source` names it in error messages."""
    root = parse_yaml(text_, source)
    if not isinstance(root.value, dict):
        raise root.error(
            f"the top level must be a mapping of sections (vehicles, goal, ...), not {describe(root.value)}"
        )
    top = Section(root, TOP_KEYS, MOVED_KEYS)

    meta = Section.within(top, "mission", ("name", "description"))
    name_node = meta.get("name")
    name = text(name_node, pattern=NAME_PATTERN, hint=NAME_HINT) if name_node else _stem_name(source)
    description = meta.text("description", "")
    origin = _origin(top)
    run = _run(Section.within(top, "run", RUN_KEYS))
    safety = _safety(Section.within(top, "safety", SAFETY_KEYS))
    limits = params(Section.within(top, "limits", param_fields(Limits())), Limits())
    guidance = Section.within(top, "guidance", (*param_fields(FieldParams()), "reference"))
    field = params(guidance, FieldParams())
    reference = params(
        Section.within(guidance, "reference", param_fields(ReferenceParams())), ReferenceParams()
    )
    control = Section.within(top, "control", ("controller", "smc", "pid"))
    controller = control.choice("controller", "smc", ("smc", "pid"))
    smc = params(Section.within(control, "smc", param_fields(SMCParams())), SMCParams())
    pid = params(Section.within(control, "pid", param_fields(PIDParams())), PIDParams())
    world = Section.within(top, "world", WORLD_KEYS)
    obstacles, obstacle_nodes = _obstacles(world)
    wind = _wind(Section.within(world, "wind", ("speed", "direction_deg", "turbulence")))
    vehicles_node = top.require("vehicles")
    vehicles = _vehicles(vehicles_node, run)
    link = _link(Section.within(world, "link", LINK_KEYS), [v.spec.name for v in vehicles])
    formation_yaml = Section.within(top, "formation", FORMATION_KEYS)
    formation = _formation(formation_yaml, vehicles)
    waypoints, waypoint_nodes = _waypoints(top)
    planner_yaml = Section.within(top, "planner", PLANNER_KEYS)
    planner = _planner(planner_yaml, limits)

    placed = checks.Placed(obstacles, obstacle_nodes, safety)
    checks.vehicles(vehicles_node, vehicles, run, safety, formation, placed)
    checks.relay(formation_yaml, formation, vehicles)
    for point, node in zip(waypoints, waypoint_nodes, strict=True):
        placed.check(point, node, "the goal" if node.path == "goal" else "this waypoint")
    if planner.start is not None:
        start_node = planner_yaml.line_of("start")
        placed.check(planner.start, start_node, "the planner start", fenced=False, floor=False)
    checks.altitudes(formation_yaml, formation, safety)
    checks.limits(top, limits, len(vehicles))

    return Mission(
        name=name,
        description=description,
        path=Path(source),
        origin=origin,
        vehicles=tuple(v.spec for v in vehicles),
        formation=formation,
        goal=waypoints[-1],
        waypoints=waypoints,
        obstacles=obstacles,
        wind=wind,
        link=link,
        field=field,
        reference=reference,
        controller=controller,
        smc=smc,
        pid=pid,
        limits=limits,
        safety=safety,
        run=run,
        planner=planner,
    )


def _stem_name(source: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9_.-]", "_", Path(source).stem)[:64].lstrip("_.-")
    return stem or "mission"


def _origin(top: Section) -> tuple[float, float, float]:
    if top.get("origin") is None:
        return DEFAULT_ORIGIN
    origin = Section.within(top, "origin", ("lat", "lon", "alt"))
    return (
        number(origin.require("lat"), at_least=-90, at_most=90, unit="deg"),
        number(origin.require("lon"), at_least=-180, at_most=180, unit="deg"),
        origin.number("alt", 0.0, at_least=-500, at_most=9000, unit="m"),
    )


def _run(run: Section) -> RunSpec:
    sim = Section.within(run, "simulator", SIMULATOR_KEYS)
    control_rate = run.number("control_rate_hz", 50.0, above=0, at_most=1000, unit="Hz")
    simulator = SimulatorSpec(
        embedded=sim.flag("embedded", True),
        time_mode=sim.choice("time_mode", "lockstep", ("lockstep", "realtime", "speedup")),
        speedup=sim.number("speedup", 1.0, above=0, at_most=10000),
        seed=sim.integer("seed", 0, at_least=0, at_most=2**32 - 1),
        rate_hz=sim.number("rate_hz", 1000.0, at_least=control_rate, at_most=100000, unit="Hz"),
        base_port=sim.integer("base_port", 14540, at_least=1024, at_most=65535),
    )
    return RunSpec(
        control_rate_hz=control_rate,
        time_limit_s=run.number("time_limit_s", 300.0, above=0, unit="s"),
        goal_tolerance_m=run.number("goal_tolerance_m", 1.0, above=0, unit="m"),
        hold_s=run.number("hold_s", 2.0, at_least=0, unit="s"),
        airborne_start=run.flag("airborne_start", False),
        takeoff_timeout_s=run.number("takeoff_timeout_s", 60.0, above=0, unit="s"),
        preflight_timeout_s=run.number("preflight_timeout_s", 60.0, above=0, unit="s"),
        land_timeout_s=run.number("land_timeout_s", 300.0, above=0, unit="s"),
        simulator=simulator,
        signing_key_file=_signing_key_file(run),
        keep_params=run.flag("keep_params", False),
    )


def _signing_key_file(run: Section) -> Path | None:
    """run.signing_key_file: a path, relative to the mission file's folder (read at flight time)."""
    text_ = run.text("signing_key_file", "")
    if not text_:
        return None
    path = Path(text_).expanduser()
    source = run.node.source
    if not path.is_absolute() and not source.startswith("<"):
        path = Path(source).parent / path
    return path


def _safety(safety: Section) -> SafetySpec:
    separation = params(
        Section.within(safety, "separation", param_fields(SeparationParams())), SeparationParams()
    )
    if separation.mode == "constant" and separation.d_emg > separation.d_max:
        node = Section.within(safety, "separation", param_fields(separation)).line_of("d_emg")
        raise node.error(
            f"d_emg ({separation.d_emg:g} m) must not exceed d_max ({separation.d_max:g} m) (spec 4)"
        )
    telemetry = params(
        Section.within(safety, "telemetry", param_fields(TelemetryParams())), TelemetryParams()
    )
    dead_gcs_yaml = Section.within(safety, "dead_gcs", param_fields(DeadGcsParams()))
    dead_gcs = params(dead_gcs_yaml, DeadGcsParams())
    if dead_gcs.failsafe_timeout_s is None:
        dead_gcs = dataclasses.replace(dead_gcs, failsafe_timeout_s=max(telemetry.lost_s, 2.0))
    assert dead_gcs.failsafe_timeout_s is not None
    if dead_gcs.failsafe_timeout_s < telemetry.lost_s:
        raise dead_gcs_yaml.line_of("failsafe_timeout_s").error(
            f"failsafe_timeout_s ({dead_gcs.failsafe_timeout_s:g} s) must be at least telemetry.lost_s "
            f"({telemetry.lost_s:g} s): a vehicle would brake on a link outage the fleet still rides out"
        )
    gcs_failsafe = safety.choice("gcs_failsafe", "land", ("brake", "land", "rtl", "off"))
    stop_accel, stop_jerk = STOP_SHAPING[gcs_failsafe]
    dead_gcs = dataclasses.replace(
        dead_gcs,
        brake_accel=stop_accel if dead_gcs.brake_accel is None else dead_gcs.brake_accel,
        brake_jerk=stop_jerk if dead_gcs.brake_jerk is None else dead_gcs.brake_jerk,
    )
    fence = Section.within(safety, "geofence", ("radius", "max_alt"))
    min_altitude = safety.number("min_altitude", 2.0, at_least=0, unit="m")
    return SafetySpec(
        separation=separation,
        min_altitude=min_altitude,
        geofence_radius=fence.number("radius", 2000.0, above=0, unit="m"),
        geofence_max_alt=fence.number(
            "max_alt", 300.0, above=min_altitude, unit="m (above safety.min_altitude)"
        ),
        collision_radius=safety.number("collision_radius", 0.175, above=0, unit="m"),
        gcs_failsafe=gcs_failsafe,
        telemetry=telemetry,
        dead_gcs=dead_gcs,
    )


def _obstacles(world: Section) -> tuple[tuple[Obstacle, ...], tuple[Node, ...]]:
    node = world.get("obstacles")
    if node is None or node.value is None:
        return (), ()
    obstacles = []
    for item in items(node):
        obstacle = Section(item, ("center", "radius", "velocity"))
        obstacles.append(
            Obstacle(
                center=vector(obstacle.require("center")),
                radius=number(obstacle.require("radius"), above=0, unit="m"),
                velocity=obstacle.vector("velocity", ZERO3),
            )
        )
    return tuple(obstacles), tuple(items(node))


def _wind(wind: Section) -> WindSpec:
    return WindSpec(
        speed=wind.number("speed", 0.0, at_least=0, at_most=100, unit="m/s"),
        direction_deg=wind.number("direction_deg", 0.0, at_least=-360, at_most=360, unit="deg") % 360.0,
        turbulence=wind.number("turbulence", 0.0, at_least=0, at_most=50, unit="m/s"),
    )


def _link(link: Section, names: list[str]) -> LinkSpec:
    """world.link: the simulator's link faults (sitl-sim --link-*; its flags override these values)."""
    rates = {key: link.number(key, 0.0, at_least=0, at_most=1) for key in LINK_PROBABILITIES}
    delays = {
        key: link.number(key, 0.0, at_least=0, at_most=MAX_LINK_DELAY_MS, unit="ms") for key in LINK_DELAYS
    }
    node = link.get("outages")
    entries = [] if node is None or node.value is None else items(node)
    return LinkSpec(
        **rates,
        **delays,
        from_s=link.number("from_s", 0.0, at_least=0, unit="s"),
        outages=tuple(_outage(Section(entry, OUTAGE_KEYS), names) for entry in entries),
    )


def _outage(outage: Section, names: list[str]) -> OutageSpec:
    """One world.link.outages entry; `vehicle` is a vehicle's name (absent: every vehicle)."""
    vehicle_node = outage.get("vehicle")
    vehicle = None
    if vehicle_node is not None:
        name = vehicle_node.value
        if not isinstance(name, str) or name not in names:
            close = difflib.get_close_matches(name, names, n=1) if isinstance(name, str) else []
            hint = f"; did you mean {close[0]!r}?" if close else f" (vehicles: {', '.join(names)})"
            raise vehicle_node.error(f"expected the name of a vehicle, got {describe(name)}{hint}")
        vehicle = names.index(name)
    duration_node = outage.require("duration_s")
    if duration_node.value in ("inf", math.inf):
        duration = math.inf
    elif isinstance(duration_node.value, str):
        raise duration_node.error(f"expected seconds or inf (for good), got {describe(duration_node.value)}")
    else:
        duration = number(duration_node, above=0, unit="s (or inf: for good)")
    return OutageSpec(
        vehicle=vehicle,
        start_s=number(outage.require("start_s"), at_least=0, unit="s"),
        duration_s=duration,
    )


def _vehicles(node: Node, run: RunSpec) -> list[ParsedVehicle]:
    entries = items(node)
    if not entries:
        raise node.error("the list is empty; a mission needs one leader and any number of followers")
    parsed = []
    for index, item in enumerate(entries):
        vehicle = Section(item, VEHICLE_KEYS)
        start = Section(vehicle.require("start"), START_KEYS)
        port = run.simulator.base_port + index
        role = vehicle.choice("role", "follower", ("leader", "follower"))
        for key in ("slot", "target"):
            if role == "leader" and vehicle.get(key) is not None:
                owner = "the mission goal" if key == "target" else "the formation's reference point"
                raise vehicle.line_of(key).error(f"the leader has no {key}; it is {owner}")
        sysid_node = vehicle.get("sysid")
        spec = VehicleSpec(
            name=vehicle.text("name", f"uav{index + 1}", pattern=NAME_PATTERN, hint=NAME_HINT),
            connection=vehicle.text("connection", f"udpout:127.0.0.1:{port}"),
            role=role,
            sysid=None if sysid_node is None else integer(sysid_node, at_least=1, at_most=254),
            slot=vehicle.optional_vector("slot"),
            start=StartState(
                position=vector(start.require("position")),
                velocity=start.vector("velocity", ZERO3),
                yaw_deg=start.number("yaw_deg", 0.0, at_least=-360, at_most=360, unit="deg"),
            ),
            target=vehicle.optional_vector("target"),
        )
        parsed.append(ParsedVehicle(spec, vehicle, start))
    return parsed


def _formation(formation: Section, vehicles: list[ParsedVehicle]) -> FormationSpec:
    topology = formation.choice("topology", "broadcast", ("broadcast", "relay"))
    adjacency_node = formation.get("adjacency")
    if adjacency_node is None or adjacency_node.value is None:
        if topology == "relay":
            raise formation.line_of("topology").error(
                "topology 'relay' needs formation.adjacency (an N x N matrix of 0/1 in vehicle order)"
            )
        adjacency = None
    else:
        adjacency = _adjacency(adjacency_node, len(vehicles))
    return FormationSpec(
        shape=formation.choice("shape", "v", SHAPES),
        spacing=formation.number("spacing", 10.0, above=0, unit="m"),
        angle_deg=formation.number("angle_deg", 45.0, above=0, at_most=90, unit="deg"),
        altitude=formation.number("altitude", 10.0, above=0, unit="m"),
        topology=topology,
        adjacency=adjacency,
        assign_slots=formation.flag("assign_slots", True),
    )


def _adjacency(node: Node, n: int) -> np.ndarray:
    rows = items(node)
    if len(rows) != n:
        raise node.error(f"expected {n} rows (one per vehicle), got {len(rows)}")
    matrix = np.zeros((n, n), dtype=int)
    for i, row in enumerate(rows):
        entries = items(row)
        if len(entries) != n:
            raise row.error(f"expected {n} entries (one per vehicle), got {len(entries)}")
        for j, entry in enumerate(entries):
            value = integer(entry)
            if value not in (0, 1):
                raise entry.error(f"expected 0 or 1, got {value}")
            if i == j and value:
                raise entry.error("the diagonal must be 0 (a vehicle does not link to itself)")
            matrix[i, j] = value
    matrix.flags.writeable = False
    return matrix


def _waypoints(top: Section) -> tuple[tuple[np.ndarray, ...], tuple[Node, ...]]:
    goal, route = top.get("goal"), top.get("waypoints")
    if goal is not None and route is not None:
        raise route.error("give either 'goal' or 'waypoints' (whose last point is the goal), not both")
    if goal is not None:
        return (vector(goal),), (goal,)
    if route is None:
        missing = Node(None, top.node.line, "goal", top.node.source)
        raise missing.error("required key is missing (give the leader's 'goal' or a list of 'waypoints')")
    points = items(route)
    if not points:
        raise route.error("the list is empty; give at least the goal")
    return tuple(vector(p) for p in points), tuple(points)


def _planner(planner: Section, limits: Limits) -> PlannerSpec:
    dimensions_node = planner.get("dimensions")
    dimensions = 3 if dimensions_node is None else integer(dimensions_node, at_least=2, at_most=3)
    time_limit = planner.number("time_limit_s", 60.0, above=0, unit="s")
    return PlannerSpec(
        dimensions=dimensions,
        dt=planner.number("dt", 0.01, above=0, below=time_limit, unit="s (below planner.time_limit_s)"),
        time_limit_s=time_limit,
        speed=planner.number("speed", limits.v_xy_leader, above=0, unit="m/s"),
        goal_radius=planner.number("goal_radius", 0.5, above=0, unit="m"),
        step=planner.choice("step", "proportional", ("proportional", "constant")),
        start=planner.optional_vector("start"),
    )
