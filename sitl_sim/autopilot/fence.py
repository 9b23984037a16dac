"""Geofences of N vehicles as ArduCopter has them (libraries/AC_Fence/AC_Fence.cpp, AC_PolyFence_loader.cpp):
the stored fence items of each vehicle, their geometry in the local ENU frame, and the breach check.

FENCE_TYPE is a bitmask: 1 maximum altitude above home (FENCE_ALT_MAX), 2 a circle around home
(FENCE_RADIUS), 4 "polygon": every inclusion/exclusion circle and polygon uploaded with the mission protocol
(mission_type FENCE, sitl_sim.network.mission_protocol), 8 minimum altitude (stored, not enforced here). All
horizontal zones are infinite vertical cylinders/prisms, as ArduPilot's: only the horizontal position counts.

The check (`Fences.check`; ArduCopter runs it at 25 Hz, ArduCopter/Copter.cpp SCHED_TASK(fence_check, 25, ..))
is vectorised over the vehicles and returns each vehicle's *new* breaches (a bitmask). As in AC_Fence::check:
- a polygon-type breach is new only when the vehicle was not breaching that type already (leaving every zone
  clears it; entering one again is a new breach);
- the home circle and the maximum altitude set up a backup fence 20 m further out on a breach, whose
  crossing is a new breach again (AC_FENCE_*_BACKUP_DISTANCE);
- for 10 s after a manual recovery started (any successful mode change while breached, ArduCopter/mode.cpp
  set_mode -> AC_Fence::manual_recovery_start, including the fence's own BRAKE/RTL/LAND) no new breach is
  reported (AC_FENCE_MANUAL_RECOVERY_TIME_MIN), though breaches are still recorded.
What the vehicle does about a new breach (FENCE_ACTION) is the autopilot's part (sitl_sim.autopilot.copter,
ArduCopter/fence.cpp). Breaches are checked whether armed or not (the pre-arm check reads them); they are only
acted on when armed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

ALT_MAX, CIRCLE, POLYGON, ALT_MIN = 1, 2, 4, 8  # FENCE_TYPE bits (AC_Fence.h AC_FENCE_TYPE_*)
# FENCE_ACTION for Copter (AC_Fence.cpp @Values{Copter}, ArduCopter/fence.cpp)
REPORT_ONLY, RTL_AND_LAND, ALWAYS_LAND, SMART_RTL, BRAKE_OR_LAND, SMART_RTL_OR_LAND = range(6)
CHECK_PERIOD_S = 0.04  # ArduCopter fence_check at 25 Hz
MANUAL_RECOVERY_S = 10.0  # AC_FENCE_MANUAL_RECOVERY_TIME_MIN
GIVE_UP_DISTANCE_M = 100.0  # AC_FENCE_GIVE_UP_DISTANCE: further outside than this, Copter just lands
BACKUP_DISTANCE_M = 20.0  # AC_FENCE_ALT_MAX_BACKUP_DISTANCE, AC_FENCE_CIRCLE_RADIUS_BACKUP_DISTANCE (Copter)
NOTIFY_PERIOD_S = 1.0  # record_breach: FENCE_STATUS sent on a new breach, at most once a second
# Fence storage of ArduCopter SITL (16 kB storage: StorageManager.cpp layout with 15 areas, StorageFence
# 48 + 256 + 256 bytes): max_items = size / 8; a circle takes 13 bytes, a polygon 2 + 8 per vertex, plus a
# 4-byte header and an end marker (AC_PolyFence_loader::fence_storage_space_required).
STORAGE_BYTES = 560
MAX_ITEMS = STORAGE_BYTES // 8

CIRCLE_EXCLUSION = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
CIRCLE_INCLUSION = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
POLYGON_EXCLUSION = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
POLYGON_INCLUSION = mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
RETURN_POINT = mavlink2.MAV_CMD_NAV_FENCE_RETURN_POINT
FENCE_COMMANDS = (POLYGON_INCLUSION, POLYGON_EXCLUSION, RETURN_POINT, CIRCLE_EXCLUSION, CIRCLE_INCLUSION)
FENCE_NAMES = ("Max Alt", "Circle", "Polygon", "Min Alt")  # AC_Fence::get_fence_names, bit order
POPCOUNT = np.array([bin(k).count("1") for k in range(16)], dtype=np.int64)


@dataclass(frozen=True)
class FenceItem:
    """One stored fence item as ArduPilot keeps it: command (MAV_CMD_NAV_FENCE_*), lat/lon in degE7, param1
    (circle radius in m as a float32, or a polygon's vertex count)."""

    command: int
    lat_e7: int
    lon_e7: int
    param1: float = 0.0

    @property
    def is_circle(self) -> bool:
        return self.command in (CIRCLE_EXCLUSION, CIRCLE_INCLUSION)

    @property
    def is_vertex(self) -> bool:
        return self.command in (POLYGON_EXCLUSION, POLYGON_INCLUSION)


def fence_names(fences: int) -> str:
    """The fences' names: "Polygon fence", "Max Alt and Circle fences", ... (AC_Fence::get_fence_names)."""
    names = [name for bit, name in enumerate(FENCE_NAMES) if fences >> bit & 1]
    if not names:
        return ""
    text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return f"{text} fence{'s' if len(names) > 1 else ''}"


def validate(items: list[FenceItem]) -> str | None:
    """Why ArduPilot refuses to store these items (the STATUSTEXT of AC_PolyFence_loader::validate_fence and
    write_fence), or None when it stores them."""
    expecting, remaining, first_count, return_points = 0, 0, 0, 0
    for item in items:
        if item.is_vertex:
            count = int(item.param1)
            if count < 3:
                return f"Invalid vertex count ({count})"
            if remaining == 0:
                remaining, first_count, expecting = count, count, item.command
            elif item.command != expecting:
                return f"Received incorrect vertex type (want={expecting} got={item.command})"
            elif count != first_count:
                return f"Unexpected vertex count want={first_count} got={count}"
            remaining -= 1
        else:
            if remaining:
                return f"Received incorrect type (want={expecting} got={item.command})"
            if item.is_circle and not item.param1 > 0.0:
                return "Non-positive circle radius"
            if item.command == RETURN_POINT:
                return_points += 1
                if return_points > 1:
                    return "Multiple return points"
        if not (abs(item.lat_e7) <= 900_000_000 and abs(item.lon_e7) <= 1_800_000_000):
            return "Bad lat or lon"
    if remaining:
        return "Incorrect item count"
    if storage_bytes(items) > STORAGE_BYTES:
        return "Fence exceeds storage size"
    return None


def storage_bytes(items: list[FenceItem]) -> int:
    """Bytes the items take in fence storage (AC_PolyFence_loader::fence_storage_space_required + end)."""
    size, k = 4 + 1, 0
    while k < len(items):
        item = items[k]
        size += 1
        if item.is_vertex:
            count = max(int(item.param1), 1)
            size += 1 + 8 * count
            k += count
            continue
        size += 12 if item.is_circle else 8
        k += 1
    return size


def point_in_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(P,) bool: points (P,2) inside the polygon (V,2) (crossing number, as Polygon_outside)."""
    x, y = points[:, 0:1], points[:, 1:2]
    x1, y1 = vertices[:, 0], vertices[:, 1]
    x2, y2 = np.roll(x1, -1), np.roll(y1, -1)
    crosses = (y1 > y) != (y2 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
    return np.asarray(np.count_nonzero(crosses & (x < x_at), axis=1) % 2 == 1)


def distance_to_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(P,) m: distance from points (P,2) to the nearest edge of the polygon (V,2)."""
    a = vertices[None, :, :]
    b = np.roll(vertices, -1, axis=0)[None, :, :]
    p = points[:, None, :]
    ab = b - a
    length2 = np.maximum(np.sum(ab * ab, axis=-1), 1e-12)
    s = np.clip(np.sum((p - a) * ab, axis=-1) / length2, 0.0, 1.0)
    closest = a + s[..., None] * ab
    return np.asarray(np.linalg.norm(p - closest, axis=-1).min(axis=1))


class Fences:
    """Stored fence items, their geometry and the breach state of N vehicles (arrays (N,))."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.items: list[tuple[FenceItem, ...]] = [() for _ in range(n)]
        self._xy: list[np.ndarray] = [np.zeros((0, 2)) for _ in range(n)]  # ENU of each stored item
        self.breaches = np.zeros(n, dtype=np.int64)  # _breached_fences
        self.breach_count = np.zeros(n, dtype=np.int64)
        self.breach_time_ms = np.zeros(n, dtype=np.int64)
        self.enabled_mask = np.zeros(n, dtype=np.int64)  # _enabled_fences
        self._enable_param = np.zeros(n)  # FENCE_ENABLE as last seen (AC_Fence::update)
        self.alt_max_backup = np.zeros(n)
        self.circle_backup = np.zeros(n)
        self.distance = np.zeros((n, 3))  # breach distance (m, > 0 outside) of max alt, circle, polygon
        self.recovery_start = np.full(n, -math.inf)  # simulated s a manual recovery started
        self.last_notify = np.full(n, -math.inf)
        self.last_check = -math.inf
        self.status_now: list[int] = []  # vehicles whose FENCE_STATUS is due at once (new breach)
        self._old_total = np.zeros(n)  # FENCE_TOTAL as last seen (AC_PolyFence_loader::update)
        self._load()

    # --- storage --------------------------------------------------------------------------------------------

    def store(self, i: int, items: list[FenceItem], xy: np.ndarray) -> None:
        """Replace vehicle i's fence with validated items; xy (K,2) their ENU positions (m)."""
        self.items[i] = tuple(items)
        self._xy[i] = np.asarray(xy, dtype=float).reshape(-1, 2)
        self._load()

    @staticmethod
    def legacy_total(items: list[FenceItem]) -> int:
        """FENCE_TOTAL that write_fence saves: circles and polygon vertices + 2 when at least 3, else 0."""
        count = sum(1 for item in items if item.command != RETURN_POINT)
        return count + 2 if count >= 3 else 0

    def legacy_clears(self, totals: np.ndarray) -> list[int]:
        """AC_PolyFence_loader::update with AC_POLYFENCE_FENCE_POINT_PROTOCOL_SUPPORT, which ArduPilot's SITL
        builds switch on (Tools/ardupilotwaf/boards.py, class sitl): FENCE_TOTAL changed to 0 while fences are
        stored -> the storage is formatted, as for an old GCS that set the point count to 0. A fence of fewer
        than 3 circles/vertices saves FENCE_TOTAL 0, so uploaded over a larger one it is erased within 0.1 s
        (seen on ArduCopter V4.7.0-dev SITL). Returns the vehicles whose fence is to be erased."""
        changed = totals != self._old_total
        self._old_total = totals.copy()
        return [int(i) for i in np.flatnonzero(changed & (totals == 0)) if self.items[i]]

    def _load(self) -> None:
        """The geometry of every vehicle's zones: circles as arrays (vectorised), polygons as a list."""
        owner, centre, radius, exclusion = [], [], [], []
        polygons: list[tuple[int, bool, np.ndarray]] = []
        for i, items in enumerate(self.items):
            k = 0
            while k < len(items):
                item = items[k]
                if item.is_circle:
                    owner.append(i)
                    centre.append(self._xy[i][k])
                    radius.append(item.param1)
                    exclusion.append(item.command == CIRCLE_EXCLUSION)
                elif item.is_vertex:
                    count = int(item.param1)
                    polygons.append((i, item.command == POLYGON_EXCLUSION, self._xy[i][k : k + count].copy()))
                    k += count
                    continue
                k += 1
        self._circle_owner = np.array(owner, dtype=np.int64)
        self._circle_xy = np.array(centre, dtype=float).reshape(-1, 2)
        self._circle_r = np.array(radius, dtype=float)
        self._circle_excl = np.array(exclusion, dtype=bool)
        self._polygons = polygons
        self._zones = np.bincount(self._circle_owner, minlength=self.n) + np.bincount(
            np.array([p[0] for p in polygons], dtype=np.int64), minlength=self.n
        )

    # --- geometry -------------------------------------------------------------------------------------------

    def zones_breached(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each vehicle's own zones at horizontal positions xy (N,2): (breached (N,) bool, distance (N,) m
        outside the fence, > 0 when breached) as AC_PolyFence_loader::breached: inside an exclusion zone
        (its depth: radius - distance for a circle, distance to the nearest edge for a polygon) or outside
        an inclusion zone (intersection of the inclusion zones)."""
        n = self.n
        breached = np.zeros(n, dtype=bool)
        distance = np.full(n, -math.inf)
        excluded = np.full(n, -math.inf)  # depth into the first exclusion zone that contains the vehicle
        outside = np.full(n, -math.inf)
        for i, is_exclusion, vertices in self._polygons:
            point = xy[i : i + 1]
            inside = bool(point_in_polygon(point, vertices)[0])
            d = float(distance_to_polygon(point, vertices)[0])
            if is_exclusion and inside and not breached[i]:
                breached[i], excluded[i] = True, d
            elif is_exclusion:
                distance[i] = max(distance[i], -d)
            elif not inside:
                outside[i] = max(outside[i], d)
            else:
                distance[i] = max(distance[i], -d)
        if len(self._circle_r):
            owner = self._circle_owner
            d = np.linalg.norm(xy[owner] - self._circle_xy, axis=1)
            depth = np.where(self._circle_excl, self._circle_r - d, d - self._circle_r)  # > 0: breached
            hit = self._circle_excl & (depth > 0.0)
            first = np.full(n, len(owner))
            np.minimum.at(first, owner[hit], np.flatnonzero(hit))
            new = (first < len(owner)) & ~breached
            excluded[new] = depth[first[new]]
            breached |= new
            np.maximum.at(distance, owner[~hit], depth[~hit])
            incl = ~self._circle_excl & (depth > 0.0)
            np.maximum.at(outside, owner[incl], depth[incl])
        out = np.isfinite(outside) & ~breached
        distance = np.where(breached, excluded, np.where(out, outside, distance))
        breached |= out
        return breached, np.where(np.isfinite(distance), distance, 0.0)

    # --- AC_Fence -------------------------------------------------------------------------------------------

    def present(self, configured: np.ndarray) -> np.ndarray:
        """(N,) fence types configured and present (AC_Fence::present: polygon only with stored zones)."""
        mask = np.where(self._zones > 0, ALT_MAX | CIRCLE | ALT_MIN | POLYGON, ALT_MAX | CIRCLE | ALT_MIN)
        return configured.astype(np.int64) & mask

    def present_one(self, i: int, configured: int) -> int:
        """AC_Fence::present of vehicle i alone."""
        return configured & (ALT_MAX | CIRCLE | ALT_MIN | (POLYGON if self._zones[i] else 0))

    def active(self, enable_param: np.ndarray) -> bool:
        """Whether any vehicle has a fence on, is switching one, or holds a breach (else nothing to check)."""
        return bool(
            enable_param.any() or self._enable_param.any() or self.enabled_mask.any() or self.breaches.any()
        )

    def update_enable(self, enable_param: np.ndarray, configured: np.ndarray) -> None:
        """AC_Fence::update: FENCE_ENABLE changed -> every configured fence but the floor on, or all off."""
        changed = enable_param != self._enable_param
        on = changed & (enable_param != 0)
        off = changed & (enable_param == 0)
        self.enabled_mask[on] = configured.astype(np.int64)[on] & ~ALT_MIN
        self.enabled_mask[off] = 0
        self.breaches[off] = 0
        self._enable_param = enable_param.copy()

    def enable(self, i: int, value: bool, fences: int, configured: int) -> None:
        """AC_Fence::enable (MAV_CMD_DO_FENCE_ENABLE): switch the configured `fences` on or off, not saved."""
        fences &= configured
        if value:
            self.enabled_mask[i] |= fences
        else:
            self.enabled_mask[i] &= ~fences
            self.breaches[i] &= ~fences

    def _limit_with_backup(
        self, on: np.ndarray, value: np.ndarray, limit: np.ndarray, bit: int, backup: np.ndarray
    ) -> np.ndarray:
        """The rule of ArduCopter's altitude and home-circle fences (AC_Fence check_fence_alt_max,
        check_fence_circle) for the (N,) vehicles `on`: `value` (N,) m at or beyond `limit` (N,) m is a breach
        of fence `bit`, new if it was not breached yet or has gone past its backup fence (`backup` (N,) m,
        updated in place: BACKUP_DISTANCE_M beyond where the breach was last reported; 0 = none); back inside,
        the breach and the backup clear. Returns (N,) `bit` where the breach is new, else 0."""
        over = on & (value >= limit)
        fresh = over & ((self.breaches & bit == 0) | ((backup != 0.0) & (value >= backup)))
        backup[fresh] = value[fresh] + BACKUP_DISTANCE_M
        clear = on & ~over & (self.breaches & bit != 0)
        self.breaches[clear] &= ~bit
        backup[clear] = 0.0
        return np.where(fresh, bit, 0)

    def check(
        self,
        t: float,
        pos: np.ndarray,
        home: np.ndarray,
        have_position: np.ndarray,
        configured: np.ndarray,
        alt_max: np.ndarray,
        radius: np.ndarray,
    ) -> np.ndarray:
        """AC_Fence::check for every vehicle at simulated time t (s): positions pos (N,3) and home (N,3) ENU
        m, have_position (N,) (the EKF has a position), FENCE_TYPE, FENCE_ALT_MAX, FENCE_RADIUS (N,).
        Returns (N,) the newly breached fence types; updates `breaches`, `distance` and `status_now`."""
        self.last_check = t
        configured = configured.astype(np.int64)
        self.breaches &= configured  # clear any breach from a non-configured fence
        enabled = self.enabled_mask & self.present(configured)
        active = (self.enabled_mask != 0) & (configured != 0)
        new = np.zeros(self.n, dtype=np.int64)

        # maximum altitude above home (check_fence_alt_max)
        on = active & (enabled & ALT_MAX != 0)
        alt = pos[:, 2] - home[:, 2]
        self.distance[:, 0] = np.where(on, alt - alt_max, self.distance[:, 0])
        new |= self._limit_with_backup(on, alt, alt_max, ALT_MAX, self.alt_max_backup)

        # circle around home (check_fence_circle); without a position the last distance stands
        on = active & (enabled & CIRCLE != 0)
        home_distance = np.hypot(pos[:, 0] - home[:, 0], pos[:, 1] - home[:, 1])
        home_distance = np.where(have_position, home_distance, self.distance[:, 1] + radius)
        self.distance[:, 1] = np.where(on, home_distance - radius, self.distance[:, 1])
        new |= self._limit_with_backup(on, home_distance, radius, CIRCLE, self.circle_backup)

        # inclusion/exclusion circles and polygons (check_fence_polygon)
        on = active & (enabled & POLYGON != 0)
        hit, depth = self.zones_breached(pos[:, :2])
        self.distance[:, 2] = depth
        inside = on & have_position & hit
        new[inside & (self.breaches & POLYGON == 0)] |= POLYGON
        self.breaches[~inside] &= ~POLYGON

        # record_breach: the first breach sets the breach time and sends FENCE_STATUS (at most 1 Hz)
        first = (new != 0) & (self.breaches == 0)
        self.breach_time_ms[first] = round(t * 1000.0)
        notify = first & (t - self.last_notify > NOTIFY_PERIOD_S)
        self.last_notify[notify] = t
        self.status_now = [int(i) for i in np.flatnonzero(notify)]
        self.breach_count += POPCOUNT[new & 0xF]  # record_breach counts each fence type
        self.breaches |= new

        # a manual recovery (a mode change while breached) ignores new breaches for 10 s
        recovering = t - self.recovery_start < MANUAL_RECOVERY_S
        self.recovery_start[~recovering] = -math.inf
        new[recovering] = 0
        return new

    def breach_distance(self, i: int, fences: int) -> float:
        """Largest distance (m) outside the given fences of vehicle i (AC_Fence::get_breach_distance)."""
        columns = [k for k, bit in enumerate((ALT_MAX, CIRCLE, POLYGON)) if fences & bit]
        return max((float(self.distance[i, k]) for k in columns), default=-math.inf)

    def manual_recovery_start(self, i: int, t: float) -> bool:
        """A mode change while breached starts the 10 s recovery window; True when it did."""
        if not self.breaches[i]:
            return False
        self.recovery_start[i] = t
        return True

    def destination_ok(
        self, i: int, xy: np.ndarray, home_xy: np.ndarray, alt: float, alt_max: float, radius: float
    ) -> bool:
        """AC_Fence::check_destination_within_fence: a guided destination (ENU horizontal xy, alt m above
        home) outside vehicle i's enabled fences is refused."""
        enabled = int(self.enabled_mask[i])
        if not enabled:
            return True
        if enabled & ALT_MAX and alt > alt_max:
            return False
        if enabled & CIRCLE and math.hypot(float(xy[0] - home_xy[0]), float(xy[1] - home_xy[1])) > radius:
            return False
        if enabled & POLYGON and self._zones[i]:
            probe = np.zeros((self.n, 2))
            probe[i] = xy
            return not bool(self.zones_breached(probe)[0][i])
        return True

    def pre_arm_failure(
        self,
        i: int,
        enable_param: float,
        configured: int,
        have_position: bool,
        margin: float,
        alt_max: float,
        radius: float,
    ) -> str | None:
        """AC_Fence::pre_arm_check of vehicle i: the reason it may not arm, or None."""
        if enable_param and not self.present_one(i, configured):
            return "Fences enabled, but none selected"
        if not int(self.enabled_mask[i]) or not configured:
            return None
        if configured & (CIRCLE | POLYGON) and not have_position:
            return "Fence requires position"
        if configured & POLYGON:
            owner = self._circle_owner == i
            if np.any(owner & ~self._circle_excl & (self._circle_r < margin)):
                return "Polygon fence margin is greater than inclusion circle radius"
        if configured & CIRCLE and radius < margin:
            return "Circle FENCE_MARGIN is greater than FENCE_RADIUS"
        if self.breaches[i]:
            return f"Vehicle breaching {fence_names(int(self.breaches[i]))}"
        if alt_max < 0.0:
            return "Invalid FENCE_ALT_MAX value"
        return None

    def mavlink_breach_type(self, i: int) -> int:
        """FENCE_STATUS breach_type of vehicle i (GCS_MAVLINK::send_fence_status)."""
        breaches = int(self.breaches[i])
        if breaches & (CIRCLE | POLYGON):
            return int(mavlink2.FENCE_BREACH_BOUNDARY)
        if breaches & ALT_MAX:
            return int(mavlink2.FENCE_BREACH_MAXALT)
        if breaches & ALT_MIN:
            return int(mavlink2.FENCE_BREACH_MINALT)
        return int(mavlink2.FENCE_BREACH_NONE)
