"""The formation the guidance flies: the FleetController configured from the mission file, the slot offsets
of the live vehicles (re-forming after a loss or a reshape), slot assignment by the shortest longest move, and
the timeline of formations flown."""

from __future__ import annotations

import numpy as np

from gcs_swarm.guidance.controller import make_position_controller
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import assign_slots, formation_offsets
from gcs_swarm.guidance.slot_assignment import AssignmentRule
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.mission import Mission
from gcs_swarm.mission.geometry import follower_targets, mission_offsets
from swarm_common.obstacle_shapes import ShapeArrays, pack_shapes

ASSIGNMENT_GAP_M = 1.0  # m beyond D_Emg kept between followers moving to their slots


def live_offsets(
    mission: Mission, alive: np.ndarray, leader: int, shape: str | None = None, spacing: float | None = None
) -> np.ndarray:
    """Slot offsets (N, 3) for the live vehicles around `leader` (re-forming after a loss, spec 6 frame):
    a generated shape gives its first slots to the live followers in vehicle order; explicit slots are kept,
    shifted so that the (possibly new) leader sits at zero. Rows of lost vehicles are zero."""
    shape = shape or mission.formation.shape
    offsets = np.zeros((len(mission.vehicles), 3))
    followers = [i for i in np.flatnonzero(alive) if i != leader]
    if shape == mission.formation.shape and any(v.slot is not None for v in mission.vehicles):
        full = mission_offsets(mission)  # explicit slots: keep them, relative to the leader
        offsets[followers] = full[followers] - full[leader]
    elif followers:
        form = mission.formation
        offsets[followers] = formation_offsets(shape, len(followers), spacing or form.spacing, form.angle_deg)
    return offsets


def build_controller(
    mission: Mission, leader: int | None = None, offsets: np.ndarray | None = None
) -> FleetController:
    """The guidance + control stack configured from the mission file (`leader`/`offsets` override the
    mission's, when the lead passes to another vehicle)."""
    leader = mission.leader_index if leader is None else leader
    return FleetController(
        n=len(mission.vehicles),
        leader=leader,
        offsets=mission_offsets(mission) if offsets is None else offsets,
        goal_waypoints=np.array(mission.waypoints, dtype=float),
        follower_targets=follower_targets(mission) if leader == mission.leader_index else None,
        field=mission.field,
        separation=mission.safety.separation,
        reference=mission.reference,
        limits=mission.limits,
        position_controller=make_position_controller(
            mission.controller, mission.smc, mission.pid, mission.limits
        ),
        adjacency=mission.formation.adjacency,
        topology=mission.formation.topology,
        control_dt=1.0 / mission.run.control_rate_hz,
        z_min=mission.safety.min_altitude,
        dead_gcs=mission.safety.dead_gcs,
        reshape=mission.reshape,
        pace=mission.pace,
        names=tuple(v.name for v in mission.vehicles),
        shapes=site_shapes(mission),
        still_obstacles=still_obstacles(mission),
    )


def site_shapes(mission: Mission) -> ShapeArrays:
    """The mission's cylinders (world.cylinders) and prisms (world.prisms), packed for the guidance and the
    report (swarm_common.obstacle_shapes, spec 2.2), in that order."""
    return pack_shapes(
        cylinders=[(c.center, c.radius, c.bottom, c.top) for c in mission.cylinders],
        prisms=[(p.footprint, p.bottom, p.top) for p in mission.prisms],
    )


def still_obstacles(mission: Mission) -> ShapeArrays:
    """Every obstacle of the mission that does not move: its spheres at rest (world.obstacles with zero
    velocity), cylinders and prisms, packed (the leader's route is planned round them)."""
    return pack_shapes(
        spheres=[(o.center, o.radius) for o in mission.obstacles if not np.any(o.velocity)],
        cylinders=[(c.center, c.radius, c.bottom, c.top) for c in mission.cylinders],
        prisms=[(p.footprint, p.bottom, p.top) for p in mission.prisms],
    )


def slots_assignable(mission: Mission) -> bool:
    """Whether followers may swap slots: `formation.assign_slots` and no vehicle pins a slot or target."""
    return mission.formation.assign_slots and all(
        v.slot is None and v.target is None for v in mission.vehicles
    )


def assign_slots_by_travel(
    mission: Mission, controller: FleetController, fleet: Fleet, flown: np.ndarray
) -> AssignmentRule | None:
    """Give the controller's current slots to the followers of the (N,) bool mask `flown` (live, not taken
    over) by the shortest longest move that neither crosses nor comes within D_Emg + 1 m of another
    (formation.assign_slots) from where they are now, the leader's slot frame as it is now; the rule that
    decided if a follower changed slot, else None."""
    if not slots_assignable(mission):
        return None
    movable = flown & np.isfinite(fleet.pos).all(axis=1)
    movable[controller.leader] = False
    assert controller.heading is not None
    offsets, rule = assign_slots(
        fleet.pos, fleet.pos[controller.leader], controller.heading.psi, controller.offsets, movable,
        mission.safety.separation.d_emg + ASSIGNMENT_GAP_M,
    )  # fmt: skip
    if np.array_equal(offsets, controller.offsets):
        return None
    controller.set_offsets(offsets)
    return rule


def note_formation(
    timeline: list[tuple[float, int, np.ndarray, bool]],
    t: float,
    controller: FleetController,
    alive: np.ndarray,
) -> None:
    """Append (t, leader, (N, 3) offsets flown (reshaped or not) with degraded widening, NaN rows for the (N,)
    not `alive`, whether a column's slots follow the leader's path) to the timeline when the formation
    changed (following the path or not changes only with the offsets)."""
    offsets = np.where(alive[:, None], controller.flown_offsets * controller.spacing_scale, np.nan)
    if timeline and timeline[-1][1] == controller.leader:
        last = timeline[-1][2]
        # np.array_equal(last, offsets, equal_nan=True), in fewer calls (once a tick)
        if last.shape == offsets.shape and bool(
            ((last == offsets) | (np.isnan(last) & np.isnan(offsets))).all()
        ):
            return
    timeline.append((t, controller.leader, offsets, controller.follows_path))
