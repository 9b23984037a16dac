"""The leader waits for its followers [add] (`guidance.reference.leader_wait_m`; spec 8a.8).

The paper's leader flies to its goal at its own cap whatever its followers do. On an airframe whose top speed
is below that cap (PX4's SIH quadrotor reaches 6.9 m/s at 35 deg tilt, below the leader's 10 m/s), leader
and followers all fly flat out, and a follower that falls behind its slot, in a turn or while the formation
assembles, never catches up. So the leader's horizontal speed cap is scaled down as the worst follower falls
behind:

    e     = max over active followers of |p_i - (p_L + R(psi_L) delta_i)|_xy     (m)
    scale = clip(1 - (e - leader_wait_m) / leader_wait_span_m, leader_wait_floor, 1)

and the leader's cap v_xy_leader becomes scale * v_xy_leader (FleetController.speed_caps). The reference
generator shapes the change (acceleration and jerk limits), so a falling cap never steps the leader's
attitude command. In the steady state of a leader held back by followers flying at their top speed
v_top < v_xy_leader the worst follower trails by about leader_wait_m + leader_wait_span_m (1 - v_top /
v_xy_leader). The floor keeps the formation moving when a follower cannot reach its slot at all (a slot
inside an obstacle, say). Followers whose slots pass obstacles still go round them as the field says;
waiting does not shorten that (docs/px4-sitl.md).
"""

from __future__ import annotations

import math

import numpy as np

from gcs_swarm.guidance.formation import rotate_to_world
from gcs_swarm.guidance.params import ReferenceParams
from swarm_common.rotations import wrap_pi_float

TURNING_MARGIN = 1.25  # the turn wait keeps the leader this many times heading_min_speed


def worst_slot_error(pos: np.ndarray, leader: int, world_offsets: np.ndarray, followers: np.ndarray) -> float:
    """m: the largest horizontal distance of a follower (rows of the (N,) bool mask `followers`) from its
    slot p_L + world offset, from positions pos (N, 3) ENU m and world-frame offsets (N, 3) m; 0 when the mask
    selects nobody."""
    if not followers.any():
        return 0.0
    slots = pos[leader] + world_offsets[followers]
    gap = pos[followers, :2] - slots[:, :2]
    return float(np.max(np.hypot(gap[:, 0], gap[:, 1])))


def leader_wait_scale(error_m: float, wait_m: float, span_m: float, floor: float) -> float:
    """The factor in [floor, 1] on the leader's speed cap for a worst follower slot error of error_m m; 1 when
    the wait is off (wait_m == 0)."""
    if wait_m <= 0.0:
        return 1.0
    return float(min(1.0, max(floor, 1.0 - (error_m - wait_m) / span_m)))


def leader_cap_scale(
    pos: np.ndarray,
    leader: int,
    offsets: np.ndarray,
    psi_leader: float,
    followers: np.ndarray,
    wait_m: float,
    span_m: float,
    floor: float,
) -> float:
    """The leader's speed-cap factor this tick from positions pos (N, 3) ENU m, leader-frame slot offsets
    (N, 3) m, the formation heading psi_leader (rad) and the (N,) bool mask of followers to wait for."""
    known = followers & np.isfinite(pos).all(axis=1)
    error = worst_slot_error(pos, leader, rotate_to_world(offsets, psi_leader), known)
    return leader_wait_scale(error, wait_m, span_m, floor)


def turn_wait_scale(
    p_leader: np.ndarray, waypoint: np.ndarray, psi_leader: float, steering: bool, ref: ReferenceParams,
    cap: float,
) -> float:  # fmt: skip
    """The factor on the leader's speed cap `cap` m/s while the formation's heading psi_leader (rad) lags the
    direction from p_leader (3,) to its waypoint (3,) ENU m by more than turn_wait_deg, falling linearly over
    turn_wait_span_deg to turn_wait_floor, but never to less than TURNING_MARGIN x heading_min_speed m/s
    (psi_L turns only while the leader is faster than that: a leg capped at 6 m/s with the floor 0.4 would
    freeze the formation's heading mid-turn); 1 when not `steering` (FleetController: on its first leg, or
    near its goal, where psi_L holds)."""
    if not steering:
        return 1.0
    lag = abs(wrap_pi_float(math.atan2(waypoint[1] - p_leader[1], waypoint[0] - p_leader[0]) - psi_leader))
    over = (math.degrees(lag) - ref.turn_wait_deg) / ref.turn_wait_span_deg
    floor = ref.turn_wait_floor
    if cap > 0.0:
        floor = max(floor, min(1.0, TURNING_MARGIN * ref.heading_min_speed / cap))
    return float(min(1.0, max(floor, 1.0 - over)))
