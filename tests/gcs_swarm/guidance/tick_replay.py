"""Replay of the guidance tick: a FleetController (with the command guard after it, as
gcs_swarm.flight.formation_tick runs them) flown in closed loop on a crude point-mass plant through varied,
deterministic situations, recording every output and the controller's internal state per tick.

Used by test_tick_replay.py, and by a throwaway script that runs the same replay against an older tree of the
code and compares the records byte for byte (so it imports only the public API that both trees share).

Situations: bundled missions (their controllers, obstacles, limits) and synthetic grid fleets of N = 1..230
with obstacles inside the influence range, vehicles pushed close to each other, vehicles going inactive (some
with NaN state rows) and coming back, degraded speed/spacing scales, a tick gap, new goals and offsets,
geofence and altitude rules of the guard in play, and the [add] options switched between their modes.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from gcs_swarm.flight.formation_plan import build_controller
from gcs_swarm.guidance.controller import make_position_controller
from gcs_swarm.guidance.fleet_controller import FleetController
from gcs_swarm.guidance.formation import formation_offsets
from gcs_swarm.guidance.params import (
    DeadGcsParams,
    FieldParams,
    G,
    Limits,
    ReferenceParams,
    SeparationParams,
)
from gcs_swarm.link.autopilots import ardupilot
from gcs_swarm.link.command_limits import CommandLimits, guard_attitude_commands
from gcs_swarm.mission import load_mission

MISSIONS = Path(__file__).resolve().parents[3] / "missions"
DT = 0.02  # s, 50 Hz


@dataclass
class Setup:
    """One replay: the controller, the initial state (N, 3) pos/vel/att, obstacle centres (K, 3) at t = 0 and
    their velocities (K, 3), radii (K,), the guard's limits, hover thrust (N,) and angle boost (N,) bool."""

    controller: FleetController
    pos: np.ndarray
    vel: np.ndarray
    att: np.ndarray
    centres: np.ndarray
    obstacle_vel: np.ndarray
    radii: np.ndarray
    limits: CommandLimits
    hover: np.ndarray
    boost: np.ndarray


def _mission_setup(name: str) -> Setup:
    mission = load_mission(MISSIONS / f"{name}.yaml")
    n = len(mission.vehicles)
    pos = np.array([v.start.position for v in mission.vehicles], dtype=float)
    vel = np.array([v.start.velocity for v in mission.vehicles], dtype=float)
    att = np.zeros((n, 3))
    att[:, 2] = [math.radians(v.start.yaw_deg) for v in mission.vehicles]
    obstacles = mission.obstacles
    centres = np.array([o.center for o in obstacles], dtype=float).reshape(-1, 3)
    obstacle_vel = np.array([o.velocity for o in obstacles], dtype=float).reshape(-1, 3)
    radii = np.array([o.radius for o in obstacles], dtype=float)
    if len(radii):  # bring the first obstacle to the fleet, inside the influence range from the start
        centres[0] = pos.mean(axis=0) + np.array([25.0, 20.0, 0.0])
    limits = CommandLimits(
        tilt_max=math.radians(mission.limits.tilt_max_deg),
        thrust_max_g=mission.limits.thrust_max_g,
        min_altitude=mission.safety.min_altitude,
        geofence_radius=mission.safety.geofence_radius,
        geofence_max_alt=mission.safety.geofence_max_alt,
    )
    return Setup(
        build_controller(mission), pos, vel, att, centres, obstacle_vel, radii, limits,
        np.linspace(0.35, 0.6, n), np.arange(n) % 2 == 0,
    )  # fmt: skip


