"""The rules of a mission that relate several keys: bounds set by other keys, references (outage vehicles,
the adjacency matrix), fleet consistency, placement against obstacles and geofence, limits.

`check_file` runs on the validated file (what building the `Mission` relies on), `check_mission` on the built
`Mission`. Each raises a MissionError at the YAML line of the value that is wrong (`root.at(key path)`).
Shapely is imported only when a mission has a site (fence polygon, exclusion zones, prisms), so that the
missions without one start as fast as before (every start of the ground station and the simulator loads one).
"""

from __future__ import annotations

import difflib
import math
import re

import numpy as np
from scipy.sparse.csgraph import breadth_first_order

from gcs_swarm.guidance.params import G
from gcs_swarm.link.autopilots import DIALECTS
from gcs_swarm.mission.geometry import mission_offsets
from gcs_swarm.mission.model import Mission, leg_at
from gcs_swarm.mission.schema import MissionFile, Range, SafetySection, describe
from gcs_swarm.mission.yaml_tree import MissionError, Node, loc_path
from swarm_common.radio_presets import RADIO_OVERRIDES, RadioError, radio_spec

# pymavlink connection strings: network forms "kind:host:port", serial "/dev/ttyX[,baud]" or "COMn[,baud]"
_NETWORK = re.compile(r"(udpin|udpout|udp|udpbcast|tcp|tcpin):([^:\s]+):([0-9]{1,5})")
_SERIAL = re.compile(r"(/dev/[^,\s]+|COM[0-9]+)(,[0-9]{3,7})?")
_LISTENING = ("udpin", "tcpin")
_CONNECTION_HINT = (
    "expected a pymavlink connection string such as 'udpout:127.0.0.1:14541', 'udpin:0.0.0.0:14550', "
    "'tcp:192.168.1.10:5760' or '/dev/ttyUSB0,57600'"
)
# safety.dead_gcs key -> the FailsafeSettings timing it becomes (gcs_swarm.flight.preflight)
ALTITUDE_TOLERANCE_M = 0.01  # m a leg waypoint's own height may differ from its leg's altitude

FAILSAFE_TIMINGS = {
    "failsafe_timeout_s": "gcs_loss_s",
    "guided_timeout_s": "guided_timeout_s",
    "offboard_loss_timeout_s": "offboard_loss_s",
}


def failsafe_timeout(safety: SafetySection) -> float:
    """safety.dead_gcs.failsafe_timeout_s, or its default telemetry.lost_s (at least what every autopilot
    accepts), in s."""
    given = safety.dead_gcs.failsafe_timeout_s
    lowest = max(d.failsafe_ranges["gcs_loss_s"][0] for d in DIALECTS if "gcs_loss_s" in d.failsafe_ranges)
    return max(safety.telemetry.lost_s, lowest) if given is None else given


# ---------------------------------------------------------------- on the validated file


def check_file(file: MissionFile, root: Node) -> None:
    """Bounds other keys set, the goal or route, the fleet's list, the topology, the outages' vehicles."""
    run, safety, planner = file.run, file.safety, file.planner
    above_floor = Range(gt=safety.min_altitude, unit="m (above safety.min_altitude)")
    below_limit = Range(lt=planner.time_limit_s, unit="s (below planner.time_limit_s)")
    for loc, value, bounds in (
        (("run", "simulator", "rate_hz"), run.simulator.rate_hz, Range(ge=run.control_rate_hz, unit="Hz")),
        (("safety", "geofence", "max_alt"), safety.geofence.max_alt, above_floor),
        (("planner", "dt"), planner.dt, below_limit),
    ):
        problem = bounds.problem(value)
        if problem:
            raise root.at(loc).error(problem)
    _safety(file.safety, root)
    if not file.vehicles:
        raise root.at(("vehicles",)).error(
            "the list is empty; a mission needs one leader and any number of followers"
        )
    for i, vehicle in enumerate(file.vehicles):
        for key in ("slot", "target"):
            if vehicle.role == "leader" and key in vehicle.model_fields_set:
                owner = "the mission goal" if key == "target" else "the formation's reference point"
                raise root.at(("vehicles", i, key)).error(f"the leader has no {key}; it is {owner}")
    _route(file, root)
    _adjacency(file, root)
    _outage_vehicles(file, root)
    _radio(file, root)


