"""Speed scheduling for a ground station that may die at any moment [add] (docs/reliability.md, "When the
ground station dies").

If the ground station stops, a vehicle flies on: up to GUID_TIMEOUT on its last attitude target, then level
at constant altitude without braking, until its GCS failsafe (FS_GCS_TIMEOUT after the last ground-station
heartbeat) puts it in BRAKE. Bounded from above (drag ignored), it covers `v T + D(v)` along its current
course: T = FS_GCS_TIMEOUT and D(v) the distance ArduCopter's BRAKE needs to stop from v (`stopping_table`).
So the horizontal speed of each vehicle is capped at the largest v for which that distance, plus a clearance,
fits before the first obstacle its course meets (inf if it meets none).

BRAKE does not stop at a constant deceleration: AC_PosControl shapes the stop (AP_Math control.cpp
shape_vel_accel, BRAKE_MODE_DECEL_RATE a = 7.5 m/s^2, PSC_JERK_XY j = 5 m/s^3): the deceleration ramps up
at j and then, below a^2 / j = 11.25 m/s, follows k v with k = j / a, an exponential decay of time constant
1.5 s. From 10 m/s that is about 20 m, not the 6.7 m of v^2 / 2a (a real ArduCopter SITL quad stopped from
10.1 m/s in 20.4 m; the sitl-sim vehicle follows the same shaping: sitl_sim.vehicle_model.position_control
.brake_shaping_step).

Shapes: pos, vel (N, 3) ENU m, m/s; centres (K, 3), radii (K,) m; cylinders and prisms packed as
swarm_common.obstacle_shapes.ShapeArrays (kinds, params, vertices).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from gcs_swarm.guidance.shaping import shape_vel_accel
from swarm_common.jit import kernel
from swarm_common.numpy_rules import maximum, minimum
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays, course_entry

SPEED_TABLE_MAX = 60.0  # m/s, the largest speed of the stopping-distance table (beyond: extrapolated)
TABLE_DT = 0.002  # s, the integration step of the stopping-distance table


@kernel
def brake_distances(speeds: np.ndarray, accel: float, jerk: float, dt: float, steps: int) -> np.ndarray:
    """(S,) m: the distance each start speed of `speeds` (S,) m/s covers until the BRAKE shaping
    (`shaping.shape_vel_accel` toward 0 with the limits accel m/s^2, jerk m/s^3) brings it to rest, never
    through it (update_vel_accel's limit), integrated at dt s for at most `steps` steps."""
    out = np.empty(speeds.shape[0])
    for i in range(speeds.shape[0]):
        v = speeds[i]
        a = 0.0
        x = 0.0
        for _ in range(steps):
            if not v > 0.0:  # at rest
                break
            a = shape_vel_accel(0.0, 0.0, v, a, accel, jerk, dt)
            v = maximum(v + a * dt, 0.0)
            if x + v * dt == x:  # a <= 0 from here on: v never grows, so x will not change again
                break
            x += v * dt
        out[i] = x
    return out


@lru_cache(maxsize=8)
def stopping_table(reaction_s: float, accel: float, jerk: float) -> tuple[np.ndarray, np.ndarray]:
    """(total (S,) m, speeds (S,) m/s): the distance v T + D(v) covered from each speed v from 0 to
    SPEED_TABLE_MAX (T = reaction_s; D the BRAKE distance `brake_distances` for the shaping's acceleration
    limit `accel` m/s^2 and jerk limit `jerk` m/s^3, the vehicle's own tracking lag not included: about 0.2 s
    of travel at the start speed on the real SITL quad), increasing in v, so that `interp` inverts it."""
    if not (accel > 0 and jerk > 0):
        raise ValueError("accel and jerk must be > 0")
    speeds = np.linspace(0.0, SPEED_TABLE_MAX, 601)
    steps = int((SPEED_TABLE_MAX / accel + 27.0 * accel / jerk) / TABLE_DT)
    return speeds * reaction_s + brake_distances(speeds, accel, jerk, TABLE_DT, steps), speeds


@kernel
def distance_along_course(
    pos: np.ndarray, vel: np.ndarray, centres: np.ndarray, radii: np.ndarray, clearance: float,
    kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray, horizon: float,
) -> np.ndarray:  # fmt: skip
    """(N,) m: how far each vehicle can go along its horizontal course (the direction of vel's x, y; at its
    altitude) before it enters an obstacle's sphere grown by `clearance` m (at its altitude: the circle of
    that sphere's cross-section), or comes within `clearance` m of a packed cylinder or prism (spec 2.2,
    obstacle_shapes.course_entry, which does not look past `horizon` m); 0 if already inside one; inf if the
    course meets none or the vehicle hovers (horizontal speed <= 1e-6 m/s)."""
    n, k_obs = pos.shape[0], radii.shape[0]
    out = np.full(n, np.inf)
    for i in range(n):
        speed = np.hypot(vel[i, 0], vel[i, 1])
        if not speed > 1e-6:
            continue
        u0, u1 = vel[i, 0] / speed, vel[i, 1] / speed
        entry_min = np.inf
        for k in range(k_obs):
            r0, r1 = centres[k, 0] - pos[i, 0], centres[k, 1] - pos[i, 1]
            dz = pos[i, 2] - centres[k, 2]
            grown = radii[k] + clearance
            grown_sq = grown * grown - dz * dz  # squared radius of the cross-section circle
            along = 0.0 + r0 * u0 + r1 * u1
            rel_sq = 0.0 + r0 * r0 + r1 * r1
            half_chord_sq = grown_sq - (rel_sq - along * along)
            if rel_sq < grown_sq and grown_sq > 0.0:
                entry = 0.0
            elif grown_sq > 0.0 and half_chord_sq >= 0.0 and along > 0.0:
                entry = along - math.sqrt(maximum(half_chord_sq, 0.0))
            else:
                entry = np.inf
            entry_min = minimum(entry_min, entry)
        for k in range(kinds.shape[0]):
            entry = course_entry(
                pos[i, 0], pos[i, 1], pos[i, 2], u0, u1, clearance, horizon, k, kinds, params, vertices
            )
            entry_min = minimum(entry_min, entry)
        out[i] = entry_min
    return out


@kernel
def interp(x: float, xp: np.ndarray, fp: np.ndarray) -> float:
    """np.interp of one x on an increasing table xp, fp (numpy's compiled_base.c arr_interp): fp[0] left of
    the table, fp[-1] right of it and at its last point, fp[j] at a table point, else the slope
    (fp[j+1] - fp[j]) / (xp[j+1] - xp[j]) times (x - xp[j]) plus fp[j]."""
    last = xp.shape[0] - 1
    if x != x:
        return x
    if x < xp[0]:
        return fp[0]
    if x > xp[last]:
        return fp[last]
    lo, hi = 0, last + 1  # j: the last table point <= x (np.searchsorted's side "right", less one)
    while lo < hi:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    j = lo - 1
    if j == last or xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + fp[j]
    if out != out:
        out = slope * (x - xp[j + 1]) + fp[j + 1]
        if out != out and fp[j] == fp[j + 1]:
            out = fp[j]
    return out


@kernel
def speed_caps_from_table(
    pos: np.ndarray, vel: np.ndarray, centres: np.ndarray, radii: np.ndarray, clearance: float,
    total: np.ndarray, speeds: np.ndarray, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """(N,) m/s: the speed whose stopping distance `total` (S,) (stopping_table) equals each vehicle's
    distance along its course (clearance m; spheres and the packed shapes, the latter looked for as far as
    the table's last distance), inf where the course is clear."""
    caps = distance_along_course(pos, vel, centres, radii, clearance, kinds, params, vertices, total[-1])
    for i in range(caps.shape[0]):
        if np.isfinite(caps[i]):
            caps[i] = interp(caps[i], total, speeds)
    return caps


def failsafe_speed_caps(
    pos: np.ndarray,
    vel: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    reaction_s: float,
    brake_accel: float,
    clearance: float,
    brake_jerk: float = 5.0,
    shapes: ShapeArrays = NO_SHAPES,
) -> np.ndarray:
    """(N,) m/s horizontal speed caps (module docstring); inf where the course is clear. `reaction_s` T s
    (FS_GCS_TIMEOUT), `brake_accel` m/s^2 and `brake_jerk` m/s^3 the BRAKE shaping's limits, `clearance` m,
    `shapes` the cylinders and prisms beside the spheres."""
    total, speeds = stopping_table(float(reaction_s), float(brake_accel), float(brake_jerk))
    return speed_caps_from_table(pos, vel, centres, radii, float(clearance), total, speeds, *shapes)
