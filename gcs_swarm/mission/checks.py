"""Cross-field checks of a mission: fleet consistency, placement against obstacles and geofence, limits.

Each check raises a MissionError at the YAML line of the value that is wrong.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gcs_swarm.guidance.params import Limits
from gcs_swarm.mission.fields import Section, param_fields
from gcs_swarm.mission.model import FormationSpec, Obstacle, RunSpec, SafetySpec, VehicleSpec
from gcs_swarm.mission.yaml_tree import Node

# pymavlink connection strings: network forms "kind:host:port", serial "/dev/ttyX[,baud]" or "COMn[,baud]"
_NETWORK = re.compile(r"(udpin|udpout|udp|udpbcast|tcp|tcpin):([^:\s]+):([0-9]{1,5})")
_SERIAL = re.compile(r"(/dev/[^,\s]+|COM[0-9]+)(,[0-9]{3,7})?")
_LISTENING = ("udpin", "tcpin")
_CONNECTION_HINT = (
    "expected a pymavlink connection string such as 'udpout:127.0.0.1:14541', 'udpin:0.0.0.0:14550', "
    "'tcp:192.168.1.10:5760' or '/dev/ttyUSB0,57600'"
)


@dataclass(frozen=True)
class ParsedVehicle:
    """A vehicle and the YAML it came from (for errors about it found later)."""

    spec: VehicleSpec
    section: Section  # the vehicle's mapping
    start_section: Section  # its `start` mapping


def endpoint(node: Node) -> tuple[str, str, int]:
    """(kind, host or device, port) of a connection string; `udp` reads as `udpin`, localhost as 127.0.0.1."""
    value = str(node.value).strip()
    network = _NETWORK.fullmatch(value)
    if network:
        kind, host, port = network.group(1), network.group(2).lower(), int(network.group(3))
        if not 1 <= port <= 65535:
            raise node.error(f"port {port} is outside 1..65535")
        kind = "udpin" if kind == "udp" else kind
        host = "127.0.0.1" if host == "localhost" else host
        return kind, ("*" if kind in _LISTENING else host), port
    serial = _SERIAL.fullmatch(value)
    if serial:
        return "serial", serial.group(1), 0
    raise node.error(f"{_CONNECTION_HINT}, got {value!r}")


class Placed:
    """Checks that points lie outside every obstacle (at t = 0) and inside the geofence and altitude band."""

    def __init__(self, obstacles: Sequence[Obstacle], nodes: Sequence[Node], safety: SafetySpec) -> None:
        self.obstacles = obstacles
        self.nodes = nodes
        self.safety = safety

    def check(
        self, point: np.ndarray, node: Node, what: str, *, fenced: bool = True, floor: bool = True
    ) -> None:
        """`what` names the point in the sentence ("the goal", "this start position")."""
        margin = self.safety.collision_radius
        for k, obstacle in enumerate(self.obstacles):
            distance = float(np.linalg.norm(point - obstacle.center))
            if distance <= obstacle.radius + margin:
                raise node.error(
                    f"{what} lies inside obstacle {self.nodes[k].path} (line {self.nodes[k].line}): "
                    f"{distance:.2f} m from its centre, which needs more than radius {obstacle.radius:g} m "
                    f"+ vehicle radius {margin:g} m"
                )
        if fenced:
            horizontal = float(np.hypot(point[0], point[1]))
            if horizontal > self.safety.geofence_radius:
                raise node.error(
                    f"{what} is {horizontal:.0f} m from the origin, outside the geofence "
                    f"(safety.geofence.radius = {self.safety.geofence_radius:g} m)"
                )
            if point[2] > self.safety.geofence_max_alt:
                raise node.error(
                    f"{what} is at {point[2]:g} m, above the geofence "
                    f"(safety.geofence.max_alt = {self.safety.geofence_max_alt:g} m)"
                )
        if floor and point[2] < self.safety.min_altitude:
            raise node.error(
                f"{what} is at {point[2]:g} m, below safety.min_altitude ({self.safety.min_altitude:g} m)"
            )


def vehicles(
    listed: Node,
    fleet: Sequence[ParsedVehicle],
    run: RunSpec,
    safety: SafetySpec,
    formation: FormationSpec,
    placed: Placed,
) -> None:
    """One leader; unique names, sysids and endpoints; embedded-simulator ports; starts, targets, slots.

    `listed` is the `vehicles` list node.
    """
    _one_leader(listed, fleet)
    _unique_identities(fleet, run)
    _starts(fleet, run, safety, placed)
    for vehicle in fleet:
        if vehicle.spec.target is not None:
            placed.check(vehicle.spec.target, vehicle.section.line_of("target"), "this target")
    _slots(fleet, formation, safety)


def _one_leader(listed: Node, fleet: Sequence[ParsedVehicle]) -> None:
    leaders = [v for v in fleet if v.spec.role == "leader"]
    if not leaders:
        raise listed.error("no vehicle has 'role: leader'; exactly one must lead")
    if len(leaders) > 1:
        raise (
            leaders[1]
            .section.line_of("role")
            .error(
                f"a second leader ({leaders[0].section.node.path} already leads); exactly one vehicle leads"
            )
        )


def _unique_identities(fleet: Sequence[ParsedVehicle], run: RunSpec) -> None:
    names: dict[str, str] = {}
    sysids: dict[int, str] = {}
    endpoints: dict[tuple[str, str, int], ParsedVehicle] = {}
    embedded = run.simulator.embedded
    for index, vehicle in enumerate(fleet):
        spec, path = vehicle.spec, vehicle.section.node.path
        if spec.name in names:
            raise vehicle.section.line_of("name").error(
                f"the name {spec.name!r} is already used by {names[spec.name]}"
            )
        names[spec.name] = path
        if spec.sysid is not None:
            if spec.sysid in sysids:
                raise vehicle.section.line_of("sysid").error(
                    f"sysid {spec.sysid} is already used by {sysids[spec.sysid]}"
                )
            if embedded and spec.sysid != index + 1:
                raise vehicle.section.line_of("sysid").error(
                    f"the embedded simulator numbers vehicles in order, so this one has sysid {index + 1}, "
                    f"not {spec.sysid} (or set run.simulator.embedded: false)"
                )
            sysids[spec.sysid] = path
        connection = vehicle.section.line_of("connection")
        key = endpoint(Node(spec.connection, connection.line, connection.path, connection.source))
        expected = f"udpout:127.0.0.1:{run.simulator.base_port + index}"
        if embedded and key != ("udpout", "127.0.0.1", run.simulator.base_port + index):
            raise connection.error(
                f"the embedded simulator serves this vehicle at {expected!r} "
                f"(run.simulator.base_port + {index}), got {spec.connection!r}"
            )
        other = endpoints.get(key)
        if other is not None:
            shared_listener = key[0] == "udpin" and spec.sysid is not None and other.spec.sysid is not None
            if not shared_listener:
                raise connection.error(
                    f"{spec.connection!r} is already used by {other.section.node.path}; vehicles may share "
                    "only a 'udpin:' listening endpoint, and then each needs its own sysid"
                )
        endpoints[key] = vehicle
    last_port = run.simulator.base_port + len(fleet) - 1
    if embedded and last_port > 65535:
        raise fleet[-1].section.node.error(f"needs port {last_port}; lower run.simulator.base_port")


def _starts(fleet: Sequence[ParsedVehicle], run: RunSpec, safety: SafetySpec, placed: Placed) -> None:
    for index, vehicle in enumerate(fleet):
        start, node = vehicle.spec.start, vehicle.start_section.line_of("position")
        z = float(start.position[2])
        if run.airborne_start and z < safety.min_altitude:
            raise node.error(
                f"an airborne start (run.airborne_start: true) must be at least safety.min_altitude "
                f"({safety.min_altitude:g} m) up, got z = {z:g} m"
            )
        if not run.airborne_start:
            if z != 0.0:
                raise node.error(
                    f"a ground start needs z = 0, got {z:g} m "
                    "(set run.airborne_start: true to start in flight)"
                )
            if np.any(start.velocity != 0.0):
                raise vehicle.start_section.line_of("velocity").error(
                    "a ground start needs zero velocity (set run.airborne_start: true to start in flight)"
                )
        placed.check(start.position, node, "this start position", floor=False)
        for other in fleet[:index]:
            gap = float(np.linalg.norm(start.position - other.spec.start.position))
            if gap < 2 * safety.collision_radius:
                raise node.error(
                    f"is {gap:.2f} m from the start of {other.section.node.path}; vehicles need at least "
                    f"{2 * safety.collision_radius:g} m (twice safety.collision_radius)"
                )


def _slots(fleet: Sequence[ParsedVehicle], formation: FormationSpec, safety: SafetySpec) -> None:
    taken: list[tuple[np.ndarray, str]] = [(np.zeros(3), "the leader")]
    for vehicle in fleet:
        if vehicle.spec.role == "leader":
            continue
        slot = vehicle.spec.slot
        if slot is None:
            if formation.shape == "offsets":
                missing = Node(
                    None,
                    vehicle.section.node.line,
                    f"{vehicle.section.node.path}.slot",
                    vehicle.section.node.source,
                )
                raise missing.error(
                    "formation.shape is 'offsets', so every follower needs its slot [x, y, z]"
                )
            continue
        for other, owner in taken:
            gap = float(np.linalg.norm(slot - other))
            if gap < 2 * safety.collision_radius:
                raise vehicle.section.line_of("slot").error(
                    f"is {gap:.2f} m from the slot of {owner}; "
                    f"slots need at least {2 * safety.collision_radius:g} m"
                )
        taken.append((slot, vehicle.section.node.path))


def relay(formation_yaml: Section, formation: FormationSpec, fleet: Sequence[ParsedVehicle]) -> None:
    """With topology 'relay' every follower must hear the leader via the graph (A[i, j] = 1: i hears j)."""
    if formation.topology != "relay" or formation.adjacency is None:
        return
    adjacency = formation.adjacency
    reached = {next(i for i, v in enumerate(fleet) if v.spec.role == "leader")}
    grew = True
    while grew:
        hearing = {i for i in range(len(fleet)) if i not in reached and any(adjacency[i, j] for j in reached)}
        reached |= hearing
        grew = bool(hearing)
    deaf = [i for i in range(len(fleet)) if i not in reached]
    if deaf:
        raise formation_yaml.line_of("adjacency").error(
            f"with topology 'relay' vehicles[{deaf[0]}] ({fleet[deaf[0]].spec.name}) never hears the leader; "
            "row i lists whom vehicle i hears"
        )


def altitudes(formation_yaml: Section, formation: FormationSpec, safety: SafetySpec) -> None:
    """The formation altitude lies between the altitude floor and the geofence ceiling."""
    if not safety.min_altitude <= formation.altitude <= safety.geofence_max_alt:
        raise formation_yaml.line_of("altitude").error(
            f"{formation.altitude:g} m is outside safety.min_altitude..safety.geofence.max_alt "
            f"({safety.min_altitude:g}..{safety.geofence_max_alt:g} m)"
        )


def limits(top: Section, limits: Limits, fleet_size: int) -> None:
    """The leader must be slower than the followers, or they never close a gap (spec 8 step 3)."""
    if fleet_size > 1 and not limits.v_xy_leader < limits.v_xy:
        node = Section.within(top, "limits", param_fields(limits)).line_of("v_xy_leader")
        raise node.error(
            f"the leader's cap ({limits.v_xy_leader:g} m/s) must be below the followers' v_xy "
            f"({limits.v_xy:g} m/s) so they can close gaps (spec 8 step 3)"
        )