def _safety(safety: SafetySection, root: Node) -> None:
    separation = safety.separation
    if separation.mode == "constant" and separation.d_emg > separation.d_max:
        raise root.at(("safety", "separation", "d_emg")).error(
            f"d_emg ({separation.d_emg:g} m) must not exceed d_max ({separation.d_max:g} m) (spec 4)"
        )
    timeout, lost_s = failsafe_timeout(safety), safety.telemetry.lost_s
    blamed = root.at(("safety", "dead_gcs", "failsafe_timeout_s"))
    if timeout < lost_s:
        raise blamed.error(
            f"failsafe_timeout_s ({timeout:g} s) must be at least telemetry.lost_s "
            f"({lost_s:g} s): a vehicle would brake on a link outage the fleet still rides out"
        )
    dead_gcs = safety.dead_gcs
    values = {"failsafe_timeout_s": timeout}
    values |= {key: getattr(dead_gcs, key) for key in ("guided_timeout_s", "offboard_loss_timeout_s")}
    for key, value in values.items():
        for dialect in DIALECTS:  # any vehicle may turn out to be any of them (autopilot: auto)
            low, high, param = dialect.failsafe_ranges.get(FAILSAFE_TIMINGS[key], (-math.inf, math.inf, ""))
            if not low <= value <= high:
                defaulted = key == "failsafe_timeout_s" and dead_gcs.failsafe_timeout_s is None
                hint = " (it defaults to telemetry.lost_s: lower that)" if defaulted else ""
                raise root.at(("safety", "dead_gcs", key)).error(
                    f"{key} ({value:g} s) must lie in {low:g}..{high:g} s "
                    f"({dialect.name}'s {param} range){hint}"
                )


def _route(file: MissionFile, root: Node) -> None:
    """The route is given once: as `goal`, `waypoints` or `legs`, none of them empty; a leg with an
    `altitude` has no waypoint at another height."""
    given = [key for key in ("goal", "waypoints", "legs") if key in file.model_fields_set]
    if len(given) > 1:
        raise root.at((given[1],)).error(
            f"give the route once: 'goal', 'waypoints' (whose last point is the goal) or 'legs', not both "
            f"'{given[0]}' and '{given[1]}'"
        )
    if not given:
        raise root.at(("goal",)).error(
            "required key is missing (give the leader's 'goal', a list of 'waypoints' or of 'legs')"
        )
    if "waypoints" in given and not file.waypoints:
        raise root.at(("waypoints",)).error("the list is empty; give at least the goal")
    if "legs" in given and not file.legs:
        raise root.at(("legs",)).error("the list is empty; give at least one leg")
    for j, leg in enumerate(file.legs):
        if not leg.waypoints:
            raise root.at(("legs", j, "waypoints")).error("the list is empty; give at least the leg's end")
        if leg.altitude is None:
            continue
        for k, point in enumerate(leg.waypoints):
            height = point[2] if isinstance(point, list) else point.alt
            if (height is not None and abs(height - leg.altitude) > ALTITUDE_TOLERANCE_M) or (
                not isinstance(point, list) and point.amsl is not None
            ):
                raise root.at(("legs", j, "waypoints", k)).error(
                    f"the leg's altitude ({leg.altitude:g} m) sets every waypoint's height; this one gives "
                    "another (leave alt/amsl out of {lat, lon} waypoints, or give the same z)"
                )


