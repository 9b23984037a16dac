"""Deliberate reshaping of the formation around obstacles [add] (docs/iaapf-smc-spec.md section 6a).

The paper flies one rigid formation and lets every follower go round an obstacle on its own repulsion, so a
formation meeting a slalom or a gap narrower than itself comes apart. Here the formation changes shape on
purpose instead, and its followers' slots move with it:

- **Candidates**, widest first: the mission's formation; the same shape with its spacing scaled down in
  `steps` steps to `min_spacing_m` between nearest slots; a column (line astern) min_spacing_m apart (short,
  so that its tail swings little when the leader turns).
- **Look-ahead**: the leader's way ahead (a `Route`: the path it will fly, predicted by running its own
  reference forward through the field, gcs_swarm.guidance.leader_path; or the straight route through its
  remaining waypoints, `route_samples`) for max(lookahead_min_m, lookahead_s x its speed cap + the leader's
  committed travel), sampled every SAMPLE_STEP_M (the committed travel: the distance the leader covers at its
  pace floors while the slowest change from the mission's shape runs, so that a change seen this far ahead
  can finish in time), the formation turned at each sample to the heading psi_L has there. A candidate fits
  when every follower's slot keeps `clearance_m` from every obstacle surface at every sample.
- **Choice**, every `decide_every_s`: the widest candidate that fits. When none does (a gap narrower than
  any shape with its clearance; along the straight route, an obstacle on the leader's own line, round which
  the leader will swerve in a way the route does not tell), the one with the most clearance, but only if
  it is narrower than the shape flown, all its slots stay outside the obstacles and it clears them by
  CLEARER_M more than the shape flown; else the shape flown is kept (a formation never widens while nothing
  fits). Narrower than the shape flown: at once; wider: once it has kept fitting, with WIDEN_MARGIN_M more
  clearance, for `restore_after_s`, so the formation does not flap at the edge of a gap, and only where the
  route runs straight while its move runs (`straight_for`: in a turn the slots would sweep round the
  leader as they move). With `widen_after_move`, a wider shape that does not fit where the leader is
  counts as fitting when it fits from where the leader will be once the move to it is over, where the route
  runs straight meanwhile, and its way there keeps clearance_m + WIDEN_MARGIN_M
  (`clear_floor`); such a widening under way is judged from its move's end and given up when the rest of
  its way no longer keeps the clearance it was planned with, less OPENING_SLACK_M. A wider shape that fits
  and whose way is not found blocked is `widening_due`: the runner's arrival waits for it
  (reshape.arrive_in_shape, FleetController.shape_settled).
- **At the goal** (the leader within GOAL_RADIUS_M of its last waypoint, where it hovers with psi_L held):
  the shape flown and the narrower candidates turned about the leader by every `goal_turn_step_deg` as well
  (`rotate_to_world`: counter-clockwise seen from above, so a slot astern turned by +90 deg lies to the
  right), so that a formation whose shape does not fit beside the obstacles there (a column whose tail
  trails back past the last obstacle) settles in one that does, instead of its followers being held off
  their slots by the repulsion until the time limit; the widest that fits, least turned, and a change to it
  only where its move keeps the clearance the slots have at its start (`_decide_at_goal`, spec 6a.3).
- **Change**: the followers are assigned to the new slots by the shortest longest move
  (gcs_swarm.guidance.slot_assignment), and the slots move from the old to the new offsets straight, or first
  along the leader's heading and then across it, or the other way round, the second phase starting when the
  first ends or while it still runs (MOVE_ORDERS, MOVE_OVERLAPS): the quickest way that keeps the vehicles
  `move_gap_m` apart (or as far as they stand at its start or end, where that is less), else whichever keeps
  them farthest apart (a column 7 m apart opening into a line 12 m apart goes straight, its closest pair
  passing 6.05 m apart; into a line 10 m apart, where straight moves would pass 5.7 m apart, it spreads
  across first, each follower still 7 m behind the next, and moves forward, each in its own lane, from a
  quarter of the way across). Each phase follows a minimum-jerk profile (quintic, zero velocity and
  acceleration at both ends) as short as lets no slot move faster than speed_m_s nor accelerate harder than
  accel_m_s2 relative to the leader (`move_duration`); where two phases overlap, both stretched in time until
  their combined rate and acceleration keep those bounds too (`timed_phases`). A widening that the leader
  spends mostly at its goal moves at up to goal_speed_m_s instead, within what the followers fly (`_plan`).
  A change that starts while the slots still move (taking over from another, or from where followers not
  yet assembled fly) carries their rate on and brings it to rest within settle_accel_m_s2 (`SlotMove`,
  `settle_profile`), so no slot's velocity jumps under its follower.
  The offsets' rate and acceleration go to the followers as velocity and acceleration feed-forwards.
- **Assembly**: a formation whose followers do not stand on their slots when it starts is carried into its
  shape along such a move from where they stand (`assemble_from`), when that move takes at most
  assembly_move_max_s, else into the widest narrower shape whose move does; farther off, each follower
  flies to its slot on its own. A change that follows at once is planned as one after assembly is: the
  followers stand on the slots of the moment.
- **Pace**: while the slots move to a narrower shape, the leader slows so that the shape flown does not
  reach the first place it does not fit before the change is done (`pace_cap`, `pace_speed`). In a phase in
  which a slot falls back along the leader's heading, not below that phase's peak fall-back rate less
  PACE_MARGIN_M_S (the phase's floor), so that no follower whose slot falls back reverses at speed; in a
  phase in which none does (a move across, a shrink), down to a hover: the leader waits for the formation.
  The cap falls no faster than `pace_decel_m_s2`: followers whose slots brake with the leader, and fall back
  besides, brake no harder than they can.
- **Footprint pace**: while the shape flown, at rest, does not fit the look-ahead and no other is taken, the
  leader slows to the fastest of a few fractions of its cap at which the path predicted for it leaves that
  shape room (`footprint_cap`, `_footprint_pace`): a rigid shape's slots cut less across the inside of a
  corner the slower its leader takes it.

Offsets are (N, 3) leader-frame metres (x forward, y left, z up), the leader's row zero. `scale` is the
spacing of the flown shape over the mission's (1 unreshaped); the inter-UAV repulsion range shrinks with it
(FleetController) so that followers in a tighter shape are not pushed out of their slots.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace
from typing import TypeVar

import numpy as np

from gcs_swarm.guidance.formation import formation_offsets, rotate_to_world
from gcs_swarm.guidance.params import ReshapeParams
from gcs_swarm.guidance.slot_assignment import assign_moves, closest_approach
from swarm_common.jit import kernel
from swarm_common.obstacle_shapes import NO_SHAPES, ShapeArrays, surface

SAMPLE_STEP_M = 2.0  # m between look-ahead samples along the leader's route
RESHAPE_CUSHION_M = 1.0  # m: in the tightest shape, neighbours repel once this much closer than min_spacing_m
# m/s: while slots fall back in the formation, the leader keeps above the peak rate at which they do, less
# this, so a follower whose slot falls back drifts backwards at under the 2 m/s of a cusp (metrics.md)
PACE_MARGIN_M_S = 1.5
WIDEN_MARGIN_M = 1.0  # m more than clearance_m a wider shape must keep to be taken (no flapping at the edge)
CLEARER_M = 1.0  # m more clearance a shape needs to be taken when no shape fits
MOVE_SAMPLE_S = 0.25  # s between the moments of a move checked for clearance (clear_floor)
CLEARANCE_TOLERANCE_M = 1e-6  # m a slot's clearance may round below its start's and still count as kept
# m a widening under way may come closer to an obstacle than it was planned to before it is given up: the
# leader does not fly on at exactly the speed the plan assumed
OPENING_SLACK_M = 1.0
# m a slot already in clearance_m's margin may come closer on its way than at the move's start: at legs2-13's
# goal a slot 7.4 m from a sphere dipped 0.4 m while the column turned and restored, and without the slack
# the formation stayed a column there (docs/metrics.md)
MARGIN_SLACK_M = 0.5
EARLY_TURN_MAX_RAD = math.radians(20.0)  # rad the route may turn while a widening runs
# fractions of the leader's speed cap at which the footprint pace (`_footprint_pace`) tries the leader's path
FOOTPRINT_PACE_STEPS = (0.8, 0.6, 0.4)
# m: the footprint pace takes the fastest of those speeds whose clearance is within this of the best one's
FOOTPRINT_SLACK_M = 2.0
GOAL_RADIUS_M = 2.0  # m from its last waypoint within which the leader is at its goal (`_decide_at_goal`)
# s: a change may run at goal_speed_m_s only where the leader reaches its goal before half of it is over; a
# leader farther than this from its goal (its route's length over its speed) is not asked, so a change there
# is planned once, at speed_m_s, and moves waiting for a clear way are kept (`FormationShaper._plan`)
GOAL_MOVE_HORIZON_S = 10.0
# m/s below the slowest follower's measured top speed a slot moves at most in such a change: room for its
# follower to correct its error on the way (`FormationShaper.followers_can_fly`)
GOAL_SPEED_MARGIN_M_S = 1.5
# moves planned and checked for clearance at the goal per decision (the costly part of a decision there)
GOAL_CHECKS_PER_DECISION = 1
FloatOrArray = TypeVar("FloatOrArray", float, np.ndarray)
# the leader's way ahead for a length m: points (P, 3) ENU m, the formation's heading there (P,) rad, their
# travel from the leader (P,) m (route_samples, gcs_swarm.guidance.leader_path)
Route = Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class ShapeChange:
    """One change of the formation's shape, for the flight's events, flight.json and the report: at vehicle
    time `t` s the formation `change`s ("narrows", "widens", "turns": the same candidate turned otherwise
    about the leader, or "restored": back to the mission's own shape, unturned) to the candidate `shape`
    (Shape.name, with its turn: `turned_name`) at spacing `scale` of the mission's, turned by `turn_deg`
    deg about the leader (counter-clockwise seen from above; non-zero only at the goal)."""

    t: float
    change: str
    shape: str
    scale: float
    turn_deg: float = 0.0

    @property
    def sentence(self) -> str:
        """The event line ("t=12.30 s formation narrows: column", "t=40.00 s formation restored")."""
        if self.change == "restored":
            return f"t={self.t:.2f} s formation restored"
        return f"t={self.t:.2f} s formation {self.change}: {self.shape}"

    def as_json(self) -> dict[str, float | str]:
        """flight.json's "reshapes" row: t_s, change, shape, scale, turn_deg."""
        return {
            "t_s": round(self.t, 3),
            "change": self.change,
            "shape": self.shape,
            "scale": round(self.scale, 4),
            "turn_deg": round(self.turn_deg, 1),
        }


@dataclass(frozen=True)
class Shape:
    """One candidate: `name` (for events), leader-frame offsets (N, 3), spacing scale (1: the mission's)."""

    name: str
    offsets: np.ndarray
    scale: float


def turned_name(name: str, angle: float) -> str:
    """A candidate's name with its turn at the goal: "column", "column turned -30 deg"."""
    degrees = round(math.degrees(angle))
    return name if degrees == 0 else f"{name} turned {degrees:+d} deg"


def goal_turns(step_deg: float) -> np.ndarray:
    """The turns (T,) rad tried at the goal, least first, every `step_deg` deg (0: none but 0): for 15 deg,
    0, +15, -15, +30, ..., +165, -165, 180 deg."""
    if step_deg <= 0.0:
        return np.zeros(1)
    steps = [0.0]
    for k in range(1, math.ceil(180.0 / step_deg - 1e-9)):
        steps += [k * step_deg, -k * step_deg]
    return np.radians(np.array([*steps, 180.0]))


def nearest_slot_spacing(offsets: np.ndarray, rows: np.ndarray) -> float:
    """Smallest distance m between two of the (N, 3) offsets of `rows` (N,) bool, the leader's (zero) among
    them; inf for fewer than two."""
    pts = offsets[rows]
    if len(pts) < 2:
        return math.inf
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    return float(d.min())


def shape_spacing(offsets: np.ndarray, leader: int) -> float:
    """m, the nearest distance between two slots of the (N, 3) offsets, the `leader`'s among them (followers'
    rows: the non-zero ones); inf for fewer than two."""
    rows = np.any(offsets != 0.0, axis=1)
    rows[leader] = True
    return nearest_slot_spacing(offsets, rows)


def shape_repulsion_range(d_max: float, spacing: float, scale: float, min_spacing: float) -> float:
    """m, the inter-UAV repulsion range in a shape of spacing `scale` < 1 of the mission's, whose nearest
    slots are `spacing` m apart (spec 6a.6): the mission's spacing, or D_max `d_max` m where that is less,
    times the scale, so that neighbours standing on their tighter slots are at most at the range's edge and
    not pushed out of them; never under `min_spacing` (min_spacing_m) less RESHAPE_CUSHION_M nor over
    D_max."""
    return min(d_max, max(min(d_max, spacing) * scale, min_spacing - RESHAPE_CUSHION_M))


def candidate_shapes(nominal: np.ndarray, leader: int, params: ReshapeParams) -> list[Shape]:
    """The candidates of the module docstring for the mission's offsets `nominal` (N, 3), widest first."""
    rows = np.any(nominal != 0.0, axis=1)
    rows[leader] = True
    followers = np.flatnonzero(rows & (np.arange(len(nominal)) != leader))
    spacing = shape_spacing(nominal, leader)
    shapes = [Shape("formation", nominal, 1.0)]
    if not followers.size or not math.isfinite(spacing):
        return shapes
    floor = min(1.0, params.min_spacing_m / spacing)
    for k in range(1, params.steps + 1):
        scale = 1.0 - (1.0 - floor) * k / params.steps
        if scale < 1.0:
            shapes.append(Shape(f"narrowed to {scale:.0%}", nominal * scale, scale))
    if params.column:
        column = np.zeros_like(nominal)
        column[followers] = formation_offsets("column", len(followers), spacing * floor)
        shapes.append(Shape("column", column, floor))
    return shapes


def route_samples(
    p_leader: np.ndarray, psi_leader: float, waypoints: np.ndarray, length: float, hold_m: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (P, 3) ENU m along the leader's route from p_leader (3,) through `waypoints` (W, 3), every
    SAMPLE_STEP_M up to `length` m, the heading (P,) rad the formation has at each (psi_leader at the
    leader's position, the direction of the route's piece elsewhere, except within `hold_m` m of the last
    waypoint, where the leader's heading holds (LeaderHeading's hold distance): there the heading the leader
    comes in with) and their distance (P,) m along the route from the leader."""
    points, headings, along_route = [np.asarray(p_leader, dtype=float)], [float(psi_leader)], [0.0]
    here, done = points[0], 0.0
    for k, wp in enumerate(waypoints):
        leg = wp - here
        size = float(np.hypot(leg[0], leg[1]))
        if size < 1e-6:
            continue
        heading = math.atan2(leg[1], leg[0])
        along = np.arange(SAMPLE_STEP_M, min(size, length - done) + 1e-9, SAMPLE_STEP_M)
        points.extend(here + leg * (a / size) for a in along)
        if k == len(waypoints) - 1 and size <= hold_m:  # the leader holds its heading all the way in
            heading = headings[-1]
        headings.extend([heading] * len(along))
        along_route.extend(done + along)
        done += size
        here = wp
        if done >= length:
            break
    return np.array(points), np.array(headings), np.array(along_route)


@kernel
def shape_clearance(
    offsets: np.ndarray, which: np.ndarray, followers: np.ndarray, points: np.ndarray, headings: np.ndarray,
    centres: np.ndarray, radii: np.ndarray, kinds: np.ndarray, params: np.ndarray, vertices: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """Smallest distance (P,) m from a follower slot to an obstacle surface (spheres: (K, 3) centres, (K,)
    radii; cylinders and prisms: the packed shapes kinds, params, vertices of swarm_common.obstacle_shapes,
    their true distance, spec 2.2) with the leader at each of points (P, 3) ENU m, heading (P,) rad, flying
    offsets[which[p]] there: offsets (S, N, 3) leader-frame m (one shape along the route: S = 1 and `which`
    zeros; a move: one row per moment), `followers` (F,) int the rows of the slots checked; inf without
    obstacles or followers."""
    out = np.full(points.shape[0], np.inf)
    for p in range(points.shape[0]):
        c, s = math.cos(headings[p]), math.sin(headings[p])
        shape = which[p]
        for i in followers:
            x = points[p, 0] + offsets[shape, i, 0] * c - offsets[shape, i, 1] * s
            y = points[p, 1] + offsets[shape, i, 0] * s + offsets[shape, i, 1] * c
            z = points[p, 2] + offsets[shape, i, 2]
            for k in range(radii.shape[0]):
                dx, dy, dz = x - centres[k, 0], y - centres[k, 1], z - centres[k, 2]
                gap = math.sqrt(dx * dx + dy * dy + dz * dz) - radii[k]
                if gap < out[p]:
                    out[p] = gap
            for k in range(kinds.shape[0]):
                gap = surface(x, y, z, k, kinds, params, vertices)[0]
                if gap < out[p]:
                    out[p] = gap
    return out


def clearance_along(
    offsets: np.ndarray, points: np.ndarray, headings: np.ndarray, centres: np.ndarray, radii: np.ndarray,
    shapes: ShapeArrays = NO_SHAPES,
) -> np.ndarray:  # fmt: skip
    """shape_clearance (P,) m of one shape's offsets (N, 3), its follower rows (non-zero offsets) checked,
    with the leader at each of points (P, 3), heading (P,) rad, among spheres and `shapes`."""
    followers = np.flatnonzero(np.any(offsets != 0.0, axis=1))
    which = np.zeros(len(points), dtype=np.int64)
    return shape_clearance(offsets[None], which, followers, points, headings, centres, radii, *shapes)


def straight_for(headings: np.ndarray, along: np.ndarray, distance: float) -> bool:
    """Whether the formation's heading (P,) rad along the route turns by at most EARLY_TURN_MAX_RAD over
    its first `distance` m (`along` (P,) m): a widening starts, and is judged from its move's end, only where
    the leader flies on straight meanwhile (in a turn its slots sweep while they move, faster than a follower
    flies)."""
    ahead = np.unwrap(headings[along <= distance + 1e-9])
    return bool(len(ahead) < 2 or np.ptp(ahead) <= EARLY_TURN_MAX_RAD)


def goal_eta(p_leader: np.ndarray, waypoints: np.ndarray, speed: float) -> float:
    """s until the leader at p_leader (3,) ENU m, flying at `speed` m/s, reaches the last of `waypoints`
    (W, 3) ENU m along them, at that speed (a leader braking into its goal takes longer: the estimate errs
    toward the goal being near); inf where that is over GOAL_MOVE_HORIZON_S (or the leader stands still)."""
    legs = np.diff(np.vstack([p_leader[None, :], waypoints])[:, :2], axis=0)
    eta = float(np.sum(np.hypot(legs[:, 0], legs[:, 1]))) / speed if speed > 0.0 else math.inf
    return eta if eta <= GOAL_MOVE_HORIZON_S else math.inf


def keeps_clear(gaps: np.ndarray, floor: float) -> bool:
    """Whether the slot clearances (M,) m of a move's moments stay at or above `floor` m (to rounding)."""
    return bool(gaps.min() >= floor - CLEARANCE_TOLERANCE_M)


def min_jerk(tau: FloatOrArray) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
    """The quintic 10 t^3 - 15 t^4 + 6 t^5 and its first and second derivatives at tau in [0, 1] (clipped),
    elementwise for an array of tau."""
    tau = np.clip(tau, 0.0, 1.0)
    return (
        tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau),
        30.0 * tau * tau * (1.0 - tau) ** 2,
        60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau),
    )