def _grid_setup(n: int, k: int, seed: int, variant: str) -> Setup:
    rng = np.random.default_rng(seed)
    offsets = np.zeros((n, 3))
    offsets[1:] = formation_offsets("grid", n - 1, 9.0)
    field = FieldParams()
    separation = SeparationParams()
    reference = ReferenceParams()
    limits = Limits()
    controller = "smc"
    topology = "broadcast"
    if variant == "plain":  # every [add] off: the spec's equations
        field = replace(field, circulation=0.0, obstacle_vertical=1.0, method="apf")
        reference = replace(
            reference, jerk_max=0.0, brake_accel=0.0, stop_accel=0.0, heading_accel_max_deg=0.0,
            heading_filter_s=0.0,
        )  # fmt: skip
        limits = replace(limits, tilt_rate_max_deg=0.0)
        separation = replace(separation, closing_brake_accel=0.0)
    elif variant == "formula":
        separation = replace(separation, mode="formula")
        reference = replace(reference, slot_margin=2.0, paper_literal=True)
        topology = "relay"
    elif variant == "pid":
        controller = "pid"
    elif variant == "slow":  # the leader waits for followers 1 m off their slots (leader_wait), and a 12 deg
        # tilt limit bounds the closing-speed cap's deceleration (separation.closing_deceleration)
        reference = replace(reference, leader_wait_m=1.0, leader_wait_span_m=4.0)
        limits = replace(limits, tilt_max_deg=12.0)
    ctl = FleetController(
        n, 0, offsets, np.array([[400.0, 60.0, 50.0], [800.0, -40.0, 60.0]]),
        field=field, separation=separation, reference=reference, limits=limits,
        position_controller=make_position_controller(controller, limits=limits),
        topology=topology, control_dt=DT, thrust_mode="norm" if variant == "pid" else "measured",
        z_min=5.0,
        dead_gcs=DeadGcsParams(failsafe_timeout_s=3.0, brake_accel=2.5, brake_jerk=5.0),
    )  # fmt: skip
    pos = offsets + np.array([0.0, 0.0, 50.0]) + rng.normal(0.0, 0.8, (n, 3))
    spread = 2.5 if variant == "slow" else 0.5  # m/s: "slow" has vehicles closing on each other at a few m/s
    vel = np.tile([6.0, 0.5, 0.0], (n, 1)) + rng.normal(0.0, spread, (n, 3))
    att = np.zeros((n, 3))
    att[:, :2] = rng.normal(0.0, 0.05, (n, 2))
    lo, hi = pos.min(axis=0) - 15.0, pos.max(axis=0) + 15.0
    centres = lo + rng.uniform(0.0, 1.0, (k, 3)) * (hi - lo)
    centres[:, 0] += 30.0
    radii = rng.uniform(1.0, 4.0, k)
    obstacle_vel = np.zeros((k, 3))
    obstacle_vel[: k // 2, 1] = rng.uniform(-2.0, 2.0, k // 2)
    guard = CommandLimits(math.radians(30.0), 1.8, 45.0, 60.0 + 5.0 * math.sqrt(n), 55.0)
    return Setup(
        ctl, pos, vel, att, centres, obstacle_vel, radii, guard, np.full(n, 0.45), rng.uniform(size=n) < 0.5
    )


SCENARIOS = {
    "paper_static_6": lambda: _mission_setup("paper_static_6"),
    "paper_nine_9": lambda: _mission_setup("paper_nine_9"),
    "paper_dynamic_6": lambda: _mission_setup("paper_dynamic_6"),
    "quickstart": lambda: _mission_setup("quickstart"),
    "quickstart_faulty": lambda: _mission_setup("quickstart_faulty"),
    "paper_dense_6": lambda: _mission_setup("paper_dense_6"),
    "ardupilot_sitl_3": lambda: _mission_setup("ardupilot_sitl_3"),
    "grid_1": lambda: _grid_setup(1, 3, 1, "default"),
    "grid_3": lambda: _grid_setup(3, 10, 2, "default"),
    "grid_3_plain": lambda: _grid_setup(3, 4, 3, "plain"),
    "grid_6_formula": lambda: _grid_setup(6, 5, 4, "formula"),
    "grid_9_pid": lambda: _grid_setup(9, 0, 5, "pid"),
    "grid_7_slow": lambda: _grid_setup(7, 4, 10, "slow"),
    "grid_12": lambda: _grid_setup(12, 10, 6, "default"),
    "grid_25": lambda: _grid_setup(25, 8, 7, "default"),
    "grid_100": lambda: _grid_setup(100, 20, 8, "default"),
    "grid_230": lambda: _grid_setup(230, 12, 9, "default"),  # above 200 vehicles: the hash-grid pair search
}


def replay(name: str, ticks: int = 400, seed: int = 0) -> Iterator[dict[str, np.ndarray]]:
    """Fly scenario `name` for `ticks` ticks; yield per tick every output (Command fields, the guard's
    commands, the thrust sent) and the controller's internal state, as arrays."""
    s = SCENARIOS[name]()
    rng = np.random.default_rng(seed)
    ctl, n = s.controller, s.controller.n
    pos, vel, att = s.pos.copy(), s.vel.copy(), s.att.copy()
    ctl.reset(pos, vel, att[:, 2], att)
    followers = np.flatnonzero(np.arange(n) != ctl.leader)
    t = 0.0
    for tick in range(ticks):
        phase = tick % 200
        active = np.ones(n, dtype=bool)
        meas_pos, meas_vel, meas_att = pos.copy(), vel.copy(), att.copy()
        if len(followers) and 40 <= phase < 70:  # a follower goes quiet, its state unknown half the time
            quiet = followers[(tick // 200) % len(followers)]
            active[quiet] = False
            if phase >= 55:
                meas_pos[quiet] = np.nan
                meas_att[quiet] = np.nan
            else:
                ctl.place_uncommanded(int(quiet), pos[quiet] + 1.0, vel[quiet])
        if phase == 80 and len(followers) >= 2:  # two followers pushed next to each other
            a, b = followers[0], followers[-1]
            pos[b] = pos[a] + np.array([1.5, -0.5, 0.2])
            vel[b] = vel[a] - np.array([2.0, 0.0, 0.0])
        ctl.set_degraded(*((0.5, 1.5) if 100 <= phase < 140 else (1.0, 1.0)))
        if tick == 150:
            t += 10 * DT  # a gap: the nominal period is used
        if tick == 250 and len(followers):
            ctl.set_offsets(ctl.offsets * 1.2)
        if tick == 320:
            ctl.set_goal(pos[ctl.leader] + np.array([3.0, 2.0, 1.0]))  # reached soon: waypoint radius
        meas_pos += rng.normal(0.0, 0.05, (n, 3))
        centres = s.centres + s.obstacle_vel * t
        cmd = ctl.tick(t, meas_pos, meas_vel, meas_att, centres, s.radii, active)
        acc = ardupilot.unboosted_thrust(cmd.thrust_acc, meas_att[:, 0], meas_att[:, 1], s.boost)
        thrust = ardupilot.thrust_from_acc(np.nan_to_num(acc), s.hover, G)
        g_roll, g_pitch, g_yaw, g_thrust, changed = guard_attitude_commands(
            cmd.roll_d, cmd.pitch_d, cmd.yaw_d, thrust, meas_pos, meas_att[:, 2], s.hover, s.limits,
            vel=meas_vel if tick % 3 else None,
        )  # fmt: skip
        record = {f.name: np.asarray(getattr(cmd, f.name)) for f in fields(cmd) if f.name != "obstacles"}
        record.update(
            clearance=cmd.clearance,
            collision=cmd.collision,
            obstacle_centres=cmd.obstacles[0],
            obstacle_radii=cmd.obstacles[1],
        )
        record.update(
            unboosted=acc, thrust=thrust, guard_roll=g_roll, guard_pitch=g_pitch, guard_yaw=g_yaw,
            guard_thrust=g_thrust, guard_changed=changed,
            ref_p=ctl.generator.p, ref_v=ctl.generator.v, ref_a=ctl.generator.a,
            leader_speed_scale=np.asarray(ctl.leader_speed_scale),
            slew_roll=ctl.slew.roll, slew_pitch=ctl.slew.pitch,
            heading=np.array([ctl.heading.psi, ctl.heading.rate]) if ctl.heading else np.zeros(0),
        )  # fmt: skip
        for attr in ("s", "d_hat", "c_hat", "integral"):
            if hasattr(ctl.position_controller, attr):
                record[f"pc_{attr}"] = np.array(getattr(ctl.position_controller, attr))
        yield {key: np.array(value) for key, value in record.items()}
        # plant: the limited thrust acceleration less gravity and a little drag; attitude lags the command
        u = np.where(np.isfinite(cmd.u), cmd.u, np.array([0.0, 0.0, G]))
        vel = vel + (u - np.array([0.0, 0.0, G]) - 0.1 * vel) * DT
        pos = pos + vel * DT
        att[:, 0] += 0.3 * (np.nan_to_num(g_roll) - att[:, 0])
        att[:, 1] += 0.3 * (np.nan_to_num(g_pitch) - att[:, 1])
        att[:, 2] = np.where(np.isfinite(cmd.yaw_d), cmd.yaw_d, att[:, 2])
        t += DT
