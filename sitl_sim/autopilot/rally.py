"""Rally points of N simulated vehicles (mission_type RALLY, sitl_sim.network.mission_protocol) and where
each autopilot's RTL returns with them: ArduCopter (libraries/AP_Rally/AP_Rally.cpp
calc_best_rally_or_home_location) and PX4 (src/modules/navigator/rtl.cpp findRtlDestination,
findClosestSafePoint). The RTL flies to the chosen point's horizontal position at its usual return altitude
and lands there (sitl_sim.autopilot.outer_loop). Positions are local ENU metres; distances horizontal, as both
autopilots measure them (Location::get_distance, get_distance_to_next_waypoint)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

# PX4 rtl.cpp: a safe point within this distance of home is not a destination of its own; another
# destination must be this much nearer than the best so far to replace it
PX4_SAFE_POINT_MIN_FROM_HOME_M = 10.0  # MAX_DIST_FROM_HOME_FOR_LAND_APPROACHES
PX4_MIN_DIST_THRESHOLD_M = 2.0  # MIN_DIST_THRESHOLD
PX4_RTL_TYPE_SAFE_POINTS_FIRST = 1  # RTL_TYPE 1: a rally point (or mission landing) before home


@dataclass(frozen=True)
class RallyItem:
    """One stored rally point: lat/lon degE7, alt_m m above home (ArduPilot's RallyLocation.alt, an int16)."""

    lat_e7: int
    lon_e7: int
    alt_m: float


class RallyPoints:
    """Each vehicle's stored rally points: the items as uploaded and their ENU positions (K,3) m."""

    def __init__(self, n: int) -> None:
        self.items: list[tuple[RallyItem, ...]] = [() for _ in range(n)]
        self.xyz: list[np.ndarray] = [np.zeros((0, 3)) for _ in range(n)]

    def store(self, i: int, items: list[RallyItem], xyz: np.ndarray) -> None:
        """Replace vehicle i's rally points: items and their ENU positions xyz (K,3) m."""
        self.items[i] = tuple(items)
        self.xyz[i] = np.asarray(xyz, dtype=float).reshape(-1, 3)

    def _distances(self, i: int, pos: np.ndarray) -> np.ndarray:
        return np.asarray(np.hypot(self.xyz[i][:, 0] - pos[0], self.xyz[i][:, 1] - pos[1]))

    def arducopter_destination(
        self, i: int, pos: np.ndarray, home: np.ndarray, limit_km: float, include_home: bool
    ) -> np.ndarray:
        """ArduCopter RTL's return point (3,) ENU m for vehicle i at pos (3,):
        AP_Rally::find_nearest_rally_point (the nearest rally point; none when RALLY_LIMIT_KM `limit_km` > 0
        and even the nearest lies beyond it), then calc_best_rally_or_home_location (that point, unless
        RALLY_INCL_HOME `include_home` and home is nearer); else home."""
        if not len(self.items[i]):
            return home.copy()
        distances = self._distances(i, pos)
        k = int(np.argmin(distances))
        if limit_km > 0.0 and distances[k] > limit_km * 1000.0:
            return home.copy()
        if include_home and not distances[k] < math.hypot(home[0] - pos[0], home[1] - pos[1]):
            return home.copy()
        return np.asarray(self.xyz[i][k].copy())

    def px4_destination(self, i: int, pos: np.ndarray, home: np.ndarray, rtl_type: int) -> np.ndarray:
        """PX4 RTL's destination (3,) ENU m for vehicle i at pos (3,) (a multicopter; no mission landing):
        home, then each safe point more than PX4_SAFE_POINT_MIN_FROM_HOME_M from home that is at least
        PX4_MIN_DIST_THRESHOLD_M nearer than the best so far (findClosestSafePoint); with RTL_TYPE 1 home
        counts as infinitely far (prioritize_safe_points_over_home). Other RTL_TYPEs (mission paths) are
        flown as 0 here."""
        best = math.inf if rtl_type == PX4_RTL_TYPE_SAFE_POINTS_FIRST else math.hypot(*(home[:2] - pos[:2]))
        destination = home.copy()
        from_home = np.hypot(self.xyz[i][:, 0] - home[0], self.xyz[i][:, 1] - home[1])
        for k, distance in enumerate(self._distances(i, pos)):
            if from_home[k] > PX4_SAFE_POINT_MIN_FROM_HOME_M and distance + PX4_MIN_DIST_THRESHOLD_M < best:
                best, destination = float(distance), self.xyz[i][k].copy()
        return np.asarray(destination)
