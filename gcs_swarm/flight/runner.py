"""The mission run: connect -> preflight -> launch -> formation flight -> arrival -> land -> report.

`MissionRunner.run()` flies the whole mission (the `run` command). The same object is tick-driven for the
operator console: `begin()` preflights and commands the launch, `step()` handles one telemetry tick in the
current phase (climb, formation flight, hold, landing), `idle()` keeps the links served while nothing flies,
and `hold()`, `resume()`, `abort()`, `set_goal()`, `set_formation()` change what the next ticks do. One tick
of formation flight = read the fleet's telemetry arrays, FleetController.tick, send SET_ATTITUDE_TARGET to
every active vehicle.
Ticks are clocked by vehicle time (telemetry time_boot_ms), so the same code flies in real time against
hardware and in lockstep against the simulator.
"""

from __future__ import annotations

import math
import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import cast

import numpy as np
from numpy.typing import NDArray
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.flight.geofence import install_fence
from gcs_swarm.flight.run_record import RunRecord
from gcs_swarm.guidance.degradation import StaleTelemetryMonitor, TelemetryAssessment
from gcs_swarm.guidance.fleet_controller import Command, FleetController
from gcs_swarm.guidance.formation import assign_slots, formation_offsets
from gcs_swarm.guidance.lost_vehicles import LostTrack, avoidance_radius, predicted_position
from gcs_swarm.guidance.params import G
from gcs_swarm.link.autopilots import ardupilot
from gcs_swarm.link.command_limits import CommandLimits, guard_attitude_commands
from gcs_swarm.link.fleet import Fleet, LinkError
from gcs_swarm.link.flight_params import FlightParams
from gcs_swarm.link.vehicle import mode_name, mode_number
from gcs_swarm.mission import Mission
from gcs_swarm.mission.geometry import follower_targets, mission_offsets

# ArduCopter FS_GCS_ENABLE values (events.cpp failsafe_gcs_on_event): 1 RTL, 5 Land, 7 Brake or Land
FS_GCS_ENABLE = {"off": 0, "rtl": 1, "land": 5, "brake": 7}
GUID_OPTIONS_THRUST = 8  # bit 3: SET_ATTITUDE_TARGET thrust is normalised collective thrust (not climb rate)
HOLD_LATCH_SPEED = 0.5  # m/s: in hold, a vehicle's position is latched once it has braked below this
PHASES = ("connect", "preflight", "launch", "formation", "hold", "land", "done")
FAILSAFE_PARAMS = ("FS_GCS_TIMEOUT", "WPNAV_SPEED", "RTL_ALT")  # s, cm/s, cm: how a lost vehicle flies home


class PreflightError(Exception):
    """The fleet cannot be launched (one sentence naming the vehicle and why); nothing has flown."""


@dataclass
class FlightResult:
    """What the run did, from the ground station's point of view (metrics come from report.py)."""

    phase_reached: str = "connect"
    arrived: bool = False
    t_formation_start: float | None = None
    t_arrival: float | None = None
    t_formation_end: float | None = None
    lost: list[str] = field(default_factory=list)
    lost_at: dict[str, float] = field(default_factory=dict)  # vehicle time s at which each was declared lost
    events: list[str] = field(default_factory=list)
    ticks: int = 0
    final_targets: np.ndarray | None = None  # (N, 3) where each vehicle should end, from the last tick
    leader: int | None = None  # the leading vehicle at the end (the lead passes on when a leader is lost)
    offsets: np.ndarray | None = None  # (N, 3) slot offsets in force at the end
    degraded_s: float = 0.0  # vehicle s flown in degraded mode (stale telemetry: slower, wider)
    holds: int = 0  # times a vehicle was held for stale telemetry
    max_telemetry_age_s: float = 0.0  # oldest position telemetry of a live vehicle at any formation tick
    params_changed: list[dict[str, object]] = field(default_factory=list)  # flight_params.ParamChange rows
    # (vehicle time s, leader, (N, 3) slot offsets flown, NaN rows for lost vehicles) at each change
    formation_timeline: list[tuple[float, int, np.ndarray]] = field(default_factory=list)
    # vehicles found flying at the start (`--airborne`): None (none were), "finish" or "land"; and for
    # "land", whether every vehicle was disarmed on the ground at the end
    reattached: str | None = None
    landed_all: bool = False


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
        controller=mission.controller,
        smc=mission.smc,
        pid=mission.pid,
        adjacency=mission.formation.adjacency,
        topology=mission.formation.topology,
        control_dt=1.0 / mission.run.control_rate_hz,
        z_min=mission.safety.min_altitude,
        dead_gcs=mission.safety.dead_gcs,
    )