def _adjacency(file: MissionFile, root: Node) -> None:
    """formation.adjacency: N x N of 0/1 in vehicle order, diagonal 0; required for topology 'relay'."""
    rows, n = file.formation.adjacency, len(file.vehicles)
    if rows is None:
        if file.formation.topology == "relay":
            raise root.at(("formation", "topology")).error(
                "topology 'relay' needs formation.adjacency (an N x N matrix of 0/1 in vehicle order)"
            )
        return
    if len(rows) != n:
        raise root.at(("formation", "adjacency")).error(
            f"expected {n} rows (one per vehicle), got {len(rows)}"
        )
    for i, row in enumerate(rows):
        if len(row) != n:
            raise root.at(("formation", "adjacency", i)).error(
                f"expected {n} entries (one per vehicle), got {len(row)}"
            )
        for j, value in enumerate(row):
            entry = root.at(("formation", "adjacency", i, j))
            if value not in (0, 1):
                raise entry.error(f"expected 0 or 1, got {value}")
            if i == j and value:
                raise entry.error("the diagonal must be 0 (a vehicle does not link to itself)")


def _radio(file: MissionFile, root: Node) -> None:
    """world.link's radio settings make a radio (swarm_common.radio_presets.radio_spec: overrides need a
    preset or capacity_bps)."""
    link = file.world.link
    try:
        radio_spec(link.radio, {key: getattr(link, key) for key in RADIO_OVERRIDES})
    except RadioError as exc:
        raise root.at(("world", "link", exc.key)).error(str(exc)) from None


def _outage_vehicles(file: MissionFile, root: Node) -> None:
    """world.link.outages[k].vehicle names a vehicle (given: the default names uav<i+1> count too)."""
    names = [vehicle.name or f"uav{i + 1}" for i, vehicle in enumerate(file.vehicles)]
    for k, outage in enumerate(file.world.link.outages or ()):
        name = outage.vehicle
        if "vehicle" in outage.model_fields_set and not (isinstance(name, str) and name in names):
            close = difflib.get_close_matches(name, names, n=1) if isinstance(name, str) else []
            hint = f"; did you mean {close[0]!r}?" if close else f" (vehicles: {', '.join(names)})"
            raise root.at(("world", "link", "outages", k, "vehicle")).error(
                f"expected the name of a vehicle, got {describe(name)}{hint}"
            )


# ---------------------------------------------------------------- on the built mission


def check_mission(mission: Mission, root: Node) -> None:
    """One leader; unique names, sysids and endpoints; starts, targets, slots; relay reach; placement of the
    route and the planner start; formation altitude; the leader's speed cap."""
    _site_polygons(mission, root)
    fence = mission.fence
    if fence.upload and fence.polygon is None and not fence.exclusions:
        raise root.at(("safety", "geofence", "upload")).error(
            "there is no site fence to upload: give safety.geofence.polygon or .exclusions"
        )
    _one_leader(mission, root)
    _unique_identities(mission, root)
    _starts(mission, root)
    for i, vehicle in enumerate(mission.vehicles):
        if vehicle.target is not None:
            _place(mission, root, vehicle.target, ("vehicles", i, "target"), "this target")
    _slots(mission, root)
    _relay(mission, root)
    for k, point in enumerate(mission.waypoints):
        key = waypoint_key(mission, root, k)
        _place(mission, root, point, key, "the goal" if key == ("goal",) else "this waypoint")
    _leg_speeds(mission, root)
    if mission.planner.start is not None:
        start = mission.planner.start
        _place(mission, root, start, ("planner", "start"), "the planner start", fenced=False, floor=False)
    formation, safety = mission.formation, mission.safety
    if not safety.min_altitude <= formation.altitude <= safety.geofence_max_alt:
        raise root.at(("formation", "altitude")).error(
            f"{formation.altitude:g} m is outside safety.min_altitude..safety.geofence.max_alt "
            f"({safety.min_altitude:g}..{safety.geofence_max_alt:g} m)"
        )
    limits = mission.limits
    if len(mission.vehicles) > 1 and not limits.v_xy_leader < limits.v_xy:
        raise root.at(("limits", "v_xy_leader")).error(
            f"the leader's cap ({limits.v_xy_leader:g} m/s) must be below the followers' v_xy "
            f"({limits.v_xy:g} m/s) so they can close gaps (spec 8 step 3)"
        )


