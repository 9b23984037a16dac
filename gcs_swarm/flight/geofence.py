"""The autopilots' own geofence around the mission's obstacles: what to fence, and the MAVLink mission
protocol (mission_type FENCE) that uploads, downloads and clears it (docs/reliability.md, "The ground
station dies").

Why: when the ground station dies, ArduCopter flies the last attitude target for GUID_TIMEOUT, then levels and
drifts until FS_GCS_TIMEOUT brakes it; a vehicle heading at an obstacle can reach it in that gap. Its own
geofence closes the gap: every static obstacle the formation can meet becomes an exclusion circle
(MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION), FENCE_TYPE 4 (inclusion/exclusion circles and polygons), FENCE_ACTION 4
(Brake or Land, ArduCopter 4.1 and later), FENCE_ENABLE 1: entering a circle puts the vehicle in BRAKE
(ArduCopter/fence.cpp), with or without a ground station.

What is fenced (`exclusion_circles`): a static sphere whose horizontal cross-section at the altitudes the
formation flies (formation.altitude plus each slot's dz, and the waypoints' heights, widened by
BAND_TOLERANCE_M) is not empty; the circle's radius is that cross-section's largest radius + the vehicle's
collision radius + `safety.dead_gcs.fence.margin_m`. ArduCopter's zones are vertical cylinders, so a sphere
above or below the formation's band would only fence off air the formation never uses (and could trap a
vehicle parked under it), hence the band. A circle is shrunk so that it keeps KEEP_OUT_M clear of every start
position, waypoint and follower target, and of the disc around the goal that holds every final slot (a vehicle
inside a circle could not arm, "PreArm: Vehicle breaching Polygon fence", or would brake at its goal); an
obstacle that cannot be fenced so is skipped and said. Moving obstacles cannot be fenced (a fence is static).

The protocol (libraries/GCS_MAVLink/MissionItemProtocol.cpp, MissionItemProtocol_Fence.cpp), each step resent
on loss and timed in vehicle time like every other exchange (gcs_swarm.link.operations):
- upload: MISSION_COUNT(n, FENCE); the vehicle asks for each item with MISSION_REQUEST (ArduPilot; the
  MAVLink spec's MISSION_REQUEST_INT is answered too) and re-asks by itself after 1 s; each is answered with
  MISSION_ITEM_INT (frame GLOBAL, x/y lat/lon degE7, param1 the radius in m); done on MISSION_ACK ACCEPTED
  after the last item. INVALID_SEQUENCE (a duplicate item) is ignored, as the vehicle carries on; a
  cancelled upload (8 s without items, OPERATION_CANCELLED) or one denied while another runs is started
  over; any other refusal is an error naming it (with the vehicle's STATUSTEXT, e.g. "Fence validation
  failed").
- download: MISSION_REQUEST_LIST(FENCE) -> MISSION_COUNT, then MISSION_REQUEST_INT(seq) -> MISSION_ITEM_INT
  for each seq, then our MISSION_ACK ACCEPTED.
- clear: MISSION_CLEAR_ALL(FENCE) -> MISSION_ACK ACCEPTED.

The site fence (`site_items`, when the mission sets safety.geofence.upload): the inclusion polygon as
MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION items, each exclusion polygon as ..._VERTEX_EXCLUSION items (param1
the polygon's vertex count, AC_PolyFence_loader::validate_fence), each exclusion circle as
MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, all at every height as ArduCopter's zones are; uploaded after the obstacle
circles, in the same fence. ArduCopter then breaches outside the inclusion polygon or inside an exclusion zone
(AC_PolyFence_loader::breached) and acts as for the circles (FENCE_ACTION). The ground station's own guard
keeps the vehicles inside anyway (gcs_swarm.link.command_limits); the autopilot's fence is for the time the
ground station is gone.

`install_fence` (called from MissionRunner.preflight) reads each vehicle's fence, uploads the items, reads
them back and compares (verify by download), then sets each autopilot's own parameters through FlightParams
(AutopilotDialect.fence_params): on ArduPilot FENCE_TYPE = 4 (exactly: the max-altitude and home-circle
fences, FENCE_TYPE's default 7, would stop the paper missions flying at 200 m, 6 km out), FENCE_ACTION and
FENCE_ENABLE = 1; on PX4 GF_ACTION alone. At the end of the run (FlightParams.restore, on disarmed vehicles
only, like the parameters) the parameters go back and the vehicle's own fence is put back: cleared when it had
none, its old items uploaded again otherwise (a `params_changed` row named "fence items", original and flown =
the item counts). FENCE_MARGIN is left alone: ArduCopter uses it for AC_Avoid's stand-off and the pre-arm
check of inclusion circles, not to decide a breach; this margin is in the circles' radius.

PX4 (src/modules/mavlink/mavlink_mission.cpp, navigator/geofence.cpp) takes the same items over the same
protocol: MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION/EXCLUSION (param1 the vertex count, at least 3) and
..._CIRCLE_INCLUSION/EXCLUSION (param1 the radius) in a global frame (parse_mavlink_mission_item), asks for
them with MISSION_REQUEST_INT once the ground station has used the _INT messages (else MISSION_REQUEST; both
are answered here), silently ignores an item of the wrong seq (no INVALID_SEQUENCE: the upload goes on when
it re-asks) and answers MISSION_ACK ACCEPTED after the last item, or ERROR (for instance a polygon of fewer
than 3 vertices), or NO_SPACE. It checks every stored zone whenever it has some (Geofence::checkAll: outside
every inclusion zone or inside an exclusion zone is a breach), says "Geofence violation", and its failsafe
acts as GF_ACTION says (commander failsafe.cpp fromGfActParam).

Rally points (`rally_items`, the mission's safety.rally, whenever it has some) are shared out one a vehicle
(`rally_by_vehicle`: a fleet holding one list would all return to the same nearest point and land on each
other) and go up the same way with mission_type RALLY: MAV_CMD_NAV_RALLY_POINT items in frame
GLOBAL_RELATIVE_ALT, z the height above home in whole metres (ArduPilot: MissionItemProtocol_Rally,
RallyLocation.alt an int16, RALLY_TOTAL follows; PX4: mavlink_mission.cpp stores them as safe points),
verified by download and put back after the run (a `params_changed` row "rally items"). The parameters that
make each autopilot's RTL (the dead-ground-station failsafe `rtl`, a fence action `rtl`) go to the vehicle's
own point are the dialect's `rally_params`: ArduPilot RALLY_INCL_HOME 0 and RALLY_LIMIT_KM 0
(AP_Rally::calc_best_rally_or_home_location), PX4 RTL_TYPE 1 (rtl.cpp findRtlDestination; PX4 ignores a rally
point within 10 m of home).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from scipy.optimize import linear_sum_assignment

from gcs_swarm.link import frames
from gcs_swarm.link.autopilots import AutopilotDialect
from gcs_swarm.link.connection import LinkError, MAVLinkMessage
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.flight_params import FlightParams, ParamChange
from gcs_swarm.link.operations import COMMAND_RETRIES, Operation, Timeout
from gcs_swarm.link.vehicle import VehicleLink
from gcs_swarm.mission import Mission
from gcs_swarm.mission.geometry import mission_offsets
from gcs_swarm.mission.model import Fence

FENCE = mavlink2.MAV_MISSION_TYPE_FENCE
RALLY = mavlink2.MAV_MISSION_TYPE_RALLY
RALLY_POINT = mavlink2.MAV_CMD_NAV_RALLY_POINT
CIRCLE_EXCLUSION = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
CIRCLE_INCLUSION = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
POLYGON_INCLUSION = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
POLYGON_EXCLUSION = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
FENCE_ITEMS = "fence items"  # the FlightParams change row of a vehicle's fence
RALLY_ITEMS = "rally items"  # ... of its rally points
BAND_TOLERANCE_M = 3.0  # m above and below the formation's altitudes that count as "met" (altitude error,
# vertical separation manoeuvres)
KEEP_OUT_M = 1.0  # m a circle keeps clear of start positions, waypoints and final slots (beyond the body)
FIRST_ANSWER_S = 1.0  # vehicle s to wait for the vehicle's first answer before sending again
SETTLE_S = 0.3  # vehicle s for ArduPilot's fence loader (10 Hz) to act on a stored fence before reading it
STALL_S = 2.5  # vehicle s without a request during an upload before it is started over (the vehicle re-asks
# after 1 s itself, MissionItemProtocol::update)
_WHAT = {FENCE: "fence", RALLY: "rally points"}  # a mission type in an error sentence
_REFUSALS_TO_RETRY = (mavlink2.MAV_MISSION_OPERATION_CANCELLED, mavlink2.MAV_MISSION_DENIED)


@dataclass(frozen=True)
class FenceItem:
    """One fence item or rally point as a vehicle stores it: MAV_CMD_NAV_FENCE_* or MAV_CMD_NAV_RALLY_POINT
    command, lat/lon degE7, param1 (a circle's radius in m, float32 on the vehicle; a polygon vertex's vertex
    count), alt_m (a rally point's height m above home, frame GLOBAL_RELATIVE_ALT; 0 for fence items)."""

    command: int
    lat_e7: int
    lon_e7: int
    param1: float = 0.0
    alt_m: float = 0.0

    def same_as(self, other: FenceItem) -> bool:
        """Equal as stored (the radius and the height as float32)."""
        return (
            self.command == other.command
            and self.lat_e7 == other.lat_e7
            and self.lon_e7 == other.lon_e7
            and np.float32(self.param1) == np.float32(other.param1)
            and np.float32(self.alt_m) == np.float32(other.alt_m)
        )


@dataclass(frozen=True)
class FenceCircle:
    """An exclusion circle around obstacle `obstacle` (index in the mission): centre (2,) ENU m, radius m."""

    obstacle: int
    centre: tuple[float, float]
    radius: float


def exclusion_circles(mission: Mission, margin_m: float) -> tuple[list[FenceCircle], list[str]]:
    """The circles to fence (see the module docstring) and one note per obstacle left out or shrunk."""
    body = float(mission.safety.collision_radius)
    offsets = mission_offsets(mission)
    heights = np.concatenate(
        [mission.formation.altitude + offsets[:, 2], [float(w[2]) for w in mission.waypoints]]
    )
    low, high = float(heights.min()) - BAND_TOLERANCE_M, float(heights.max()) + BAND_TOLERANCE_M
    # points a circle keeps clear of; the goal's disc holds every final slot, whatever the final heading
    points = [np.asarray(v.start.position[:2], dtype=float) for v in mission.vehicles]
    points += [np.asarray(w[:2], dtype=float) for w in mission.waypoints]
    points += [np.asarray(v.target[:2], dtype=float) for v in mission.vehicles if v.target is not None]
    slots = float(np.linalg.norm(offsets[:, :2], axis=1).max())
    goal = np.asarray(mission.goal[:2], dtype=float)
    circles, notes = [], []
    for k, obstacle in enumerate(mission.obstacles):
        centre = np.asarray(obstacle.center, dtype=float)
        if np.any(np.asarray(obstacle.velocity) != 0.0):
            notes.append(f"obstacle {k} moves: a fence is static, it is not fenced")
            continue
        dz = abs(float(centre[2]) - min(max(float(centre[2]), low), high))
        if dz >= obstacle.radius + body:
            notes.append(f"obstacle {k} does not reach the formation's altitudes ({low:g}..{high:g} m)")
            continue
        section = math.sqrt(max(obstacle.radius**2 - dz**2, 0.0))
        wanted = section + body + margin_m
        limits = [float(np.hypot(*(p - centre[:2]))) - body - KEEP_OUT_M for p in points]
        limits.append(float(np.hypot(*(goal - centre[:2]))) - slots - body - KEEP_OUT_M)
        limit = min(limits)
        if limit <= section + body:
            notes.append(f"obstacle {k} stands too close to a start, waypoint or goal slot to be fenced")
            continue
        radius = min(wanted, limit)
        if radius < wanted:
            notes.append(
                f"obstacle {k}: fence radius {radius:.1f} m instead of {wanted:.1f} m (a start, waypoint or "
                "goal slot is near)"
            )
        circles.append(FenceCircle(k, (float(centre[0]), float(centre[1])), round(radius, 2)))
    return circles, notes


def circle_items(circles: Iterable[FenceCircle], origin: frames.Origin) -> list[FenceItem]:
    """MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION items of the circles (centres geodetic, around the origin)."""
    return [
        FenceItem(CIRCLE_EXCLUSION, *_geodetic_e7(circle.centre[0], circle.centre[1], origin), circle.radius)
        for circle in circles
    ]


def _geodetic_e7(east: float, north: float, origin: frames.Origin) -> tuple[int, int]:
    """(lat, lon) degE7 of the ENU point (east, north, 0) m about the origin."""
    lat, lon, _ = frames.enu_to_geodetic([east, north, 0.0], origin)
    return round(float(lat) * 1e7), round(float(lon) * 1e7)


def site_items(fence: Fence, origin: frames.Origin) -> list[FenceItem]:
    """The mission's site fence as fence items (module docstring): the inclusion polygon's vertices, each
    exclusion polygon's, then the exclusion circles (radius m, param1)."""
    polygons = [(fence.polygon, POLYGON_INCLUSION)] if fence.polygon is not None else []
    polygons += [(zone.polygon, POLYGON_EXCLUSION) for zone in fence.exclusions if zone.polygon is not None]
    items = [
        FenceItem(command, *_geodetic_e7(float(e), float(n), origin), float(len(vertices)))
        for vertices, command in polygons
        for e, n in vertices
    ]
    items += [
        FenceItem(
            CIRCLE_EXCLUSION, *_geodetic_e7(float(zone.center[0]), float(zone.center[1]), origin), zone.radius
        )
        for zone in fence.exclusions
        if zone.polygon is None and zone.center is not None
    ]
    return items


def rally_items(rally: Iterable[np.ndarray], origin: frames.Origin) -> list[FenceItem]:
    """The mission's rally points (3,) ENU m each as MAV_CMD_NAV_RALLY_POINT items: lat/lon about the origin,
    the height above the origin as metres above home (a flat site; the vehicles start at the origin's
    height), rounded to whole metres as ArduPilot stores it (RallyLocation.alt, an int16)."""
    return [
        FenceItem(
            RALLY_POINT, *_geodetic_e7(float(p[0]), float(p[1]), origin), 0.0, float(round(float(p[2])))
        )
        for p in rally
    ]


def rally_by_vehicle(mission: Mission) -> dict[str, list[np.ndarray]]:
    """Vehicle name -> the rally points (3,) ENU m it gets: one each, a different one for every vehicle, by
    the least total horizontal distance from the vehicles' starts (their homes; scipy
    linear_sum_assignment). Both autopilots send every vehicle of a fleet that shares a rally list to the
    same nearest point, where they would land on each other (seen in sitl-sim: three quadrotors killed one
    second into formation flight all flew to one point); so each vehicle holds only its own. A vehicle left
    without one (fewer points than vehicles) holds none and returns home."""
    if not mission.rally:
        return {}
    starts = np.array([v.start.position[:2] for v in mission.vehicles], dtype=float)
    points = np.array([p[:2] for p in mission.rally], dtype=float)
    cost = np.linalg.norm(starts[:, None, :] - points[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(cost)
    given = {mission.vehicles[r].name: [mission.rally[c]] for r, c in zip(rows, cols, strict=True)}
    return {v.name: given.get(v.name, []) for v in mission.vehicles}


# --------------------------------------------------------------------------------------------------- protocol


def _ack_name(result: int) -> str:
    entry = mavlink2.enums["MAV_MISSION_RESULT"].get(result)
    return entry.name.removeprefix("MAV_MISSION_") if entry is not None else str(result)


def _fence_messages(link: VehicleLink, mission_type: int = FENCE) -> list[MAVLinkMessage]:
    """The MISSION_* messages of `mission_type` (FENCE, RALLY) received since the last call (others are
    dropped: one transfer runs at a time on a vehicle)."""
    out = []
    while link.mission_messages:
        msg = link.mission_messages.popleft()
        if getattr(msg, "mission_type", 0) == mission_type:
            out.append(msg)
    return out


def _require_alive(link: VehicleLink) -> None:
    if link.sysid is None or not link.state.alive[link.index]:
        raise LinkError(f"{link.name} is not responding (its link is down)")


def _send_item(link: VehicleLink, seq: int, item: FenceItem, mission_type: int) -> None:
    """MISSION_ITEM_INT of `item`: frame GLOBAL for a fence item, GLOBAL_RELATIVE_ALT for a rally point
    (the only frame ArduPilot's MissionItemProtocol_Rally takes besides its _INT twin)."""
    rally = item.command == RALLY_POINT
    link.send(
        link.mav.mission_item_int_encode(
            link.sysid or 0,
            link.compid,
            seq,
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT if rally else mavlink2.MAV_FRAME_GLOBAL,
            item.command,
            0,
            0,
            float(item.param1),
            0.0,
            0.0,
            0.0,
            item.lat_e7,
            item.lon_e7,
            float(item.alt_m),
            mission_type,
        )
    )


def op_upload_fence(
    link: VehicleLink, items: list[FenceItem], retries: int = COMMAND_RETRIES, mission_type: int = FENCE
) -> Operation[None]:
    """Upload `items` as the vehicle's whole fence (or rally list: `mission_type` RALLY) (MISSION_COUNT, then
    the items it asks for, until MISSION_ACK ACCEPTED); started over (up to `retries` times) when it stalls,
    is cancelled or denied."""
    _require_alive(link)
    count = len(items)
    texts = link.telemetry.statustexts
    last_refusal = "no answer"
    what = _WHAT[mission_type]
    _fence_messages(link, mission_type)
    timeout = Timeout(FIRST_ANSWER_S, link.vehicle_clock)
    for _ in range(retries + 1):
        link.send(link.mav.mission_count_encode(link.sysid or 0, link.compid, count, mission_type))
        timeout.seconds = FIRST_ANSWER_S
        timeout.restart()
        sent_last = count == 0
        restart = False
        while not restart and not timeout.expired():
            yield
            for msg in _fence_messages(link, mission_type):
                kind = msg.get_type()
                if kind in ("MISSION_REQUEST", "MISSION_REQUEST_INT"):
                    if 0 <= msg.seq < count:
                        _send_item(link, msg.seq, items[msg.seq], mission_type)
                        sent_last |= msg.seq == count - 1
                        timeout.seconds = STALL_S
                        timeout.restart()
                    continue
                if kind != "MISSION_ACK":
                    continue
                result = msg.type
                if result == mavlink2.MAV_MISSION_ACCEPTED and sent_last:
                    return
                if result in (mavlink2.MAV_MISSION_ACCEPTED, mavlink2.MAV_MISSION_INVALID_SEQUENCE):
                    continue  # an earlier transfer's, or a duplicate item's: the upload goes on
                last_refusal = f"MISSION_ACK {_ack_name(result)}"
                if result in _REFUSALS_TO_RETRY or (result == mavlink2.MAV_MISSION_ERROR and not sent_last):
                    restart = True
                    break
                said = f' ("{link.telemetry.last_statustext}")' if link.telemetry.statustexts > texts else ""
                raise LinkError(f"{link.name} refused the {what}: {last_refusal}{said}")
    raise LinkError(f"{link.name} did not take the {what} ({retries + 1} attempts; last: {last_refusal})")


def op_download_fence(
    link: VehicleLink, retries: int = COMMAND_RETRIES, mission_type: int = FENCE
) -> Operation[list[FenceItem]]:
    """The vehicle's fence items (or rally points: `mission_type` RALLY) (MISSION_REQUEST_LIST, then
    MISSION_REQUEST_INT per item), each request resent after a silent second of vehicle time (up to
    `retries` times)."""
    _require_alive(link)
    what = _WHAT[mission_type]
    _fence_messages(link, mission_type)
    timeout = Timeout(FIRST_ANSWER_S, link.vehicle_clock)
    count: int | None = None
    for _ in range(retries + 1):
        link.send(link.mav.mission_request_list_encode(link.sysid or 0, link.compid, mission_type))
        timeout.restart()
        while count is None and not timeout.expired():
            yield
            for msg in _fence_messages(link, mission_type):
                if msg.get_type() == "MISSION_COUNT":
                    count = int(msg.count)
                elif msg.get_type() == "MISSION_ACK" and msg.type not in _REFUSALS_TO_RETRY:
                    raise LinkError(
                        f"{link.name} refused to list its {what}: MISSION_ACK {_ack_name(msg.type)}"
                    )
        if count is not None:
            break
    if count is None:
        raise LinkError(f"{link.name} did not say how many {what} items it has ({retries + 1} requests)")
    items: list[FenceItem | None] = [None] * count
    for seq in range(count):
        for _ in range(retries + 1):
            if items[seq] is not None:
                break
            link.send(link.mav.mission_request_int_encode(link.sysid or 0, link.compid, seq, mission_type))
            timeout.restart()
            while items[seq] is None and not timeout.expired():
                yield
                for msg in _fence_messages(link, mission_type):
                    if msg.get_type() == "MISSION_ITEM_INT" and 0 <= msg.seq < count:
                        items[msg.seq] = FenceItem(
                            int(msg.command), int(msg.x), int(msg.y), float(msg.param1), float(msg.z)
                        )
                    elif (
                        msg.get_type() == "MISSION_ACK" and msg.type == mavlink2.MAV_MISSION_INVALID_SEQUENCE
                    ):
                        raise LinkError(f"{link.name}'s {what} changed while it was read (item {seq})")
        if items[seq] is None:
            raise LinkError(f"{link.name} did not send {what} item {seq} ({retries + 1} requests)")
    accepted = mavlink2.MAV_MISSION_ACCEPTED
    link.send(link.mav.mission_ack_encode(link.sysid or 0, link.compid, accepted, mission_type))
    return [item for item in items if item is not None]


def op_clear_fence(
    link: VehicleLink, retries: int = COMMAND_RETRIES, mission_type: int = FENCE
) -> Operation[None]:
    """MISSION_CLEAR_ALL(`mission_type`: FENCE or RALLY) until MISSION_ACK ACCEPTED (resent after a silent
    second, or when denied)."""
    _require_alive(link)
    what = _WHAT[mission_type]
    _fence_messages(link, mission_type)
    timeout = Timeout(FIRST_ANSWER_S, link.vehicle_clock)
    for _ in range(retries + 1):
        link.send(link.mav.mission_clear_all_encode(link.sysid or 0, link.compid, mission_type))
        timeout.restart()
        while not timeout.expired():
            yield
            for msg in _fence_messages(link, mission_type):
                if msg.get_type() != "MISSION_ACK":
                    continue
                if msg.type == mavlink2.MAV_MISSION_ACCEPTED:
                    return
                if msg.type not in _REFUSALS_TO_RETRY:
                    raise LinkError(
                        f"{link.name} refused to clear its {what}: MISSION_ACK {_ack_name(msg.type)}"
                    )
    raise LinkError(f"{link.name} did not confirm clearing its {what} ({retries + 1} requests)")


def _legacy_total(items: list[FenceItem]) -> int:
    """FENCE_TOTAL an ArduPilot saves with these items (AC_PolyFence_loader::write_fence)."""
    count = sum(1 for item in items if item.command != mavlink2.MAV_CMD_NAV_FENCE_RETURN_POINT)
    return count + 2 if count >= 3 else 0


def _settle(link: VehicleLink) -> Operation[None]:
    timeout = Timeout(SETTLE_S, link.vehicle_clock)
    while not timeout.expired():
        yield


def op_put_fence(
    link: VehicleLink, items: list[FenceItem], retries: int = COMMAND_RETRIES, mission_type: int = FENCE
) -> Operation[None]:
    """Make `items` the vehicle's fence (or rally list: `mission_type` RALLY) and read it back after
    SETTLE_S: LinkError if what it stored differs.

    ArduPilot SITL builds erase a fence whose FENCE_TOTAL (circles and vertices + 2, or 0 below 3) is 0 when
    the previous one's was not (AC_PolyFence_loader::update, the old fence-point protocol): so 1 or 2 circles
    are uploaded over a cleared fence (FENCE_TOTAL already 0), never straight over a bigger one."""
    if items and mission_type == FENCE and _legacy_total(items) == 0:
        yield from op_clear_fence(link, retries)
        yield from _settle(link)
    if items:
        yield from op_upload_fence(link, items, retries, mission_type)
    else:
        yield from op_clear_fence(link, retries, mission_type)
    yield from _settle(link)
    stored = yield from op_download_fence(link, retries, mission_type)
    if not _same(stored, items):
        raise LinkError(
            f"{link.name} stored different {_WHAT[mission_type]} than uploaded ({len(stored)} items read "
            f"back, {len(items)} sent)"
        )


# --------------------------------------------------------------------------------------------------- the run


class FenceInstall:
    """What `install_fence` did: the circles and items, the rally points, each vehicle's fence and rally
    points before the run; `restore` and `restore_rally` put them back (FlightParams restorers), `report`
    turns a vehicle's breach STATUSTEXT into an event."""

    def __init__(
        self,
        circles: list[FenceCircle],
        items: list[FenceItem],
        rally: dict[str, list[FenceItem]],
        action: str,
        events: list[str],
        progress: Callable[[str], None],
    ) -> None:
        self.circles = circles
        self.items = items
        self.rally = rally  # vehicle name -> its rally points as installed
        self.before: dict[str, list[FenceItem]] = {}  # vehicle name -> its fence before the run
        self.rally_before: dict[str, list[FenceItem]] = {}  # ... its rally points
        self.action = action
        self.events = events
        self.progress = progress

    def restore(self, link: VehicleLink, change: ParamChange) -> Operation[None]:
        """The vehicle's own fence back (cleared if it had none), verified by download."""
        return op_put_fence(link, self.before.get(link.name, []))

    def restore_rally(self, link: VehicleLink, change: ParamChange) -> Operation[None]:
        """The vehicle's own rally points back (cleared if it had none), verified by download."""
        return op_put_fence(link, self.rally_before.get(link.name, []), mission_type=RALLY)

    def report(self, link: VehicleLink, text: str) -> None:
        """A STATUSTEXT "<fences> breached" (ArduCopter/fence.cpp) or "Geofence violation" (PX4 navigator
        geofence_breach_check): the autopilot switches mode by itself (BRAKE for FENCE_ACTION 4, Hold for
        GF_ACTION 2) and ignores the ground station's attitude targets: say so."""
        if ("fence" in text and text.endswith("breached")) or text.startswith("Geofence violation"):
            t = max(int(link.state.time_ms[link.index]), 0) / 1000.0
            said = f"t={t:.2f} s {link.name}: {text}: its autopilot takes over (fence action {self.action})"
            self.events.append(said)
            self.progress(f"! {said}")


def _same(a: list[FenceItem], b: list[FenceItem]) -> bool:
    return len(a) == len(b) and all(x.same_as(y) for x, y in zip(a, b, strict=True))


def _put_on_all(
    fleet: Fleet,
    flight: FlightParams,
    links: list[VehicleLink],
    items: dict[str, list[FenceItem]],
    mission_type: int,
) -> dict[str, list[FenceItem]]:
    """Read each vehicle's list of `mission_type`, make items[its name] its list (verified by download) and
    add a change row (FENCE_ITEMS or RALLY_ITEMS: item counts before and flown) where it differed; returns
    the lists before, by vehicle name."""
    old = fleet.run(op_download_fence(link, mission_type=mission_type) for link in links)
    before = {link.name: items_before for link, items_before in zip(links, old, strict=True)}
    fleet.run(op_put_fence(link, items[link.name], mission_type=mission_type) for link in links)
    row = FENCE_ITEMS if mission_type == FENCE else RALLY_ITEMS
    for link in links:
        if not _same(before[link.name], items[link.name]):
            counts = float(len(before[link.name])), float(len(items[link.name]))
            flight.changes.append(ParamChange(link.name, row, *counts))
    return before


def _set_by_dialect(
    flight: FlightParams,
    links: list[VehicleLink],
    params: Callable[[AutopilotDialect], list[tuple[str, float]]],
) -> None:
    """Set `params(dialect)` on the vehicles of each autopilot dialect among `links`."""
    dialects = {link.channel.autopilot.key: link.channel.autopilot for link in links}
    for key, dialect in dialects.items():
        rows = [link.index for link in links if link.channel.autopilot.key == key]
        for name, value in params(dialect):
            flight.set_all(name, value, rows)


def install_fence(
    fleet: Fleet,
    flight: FlightParams,
    mission: Mission,
    events: list[str],
    progress: Callable[[str], None],
) -> FenceInstall | None:
    """Preflight: fence the obstacles on every live vehicle (see the module docstring) when
    safety.dead_gcs.fence.enabled, the site fence when safety.geofence.upload, and the rally points of
    safety.rally whenever the mission has some (each autopilot's RTL then returns to the nearest:
    AutopilotDialect.rally_params); notes and breaches go to `events` (flight.json) and `progress`. LinkError
    when a vehicle does not take them; None when there is nothing to install."""
    params = mission.safety.dead_gcs.fence
    circles, notes = exclusion_circles(mission, params.margin_m) if params.enabled else ([], [])
    for note in notes:
        events.append(f"fence: {note}")
        progress(f"fence: {note}")
    site = site_items(mission.fence, mission.origin) if mission.fence.upload else []
    items = circle_items(circles, mission.origin) + site
    rally = {name: rally_items(points, mission.origin) for name, points in rally_by_vehicle(mission).items()}
    if not items and not rally:
        return None
    links = [link for link in fleet.select() if link.channel.autopilot.geofence]
    unfenced = [link.name for link in fleet.select() if not link.channel.autopilot.geofence]
    if unfenced:
        note = f"not installed on {', '.join(unfenced)} (the ground station cannot fence that autopilot yet)"
        events.append(f"fence: {note}")
        progress(f"fence: {note}")
    if not links:
        return None
    install = FenceInstall(circles, items, rally, params.action, events, progress)
    if items:
        install.before = _put_on_all(fleet, flight, links, {link.name: items for link in links}, FENCE)
        flight.restorers[FENCE_ITEMS] = install.restore
        _set_by_dialect(flight, links, lambda dialect: dialect.fence_params(params.action))
        for link in (link for link in fleet.links if link.channel.autopilot.geofence):  # one reporter each,
            # even if preflight runs again
            link.statustext_hooks[:] = [
                hook
                for hook in link.statustext_hooks
                if not isinstance(getattr(hook, "__self__", None), FenceInstall)
            ]
            link.statustext_hooks.append(install.report)
    if rally:
        own = {link.name: rally.get(link.name, []) for link in links}
        install.rally_before = _put_on_all(fleet, flight, links, own, RALLY)
        flight.restorers[RALLY_ITEMS] = install.restore_rally
        _set_by_dialect(flight, links, lambda dialect: dialect.rally_params())
    radii = ", ".join(f"{c.radius:.1f}" for c in circles)
    what = [f"{len(circles)} exclusion circle(s) around obstacles, radii {radii} m"] if circles else []
    what += [f"the site fence ({len(site)} items)"] if site else []
    what += [f"{len(mission.rally)} rally point(s), one a vehicle"] if rally else []
    action = f", action {params.action}" if items else ""
    progress(f"fence: {' and '.join(what)} on every vehicle{action}")
    return install