# The minimum-jerk profile's peaks per unit move and time: rate 1.875 (at tau = 1/2) and acceleration
# 10 / sqrt(3) (at tau = 1/2 - sqrt(3)/6).
MIN_JERK_PEAK_RATE = 1.875
MIN_JERK_PEAK_ACCEL = 10.0 / math.sqrt(3.0)


def settle_profile(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The quintic tau (1 - tau)^3 (1 + 3 tau) and its first and second derivatives at tau (clipped to
    [0, 1]): slope 1 and value and curvature 0 at tau = 0, value, slope and curvature 0 at tau = 1. A rate
    r carried into a move as r T settle_profile(t / T) starts at r and comes to rest after T s without a
    jump in acceleration."""
    tau = np.clip(tau, 0.0, 1.0)
    return (
        tau * (1.0 - tau) ** 3 * (1.0 + 3.0 * tau),
        1.0 - 18.0 * tau**2 + 32.0 * tau**3 - 15.0 * tau**4,
        -36.0 * tau + 96.0 * tau**2 - 60.0 * tau**3,
    )


# The settling profile's peak |second derivative| (at tau = (16 - sqrt 76) / 30)
SETTLE_PEAK_ACCEL = float(abs(settle_profile(np.array([(16.0 - math.sqrt(76.0)) / 30.0]))[2][0]))


def settle_duration(rate: np.ndarray, accel: float) -> float:
    """s, the shortest settling (`settle_profile`) of the slot rates (N, 3) m/s whose acceleration stays
    within `accel` m/s^2; a slot settling from r m/s carries on 16 r T / 81 m at most (the profile's peak,
    at tau = 1/3)."""
    return SETTLE_PEAK_ACCEL * float(np.max(np.linalg.norm(rate, axis=-1), initial=0.0)) / accel


def move_duration(distance: float, speed: float, accel: float) -> float:
    """s, the shortest minimum-jerk move over `distance` m whose rate stays within `speed` m/s and whose
    acceleration within `accel` m/s^2."""
    if distance <= 0.0:
        return 0.0
    return max(MIN_JERK_PEAK_RATE * distance / speed, math.sqrt(MIN_JERK_PEAK_ACCEL * distance / accel))


# Where the second phase of a two-phase move starts, as a share of the first phase's duration: 1, once the
# first is over; less, while it still runs, so that the slots cut the corner (a column opening into a V at
# its goal took 16 s along then across, docs/metrics.md)
MOVE_OVERLAPS = (1.0, 0.75, 0.5, 0.25)


def _move_orders() -> dict[str, tuple[tuple[tuple[int, ...], float], ...]]:
    """Straight, and along then across or across then along with the second phase starting at each share of
    MOVE_OVERLAPS, by name."""
    orders: dict[str, tuple[tuple[tuple[int, ...], float], ...]] = {"straight": (((0, 1, 2), 0.0),)}
    for first, second, names in (((0, 2), (1,), ("along", "across")), ((1, 2), (0,), ("across", "along"))):
        for share in MOVE_OVERLAPS:
            later = "then" if share == 1.0 else f"from {share:.0%}"
            name = f"{names[0]}, {later} {names[1]}"
            orders[name] = ((first, 0.0), (second, share))
    return orders


# The ways the slots may move from one shape to another: which axes of the leader frame move in each phase
# (the vertical moves with the first phase), and when each phase starts, as a share of the duration of the
# phase before it
MOVE_ORDERS: dict[str, tuple[tuple[tuple[int, ...], float], ...]] = _move_orders()
# before the formation has assembled, a change's phases do not overlap (`FormationShaper._plan`): its slots
# start where the followers stand, and a quicker change lets the leader speed up sooner while they still
# converge on them (gap-16: a column of six formed in 9.9 s instead of 13.7 s met a gap 20 m wide at 10 m/s,
# its tail 21 m off its slot; docs/metrics.md)
UNASSEMBLED_ORDERS = tuple(order for order in MOVE_ORDERS.values() if all(s == 1.0 for _, s in order[1:]))
OVERLAP_SAMPLES = 128  # moments of each stretch of a move in which two phases run together, sampled
# the stretch of overlapping phases is this much longer than their sampled peaks ask for, since the true peak
# lies between two samples (at 64 samples it was up to 6e-5 above the larger one; the tests check the bounds
# at 2001 moments of the move: tests/gcs_swarm/guidance/test_reshape.py)
PEAK_SAMPLING_MARGIN = 1.001


@dataclass(frozen=True)
class SlotMove:
    """The slots moving from `start` to `end` (N, 3) leader-frame m from t0 s: in each phase, `begin` s after
    t0, that phase's `axes` go from `start` to `end` along a minimum-jerk profile of its `duration` s. Each
    axis moves in one phase; phases may overlap. A move begun while the slots were still moving carries
    their rate then, `start_rate` (N, 3) m/s, on and brings it to rest over its first `settle_s` s
    (`settle_profile`), so that no slot's velocity jumps where one change of shape takes over from
    another."""

    start: np.ndarray
    end: np.ndarray
    t0: float
    phases: tuple[tuple[tuple[int, ...], float, float], ...]  # (axes, begin s, duration s)
    start_rate: np.ndarray | None = None
    settle_s: float = 0.0

    @property
    def duration(self) -> float:
        """s, the whole move."""
        return max(max((begin + d for _, begin, d in self.phases), default=0.0), self.settle_s)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Offsets (N, 3) at time t s, their rate (N, 3) m/s and their acceleration (N, 3) m/s^2."""
        offsets, rate, accel = self.along(np.array([t], dtype=float))
        return offsets[0], rate[0], accel[0]

    def along(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Offsets (T, N, 3) at the (T,) times s, their rate (T, N, 3) m/s and acceleration (T, N, 3)
        m/s^2."""
        shape = (len(times), *self.start.shape)
        offsets = np.broadcast_to(self.start, shape).copy()
        rate, accel = np.zeros(shape), np.zeros(shape)
        elapsed = times - self.t0
        for axes, begin, duration in self.phases:
            cols = list(axes)
            delta = self.end[:, cols] - self.start[:, cols]
            if duration <= 0.0:
                offsets[:, :, cols] = self.end[:, cols]
                continue
            lam, dlam, ddlam = min_jerk((elapsed - begin) / duration)
            offsets[:, :, cols] = self.start[:, cols] + lam[:, None, None] * delta
            rate[:, :, cols] = (dlam / duration)[:, None, None] * delta
            accel[:, :, cols] = (ddlam / duration**2)[:, None, None] * delta
        if self.start_rate is not None and self.settle_s > 0.0:
            begun = (elapsed >= 0.0)[:, None, None]
            h, dh, ddh = settle_profile(elapsed / self.settle_s)
            offsets += begun * (self.settle_s * h)[:, None, None] * self.start_rate
            rate += begun * dh[:, None, None] * self.start_rate
            accel += begun * (ddh / self.settle_s)[:, None, None] * self.start_rate
        return offsets, rate, accel

    def stretches(self) -> list[tuple[float, float, list[int]]]:
        """The move cut at every start and end of a phase and where its settling ends: (from s, to s after
        t0, the indices of the phases running throughout), in order."""
        moving = [(i, begin, begin + d) for i, (_, begin, d) in enumerate(self.phases) if d > 0.0]
        settle = {self.settle_s} if self.settle_s > 0.0 else set()
        bounds = sorted({0.0} | {a for _, a, _ in moving} | {b for _, _, b in moving} | settle)
        return [
            (a, b, [i for i, begin, end in moving if begin <= a and b <= end])
            for a, b in zip(bounds, bounds[1:], strict=False)
        ]

    def phases_left(self, t: float) -> list[tuple[float, float]]:
        """The stretches of the move (`stretches`) not over at t s, in order: (their time left s, the leader's
        pace floor m/s in them, `fall_back_floor` of the peak fall-back rate of the phases running then)."""
        out = []
        for a, b, running in self.stretches():
            if t < self.t0 + b:
                back = 0.0
                for i in running:
                    axes, _, duration = self.phases[i]
                    if 0 in axes:  # the peak rate of the longest backward move along the heading (min_jerk)
                        fall = float(np.max(self.start[:, 0] - self.end[:, 0], initial=0.0))
                        back = max(back, MIN_JERK_PEAK_RATE * fall / duration)
                out.append((self.t0 + b - max(t, self.t0 + a), fall_back_floor(back)))
        return out


def fall_back_floor(rate: float) -> float:
    """m/s, the slowest the leader may fly while slots fall back along its heading at up to `rate` m/s
    relative to it (module docstring, Pace): 0 when none does."""
    return max(rate - PACE_MARGIN_M_S, 0.0) if rate > 0.0 else 0.0


def pace_speed(phases: list[tuple[float, float]], room: float) -> float:
    """The fastest speed v m/s at which the leader, flying max(v, floor) in each of `phases` (time left s,
    floor m/s), covers at most `room` m before they are over (module docstring, Pace); 0 when the floors alone
    take it further. The travel sum max(v, f_k) d_k grows with v and bends at each floor, so v is solved
    piece by piece between floors, lowest first."""
    by_floor = sorted(phases, key=lambda phase: phase[1])
    at_floors = sum(duration * floor for duration, floor in by_floor)  # m covered when every phase is floored
    if at_floors >= room:
        return 0.0
    free_time = 0.0  # s of the phases whose floors lie below v: the leader flies v in them
    for duration, floor in by_floor:
        if free_time > 0.0 and (room - at_floors) / free_time <= floor:
            break
        free_time += duration
        at_floors -= duration * floor
    return (room - at_floors) / free_time if free_time > 0.0 else 0.0


@kernel
def closest_pair_sampled(positions: np.ndarray) -> float:
    """Smallest distance m between two different rows of `positions` (T, M, 3) m at any of its T moments
    (at each, slot_assignment.closest_approach of the rows standing still); inf with fewer than two rows.
    Compiled: a move of a hundred slots is sampled at OVERLAP_SAMPLES moments per stretch, every decision
    (`closest_pair_in`)."""
    best = math.inf
    for k in range(positions.shape[0]):
        best = min(best, closest_approach(positions[k], positions[k]))
    return best


def closest_pair_in(move: SlotMove, rows: np.ndarray) -> float:
    """Smallest distance m between two of the (N,) bool `rows` while `move` runs: exactly in a stretch in
    which one phase runs (its axes move together, proportionally: a straight synchronised move, whose closest
    approach slot_assignment.closest_approach gives), sampled at OVERLAP_SAMPLES moments where two do or the
    slots still settle from the rate they started with."""
    best = math.inf
    for a, b, running in move.stretches():
        if len(running) > 1 or a < move.settle_s:
            moments = move.t0 + np.linspace(a, b, OVERLAP_SAMPLES)
            best = min(best, closest_pair_sampled(np.ascontiguousarray(move.along(moments)[0][:, rows])))
        else:
            ends = move.along(move.t0 + np.array([a, b]))[0][:, rows]
            best = min(best, closest_approach(ends[0], ends[1]))
    return best


def timed_phases(
    start: np.ndarray, end: np.ndarray, order: tuple[tuple[tuple[int, ...], float], ...], speed: float,
    accel: float,
) -> tuple[tuple[tuple[int, ...], float, float], ...]:  # fmt: skip
    """The phases (axes, begin s, duration s) of the move start -> end (N, 3) in `order`: each phase as long
    as the `move_duration` of its longest move, starting its share of the phase before it after that one
    began; where phases overlap, all of them stretched in time until no slot's combined rate exceeds `speed`
    m/s nor its acceleration `accel` m/s^2 (a rate scales as 1/stretch, an acceleration as 1/stretch^2)."""
    phases: list[tuple[tuple[int, ...], float, float]] = []
    begin = 0.0
    for axes, share in order:
        longest = float(np.max(np.linalg.norm((end - start)[:, list(axes)], axis=1)))
        if phases:
            begin += share * phases[-1][2]
        phases.append((axes, begin, move_duration(longest, speed, accel)))
    move = SlotMove(start, end, 0.0, tuple(phases))
    overlapped = [(a, b) for a, b, running in move.stretches() if len(running) > 1]
    if not overlapped:
        return move.phases
    moments = np.concatenate([np.linspace(a, b, OVERLAP_SAMPLES) for a, b in overlapped])
    _, rate, acc = move.along(moments)
    stretch = max(
        1.0,
        PEAK_SAMPLING_MARGIN * float(np.max(np.linalg.norm(rate, axis=-1))) / speed,
        PEAK_SAMPLING_MARGIN * math.sqrt(float(np.max(np.linalg.norm(acc, axis=-1))) / accel),
    )
    return tuple((axes, b * stretch, d * stretch) for axes, b, d in phases)


def plan_move(
    start: np.ndarray,
    end: np.ndarray,
    rows: np.ndarray,
    t0: float,
    speed: float,
    accel: float = math.inf,
    keep_apart: float = math.inf,
    orders: Iterable[tuple[tuple[tuple[int, ...], float], ...]] = MOVE_ORDERS.values(),
    start_rate: np.ndarray | None = None,
    settle_accel: float | None = None,
) -> SlotMove:
    """The move from `start` to `end` (N, 3) among `orders` (`timed_phases`): the quickest of those
    that keep the (N,) bool `rows` (the leader's among them) `keep_apart` m apart, or as far apart as they
    stand at the start or the end where that is closer; else the one that keeps them farthest apart.
    `start_rate` (N, 3) m/s: the slots' rate at the start, brought to rest within `settle_accel` m/s^2
    (None: `accel`; `settle_duration`)."""
    here, there = start[rows], end[rows]
    floor = min(keep_apart, closest_approach(here, here), closest_approach(there, there))
    braking = accel if settle_accel is None else settle_accel
    settle_s = 0.0 if start_rate is None or math.isinf(braking) else settle_duration(start_rate, braking)
    carried = start_rate if settle_s > 0.0 else None
    moves = [
        SlotMove(start, end, t0, timed_phases(start, end, o, speed, accel), carried, settle_s) for o in orders
    ]
    # the quickest that keeps them apart, else the one that passes farthest apart (the first of equals in
    # `orders`): checked quickest first, so the closest approach (the costly part) is found only until one
    # keeps them apart
    best, best_rank = SlotMove(start, end, t0, (), carried, settle_s), (-math.inf, 0)
    for k in sorted(range(len(moves)), key=lambda k: moves[k].duration):  # (stable: equals keep their order)
        gap = closest_pair_in(moves[k], rows)
        if gap >= floor - 1e-6:
            return moves[k]
        if (gap, -k) > best_rank:
            best, best_rank = moves[k], (gap, -k)
    return best


class FormationShaper:
    """The shape the formation flies (module docstring): `flown(t)` the offsets and their rate now, `decide`
    the choice of shape, `set_nominal` a new mission formation (a re-form, a console reshape)."""

    def __init__(
        self, params: ReshapeParams, nominal: np.ndarray, leader: int, min_gap: float, hold_m: float = 0.0
    ) -> None:
        """`nominal` (N, 3) the mission's offsets; `min_gap` m the distance followers moving to new slots
        keep from each other (slot_assignment); `hold_m` m the distance from its last waypoint within which
        the leader's heading holds (route_samples)."""
        self.params = params
        self.leader = leader
        self.min_gap = min_gap
        self.hold_m = hold_m
        self.changes: list[ShapeChange] = []  # the changes of shape made; the caller empties it
        # s until the leader stops at its goal, estimated at each decision (`decide`); inf beyond
        # GOAL_MOVE_HORIZON_S
        self.goal_eta_s = math.inf
        # m/s, fastest a slot may move in a widening the leader spends mostly at its goal
        # (`followers_can_fly`)
        self.goal_move_speed = params.speed_m_s
        self.assembled = True  # the formation has assembled (`decide`)
        self._set(np.array(nominal, dtype=float))
        self.next_decision = -math.inf
        self.wider_since: float | None = None  # s, since when a wider shape has fitted (restore_after_s)
        self.widen_blocked = False  # a wider shape fits but the way to it was found blocked (`widening_due`)
        self.pace_cap = math.inf  # m/s, the leader's speed cap while the slots move (`_pace`)
        # m/s, the leader's speed cap while the shape flown does not fit its path (`_footprint_pace`)
        self.footprint_cap = math.inf
        self.paced_at = -math.inf  # s, when pace_cap was last set
        self.waiting_moves: dict[int, SlotMove] = {}  # widenings planned, by shape, waiting for a clear way
        # (N, 3) leader-frame m: where a column following the leader's path (column_path) has its slots now,
        # which is where a change of shape starts from (`start_state`); None when the slots are rigid
        self.bent: np.ndarray | None = None

    def _set(self, nominal: np.ndarray) -> None:
        self.shapes = candidate_shapes(nominal, self.leader, self.params)
        self.spacing = shape_spacing(nominal, self.leader)  # m, the mission's shape's nearest slots
        self.current = 0  # index into shapes of the shape flown (or being formed)
        self.turn = 0.0  # rad, that shape's turn about the leader (non-zero only at the goal)
        # (shape index, turn) whose move from the shape flown at the goal was found to pass closer to an
        # obstacle than allowed (`_decide_at_goal`); forgotten when the shape flown changes
        self.goal_blocked: set[tuple[int, float]] = set()
        # the move under way is a widening started before its shape fitted where the leader was (`decide`)
        self.opening_early = False
        self.opening_floor = 0.0  # m, the least slot clearance that move was planned to keep
        self.move = SlotMove(nominal, nominal, 0.0, ())
        self.start_scale = self.end_scale = 1.0
        # m the leader covers at its pace floors while the slowest change from the mission's shape runs,
        # assembled or not
        self.committed_m = max(
            sum(d * floor for d, floor in self._plan(k, nominal, 0.0, assembled).phases_left(0.0))
            for k in range(len(self.shapes))
            for assembled in (True, False)
        )

    def followers_can_fly(self, top_speed: float | None) -> None:
        """The slowest follower's top speed m/s as measured (capability.SpeedEnvelope.leader_cap; inf: not
        yet measured; None: never measured, the pace off): a widening the leader spends mostly at its goal
        may move its slots at up to goal_speed_m_s, but not faster than that top speed less
        GOAL_SPEED_MARGIN_M_S, and at speed_m_s until it is measured (`goal_move_speed`, `_plan`)."""
        params = self.params
        if top_speed is None:
            self.goal_move_speed = params.goal_speed_m_s
        elif math.isinf(top_speed):
            self.goal_move_speed = params.speed_m_s
        else:
            self.goal_move_speed = max(
                params.speed_m_s, min(params.goal_speed_m_s, top_speed - GOAL_SPEED_MARGIN_M_S)
            )

    def set_nominal(self, nominal: np.ndarray, leader: int, t: float | None) -> None:
        """A new mission formation (N, 3) around `leader`: flown at once when t is None, else reached from
        the offsets flown now along a reshape that starts at t s."""
        was, rate = (None, None) if t is None else self.start_state(t)
        self.leader = leader
        self._set(np.array(nominal, dtype=float))
        if was is not None and t is not None:
            self._change_to(0, was, t, announce=False, rate=rate)

    def start_state(self, t: float) -> tuple[np.ndarray, np.ndarray | None]:
        """Offsets (N, 3) a change of shape starting at t s starts from, and their rate (N, 3) m/s
        (`SlotMove`): the slots flown and their rate, so that the slots neither jump nor stop dead when the
        change starts and its clearance is checked from where they are; or where a column following the
        leader's path has them (`bent`), rate None."""
        if self.bent is not None:
            return self.bent, None
        offsets, rate, _ = self.flown(t)
        return offsets, rate

    def flown(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Offsets (N, 3) flown at time t s, their rate of change (N, 3) m/s and its rate (N, 3) m/s^2."""
        return self.move.at(t)

    def scale(self, t: float) -> float:
        """Spacing scale of the shape flown at t (interpolated during a change)."""
        duration = self.move.duration
        if duration <= 0.0 or t >= self.move.t0 + duration:
            return self.end_scale
        lam = min_jerk((t - self.move.t0) / duration)[0]
        return self.start_scale + lam * (self.end_scale - self.start_scale)

    @property
    def widening_due(self) -> bool:
        """At the last decision a wider shape fitted and the way to it was not found blocked: unless the
        obstacles move, the formation will widen (the arrival waits for it: FleetController.shape_settled)."""
        return self.wider_since is not None and not self.widen_blocked

    @property
    def shape_name(self) -> str:
        """Name of the shape flown or being formed, with its turn at the goal."""
        return turned_name(self.shapes[self.current].name, self.turn)

    def _plan(
        self, index: int, now: np.ndarray, t: float, assembled: bool | None = None, turn: float = 0.0,
        rate: np.ndarray | None = None,
    ) -> SlotMove:  # fmt: skip
        """The move from the offsets `now` (N, 3) to shape `index`, turned by `turn` rad about the leader
        (`rotate_to_world`), starting at t: followers assigned to the new slots by the shortest longest move,
        the quickest move order that keeps them move_gap_m apart (`plan_move`); before the formation has
        assembled, the one that keeps them farthest apart (the followers are still flying to their slots, and
        a quicker sweep of the slots across their way reversed some: spec 6a.4), among UNASSEMBLED_ORDERS.
        `assembled`: as if the formation had assembled or not (None: as it has, `self.assembled`); `rate`
        (N, 3) m/s: the slots' rate at `now` (None: at rest). The slots move at up to speed_m_s relative to
        the leader; into a wider shape, at up to goal_move_speed where the leader reaches its goal
        (goal_eta_s) before half of such a move is over: its slots' rate peaks half way, once the leader has
        stopped, and is then their followers' own speed (goal_speed_m_s); their acceleration then takes the
        share of the reference's that the leader's braking took (pace_decel_m_s2) as well. Not a turn or a
        narrowing at the goal: a column turned there at that speed while its followers still braked behind
        the leader, and two of them swung onto the slots' new way at over 2 m/s, a cusp (gap-16)."""
        target = rotate_to_world(self.shapes[index].offsets, turn)
        followers = np.flatnonzero(np.any(target != 0.0, axis=1))
        end = np.array(target)
        if followers.size > 1:
            order, _ = assign_moves(now[followers], target[followers], self.min_gap)
            end[followers] = target[followers[order]]
        rows = np.any(now != 0.0, axis=1) | np.any(end != 0.0, axis=1)
        rows[self.leader] = True
        params = self.params
        if self.assembled if assembled is None else assembled:
            orders, keep_apart = tuple(MOVE_ORDERS.values()), params.move_gap_m
        else:
            orders, keep_apart = UNASSEMBLED_ORDERS, math.inf
        widening = index < self.current
        if widening and self.goal_move_speed > params.speed_m_s and math.isfinite(self.goal_eta_s):
            quick = plan_move(
                now, end, rows, t, self.goal_move_speed, params.accel_m_s2 + params.pace_decel_m_s2,
                keep_apart, orders, rate, params.settle_accel_m_s2,
            )  # fmt: skip
            if self.goal_eta_s <= quick.duration / 2.0:
                return quick
        return plan_move(
            now, end, rows, t, params.speed_m_s, params.accel_m_s2, keep_apart, orders, rate,
            params.settle_accel_m_s2,
        )  # fmt: skip

    def _change_to(
        self, index: int, now: np.ndarray, t: float, announce: bool = True, move: SlotMove | None = None,
        start_scale: float | None = None, turn: float = 0.0, rate: np.ndarray | None = None,
    ) -> None:  # fmt: skip
        """Start moving the slots from the offsets `now` (N, 3), at `rate` (N, 3) m/s (None: at rest), to
        shape `index` turned by `turn` rad at t (along `move`, planned by `_plan` with that turn, when given),
        the spacing scale from `start_scale` (None: the scale flown at t)."""
        self.start_scale = self.scale(t) if start_scale is None else start_scale
        self.end_scale = self.shapes[index].scale
        self.move = move if move is not None else self._plan(index, now, t, turn=turn, rate=rate)
        self.waiting_moves = {}
        self.goal_blocked = set()
        self.opening_early = False
        if announce:
            if index == 0 and turn == 0.0:
                change = "restored"
            else:
                change = "narrows" if index > self.current else "widens" if index < self.current else "turns"
            shape = self.shapes[index]
            name = turned_name(shape.name, turn)
            self.changes.append(ShapeChange(t, change, name, shape.scale, math.degrees(turn)))
        self.current, self.turn = index, turn

    def assemble_from(
        self, starts: list[tuple[np.ndarray, np.ndarray]], t: float
    ) -> tuple[int | None, float]:
        """Which of `starts` the formation assembles from, along a move that starts at t s where its
        followers stand, and that move's duration s (spec 6a.4). Each start is where they stand, (N, 3)
        leader-frame m, and the rate they fly, (N, 3) m/s, in one frame the formation may start in, the
        preferred first. The move goes into the shape flown, or where every start's move would take longer
        than assembly_move_max_s, into the widest narrower candidate one start's move into which does not
        (a change of shape, announced: a launch grid stands closer together than the mission's shape, so a
        narrower shape is nearer; gap-6's V of eight, 11.4 s away, is reached narrowed to 87 % in 9.5 s, and
        widened once assembled); then the followers are on the slots of that moment from the start, and the
        slots carry them into the shape. Where no move is short enough nothing changes (None), each follower
        flies to its slot on its own, and the duration is that of the quickest move into the shape flown.
        The move is planned as a change once the formation has assembled is (the quickest order that keeps
        move_gap_m, its phases may overlap), since its followers stand on its slots from its start: on 30 of
        the 80 generated courses the assembly move came 0.2-4.8 s shorter than one phase after the other, on
        2 up to 0.9 s longer, with the same bounds met (docs/metrics.md)."""
        quickest = math.inf
        for k in range(self.current, len(self.shapes)):
            for which, (standing, rate) in enumerate(starts):
                move = self._plan(k, standing, t, assembled=True, rate=rate)
                if k == self.current:
                    quickest = min(quickest, move.duration)
                if move.duration <= self.params.assembly_move_max_s:
                    self._change_to(
                        k, standing, t, announce=k != self.current, move=move,
                        start_scale=self._standing_scale(standing),
                    )  # fmt: skip
                    return which, move.duration
        return None, quickest

    def _standing_scale(self, standing: np.ndarray) -> float:
        """The spacing scale of followers standing at `standing` (N, 3): their nearest spacing over the
        mission's, at most 1, so the repulsion range starts at the spacing they stand at (spec 6a.6)."""
        return min(1.0, shape_spacing(standing, self.leader) / self.spacing)

    def _widening(self, index: int, t: float) -> SlotMove:
        """The move to the wider shape `index` from t: planned once while the slots stand still, then the
        same move started later (the assignment is the costly part); planned afresh each time while a column
        follows the leader's path (its slots move in the leader's frame), or near the goal (goal_eta_s: the
        move's speed depends on when the leader gets there)."""
        cached = self.waiting_moves.get(index)
        near_goal = math.isfinite(self.goal_eta_s)
        if cached is None or cached.start is not self.move.end or self.bent is not None or near_goal:
            settled = t >= self.move.t0 + self.move.duration and self.bent is None and not near_goal
            if settled:
                cached = self._plan(index, self.move.end, t)
            else:
                now, rate = self.start_state(t)
                cached = self._plan(index, now, t, rate=rate)
            if settled:
                self.waiting_moves[index] = cached
            else:
                self.waiting_moves.pop(index, None)
        return replace(cached, t0=t)

    def clear_floor(
        self, move: SlotMove, route: Route, speed: float, centres: np.ndarray, radii: np.ndarray,
        shapes: ShapeArrays = NO_SHAPES, early: bool = False,
    ) -> float | None:  # fmt: skip
        """The least clearance m the slots keep from every obstacle surface while `move` runs with the
        leader going on along `route` at `speed` m/s (stopping where it ends), if each keeps its own floor,
        else None. A slot's floor is clearance_m or, where that slot is closer already at the move's start,
        as much as it has then less MARGIN_SLACK_M (the slots of a tail still short of a gap must not cut
        through its sides on their way to a wider shape, and a column whose tail came to rest in an
        obstacle's margin may still open out of it past that obstacle; one slot's start in a margin does not
        let another into it: legs3-2 re-formed at its goal with its tail slot 1.6 m from a sphere because the
        slot beside it started there, docs/metrics.md); `early`, a widening judged from its move's end
        (`decide`): clearance_m + WIDEN_MARGIN_M for every slot the whole way, as much as a shape that fits
        where the leader is keeps. Sampled every MOVE_SAMPLE_S; clearance_m without obstacles."""
        clearance = self.params.clearance_m
        if early:
            floor = clearance + WIDEN_MARGIN_M
            gaps = self._move_gaps(move, route, speed, centres, radii, shapes, move.t0)
            return floor if keeps_clear(gaps, floor) else None
        offsets, which, points, headings = self._move_samples(move, route, speed, move.t0)
        least = clearance
        for row in self._moved_rows(move):
            gaps = shape_clearance(offsets, which, np.array([row]), points, headings, centres, radii, *shapes)
            floor = min(clearance, float(gaps[0]) - MARGIN_SLACK_M)
            if not keeps_clear(gaps, floor):
                return None
            least = min(least, floor)
        return least

    @staticmethod
    def _moved_rows(move: SlotMove) -> np.ndarray:
        """The follower rows (F,) int of `move`: its slots not at the leader at its start or its end."""
        return np.flatnonzero(np.any(move.start != 0.0, axis=1) | np.any(move.end != 0.0, axis=1))

    def _move_samples(
        self, move: SlotMove, route: Route, speed: float, since: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The moments of `move` from `since` s to its end, every MOVE_SAMPLE_S, with the leader going on
        along `route` at `speed` m/s, as shape_clearance's first arguments: the offsets (M, N, 3) leader-frame
        m, which (M,) int, and the leader's points (M, 3) ENU m and headings (M,) rad."""
        left = max(move.t0 + move.duration - since, 0.0)
        moments = np.linspace(0.0, left, max(2, math.ceil(left / MOVE_SAMPLE_S) + 1))
        travel = speed * moments
        points, headings, along = route(float(travel[-1]))
        at = np.minimum(np.searchsorted(along, travel), len(along) - 1)
        offsets = move.along(since + moments)[0]
        return offsets, np.arange(len(moments), dtype=np.int64), points[at], headings[at]

    def _move_gaps(
        self, move: SlotMove, route: Route, speed: float, centres: np.ndarray, radii: np.ndarray,
        shapes: ShapeArrays, since: float,
    ) -> np.ndarray:  # fmt: skip
        """Smallest slot clearance (M,) m at each moment of `move` from `since` s to its end, every
        MOVE_SAMPLE_S, with the leader going on along `route` at `speed` m/s (`clear_floor`)."""
        offsets, which, points, headings = self._move_samples(move, route, speed, since)
        return shape_clearance(
            offsets, which, self._moved_rows(move), points, headings, centres, radii, *shapes
        )

    def decide(
        self, t: float, p_leader: np.ndarray, psi_leader: float, waypoints: np.ndarray, speed_cap: float,
        speed: float, centres: np.ndarray, radii: np.ndarray, shapes: ShapeArrays = NO_SHAPES,
        route: Route | None = None, assembled: bool = True,
        standing: Callable[[], tuple[np.ndarray, np.ndarray]] | None = None,
        route_at: Callable[[float], Route] | None = None,
    ) -> None:  # fmt: skip
        """Choose the shape at time t s (module docstring) for the leader at p_leader (3,) ENU m heading
        psi_leader rad toward `waypoints` (W, 3) at up to speed_cap m/s, flying at `speed` m/s now, among
        spherical obstacles (K, 3), (K,) m and the still cylinders and prisms `shapes` (spec 2.2), along
        `route` (the leader's path predicted, gcs_swarm.guidance.leader_path; None: the straight route
        through the waypoints, route_samples). `assembled`: whether the formation has assembled (every
        follower reached its slot once; FleetController): until then a change moves its slots the way that
        keeps them farthest apart, not the quickest (`_plan`). `standing`, given before the formation has
        assembled: where the followers stand now, (N, 3) leader-frame m, and how they move in that frame,
        (N, 3) m/s, asked for only when the formation narrows: the narrowing starts from there, at that rate,
        not from the slots they are still flying to (spec 6a.4), its spacing scale from theirs. `route_at`:
        the leader's path predicted at a speed cap m/s other than speed_cap (None: `route` does not depend on
        it), for the footprint pace (`_footprint_pace`)."""
        if t < self.next_decision or len(self.shapes) < 2:
            return
        self.next_decision = t + self.params.decide_every_s
        self.assembled = assembled
        if route is None:

            def route(length: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
                return route_samples(p_leader, psi_leader, waypoints, length, self.hold_m)

        goal = np.asarray(waypoints[-1], dtype=float)
        self.goal_eta_s = goal_eta(p_leader, waypoints, speed)
        if len(waypoints) == 1 and math.hypot(*(goal - p_leader)[:2]) <= GOAL_RADIUS_M:
            self.goal_eta_s = 0.0
            self._decide_at_goal(t, goal, psi_leader, route, speed, centres, radii, shapes)
            self.pace_cap, self.paced_at = math.inf, t  # the leader hovers on its goal: nothing to pace
            self.footprint_cap = math.inf
            return
        self.goal_blocked = set()
        if self.turn != 0.0:  # the leader left its goal (a console goto): its shape, unturned, at once
            now, rate = self.start_state(t)
            self._change_to(self.current, now, t, rate=rate)
        length = max(self.params.lookahead_min_m, self.params.lookahead_s * speed_cap + self.committed_m)
        # [add] a wider shape that does not fit where the leader is may still be flown once the move to it is
        # over: it must fit from where the leader will be then on, for the look-ahead, and the way there must
        # keep clearance_m + WIDEN_MARGIN_M (widen_after_move; spec 6a.3)
        widenings = (
            {k: self._widening(k, t) for k in range(self.current)} if self.params.widen_after_move else {}
        )
        skips = {k: speed * move.duration for k, move in widenings.items()}  # m the leader flies meanwhile
        left = self.move.t0 + self.move.duration - t
        opening = self.opening_early and left > 0.0  # an early widening under way: judged the same way
        if opening:
            skips[self.current] = speed * left
        longest = length + max(skips.values(), default=0.0)
        every_point, every_heading, every_along = route(longest)
        seen = every_along <= length + 1e-9
        points, headings, along = every_point[seen], every_heading[seen], every_along[seen]
        reach = max(float(np.max(np.linalg.norm(s.offsets, axis=1))) for s in self.shapes)
        near = np.linalg.norm(centres - p_leader, axis=1) - radii <= longest + reach + self.params.clearance_m
        every = centres, radii
        centres, radii = centres[near], radii[near]  # only obstacles a slot can come near in the look-ahead

        def fit_after(offsets: np.ndarray, travel: float) -> float:
            """The clearance m of `offsets` along the look-ahead from `travel` m on (or the route's end)."""
            start = min(travel, float(every_along[-1]))
            ahead = (every_along >= start - 1e-9) & (every_along <= start + length + 1e-9)
            check = every_point[ahead], every_heading[ahead]
            return float(clearance_along(offsets, *check, centres, radii, shapes).min())

        best, best_gap, gaps, early_floors = 0, -math.inf, {}, {}
        for k, shape in enumerate(self.shapes):
            gaps[k] = float(clearance_along(shape.offsets, points, headings, centres, radii, shapes).min())
            need = self.params.clearance_m + (WIDEN_MARGIN_M if k < self.current else 0.0)
            if k < self.current and gaps[k] < need and k in skips:
                if straight_for(every_heading, every_along, skips[k]):  # in a turn, slots sweep as they move
                    after = fit_after(shape.offsets, skips[k])
                    floor = None
                    if after >= need:
                        floor = self.clear_floor(widenings[k], route, speed, *every, shapes, early=True)
                    if floor is not None:
                        gaps[k], early_floors[k] = after, floor
            elif k == self.current and opening:  # from the move's end, the rest of its way clear as planned
                rest = self._move_gaps(self.move, route, speed, *every, shapes, t)
                gaps[k] = fit_after(shape.offsets, skips[k])
                if not keeps_clear(rest, self.opening_floor - OPENING_SLACK_M):
                    gaps[k] = min(gaps[k], float(rest.min()))
            if gaps[k] >= need:
                best = k
                break
            if gaps[k] > best_gap + 1e-9:
                best, best_gap = k, gaps[k]
        else:  # none fits: a narrower shape whose slots all stay outside obstacles, clearly clearer than the
            # one flown; never a wider one (a column stalled in front of a gap widened into it)
            if not (best > self.current and best_gap > max(0.0, gaps[self.current] + CLEARER_M)):
                best = self.current
        self.widen_blocked = False
        if best > self.current:
            self.wider_since = None
            if standing is None:
                now, rate = self.start_state(t)
                self._change_to(best, now, t, rate=rate)
            else:
                stand, moving = standing()
                self._change_to(best, stand, t, start_scale=self._standing_scale(stand), rate=moving)
        elif best < self.current:
            if self.wider_since is None:
                self.wider_since = t
            if t - self.wider_since >= self.params.restore_after_s:
                move = widenings[best] if best in widenings else self._widening(best, t)
                # and only where the route runs straight meanwhile: in a turn the slots sweep round the
                # leader while they move, faster than a follower flies (legs2-5, legs3-4; spec 6a.3)
                if straight_for(every_heading, every_along, speed * move.duration):
                    early = best in early_floors
                    floor = (
                        early_floors[best] if early else self.clear_floor(move, route, speed, *every, shapes)
                    )
                    if floor is not None:  # the way there keeps clear too
                        self.wider_since = None
                        self._change_to(best, move.start, t, move=move)
                        self.opening_early, self.opening_floor = early, floor
                    else:
                        self.widen_blocked = True
        else:
            self.wider_since = None
        self.footprint_cap = math.inf
        at_rest = not self.move.phases_left(t)
        if best == self.current and gaps[best] < self.params.clearance_m and route_at is not None and at_rest:
            self.footprint_cap = self._footprint_pace(t, route_at, speed_cap, speed, centres, radii, shapes)
        self._pace(t, speed, points, headings, along, centres, radii, shapes)

    def _footprint_pace(
        self, t: float, route_at: Callable[[float], Route], speed_cap: float, speed: float,
        centres: np.ndarray, radii: np.ndarray, shapes: ShapeArrays,
    ) -> float:  # fmt: skip
        """The leader's speed cap m/s while the shape flown, at rest, does not fit the look-ahead and no other
        shape was taken (spec 6a.10): the fastest of speed_cap and speed_cap x FOOTPRINT_PACE_STEPS at which
        the shape, along the leader's path predicted at that cap (`route_at`), keeps clearance_m from every
        obstacle surface, or at most FOOTPRINT_SLACK_M less than the clearest of them does; inf where that is
        speed_cap itself. Only the path the leader reaches before it could brake from its `speed` m/s at
        pace_decel_m_s2, plus lookahead_min_m, counts: a tighter place farther on is paced for when it is
        that near. A rigid shape's heading psi_L turns at a rate of its own (spec 6a.7), so a leader that
        takes a corner slower carries its slots round it closer to its own path (gap-12: a column of nine,
        56 m long, its leader through a detour at 10 m/s, predicted 0.4 m from a sphere; at 4 m/s 5.4 m)."""
        offsets = self.flown(t)[0]
        window = self.params.lookahead_min_m + speed**2 / (2.0 * self.params.pace_decel_m_s2)
        tried = []
        for step in (1.0, *FOOTPRINT_PACE_STEPS):
            points, headings, along = route_at(speed_cap * step)(window)
            near = along <= window + 1e-9
            clearance = clearance_along(offsets, points[near], headings[near], centres, radii, shapes)
            tried.append((speed_cap * step, float(clearance.min())))
        enough = min(self.params.clearance_m, max(g for _, g in tried) - FOOTPRINT_SLACK_M)
        chosen = next(v for v, g in tried if g >= enough)
        return math.inf if chosen >= speed_cap else chosen

    def _decide_at_goal(
        self, t: float, goal: np.ndarray, psi_leader: float, route: Route, speed: float, centres: np.ndarray,
        radii: np.ndarray, shapes: ShapeArrays,
    ) -> None:  # fmt: skip
        """The shape at the goal (module docstring), with the leader hovering at `goal` (3,) ENU m, psi_L
        `psi_leader` rad, flying at `speed` m/s now along `route`, among spheres (K, 3), (K,) m and `shapes`:
        the candidates no wider than the shape flown turned by every goal_turns about the leader, the wider
        ones unturned (re-forming into a turned wider shape at the goal took 6-49 s more on 27 of 60 generated
        courses, spec 6a.3), in that order (widest first, least turned first). While the shape flown keeps
        clearance_m from every obstacle surface, the first wider one that keeps 1 m more (a formation that
        fits is not turned again for less turn); while it does not, the first that fits, or where none does
        the one with the most clearance, if that clears the obstacles by CLEARER_M more than the shape flown.
        A wider one once it has kept fitting for restore_after_s; any only if its move keeps clear
        (`clear_floor`, the leader going on along `route`), else the next (a way found blocked is not checked
        again until the shape flown changes), at most GOAL_CHECKS_PER_DECISION moves checked per decision.
        As away from the goal, a widening is due (`widening_due`) only until the way to the widest that fits
        is found blocked: the arrival does not wait while the narrower ones are checked."""
        turns = goal_turns(self.params.goal_turn_step_deg)
        keys = [
            (k, float(turn))
            for k in range(len(self.shapes))
            for turn in turns
            if k >= self.current or turn == 0
        ]
        offsets = np.stack([rotate_to_world(self.shapes[k].offsets, turn) for k, turn in keys])
        rows = np.flatnonzero(np.any(offsets != 0.0, axis=(0, 2)))
        which = np.arange(len(keys), dtype=np.int64)
        points, headings = np.repeat(goal[None, :], len(keys), axis=0), np.full(len(keys), psi_leader)
        gaps = shape_clearance(offsets, which, rows, points, headings, centres, radii, *shapes)
        flown = keys.index((self.current, self.turn))
        need = [self.params.clearance_m + (WIDEN_MARGIN_M if k < self.current else 0.0) for k, _ in keys]
        fits = [j for j in range(len(keys)) if gaps[j] >= need[j]]
        if gaps[flown] >= need[flown]:
            order = [j for j in fits if keys[j][0] < self.current]
        elif fits:
            order = fits
        else:
            clearest = int(np.argmax(gaps))
            order = [clearest] if gaps[clearest] > max(0.0, gaps[flown] + CLEARER_M) else []
        wider_fits = self.widen_blocked = False
        checks = 0
        for j in order:
            k, turn = keys[j]
            wider = k < self.current
            wider_fits |= wider
            if keys[j] in self.goal_blocked:
                self.widen_blocked |= wider
                continue
            if wider:
                if self.wider_since is None:
                    self.wider_since = t
                if t - self.wider_since < self.params.restore_after_s:
                    return  # a wider shape is due: the arrival waits for it
            if checks == GOAL_CHECKS_PER_DECISION:  # the rest at the next decisions
                return
            checks += 1
            now, rate = self.start_state(t)
            move = self._plan(k, now, t, turn=turn, rate=rate)
            if self.clear_floor(move, route, speed, centres, radii, shapes) is not None:
                self.wider_since = None
                self._change_to(k, move.start, t, move=move, turn=turn)
                return
            self.goal_blocked.add(keys[j])
            self.widen_blocked |= wider
        if not wider_fits:
            self.wider_since = None

    def _pace(
        self, t: float, speed: float, points: np.ndarray, headings: np.ndarray, along: np.ndarray,
        centres: np.ndarray, radii: np.ndarray, shapes: ShapeArrays,
    ) -> None:  # fmt: skip
        """The leader's speed cap while the slots move (`pace_cap`): the shape flown now must not reach the
        first place along the route where it does not fit before the change is done, so the leader covers at
        most that distance in the change's remaining phases, each at least at its floor (`pace_speed`; module
        docstring, Pace); inf otherwise. The cap falls from the leader's `speed` m/s, or from the cap before
        where that is lower, no faster than pace_decel_m_s2, so that followers whose slots brake with the
        leader can brake as fast; a cap before that lay above the leader's speed (a change with room to
        spare) does not delay the braking."""
        phases = self.move.phases_left(t)
        cap = self.footprint_cap
        if phases and self.current != 0:
            gap = clearance_along(self.flown(t)[0], points, headings, centres, radii, shapes)
            tight = np.flatnonzero(gap < self.params.clearance_m)
            if len(tight):
                cap = max(phases[0][1], pace_speed(phases, float(along[tight[0]])))
        if math.isfinite(cap):
            start = min(self.pace_cap, speed)
            elapsed = t - self.paced_at if math.isfinite(self.paced_at) else self.params.decide_every_s
            cap = max(cap, start - self.params.pace_decel_m_s2 * elapsed)
        self.pace_cap, self.paced_at = cap, t