def endpoint(connection: str, blamed: Node) -> tuple[str, str, int]:
    """(kind, host or device, port) of a connection string; `udp` reads as `udpin`, localhost as 127.0.0.1."""
    value = connection.strip()
    network = _NETWORK.fullmatch(value)
    if network:
        kind, host, port = network.group(1), network.group(2).lower(), int(network.group(3))
        if not 1 <= port <= 65535:
            raise blamed.error(f"port {port} is outside 1..65535")
        kind = "udpin" if kind == "udp" else kind
        host = "127.0.0.1" if host == "localhost" else host
        return kind, ("*" if kind in _LISTENING else host), port
    serial = _SERIAL.fullmatch(value)
    if serial:
        return "serial", serial.group(1), 0
    raise blamed.error(f"{_CONNECTION_HINT}, got {value!r}")


def _place(
    mission: Mission,
    root: Node,
    point: np.ndarray,
    loc: tuple[str | int, ...],
    what: str,
    *,
    fenced: bool = True,
    floor: bool = True,
) -> None:
    """`point` (3,) m ENU at key path `loc` lies outside every obstacle (at t = 0), and inside the geofence
    (`fenced`) and above the altitude floor (`floor`); `what` names it in the sentence ("the goal")."""
    safety, node = mission.safety, root.at(loc)
    margin = safety.collision_radius
    for k, obstacle in enumerate(mission.obstacles):
        distance = float(np.linalg.norm(point - obstacle.center))
        if distance <= obstacle.radius + margin:
            where = root.at(("world", "obstacles", k))
            raise node.error(
                f"{what} lies inside obstacle {where.path} (line {where.line}): "
                f"{distance:.2f} m from its centre, which needs more than radius {obstacle.radius:g} m "
                f"+ vehicle radius {margin:g} m"
            )
    for k, prism in enumerate(mission.prisms):
        from shapely.geometry import Point, Polygon

        if prism.bottom - margin <= point[2] <= prism.top + margin:
            gap = Polygon(prism.footprint).exterior.distance(Point(point[:2]))
            if Polygon(prism.footprint).contains(Point(point[:2])) or gap <= margin:
                where = root.at(("world", "prisms", k))
                raise node.error(f"{what} lies inside prism {prism.name!r} ({where.path}, line {where.line})")
    for k, cylinder in enumerate(mission.cylinders):
        if cylinder.bottom - margin <= point[2] <= cylinder.top + margin:
            if float(np.linalg.norm(point[:2] - cylinder.center)) <= cylinder.radius + margin:
                where = root.at(("world", "cylinders", k))
                raise node.error(
                    f"{what} lies inside cylinder {cylinder.name!r} ({where.path}, line {where.line})"
                )
    if fenced:
        _in_fence(mission, root, point, node, what)
        horizontal = float(np.hypot(point[0], point[1]))
        if horizontal > safety.geofence_radius:
            raise node.error(
                f"{what} is {horizontal:.0f} m from the origin, outside the geofence "
                f"(safety.geofence.radius = {safety.geofence_radius:g} m)"
            )
        if point[2] > safety.geofence_max_alt:
            raise node.error(
                f"{what} is at {point[2]:g} m, above the geofence "
                f"(safety.geofence.max_alt = {safety.geofence_max_alt:g} m)"
            )
    if floor and point[2] < safety.min_altitude:
        raise node.error(
            f"{what} is at {point[2]:g} m, below safety.min_altitude ({safety.min_altitude:g} m)"
        )


def _site_polygons(mission: Mission, root: Node) -> None:
    """The fence polygon, the exclusion polygons and the prisms' footprints are simple polygons (shapely:
    at least 3 vertices, no self-intersection, non-zero area)."""
    fence = mission.fence
    shapes: list[tuple[np.ndarray, tuple[str | int, ...]]] = []
    if fence.polygon is not None:
        shapes.append((fence.polygon, ("safety", "geofence", "polygon")))
    shapes += [
        (zone.polygon, ("safety", "geofence", "exclusions", k, "polygon"))
        for k, zone in enumerate(fence.exclusions)
        if zone.polygon is not None
    ]
    shapes += [(prism.footprint, ("world", "prisms", k, "polygon")) for k, prism in enumerate(mission.prisms)]
    if not shapes:
        return
    import shapely
    from shapely.geometry import Polygon

    for vertices, loc in shapes:
        if len({tuple(v) for v in vertices}) < 3:
            raise root.at(loc).error(f"a polygon needs at least 3 distinct vertices, got {len(vertices)}")
        polygon = Polygon(vertices)
        if not polygon.is_valid or polygon.area <= 0.0:
            raise root.at(loc).error(f"not a simple polygon ({shapely.is_valid_reason(polygon)})")


