"""One tick of formation flight: measured state -> guidance (FleetController.tick) -> ArduPilot thrust ->
final command guard -> SET_ATTITUDE_TARGET to every active vehicle (and a zero-velocity target to every held
one), then how far each vehicle is from where it should end. In the position command mode (a link too slow for
attitude targets, link.command_mode) each active vehicle gets the guidance's reference position, velocity and
acceleration instead (through the final guard's guard_position_targets), once per position report; the
attitude commands are still made (record.csv keeps them) but not sent."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import NDArray

from gcs_swarm.flight.preflight import VehicleSetup
from gcs_swarm.flight.tick_timing import GUIDANCE, TickTiming
from gcs_swarm.guidance.degradation import TelemetryAssessment
from gcs_swarm.guidance.fleet_controller import Command, FleetController
from gcs_swarm.guidance.params import G
from gcs_swarm.link.attitude_commands import attitude_commands
from gcs_swarm.link.command_limits import CommandLimits, guard_position_targets
from gcs_swarm.link.command_mode import POSITION
from gcs_swarm.link.fleet import Fleet


@dataclass(frozen=True)
class SentTick:
    """What one formation tick sent: the guidance's command, the (N,) normalised thrust after the guard,
    the (N,) bool mask of vehicles commanded, and how many of those the guard changed."""

    command: Command
    thrust: np.ndarray
    active: np.ndarray
    limited: int


def send_formation_tick(
    fleet: Fleet,
    controller: FleetController,
    t: float,
    state: tuple[np.ndarray, np.ndarray, np.ndarray],
    verdict: TelemetryAssessment,
    obstacles: tuple[np.ndarray, np.ndarray],
    setup: VehicleSetup,
    limits: CommandLimits,
    flown: np.ndarray,
    timing: TickTiming | None = None,
) -> SentTick:
    """Command the fleet at vehicle time t (s) from the measured `state` pos (N, 3) ENU m, vel (N, 3) m/s,
    att (N, 3) rad (roll, pitch, yaw) and the telemetry verdict (the positions predicted to now, which the
    guidance and the guard use, and the held vehicles), around `obstacles`
    ((K, 3) ENU m centres, (K,) m radii at time t). A vehicle whose state is not finite (broken telemetry)
    gets no command this tick, as if lost; a held one brakes on its own autopilot. Only vehicles of the
    (N,) bool mask `flown` (live, not taken over by an operator) are sent anything. `timing`, if given, marks
    the end of the guidance (flight.tick_timing). What is sent follows fleet.command_plan (module doc)."""
    pos, vel, att = state
    finite = cast(NDArray[np.bool_], np.isfinite(np.hstack((pos, vel, att))).all(axis=1))  # (N,)
    active = flown & finite & ~verdict.held
    centres, radii = obstacles
    cmd = controller.tick(t, verdict.pos, vel, att, centres, radii, active)
    if timing is not None:
        timing.mark(GUIDANCE)
    # attitude_commands: each vehicle's autopilot dialect makes its thrust, then the final command guard
    roll, pitch, yaw, thrust, limited = attitude_commands(
        cmd.roll_d, cmd.pitch_d, cmd.yaw_d, cmd.thrust_acc, att, verdict.pos, vel, setup.hover,
        setup.angle_boost, G, limits, fleet.dialects,
    )  # fmt: skip
    plan = fleet.command_plan
    if plan is not None and plan.mode == POSITION:  # the reference as a trajectory point (command_mode)
        ref = guard_position_targets(cmd.ref_pos, cmd.ref_vel, cmd.ref_acc, verdict.pos, limits, G)
        fleet.send_trajectory_targets(ref.pos, ref.vel, ref.acc, cmd.yaw_d, active)
        limited = ref.changed
    else:
        fleet.send_attitude_targets(roll, pitch, yaw, thrust, mask=active)
    for i in np.flatnonzero(verdict.held & flown):
        fleet.vehicle(int(i)).setpoints.send_velocity_target(
            np.zeros(3), yaw=float(att[i, 2]) if finite[i] else None
        )
    return SentTick(cmd, thrust, active, int(np.count_nonzero(limited & active)))


def end_targets(cmd: Command, controller: FleetController) -> np.ndarray:
    """(N, 3) ENU m where each vehicle should end: its slot, the leader its last waypoint."""
    targets = np.array(cmd.slots, dtype=float)
    targets[controller.leader] = controller.waypoints[-1]
    return targets


def formation_rms(errors: np.ndarray, active: np.ndarray, leader: int) -> float:
    """RMS m of the (N,) distances to target over the active followers (0 without any)."""
    followers = active.copy()
    followers[leader] = False
    return math.sqrt(float(np.mean(errors[followers] ** 2))) if followers.any() else 0.0