class MissionRunner:
    """Flies one mission over a Fleet. `progress` receives one-line status updates."""

    def __init__(
        self,
        mission: Mission,
        fleet: Fleet,
        record: RunRecord | None,
        progress: Callable[[str], None] = print,
        progress_period_s: float = 1.0,
    ) -> None:
        self.mission = mission
        self.fleet = fleet
        self.record = record
        self.progress = progress
        self.progress_period_s = progress_period_s
        self.result = FlightResult()
        self.phase = "connect"
        self.hover = np.full(len(mission.vehicles), 0.5)
        self.angle_boost = np.zeros(
            len(mission.vehicles), dtype=bool
        )  # ATC_ANGLE_BOOST on, read in preflight
        self.controller = build_controller(mission)
        self.shape: tuple[str | None, float | None] = (
            None,
            None,
        )  # live reshape (console), else the mission's
        self.command_limits = CommandLimits(
            tilt_max=math.radians(mission.limits.tilt_max_deg),
            thrust_max_g=mission.limits.thrust_max_g,
            min_altitude=mission.safety.min_altitude,
            geofence_radius=mission.safety.geofence_radius,
            geofence_max_alt=mission.safety.geofence_max_alt,
        )
        self.commands_limited = 0  # vehicle-ticks whose command the final guard had to change
        self.last_command: Command | None = None
        self.formation_rms = math.nan
        self._hold_since: float | None = None
        self._launch_since: float | None = None  # vehicle time of the tick-driven launch (console)
        self._land_since: float | None = None  # vehicle time LAND was commanded by a landing tick (console)
        self._hold_points = np.full((len(mission.vehicles), 3), np.nan)  # (N, 3) ENU m, latched in hold
        self._last_progress_wall = 0.0
        self._obstacle_radii = np.array([o.radius for o in mission.obstacles], dtype=float)
        self.telemetry = StaleTelemetryMonitor(mission.safety.telemetry)
        self._held = np.zeros(len(mission.vehicles), dtype=bool)
        self._degraded = False
        self._last_tick_t: float | None = None
        self.failsafe_params = np.tile([5.0, 1000.0, 1500.0], (len(mission.vehicles), 1))  # (N, 3) as read
        self._home = np.full((len(mission.vehicles), 3), np.nan)  # (N, 3) ENU m where each took off
        self._lost_tracks: dict[int, LostTrack] = {}
        self.tick_latency_s: list[float] = []  # wall s from a complete telemetry tick to its last command out
        self.flight_params = FlightParams(fleet)  # what the run sets on the vehicles, restored at the end
        # vehicle time (s) at which this process kills itself with SIGKILL: rehearses a ground-station crash
        # at an exact moment (`gcs-swarm run --crash-at`, docs/reliability.md); None: never
        self.crash_at_s: float | None = None
        # what to do with vehicles found flying at the start (`gcs-swarm run --airborne`): "finish" the
        # mission from where they are, "land" them, or None: refuse and say so
        self.airborne: str | None = None

    # ----- the whole mission -----

    def run(self) -> FlightResult:
        """All phases; PreflightError / LinkError before launch, FlightResult after. Vehicles found already
        flying (a ground station that crashed left them holding) are handled as `self.airborne` says."""
        self.connect()
        expect_flying = self.mission.run.airborne_start  # the simulator starts them in the air on purpose
        if not expect_flying:
            self.stop_unflown()
        self.preflight()
        flying = self.flying()
        if flying.any() and not expect_flying:
            self._reattach(flying)
            if self.phase == "done":
                return self.result
        else:
            self.launch()
        self.start_formation()
        while self.phase in ("formation", "hold"):
            self.step()
        self.land()
        return self.result

    def connect(self, timeout_s: float = 30.0) -> None:
        """Wait up to timeout_s for every vehicle's HEARTBEAT (LinkError naming the silent ones)."""
        self._set_phase("connect")
        self.fleet.connect(timeout_s=timeout_s)

    def preflight(self) -> None:
        """Wait for position estimates and pre-arm health; set and verify params; hover thrust; streams."""
        self._set_phase("preflight")
        fleet, run = self.fleet, self.mission.run
        try:
            fleet.wait_ready(timeout_s=run.preflight_timeout_s, progress=self.progress)
            safety = self.mission.safety
            flight = self.flight_params
            flight.set_all("GUID_OPTIONS", GUID_OPTIONS_THRUST)
            flight.set_all("FS_GCS_ENABLE", FS_GCS_ENABLE[safety.gcs_failsafe])
            flight.set_all("FS_GCS_TIMEOUT", float(safety.dead_gcs.failsafe_timeout_s or 0.0))
            flight.set_all("GUID_TIMEOUT", safety.dead_gcs.guided_timeout_s)
            # the autopilots' own geofence around the obstacles (flight.geofence, docs/reliability.md)
            install_fence(fleet, flight, self.mission, self.result.events, self.progress)
            self.hover = fleet.param_get_all("MOT_THST_HOVER")
            self.angle_boost = np.array(
                [ardupilot.is_boost_on(v) for v in fleet.param_get_all("ATC_ANGLE_BOOST")]
            )
            self.failsafe_params = np.column_stack([fleet.param_get_all(name) for name in FAILSAFE_PARAMS])
        except LinkError as exc:
            raise PreflightError(f"preflight failed: {exc}") from exc
        bad = [name for name, h in zip(fleet.names, self.hover, strict=True) if not 0.05 < h < 0.95]
        if bad:
            raise PreflightError(f"MOT_THST_HOVER of {', '.join(bad)} is outside 0.05..0.95")

    def launch(self) -> None:
        """GUIDED, arm, take off to the formation altitude (each vehicle plus its slot's dz)."""
        self.command_launch()
        if self.mission.run.airborne_start:
            return
        self.fleet.wait_until(
            self.launched,
            timeout_s=self.mission.run.takeoff_timeout_s,
            what="every vehicle at its takeoff altitude",
        )

    def command_launch(self) -> None:
        """Phase 'launch': GUIDED, arm and take off (each acknowledged); the climb itself is not awaited."""
        self._set_phase("launch")
        fleet, mission = self.fleet, self.mission
        self._home = (
            fleet.pos
        )  # on the ground: the failsafe's home (an airborne start's home is the ground below)
        if mission.run.airborne_start:
            self._home[:, 2] = 0.0
        try:
            fleet.set_mode_all("GUIDED")
            if mission.run.airborne_start:
                return
            fleet.arm_all()
            fleet.takeoff_all(self.takeoff_altitudes())
        except LinkError as exc:
            raise PreflightError(f"launch refused: {exc}") from exc

    def stop_unflown(self) -> None:
        """Vehicles found armed in GUIDED and not known to be on the ground fly targets nobody sends any more
        (a ground station died and its GCS failsafe has not fired yet, and our heartbeats now keep it from
        firing): ArduCopter levels them and lets them drift on. Put them in BRAKE at once, before the
        minutes of preflight, and say so; what happens next is `self.airborne`'s choice."""
        fleet = self.fleet
        guided = fleet.mode == mode_number("GUIDED")
        on_ground = fleet.landed_state == mavlink2.MAV_LANDED_STATE_ON_GROUND
        drifting = fleet.armed & fleet.alive & guided & ~on_ground
        if not drifting.any():
            return
        names = [fleet.names[i] for i in np.flatnonzero(drifting)]
        self.progress(f"{', '.join(names)} armed in GUIDED with nobody flying them: BRAKE")
        self.result.events.append(f"found armed in GUIDED, stopped in BRAKE: {', '.join(names)}")
        try:
            fleet.set_mode_all("BRAKE", names)
        except LinkError as exc:
            raise PreflightError(f"cannot stop the drifting vehicles: {exc}") from exc

    def flying(self) -> np.ndarray:
        """(N,) bool: vehicles that are armed and not on the ground (EXTENDED_SYS_STATE), e.g. holding where a
        crashed ground station left them."""
        fleet = self.fleet
        on_ground = np.isin(fleet.landed_state, (mavlink2.MAV_LANDED_STATE_ON_GROUND,))
        return fleet.armed & fleet.alive & ~on_ground

    def describe_flying(self, flying: np.ndarray) -> str:
        """One clause per flying vehicle: its name, mode, height and speed."""
        fleet = self.fleet
        parts = []
        for i in np.flatnonzero(flying):
            mode = mode_name(int(fleet.mode[i]))
            height = (
                float(fleet.pos[i, 2]) - float(self._home[i, 2])
                if np.isfinite(self._home[i, 2])
                else float(fleet.pos[i, 2])
            )
            parts.append(
                f"{fleet.names[i]} {mode} at {height:.1f} m, {float(np.linalg.norm(fleet.vel[i])):.1f} m/s"
            )
        return "; ".join(parts)

    def _reattach(self, flying: np.ndarray) -> None:
        """Vehicles are already in the air: `airborne` "finish" takes them back into GUIDED and flies the
        mission on from where they are; "land" lands them where they are and ends the run; None refuses
        with what was found (PreflightError)."""
        found = self.describe_flying(flying)
        self.result.events.append(f"vehicles already flying: {found}")
        if not flying.all() and self.airborne == "finish":
            on_ground = ", ".join(n for n, f in zip(self.fleet.names, flying, strict=True) if not f)
            raise PreflightError(
                f"some vehicles fly and some are on the ground ({on_ground}): land them first"
            )
        if self.airborne == "land":
            self.progress(f"vehicles already flying: {found}: landing them")
            self.result.reattached = "land"
            self._home = self.fleet.pos
            self.land()
            self.result.landed_all = not bool((self.fleet.armed & self.fleet.alive).any())
            return
        if self.airborne != "finish":
            raise PreflightError(
                f"vehicles already flying: {found}. Say --airborne finish to fly the mission on from where "
                "they are, or --airborne land to land them where they are"
            )
        self.progress(f"vehicles already flying: {found}: finishing the mission from here")
        self.result.reattached = "finish"
        self._set_phase("launch")
        self._home = self.fleet.pos
        self._home[:, 2] = 0.0
        try:
            self.fleet.set_mode_all("GUIDED")
        except LinkError as exc:
            raise PreflightError(f"cannot take the vehicles back: {exc}") from exc

    def takeoff_altitudes(self) -> np.ndarray:
        """(N,) m: the formation altitude plus each vehicle's slot dz."""
        return self.mission.formation.altitude + mission_offsets(self.mission)[:, 2]

    def launched(self) -> bool:
        """Every vehicle is within 0.5 m of its takeoff altitude (always, for an airborne start)."""
        if self.mission.run.airborne_start:
            return True
        return bool((self.fleet.pos[:, 2] >= self.takeoff_altitudes() - 0.5).all())

    def start_formation(self) -> None:
        """Initialise the guidance at the measured state and enter formation flight."""
        if not self.fleet.wait_tick(timeout_s=10.0):
            raise LinkError("no telemetry tick arrived after launch")
        self._enter_formation()
        self._formation_tick()  # act on the tick just consumed, then answer it (lockstep rule)
        self.fleet.answer_frame()

    def _enter_formation(self) -> None:
        fleet = self.fleet
        self.controller.reset(fleet.pos, fleet.vel, fleet.att[:, 2], fleet.att)
        self._assign_slots()
        self.telemetry.reset()
        self._held[:], self._degraded, self._last_tick_t = False, False, None
        self.result.t_formation_start = self.vehicle_time()
        self._set_phase("formation")

    def begin(self) -> None:
        """Console `start`: preflight and command the launch; later `step()`s finish the climb (phase
        'launch'), fly the formation and land on arrival. PreflightError / LinkError if nothing took off."""
        self.preflight()
        self.command_launch()
        self._launch_since = self.vehicle_time()
        self._land_since = None

    def step(self, timeout_s: float = 5.0) -> bool:
        """Handle one telemetry tick in the current phase; False if no tick arrived within timeout_s."""
        fleet = self.fleet
        if not fleet.wait_tick(timeout_s=timeout_s):
            fleet.answer_frame()  # a silent vehicle must not stall the others' lockstep frames
            self._note_lost()
            if self.phase in ("formation", "hold") and not fleet.alive.any():
                self.result.events.append("every vehicle stopped answering")
                self._set_phase("land")
            return False
        tick_in = time.perf_counter()
        if self.crash_at_s is not None and self.vehicle_time() >= self.crash_at_s:
            os.kill(os.getpid(), signal.SIGKILL)  # rehearsal of a ground-station crash (--crash-at)
        self._note_lost()
        if self.phase == "launch":
            self._launch_tick()
        elif self.phase == "formation":
            self._formation_tick()
            self.tick_latency_s.append(time.perf_counter() - tick_in)
        elif self.phase == "hold":
            self._hold_tick()
        elif self.phase == "land":
            self._landing_tick()
        fleet.answer_frame()  # vehicles not commanded this tick
        return True

    def idle(self, timeout_s: float = 0.02) -> None:
        """Keep the links served while the mission is not flying (before `begin`, after 'done'): receive for
        up to timeout_s, note lost vehicles, answer every new lockstep frame."""
        self.fleet.pump(timeout_s)
        self._note_lost()
        self.fleet.answer_frame()

    def land(self) -> None:
        """LAND every reachable vehicle and wait until they disarm (auto-disarm after touchdown)."""
        if self.phase != "land":
            self._set_phase("land")
        fleet = self.fleet
        self._command_landing()
        try:
            fleet.wait_until(
                lambda: not bool((fleet.armed & fleet.alive).any()),
                timeout_s=self.mission.run.land_timeout_s,
                what="every vehicle disarmed after landing",
            )
        except LinkError as exc:
            self.result.events.append(str(exc))
        self._set_phase("done")

    def restore_params(self) -> None:
        """Put back the parameters the run changed, on every vehicle now disarmed
        (gcs_swarm.link.flight_params); the list, with what was restored, goes to the result (flight.json
        `params_changed`). Skipped when the mission says run.keep_params."""
        if not self.mission.run.keep_params:
            try:
                self.flight_params.restore()
            except LinkError as exc:
                self.result.events.append(f"restoring parameters: {exc}")
        changes = self.flight_params.changes
        self.result.params_changed = [c.as_json() for c in changes]
        kept = [f"{c.vehicle} {c.name}" for c in changes if not c.restored]
        if kept:
            why = "run.keep_params" if self.mission.run.keep_params else "still armed or not answering"
            self.result.events.append(f"parameters left as flown ({why}): {', '.join(kept)}")

    # ----- operator commands (console) -----

    def hold(self) -> None:
        """Every vehicle brakes and holds its position (GUIDED position targets) until resume()."""
        if self.phase == "formation":
            self._hold_points[:] = np.nan
            self._set_phase("hold")

    def resume(self) -> None:
        """Back to formation flight from the current state."""
        if self.phase == "hold":
            fleet = self.fleet
            self.controller.reset(fleet.pos, fleet.vel, fleet.att[:, 2], fleet.att)
            self._hold_since = None
            self._set_phase("formation")

    def abort(self) -> None:
        """Stop the mission: phase 'land' (the caller's `land()` or the next `step()` lands every vehicle)."""
        if self.phase in ("launch", "formation", "hold"):
            self.result.events.append("aborted by the operator")
            self._set_phase("land")

    def set_goal(self, goal: np.ndarray) -> None:
        """Move the leader's goal (3,) ENU m live."""
        self.controller.set_goal(np.asarray(goal, dtype=float))
        self._hold_since = None
        self.result.events.append(f"goal moved to {np.round(goal, 2).tolist()}")

    def set_formation(self, shape: str, spacing: float | None = None) -> None:
        """Reshape in flight (inter-UAV avoidance stays active while vehicles change slots)."""
        self.shape = (shape, spacing)
        alive = self.fleet.alive
        self.controller.set_offsets(live_offsets(self.mission, alive, self.controller.leader, shape, spacing))
        if self.phase in ("formation", "hold"):
            self._assign_slots()
        self._hold_since = None
        self.result.events.append(f"formation changed to {shape} {spacing or ''}".strip())

    # ----- tick-driven launch and landing (console) -----

    def _launch_tick(self) -> None:
        if self.launched():
            self._enter_formation()
            return
        t0 = self._launch_since if self._launch_since is not None else self.vehicle_time()
        self._launch_since = t0
        timeout = self.mission.run.takeoff_timeout_s
        if self.vehicle_time() - t0 > timeout:
            self.result.events.append(
                f"timed out after {timeout:g} s waiting for every vehicle at its takeoff altitude"
            )
            self._set_phase("land")

    def _landing_tick(self) -> None:
        fleet, t = self.fleet, self.vehicle_time()
        if self._land_since is None:
            self._land_since = t
            self._command_landing()
        if not bool((fleet.armed & fleet.alive).any()):
            self._set_phase("done")
        elif t - self._land_since > self.mission.run.land_timeout_s:
            self.result.events.append(
                f"timed out after {self.mission.run.land_timeout_s:g} s waiting for every vehicle disarmed "
                "after landing"
            )
            self._set_phase("done")

    def _hold_tick(self) -> None:
        """Brake (target: where the vehicle is) until slower than HOLD_LATCH_SPEED, then hold that point.

        Re-targeting the current position on every tick would let the autopilot's velocity integrator,
        wound up while braking, drift the vehicle back; a fixed point is held by its position loop."""
        fleet = self.fleet
        pos, vel, yaw = fleet.pos, fleet.vel, fleet.att[:, 2]
        for i in np.flatnonzero(fleet.alive & np.isfinite(pos).all(axis=1)):
            latched = bool(np.isfinite(self._hold_points[i]).all())
            if not latched and np.linalg.norm(vel[i]) < HOLD_LATCH_SPEED:
                self._hold_points[i], latched = pos[i], True
            target = self._hold_points[i] if latched else pos[i]
            fleet.vehicle(int(i)).send_position_target(
                target, yaw=float(yaw[i]) if np.isfinite(yaw[i]) else None
            )

    def _command_landing(self) -> None:
        try:
            self.fleet.land_all()
        except LinkError as exc:
            self.result.events.append(f"landing: {exc}")

    # ----- formation tick -----

    def _formation_tick(self) -> None:
        fleet, run, ctl = self.fleet, self.mission.run, self.controller
        t = self.vehicle_time()
        self.result.t_formation_end = t
        pos, vel, att = fleet.pos, fleet.vel, fleet.att
        verdict = self._assess_telemetry(t, pos, vel)
        ctl.set_degraded(verdict.speed_scale, verdict.spacing_scale)
        # a vehicle whose state is not finite (broken telemetry) gets no command this tick, as if lost; a held
        # one brakes on its own autopilot
        finite = cast(NDArray[np.bool_], np.isfinite(np.hstack((pos, vel, att))).all(axis=1))  # (N,)
        active = fleet.alive & finite & ~verdict.held
        ghosts, ghost_radii = self._place_lost(t)
        centres = np.array([o.center_at(t) for o in self.mission.obstacles]).reshape(-1, 3)
        centres, radii = np.vstack([centres, ghosts]), np.concatenate([self._obstacle_radii, ghost_radii])
        cmd = ctl.tick(t, verdict.pos, vel, att, centres, radii, active)
        # ArduCopter adds its own 1/cos(tilt) to guided thrust when ATC_ANGLE_BOOST is on: not twice
        acc = ardupilot.unboosted_thrust(cmd.thrust_acc, att[:, 0], att[:, 1], self.angle_boost)
        thrust = ardupilot.thrust_from_acc(np.nan_to_num(acc), self.hover, G)
        roll, pitch, yaw, thrust, limited = guard_attitude_commands(
            cmd.roll_d,
            cmd.pitch_d,
            cmd.yaw_d,
            thrust,
            verdict.pos,
            att[:, 2],
            self.hover,
            self.command_limits,
            vel=vel,
        )
        self.commands_limited += int(np.count_nonzero(limited & active))
        fleet.send_attitude_targets(roll, pitch, yaw, thrust, mask=active)
        for i in np.flatnonzero(verdict.held & fleet.alive):
            fleet.vehicle(int(i)).send_velocity_target(
                np.zeros(3), yaw=float(att[i, 2]) if finite[i] else None
            )
        self.last_command = cmd
        self.result.ticks += 1
        if self.record is not None:
            self.record.write_tick(t, self.phase, pos, vel, att, cmd, thrust, active)
        targets = np.array(cmd.slots, dtype=float)
        targets[ctl.leader] = ctl.waypoints[-1]
        self.result.final_targets = targets
        self.result.leader, self.result.offsets = ctl.leader, ctl.offsets
        self._note_formation(t, fleet.alive)
        errors = np.linalg.norm(pos - targets, axis=1)
        followers = active.copy()
        followers[ctl.leader] = False
        self.formation_rms = math.sqrt(float(np.mean(errors[followers] ** 2))) if followers.any() else 0.0
        last_leg = cmd.waypoint_index == len(ctl.waypoints) - 1
        if last_leg and active.any() and bool((errors[active] <= run.goal_tolerance_m).all()):
            self._hold_since = t if self._hold_since is None else self._hold_since
            if t - self._hold_since >= run.hold_s:
                self.result.arrived = True
                self.result.t_arrival = self._hold_since
                self._set_phase("land")
                return
        else:
            self._hold_since = None
        self._report_progress(t - (self.result.t_formation_start or t), cmd)
        if t - (self.result.t_formation_start or t) > run.time_limit_s:
            self.result.events.append(f"time limit {run.time_limit_s:g} s reached before arrival")
            self._set_phase("land")

    def slots_assignable(self) -> bool:
        """Whether followers may swap slots: `formation.assign_slots` and no vehicle pins a slot or target."""
        m = self.mission
        return m.formation.assign_slots and all(v.slot is None and v.target is None for v in m.vehicles)

    def _assign_slots(self) -> None:
        """Give the current slots to the live followers by least total travel (formation.assign_slots) from
        where they are now, the leader's slot frame as it is now."""
        if not self.slots_assignable():
            return
        ctl, fleet = self.controller, self.fleet
        movable = fleet.alive & np.isfinite(fleet.pos).all(axis=1)
        movable[ctl.leader] = False
        assert ctl.heading is not None
        offsets = assign_slots(fleet.pos, fleet.pos[ctl.leader], ctl.heading.psi, ctl.offsets, movable)
        if not np.array_equal(offsets, ctl.offsets):
            ctl.set_offsets(offsets)
            self.result.events.append("slots assigned by least travel")

    def _place_lost(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Where lost vehicles have probably flown on their failsafe: (K, 3) ENU m and (K,) m, spheres the
        others avoid as moving obstacles (each also repels them from its centre). A vehicle heard again is
        flown from its measured state."""
        for i in [i for i in self._lost_tracks if self.fleet.alive[i]]:
            del self._lost_tracks[i]
        p = self.mission.safety.telemetry
        centres, radii = np.zeros((0, 3)), np.zeros(0)
        for i, track in self._lost_tracks.items():
            here = predicted_position(track, t)
            moving = (here - predicted_position(track, t - 0.1)) / 0.1
            self.controller.place_uncommanded(i, here, moving)
            radius = avoidance_radius(track, t, p.lost_radius, p.lost_radius_growth, p.lost_radius_max)
            centres, radii = np.vstack([centres, here]), np.append(radii, radius)
        return centres, radii

    def _track_lost(self, i: int) -> None:
        """Start predicting lost vehicle i from its last report (gcs_swarm.guidance.lost_vehicles)."""
        st = self.fleet.state
        pos, vel = self.fleet.pos[i], self.fleet.vel[i]
        if st.position_ms[i] < 0 or not (np.isfinite(pos).all() and np.isfinite(vel).all()):
            return  # never reported a position: nothing to predict from
        timeout_s, speed_cm_s, rtl_alt_cm = self.failsafe_params[i]
        home = self._home[i] if np.isfinite(self._home[i]).all() else pos
        self._lost_tracks[i] = LostTrack(
            t_last=float(st.position_ms[i]) / 1000.0,
            pos=pos,
            vel=vel,
            home=home,
            action=self.mission.safety.gcs_failsafe,
            failsafe_s=float(timeout_s),
            speed=max(float(speed_cm_s) / 100.0, 0.1),
            rtl_alt=max(float(rtl_alt_cm) / 100.0, 0.0),
        )

    def _note_formation(self, t: float, alive: np.ndarray) -> None:
        """Append the formation flown (leader, offsets with degraded widening) to the timeline on a change."""
        ctl, timeline = self.controller, self.result.formation_timeline
        offsets = np.where(alive[:, None], ctl.offsets * ctl.spacing_scale, np.nan)
        if (
            timeline
            and timeline[-1][1] == ctl.leader
            and np.array_equal(timeline[-1][2], offsets, equal_nan=True)
        ):
            return
        timeline.append((t, ctl.leader, offsets))

    def telemetry_age(self) -> np.ndarray:
        """(N,) s: each vehicle's newest time_boot_ms minus that of its latest position (inf before one)."""
        st = self.fleet.state
        age = (st.time_ms - st.position_ms).astype(float) / 1000.0
        return np.where(st.position_ms >= 0, age, np.inf)

    def _assess_telemetry(self, t: float, pos: np.ndarray, vel: np.ndarray) -> TelemetryAssessment:
        """Predict, degrade or hold on stale telemetry (gcs_swarm.guidance.degradation); events on changes."""
        alive, names = self.fleet.alive, self.fleet.names
        verdict = self.telemetry.assess(t, pos, vel, self.telemetry_age(), alive, self.controller.leader)
        dt = 0.0 if self._last_tick_t is None else max(0.0, t - self._last_tick_t)
        self._last_tick_t = t
        ages = verdict.age[alive & np.isfinite(verdict.age)]
        if ages.size:
            self.result.max_telemetry_age_s = max(self.result.max_telemetry_age_s, float(ages.max()))
        if verdict.degraded:
            self.result.degraded_s += dt
        if verdict.degraded != self._degraded:
            p = self.mission.safety.telemetry
            scales = f"speed x{p.degraded_speed:g}, spacing x{p.degraded_spacing:g}"
            text = (
                f"stale telemetry: degraded flight ({scales})"
                if verdict.degraded
                else "telemetry fresh again: normal flight"
            )
            self.result.events.append(f"t={t:.2f} s {text}")
            self.progress(f"! {text}")
        for i in np.flatnonzero(verdict.held != self._held):
            if verdict.held[i]:
                self.result.holds += 1
                old = not verdict.age[i] <= self.mission.safety.telemetry.hold_s
                why = f"telemetry {verdict.age[i]:.2f} s old" if old else "the leader's telemetry is stale"
                text = f"{names[i]} held: {why}"
            elif alive[i]:
                text = f"{names[i]} rejoins: telemetry fresh again"
            else:
                continue  # lost: the re-form event tells
            self.result.events.append(f"t={t:.2f} s {text}")
            self.progress(f"! {text}")
        self._degraded, self._held = verdict.degraded, verdict.held.copy()
        return verdict

    # ----- helpers -----

    def vehicle_time(self) -> float:
        """Vehicle time in s: the newest time_boot_ms among live vehicles."""
        times = self.fleet.time_ms
        alive = times[self.fleet.alive]
        return float(alive.max() if alive.size else times.max()) / 1000.0

    def _note_lost(self) -> None:
        newly_lost = False
        for i, name in enumerate(self.fleet.names):
            if not self.fleet.alive[i] and name not in self.result.lost:
                self.result.lost.append(name)
                self.result.lost_at[name] = self.vehicle_time()
                self.result.events.append(f"{name} lost")
                self.progress(f"! {name} lost: the rest keep flying")
                newly_lost = True
                if self.phase in ("formation", "hold"):
                    self._track_lost(i)
        if newly_lost and self.phase in ("formation", "hold") and self.fleet.alive.any():
            self._reform()

    def _reform(self) -> None:
        """Close the gaps a lost vehicle leaves (its last known position keeps repelling the others); a lost
        leader hands the lead to the live vehicle with the lowest index, which flies on to the same goal."""
        fleet, ctl = self.fleet, self.controller
        alive = fleet.alive
        leader = ctl.leader if alive[ctl.leader] else int(np.flatnonzero(alive)[0])
        shape, spacing = self.shape
        offsets = live_offsets(self.mission, alive, leader, shape, spacing)
        if leader == ctl.leader:
            ctl.set_offsets(offsets)
            self._assign_slots()
            self.result.events.append("formation re-formed without the lost vehicles")
            return
        remaining = ctl.waypoints[ctl.waypoint_index :]
        self.controller = build_controller(self.mission, leader=leader, offsets=offsets)
        self.controller.set_goal_waypoints(remaining)
        self.controller.reset(fleet.pos, fleet.vel, fleet.att[:, 2], fleet.att)
        self._assign_slots()
        self._hold_since = None
        text = f"leader lost: {fleet.names[leader]} takes the lead"
        self.result.events.append(text)
        self.progress(f"! {text}")

    def _set_phase(self, name: str) -> None:
        self.phase = name
        self.result.phase_reached = name
        self.progress(f"phase {name}")

    def _report_progress(self, t: float, cmd: Command) -> None:
        now = time.monotonic()
        if now - self._last_progress_wall < self.progress_period_s:
            return
        self._last_progress_wall = now
        self.progress(
            f"t={t:7.1f} s  leader to goal {cmd.leader_goal_distance:8.1f} m  "
            f"formation rms {self.formation_rms:6.2f} m"
        )