def _in_fence(mission: Mission, root: Node, point: np.ndarray, node: Node, what: str) -> None:
    """`point` (3,) m ENU lies inside the fence polygon and outside every exclusion zone, by more than the
    vehicle's collision radius."""
    fence = mission.fence
    if fence.polygon is None and not fence.exclusions:
        return
    from shapely.geometry import Point, Polygon

    margin = mission.safety.collision_radius
    where = Point(point[:2])
    if fence.polygon is not None:
        polygon = Polygon(fence.polygon)
        if not polygon.contains(where) or polygon.exterior.distance(where) <= margin:
            raise node.error(
                f"{what} is not inside the fence polygon (safety.geofence.polygon) by more than the vehicle "
                f"radius {margin:g} m"
            )
    for k, zone in enumerate(fence.exclusions):
        if zone.polygon is not None:
            inside = Polygon(zone.polygon).buffer(margin).contains(where)
        else:
            inside = float(np.linalg.norm(point[:2] - zone.center)) <= zone.radius + margin
        if inside:
            given = root.at(("safety", "geofence", "exclusions", k))
            raise node.error(
                f"{what} lies in exclusion zone {zone.name!r} ({given.path}, line {given.line}) or within "
                f"the vehicle radius {margin:g} m of it"
            )


def fence_reach(mission: Mission) -> tuple[float, str]:
    """(m, how it is made up): how far from the leader's straight legs the formation may be, which the site
    fence must leave free: the widest slot's horizontal distance from the leader (in the widest formation
    of the mission's legs) + the vehicle's collision
    radius + the command guard's braking margin at the leader's speed cap, v^2 / (2 g tan(tilt_max)) (the
    guard levels tilts towards a fence edge within that margin, gcs_swarm.link.command_limits)."""
    shapes = [mission_offsets(mission)]
    shapes += [mission_offsets(mission, leg.shape, leg.spacing) for leg in mission.legs]
    slots = max(float(np.hypot(offsets[:, 0], offsets[:, 1]).max()) for offsets in shapes)
    body = float(mission.safety.collision_radius)
    limits = mission.limits
    braking = limits.v_xy_leader**2 / (2.0 * G * math.tan(math.radians(limits.tilt_max_deg)))
    how = f"widest slot {slots:.2f} m + vehicle radius {body:g} m + braking margin {braking:.2f} m"
    return slots + body + braking, how


def waypoint_key(mission: Mission, root: Node, k: int) -> tuple[str | int, ...]:
    """Where the file gives Mission.waypoints[k]: ("goal",), ("waypoints", k) or ("legs", j, "waypoints",
    m)."""
    if mission.legs:
        j = leg_at(mission.legs, k)
        return ("legs", j, "waypoints", k - mission.legs[j].first)
    if len(mission.waypoints) == 1 and root.at(("waypoints",)).value is None:
        return ("goal",)
    return ("waypoints", k)


def _leg_speeds(mission: Mission, root: Node) -> None:
    """No leg asks the leader for more than limits.v_xy_leader."""
    cap = mission.limits.v_xy_leader
    for j, leg in enumerate(mission.legs):
        if leg.speed > cap:
            raise root.at(("legs", j, "speed")).error(
                f"{leg.speed:g} m/s is above the leader's cap limits.v_xy_leader ({cap:g} m/s)"
            )


def _fenced_legs(mission: Mission, root: Node) -> MissionError | None:
    """The refusal to fly unless every straight leg of the leader's route (its start, then each waypoint up
    to the goal), widened by the formation's reach (fence_reach), lies inside the fence polygon and clear of
    every exclusion zone: the guidance flies the legs and does not itself know the fence, so in normal flight
    it must not need the guard. None when they do (or there is no site fence)."""
    fence = mission.fence
    if fence.polygon is None and not fence.exclusions:
        return None
    from shapely.geometry import LineString, Point, Polygon

    reach, how = fence_reach(mission)
    leader = mission.vehicles[mission.leader_index]
    points = [np.asarray(leader.start.position[:2], dtype=float)]
    points += [np.asarray(w[:2], dtype=float) for w in mission.waypoints]
    keys = [loc_path(waypoint_key(mission, root, k)) for k in range(len(mission.waypoints))]
    for k in range(1, len(points)):
        a, b = points[k - 1], points[k]
        leg = LineString([a, b]) if np.any(a != b) else Point(a)
        swept = leg.buffer(reach)
        node = root.at(waypoint_key(mission, root, k - 1))
        came = "the leader's start" if k == 1 else keys[k - 2]
        what = f"the leg from {came} to {'the goal' if keys[k - 1] == 'goal' else keys[k - 1]}"
        if fence.polygon is not None:
            polygon = Polygon(fence.polygon)
            if not polygon.contains(swept):
                gap = polygon.exterior.distance(leg) if polygon.contains(leg) else 0.0
                return node.error(
                    f"{what} comes within {gap:.2f} m of the fence polygon's edge (safety.geofence.polygon); "
                    f"the formation needs {reach:.2f} m beside its leader's legs ({how})"
                )
        for j, zone in enumerate(fence.exclusions):
            shape = (
                Polygon(zone.polygon) if zone.polygon is not None else Point(zone.center).buffer(zone.radius)
            )
            if swept.intersects(shape):
                given = root.at(("safety", "geofence", "exclusions", j))
                return node.error(
                    f"{what} comes within {leg.distance(shape):.2f} m of exclusion zone {zone.name!r} "
                    f"({given.path}, line {given.line}); the formation needs {reach:.2f} m beside its "
                    f"leader's legs ({how})"
                )
    return None


def flight_refusal(mission: Mission, root: Node) -> MissionError | None:
    """The refusal to fly a valid mission whose leader's legs bring the formation too near the site fence
    (_fenced_legs), or None: `gcs-swarm check` validates such a mission, `gcs-swarm run` refuses it."""
    return _fenced_legs(mission, root)


def _one_leader(mission: Mission, root: Node) -> None:
    leaders = [i for i, v in enumerate(mission.vehicles) if v.role == "leader"]
    if not leaders:
        raise root.at(("vehicles",)).error("no vehicle has 'role: leader'; exactly one must lead")
    if len(leaders) > 1:
        raise root.at(("vehicles", leaders[1], "role")).error(
            f"a second leader (vehicles[{leaders[0]}] already leads); exactly one vehicle leads"
        )


def _unique_identities(mission: Mission, root: Node) -> None:
    names: dict[str, str] = {}
    sysids: dict[int, str] = {}
    endpoints: dict[tuple[str, str, int], int] = {}
    simulator = mission.run.simulator
    for index, vehicle in enumerate(mission.vehicles):
        path = f"vehicles[{index}]"
        if vehicle.name in names:
            raise root.at(("vehicles", index, "name")).error(
                f"the name {vehicle.name!r} is already used by {names[vehicle.name]}"
            )
        names[vehicle.name] = path
        if vehicle.sysid is not None:
            sysid = root.at(("vehicles", index, "sysid"))
            if vehicle.sysid in sysids:
                raise sysid.error(f"sysid {vehicle.sysid} is already used by {sysids[vehicle.sysid]}")
            if simulator.embedded and vehicle.sysid != index + 1:
                raise sysid.error(
                    f"the embedded simulator numbers vehicles in order, so this one has sysid {index + 1}, "
                    f"not {vehicle.sysid} (or set run.simulator.embedded: false)"
                )
            sysids[vehicle.sysid] = path
        connection = root.at(("vehicles", index, "connection"))
        key = endpoint(vehicle.connection, connection)
        expected = f"udpout:127.0.0.1:{simulator.base_port + index}"
        if simulator.embedded and key != ("udpout", "127.0.0.1", simulator.base_port + index):
            raise connection.error(
                f"the embedded simulator serves this vehicle at {expected!r} "
                f"(run.simulator.base_port + {index}), got {vehicle.connection!r}"
            )
        other = endpoints.get(key)
        if other is not None:
            shared_listener = (
                key[0] == "udpin" and vehicle.sysid is not None and mission.vehicles[other].sysid is not None
            )
            if not shared_listener:
                raise connection.error(
                    f"{vehicle.connection!r} is already used by vehicles[{other}]; vehicles may share "
                    "only a 'udpin:' listening endpoint, and then each needs its own sysid"
                )
        endpoints[key] = index
    last_port = simulator.base_port + len(mission.vehicles) - 1
    if simulator.embedded and last_port > 65535:
        last = len(mission.vehicles) - 1
        raise root.at(("vehicles", last)).error(f"needs port {last_port}; lower run.simulator.base_port")


def _starts(mission: Mission, root: Node) -> None:
    run, safety = mission.run, mission.safety
    for index, vehicle in enumerate(mission.vehicles):
        start, loc = vehicle.start, ("vehicles", index, "start", "position")
        z = float(start.position[2])
        if run.airborne_start and z < safety.min_altitude:
            raise root.at(loc).error(
                f"an airborne start (run.airborne_start: true) must be at least safety.min_altitude "
                f"({safety.min_altitude:g} m) up, got z = {z:g} m"
            )
        if not run.airborne_start:
            if z != 0.0:
                raise root.at(loc).error(
                    f"a ground start needs z = 0, got {z:g} m "
                    "(set run.airborne_start: true to start in flight)"
                )
            if np.any(start.velocity != 0.0):
                raise root.at(("vehicles", index, "start", "velocity")).error(
                    "a ground start needs zero velocity (set run.airborne_start: true to start in flight)"
                )
        _place(mission, root, start.position, loc, "this start position", floor=False)
        for other_index, other in enumerate(mission.vehicles[:index]):
            gap = float(np.linalg.norm(start.position - other.start.position))
            if gap < 2 * safety.collision_radius:
                raise root.at(loc).error(
                    f"is {gap:.2f} m from the start of vehicles[{other_index}]; vehicles need at least "
                    f"{2 * safety.collision_radius:g} m (twice safety.collision_radius)"
                )


def _slots(mission: Mission, root: Node) -> None:
    collision_radius = mission.safety.collision_radius
    taken: list[tuple[np.ndarray, str]] = [(np.zeros(3), "the leader")]
    for index, vehicle in enumerate(mission.vehicles):
        if vehicle.role == "leader":
            continue
        slot = vehicle.slot
        if slot is None:
            if mission.formation.shape == "offsets":
                raise root.at(("vehicles", index, "slot")).error(
                    "formation.shape is 'offsets', so every follower needs its slot [x, y, z]"
                )
            continue
        for other, owner in taken:
            gap = float(np.linalg.norm(slot - other))
            if gap < 2 * collision_radius:
                raise root.at(("vehicles", index, "slot")).error(
                    f"is {gap:.2f} m from the slot of {owner}; slots need at least {2 * collision_radius:g} m"
                )
        taken.append((slot, f"vehicles[{index}]"))


def _relay(mission: Mission, root: Node) -> None:
    """With topology 'relay' every follower must hear the leader via the graph (A[i, j] = 1: i hears j)."""
    adjacency, n = mission.formation.adjacency, len(mission.vehicles)
    if mission.formation.topology != "relay" or adjacency is None:
        return
    # who hears the leader, directly or through others: a search from it along j -> i wherever A[i, j] = 1
    reached = breadth_first_order(adjacency.T, mission.leader_index, return_predecessors=False)
    deaf = [i for i in range(n) if i not in reached]
    if deaf:
        raise root.at(("formation", "adjacency")).error(
            f"with topology 'relay' vehicles[{deaf[0]}] ({mission.vehicles[deaf[0]].name}) never hears the "
            "leader; row i lists whom vehicle i hears"
        )
