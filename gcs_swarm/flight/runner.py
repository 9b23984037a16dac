"""The mission run: connect -> preflight -> launch -> formation flight -> arrival -> land -> report.

`MissionRunner.run()` flies the whole mission (the `run` command). The same object is tick-driven for the
operator console: `begin()` preflights and commands the launch, `step()` handles one telemetry tick in the
current phase (climb, formation flight, hold, landing), `idle()` keeps the links served while nothing flies,
and `hold()`, `resume()`, `abort()`, `set_goal()`, `set_formation()` change what the next ticks do. One tick
of formation flight = read the fleet's telemetry arrays, FleetController.tick, send SET_ATTITUDE_TARGET to
every active vehicle (gcs_swarm.flight.formation_tick).
Ticks are clocked by vehicle time (telemetry time_boot_ms), so the same code flies in real time against
hardware and in lockstep against the simulator.

This module is the state machine; each phase's work lives in its own module: preflight, launch, reattach
(vehicles found flying), formation_tick, formation_plan (guidance set-up, re-forming), stale_telemetry,
lost_vehicles, landing (and the operator's hold).
"""

from __future__ import annotations

import logging
import math
import os
import signal
import time
from collections.abc import Callable

import numpy as np

from gcs_swarm.flight import reattach
from gcs_swarm.flight.formation_plan import (
    assign_slots_by_travel,
    build_controller,
    live_offsets,
    note_formation,
)
from gcs_swarm.flight.formation_tick import end_targets, formation_rms, send_formation_tick
from gcs_swarm.flight.jit_watch import JitWatch
from gcs_swarm.flight.landing import PositionHold, command_landing, land_and_wait, landed
from gcs_swarm.flight.launch import command_launch, home_positions, launched
from gcs_swarm.flight.legs import LegTracker
from gcs_swarm.flight.lost_vehicles import LostVehicleTracks
from gcs_swarm.flight.phase import Phase
from gcs_swarm.flight.preflight import VehicleSetup, preflight_fleet
from gcs_swarm.flight.result import FlightResult
from gcs_swarm.flight.run_record import RunRecord
from gcs_swarm.flight.stale_telemetry import StaleTelemetryWatch
from gcs_swarm.flight.takeover import TakeoverWatch
from gcs_swarm.flight.tick_timing import ASSESS, RECORD, SEND, MissedFramesByPhase, TickTiming
from gcs_swarm.guidance.fleet_controller import Command
from gcs_swarm.guidance.obstacles import centres_at
from gcs_swarm.guidance.params import G
from gcs_swarm.link.autopilots import formation_mode, launch_mode, takeoff_mode
from gcs_swarm.link.command_limits import CommandLimits, GuardFence
from gcs_swarm.link.command_mode import ATTITUDE
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.flight_params import FlightParams
from gcs_swarm.mission import Mission

log = logging.getLogger(__name__)


class MissionRunner:
    """Flies one mission over a Fleet. `progress` receives one-line status updates for the operator."""

    def __init__(
        self,
        mission: Mission,
        fleet: Fleet,
        record: RunRecord | None,
        progress: Callable[[str], None],
        progress_period_s: float = 1.0,
    ) -> None:
        n = len(mission.vehicles)
        self.mission = mission
        self.fleet = fleet
        self.record = record
        self.progress = progress
        self.progress_period_s = progress_period_s
        self.result = FlightResult()
        self.phase = Phase.CONNECT
        self.jit_watch = JitWatch()  # numba's work once the vehicles arm: flight.json jit_after_arming
        self.setup = VehicleSetup.assumed(n)  # hover thrust, angle boost, failsafe params: read in preflight
        self.controller = build_controller(mission)
        # live reshape (console, a leg's formation): shape and spacing; None: the mission's
        self.shape: tuple[str | None, float | None] = (None, None)
        self.legs = LegTracker(mission.legs)  # the route's legs (mission key `legs`)
        self.command_limits = CommandLimits(
            tilt_max=math.radians(mission.limits.tilt_max_deg),
            thrust_max_g=mission.limits.thrust_max_g,
            min_altitude=mission.safety.min_altitude,
            geofence_radius=mission.safety.geofence_radius,
            geofence_max_alt=mission.safety.geofence_max_alt,
            # the site fence, buildings and trees; the braking margin assumes full-tilt braking, g tan(tilt)
            fence=GuardFence.of(
                mission.fence.polygon,
                mission.fence.exclusions,
                G * math.tan(math.radians(mission.limits.tilt_max_deg)),
                mission.prisms,
                mission.cylinders,
            ),
        )
        self.commands_limited = 0  # vehicle-ticks whose command the final guard had to change
        self.last_command: Command | None = None
        self.formation_rms = math.nan
        self._hold_since: float | None = None  # vehicle time s since which every vehicle is at its target
        self._launch_since: float | None = None  # vehicle time of the tick-driven launch (console)
        self._land_since: float | None = None  # vehicle time LAND was commanded by a landing tick (console)
        self.position_hold = PositionHold(n)
        self._last_progress_wall = 0.0
        self._obstacle_radii = np.array([o.radius for o in mission.obstacles], dtype=float)
        self._obstacle_centres0 = np.array([o.center for o in mission.obstacles], dtype=float).reshape(-1, 3)
        self._obstacle_velocities = np.array([o.velocity for o in mission.obstacles], dtype=float).reshape(
            -1, 3
        )
        # the watches look `self.progress` up at each call: the console swaps it after construction
        self.telemetry = StaleTelemetryWatch(
            mission.safety.telemetry, n, self.result, lambda text: self.progress(text)
        )
        self._home = np.full((n, 3), np.nan)  # (N, 3) ENU m where each took off
        self._lost = LostVehicleTracks()
        # vehicles someone else switched out of GUIDED (flight.takeover); console `rejoin` hands one back
        self.takeover = TakeoverWatch(fleet, self.result, lambda text: self.progress(text))
        # vehicle s the others hold after the leader was taken over before they land; None: until the
        # operator decides (console `leader NAME` or `rejoin NAME`)
        self.leader_takeover_timeout_s: float | None = mission.run.leader_takeover_timeout_s
        self._leader_taken_since: float | None = None  # vehicle s since when the leader is taken over
        self._held_for_leader = False  # the hold was entered because the leader was taken over
        self.tick_latency_s: list[float] = []  # wall s from a complete telemetry tick to its last command out
        self.tick_timing = TickTiming()  # where each formation tick's wall time went (flight.tick_timing)
        self.frames_missed = MissedFramesByPhase(fleet.names, fleet.state.frames_missed)
        self.flight_params = FlightParams(fleet)  # what the run sets on the vehicles, restored at the end
        # vehicle time (s) at which this process kills itself with SIGKILL: rehearses a ground-station crash
        # at an exact moment (`gcs-swarm run --crash-at`, docs/reliability.md); None: never
        self.crash_at_s: float | None = None
        # what to do with vehicles found flying at the start (`gcs-swarm run --airborne`): "finish" the
        # mission from where they are, "land" them, or None: refuse and say so
        self.airborne: str | None = None
        # called after each step() and idle(), once the tick's commands are out and its frame answered: a
        # watcher copies what it shows there (the live page, gcs_swarm.web.live), never inside the tick
        self.on_tick: Callable[[], None] | None = None

    # ----- the whole mission -----

    def run(self) -> FlightResult:
        """All phases; PreflightError / LinkError before launch, FlightResult after. Vehicles found already
        flying (a ground station that crashed left them holding) are handled as `self.airborne` says."""
        self.connect()
        expect_flying = self.mission.run.airborne_start  # the simulator starts them in the air on purpose
        if not expect_flying:
            reattach.stop_unflown(self.fleet, self.result.events, self.progress, self.takeover)
        self.preflight()
        flying = reattach.flying(self.fleet)
        if flying.any() and not expect_flying:
            self._reattach(flying)
            if self.phase is Phase.DONE:
                return self.result
        else:
            self.launch()
        self.start_formation()
        while self.phase.in_formation:
            self.step()
        self.land()
        return self.result

    def connect(self, timeout_s: float = 30.0) -> None:
        """Wait up to timeout_s for every vehicle's HEARTBEAT (LinkError naming the silent ones)."""
        self._set_phase(Phase.CONNECT)
        self.fleet.connect(timeout_s=timeout_s)
        self.result.autopilots = {link.name: link.channel.autopilot.name for link in self.fleet.links}

    def preflight(self) -> None:
        """Wait for position estimates and pre-arm health; set and verify params; hover thrust; streams."""
        self._set_phase(Phase.PREFLIGHT)
        plan = self.fleet.command_plan
        if plan is not None:  # chosen from the link budget before the fleet connected (link.command_mode)
            self.result.command_mode = plan.as_json()
            self.result.events.append(plan.text())
            self.progress(plan.text())
        self.setup = preflight_fleet(
            self.fleet, self.mission, self.flight_params, self.result.events, self.progress
        )

    def launch(self) -> None:
        """GUIDED, arm, take off to the formation altitude (each vehicle plus its slot's dz); a vehicle taken
        over during the climb is not waited for."""
        self.command_launch()
        if self.mission.run.airborne_start:
            return
        self.fleet.wait_until(
            self._climbed,
            timeout_s=self.mission.run.takeoff_timeout_s,
            what="every vehicle at its takeoff altitude",
        )

    def _climbed(self) -> bool:
        """Every vehicle not taken over is at its takeoff altitude. Vehicles switched out of GUIDED since the
        launch commanded it are marked taken over first (flight.takeover): the ground station's GUIDED is
        confirmed by each HEARTBEAT before command_launch returns, and arming and takeoff change no mode, so
        only someone else's switch counts."""
        self.takeover.detect(self.vehicle_time())
        return launched(self.fleet, self.mission, ~self.takeover.taken)

    def command_launch(self) -> None:
        """Phase 'launch': each autopilot's launch mode, arm and take off (each acknowledged; the modes the
        takeoff passes through on its own are ours too); the climb itself is not awaited."""
        self._set_phase(Phase.LAUNCH)
        self.jit_watch.start()
        self._home = home_positions(self.fleet, self.mission)
        if self.mission.run.airborne_start:
            self.takeover.commanded(formation_mode)
        else:
            self.takeover.commanded(launch_mode, passing=takeoff_mode)
        command_launch(self.fleet, self.mission)

    def _reattach(self, flying: np.ndarray) -> None:
        """Vehicles are already in the air: `airborne` "finish" takes them back into GUIDED and flies the
        mission on from where they are; "land" lands them where they are and ends the run; None refuses
        with what was found (PreflightError)."""
        found = reattach.describe_flying(self.fleet, flying, self._home)
        self.result.events.append(f"vehicles already flying: {found}")
        reattach.check_airborne_choice(self.fleet, flying, self.airborne, found)
        if self.airborne == "land":
            self.progress(f"vehicles already flying: {found}: landing them")
            self.result.reattached = "land"
            self._home = self.fleet.pos
            self.land()
            self.result.landed_all = landed(self.fleet, ~self.takeover.taken)
            return
        self.progress(f"vehicles already flying: {found}: finishing the mission from here")
        self.result.reattached = "finish"
        self._set_phase(Phase.LAUNCH)
        self.jit_watch.start()
        self._home = self.fleet.pos
        self._home[:, 2] = 0.0
        reattach.take_back(self.fleet, self.takeover)

    def start_formation(self) -> None:
        """Bring every vehicle into its formation mode (`_take_control`: PX4's OFFBOARD needs a setpoint
        stream first, streamed here, before the first formation tick, while the vehicles still hold in
        their launch mode), then initialise the guidance at the measured state and fly the first tick."""
        if not self._take_control():
            return
        self.tick_timing.begin(self.fleet)
        if not self.fleet.wait_tick(timeout_s=10.0):
            raise LinkError("no telemetry tick arrived after launch")
        self._enter_formation()
        # act on the tick just consumed, then answer it (lockstep rule); a leader taken over during the
        # climb: the others hold
        if self.phase is Phase.FORMATION:
            self._formation_tick()
        else:
            self.position_hold.tick(self.fleet, self.takeover.flown)
        self.fleet.answer_frame()
        self.tick_timing.end(self.fleet)

    def _take_control(self) -> bool:
        """Vehicles that launch in another mode than their formation mode (PX4 holds in LOITER after its
        takeoff) enter it now (Fleet.take_control_all: OFFBOARD after a setpoint stream); an ArduCopter
        launched in GUIDED already flies in it (one that left it was taken over). A refusal lands the
        fleet: False, phase land."""
        fleet = self.fleet
        separate = np.array([d.launch_mode != d.formation_mode for d in fleet.dialects], dtype=bool)
        waiting = self.takeover.flown & separate & ~fleet.in_mode(formation_mode)
        rows = [int(i) for i in np.flatnonzero(waiting)]
        if not rows:
            return True
        self.takeover.commanded(formation_mode, rows)
        try:
            fleet.take_control_all(rows)
            fleet.answer_frame()  # the frame the mode change ended on: the formation starts on the next one
        except LinkError as exc:
            self.result.events.append(f"formation not started: {exc}")
            self.progress(f"! formation not started: {exc}")
            self._set_phase(Phase.LAND)
            return False
        return True

    def _enter_formation(self) -> None:
        fleet = self.fleet
        self.controller.reset(fleet.pos, fleet.vel, fleet.att[:, 2], fleet.att)
        self._assign_slots()
        self.telemetry.reset()
        t = self.vehicle_time()
        self.result.t_formation_start = t
        self._set_phase(Phase.FORMATION)
        self._fly_without([int(i) for i in np.flatnonzero(self.takeover.taken)], t)  # taken during the climb

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
        self.tick_timing.begin(fleet)
        if not fleet.wait_tick(timeout_s=timeout_s):
            fleet.answer_frame()  # a silent vehicle must not stall the others' lockstep frames
            self._note_lost()
            if self.phase.in_formation and not fleet.alive.any():
                self.result.events.append("every vehicle stopped answering")
                self._set_phase(Phase.LAND)
            return False
        tick_in = time.perf_counter()
        if self.crash_at_s is not None and self.vehicle_time() >= self.crash_at_s:
            log.info(
                "vehicle time %.3f s: killing the ground station (--crash-at rehearsal)", self.crash_at_s
            )
            os.kill(os.getpid(), signal.SIGKILL)  # rehearsal of a ground-station crash (--crash-at)
        self._note_lost()
        if self.phase.airborne:
            self._note_takeovers()
        if self.phase is Phase.LAUNCH:
            self._launch_tick()
        elif self.phase is Phase.FORMATION:
            self._formation_tick()
            self.tick_latency_s.append(time.perf_counter() - tick_in)
        elif self.phase is Phase.HOLD:
            self.position_hold.tick(fleet, self.takeover.flown)
            self._wait_for_leader_decision()
        elif self.phase is Phase.LAND:
            self._landing_tick()
        fleet.answer_frame()  # vehicles not commanded this tick
        self.tick_timing.end(fleet)
        if self.on_tick is not None:
            self.on_tick()
        return True

    def timing_summary(self) -> dict[str, object]:
        """flight.json's tick timing: the worst formation tick, the time per phase and the frames missed
        (flight.tick_timing)."""
        return {
            **self.tick_timing.summary(),
            "frames_missed": self.frames_missed.summary(),
            "jit_after_arming": self.jit_watch.figures(),
        }

    def idle(self, timeout_s: float = 0.02) -> None:
        """Keep the links served while the mission is not flying (before `begin`, after 'done'): receive for
        up to timeout_s, note lost vehicles, answer every new lockstep frame."""
        self.fleet.pump(timeout_s)
        self._note_lost()
        self.fleet.answer_frame()
        if self.on_tick is not None:
            self.on_tick()

    def land(self) -> None:
        """LAND every reachable vehicle and wait until they disarm (auto-disarm after touchdown)."""
        if self.phase is not Phase.LAND:
            self._set_phase(Phase.LAND)
        ours = ~self.takeover.taken  # vehicles taken over are left to their operator
        self.takeover.commanded_landing(ours & self.fleet.alive)
        land_and_wait(self.fleet, self.mission.run.land_timeout_s, self.result.events, ours)
        self._set_phase(Phase.DONE)

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
        if self.phase is Phase.FORMATION:
            self.position_hold.clear()
            self._set_phase(Phase.HOLD)

    def resume(self) -> None:
        """Back to formation flight from the current state; ValueError while the leader is taken over
        (promote another with `promote` or hand it back with `rejoin` first)."""
        if self.phase is Phase.HOLD:
            self._check_leader_flown()
            fleet = self.fleet
            self.controller.reset(fleet.pos, fleet.vel, fleet.att[:, 2], fleet.att)
            self._hold_since = None
            self._set_phase(Phase.FORMATION)

    def abort(self) -> None:
        """Stop the mission: phase 'land' (the caller's `land()` or the next `step()` lands every vehicle)."""
        if self.phase.airborne:
            self.result.events.append("aborted by the operator")
            self._set_phase(Phase.LAND)

    def set_goal(self, goal: np.ndarray) -> None:
        """Move the leader's goal (3,) ENU m live."""
        self.controller.set_goal(np.asarray(goal, dtype=float))
        self.legs.ended = True  # the route is the operator's now: the leg flown keeps its formation and speed
        self._hold_since = None
        self.result.events.append(f"goal moved to {np.round(goal, 2).tolist()}")

    def set_formation(self, shape: str, spacing: float | None = None) -> None:
        """Reshape in flight (inter-UAV avoidance stays active while vehicles change slots)."""
        self.shape = (shape, spacing)
        flown = self.takeover.flown
        self.controller.set_offsets(live_offsets(self.mission, flown, self.controller.leader, shape, spacing))
        if self.phase.in_formation:
            self._assign_slots()
        self._hold_since = None
        self.result.events.append(f"formation changed to {shape} {spacing or ''}".strip())

    # ----- tick-driven launch and landing (console) -----

    def _launch_tick(self) -> None:
        if launched(self.fleet, self.mission, ~self.takeover.taken):
            if self._take_control():
                self._enter_formation()
            return
        t0 = self._launch_since if self._launch_since is not None else self.vehicle_time()
        self._launch_since = t0
        timeout = self.mission.run.takeoff_timeout_s
        if self.vehicle_time() - t0 > timeout:
            self.result.events.append(
                f"timed out after {timeout:g} s waiting for every vehicle at its takeoff altitude"
            )
            self._set_phase(Phase.LAND)

    def _landing_tick(self) -> None:
        t = self.vehicle_time()
        ours = ~self.takeover.taken  # vehicles taken over are left to their operator
        if self._land_since is None:
            self._land_since = t
            self.takeover.commanded_landing(ours & self.fleet.alive)
            command_landing(self.fleet, self.result.events, ours)
        if landed(self.fleet, ours):
            self._set_phase(Phase.DONE)
        elif t - self._land_since > self.mission.run.land_timeout_s:
            self.result.events.append(
                f"timed out after {self.mission.run.land_timeout_s:g} s waiting for every vehicle disarmed "
                "after landing"
            )
            self._set_phase(Phase.DONE)

    # ----- formation tick -----

    def _formation_tick(self) -> None:
        fleet, run, ctl, timing = self.fleet, self.mission.run, self.controller, self.tick_timing
        t = self.vehicle_time()
        timing.at(t)
        self.result.t_formation_end = t
        pos, vel, att = fleet.pos, fleet.vel, fleet.att
        verdict = self.telemetry.assess(fleet, t, pos, vel, ctl.leader)
        ctl.set_degraded(verdict.speed_scale, verdict.spacing_scale)
        telemetry = self.mission.safety.telemetry
        ghosts, ghost_radii = self._lost.place(t, fleet.alive, ctl, telemetry)
        taken, taken_radii = self.takeover.place(ctl, telemetry.lost_radius)  # moving obstacles, as measured
        centres = centres_at(self._obstacle_centres0, self._obstacle_velocities, t)  # Obstacle.center_at
        obstacles = (
            np.vstack([centres, ghosts, taken]),
            np.concatenate([self._obstacle_radii, ghost_radii, taken_radii]),
        )
        flown = self.takeover.flown
        timing.mark(ASSESS)
        sent = send_formation_tick(
            fleet, ctl, t, (pos, vel, att), verdict, obstacles, self.setup, self.command_limits, flown, timing
        )
        timing.mark(SEND)
        cmd, active = sent.command, sent.active
        self.commands_limited += sent.limited
        self.last_command = cmd
        self.result.ticks += 1
        if self.record is not None:
            self.record.write_tick(t, self.phase, pos, vel, att, cmd, sent.thrust, active)
        timing.mark(RECORD)
        targets = end_targets(cmd, ctl)
        self.result.final_targets = targets
        self.result.leader, self.result.offsets = ctl.leader, ctl.offsets
        note_formation(self.result.formation_timeline, t, ctl, flown)
        changes = ctl.drain_shape_changes()  # reshapes around obstacles
        self.result.reshapes += [change.as_json() for change in changes]
        self.result.detours += [detour.as_json() for detour in ctl.drain_detours()]  # round gaps
        for event in [change.sentence for change in changes] + ctl.drain_events():  # and the leader's pace
            self.result.events.append(event)
            self.progress(event)
        leg_index = self.legs.due(cmd.waypoint_index)
        if leg_index is not None:
            self._start_leg(t, leg_index)
        errors = np.linalg.norm(pos - targets, axis=1)
        self.formation_rms = formation_rms(errors, active, ctl.leader)
        last_waypoint = ctl.on_last_point  # no via point of the route before it
        at_goal = bool((errors[active] <= run.goal_tolerance_m).all()) and ctl.shape_settled(t)
        if last_waypoint and active.any() and at_goal:
            self._hold_since = t if self._hold_since is None else self._hold_since
            if t - self._hold_since >= run.hold_s:
                self.result.arrived = True
                self.result.t_arrival = self._hold_since
                self._set_phase(Phase.LAND)
                return
        else:
            self._hold_since = None
        self._report_progress(t - (self.result.t_formation_start or t), cmd)
        if t - (self.result.t_formation_start or t) > run.time_limit_s:
            self.result.events.append(f"time limit {run.time_limit_s:g} s reached before arrival")
            self._set_phase(Phase.LAND)

    def _start_leg(self, t: float, k: int) -> None:
        """The leader starts leg k of the mission's route (vehicle time t s): its formation (reached by a
        smooth reshape, slots reassigned) and the leader's speed cap from now on; an event and a row of
        flight.json's legs."""
        leg, ctl, form = self.mission.legs[k], self.controller, self.mission.formation
        shape, spacing = self.shape
        if (leg.shape, leg.spacing) != (shape or form.shape, spacing or form.spacing):
            self.shape = (leg.shape, leg.spacing)
            flown = self.takeover.flown
            ctl.set_offsets(live_offsets(self.mission, flown, ctl.leader, leg.shape, leg.spacing))
            self._assign_slots()
            self._hold_since = None
        ctl.set_leader_speed(leg.speed)
        row: dict[str, float | int | str] = {"index": k, "name": leg.name, "t_s": round(t, 3)}
        row |= {"shape": leg.shape, "spacing_m": leg.spacing, "speed_m_s": leg.speed}
        row["first_waypoint"] = leg.first
        self.result.legs.append(row)
        text = (
            f"t={t:.2f} s leg {k + 1} of {len(self.mission.legs)} ({leg.name}): {leg.shape} "
            f"{leg.spacing:g} m apart, leader at most {leg.speed:g} m/s"
        )
        self.result.events.append(text)
        self.progress(text)

    def _assign_slots(self) -> None:
        """Give the current slots to the live followers by the shortest longest move from where they are."""
        rule = assign_slots_by_travel(self.mission, self.controller, self.fleet, self.takeover.flown)
        if rule is not None:
            self.result.events.append(f"slots assigned by {rule}")

    # ----- helpers -----

    def vehicle_time(self) -> float:
        """Vehicle time in s: the newest time_boot_ms among live vehicles."""
        times = self.fleet.time_ms
        alive = times[self.fleet.alive]
        return float(alive.max() if alive.size else times.max()) / 1000.0

    def _note_lost(self) -> None:
        alive = self.fleet.alive
        if alive.all():  # every tick of a healthy flight: nothing to note
            return
        newly_lost = False
        for i, name in enumerate(self.fleet.names):
            if not alive[i] and name not in self.result.lost:
                self.result.lost.append(name)
                self.result.lost_at[name] = self.vehicle_time()
                self.result.events.append(f"{name} lost")
                self.progress(f"! {name} lost: the rest keep flying")
                newly_lost = True
                if self.phase.in_formation:
                    self._lost.start(
                        self.fleet,
                        i,
                        self._home[i],
                        self.setup.failsafe_params[i],
                        self.mission.safety.gcs_failsafe,
                    )
        if newly_lost and self.phase.in_formation and self.fleet.alive.any():
            self._reform()

    def _reform(self, change: str = "without the lost vehicles") -> None:
        """Close the gaps a lost vehicle (or one taken over) leaves (its last known position keeps repelling
        the others), or open one for a vehicle that rejoins; a lost leader hands the lead to the live vehicle
        with the lowest index, which flies on to the same goal. A leader taken over keeps the lead (the
        formation holds until the operator decides). `change` completes the event "formation re-formed"."""
        fleet, ctl = self.fleet, self.controller
        alive, flown = fleet.alive, self.takeover.flown
        leader = ctl.leader if alive[ctl.leader] else int(np.flatnonzero(flown if flown.any() else alive)[0])
        if leader == ctl.leader:
            shape, spacing = self.shape
            ctl.set_offsets(live_offsets(self.mission, flown, leader, shape, spacing))
            self._assign_slots()
            self.result.events.append(f"formation re-formed {change}")
            return
        self._pass_lead(leader, f"leader lost: {fleet.names[leader]} takes the lead")

    def _pass_lead(self, leader: int, text: str) -> None:
        """Vehicle `leader` leads from now on, flying on to the remaining waypoints; the slots are re-formed
        around it for the vehicles flown; `text` goes to the events and the progress line."""
        fleet, ctl = self.fleet, self.controller
        shape, spacing = self.shape
        offsets = live_offsets(self.mission, self.takeover.flown, leader, shape, spacing)
        remaining = ctl.waypoints[ctl.waypoint_index :]
        self.legs.rebase(ctl.waypoint_index)
        self.controller = build_controller(self.mission, leader=leader, offsets=offsets)
        self.controller.set_goal_waypoints(remaining)
        if self.legs.flown is not None:
            self.controller.set_leader_speed(self.legs.flown.speed)
        self.controller.reset(fleet.pos, fleet.vel, fleet.att[:, 2], fleet.att)
        self._assign_slots()
        self._hold_since = None
        self.result.events.append(text)
        self.progress(f"! {text}")

    # ----- operator takeover (flight.takeover) -----

    def _note_takeovers(self) -> None:
        """Vehicles switched out of the mode we commanded are no longer flown: the formation re-forms
        without them (each stays a moving obstacle); a leader taken over makes the others hold. During the
        climb they are only marked: the formation starts without them (_enter_formation)."""
        t = self.vehicle_time()
        taken = self.takeover.detect(t)
        if self.phase is not Phase.LAUNCH:
            self._fly_without(taken, t)

    def _fly_without(self, taken: list[int], t: float) -> None:
        """Re-form without the vehicles `taken` over (rows) at vehicle time t s; hold if the leader is one."""
        if not taken or not self.takeover.flown.any():
            return
        self._reform("without the vehicles taken over")
        if self.controller.leader in taken:
            self._leader_taken(t)

    def _leader_taken(self, t: float) -> None:
        name = self.fleet.names[self.controller.leader]
        self._leader_taken_since = t
        if self.phase is Phase.FORMATION:
            self._held_for_leader = True
            self.position_hold.clear()
            self._set_phase(Phase.HOLD)
        timeout = self.leader_takeover_timeout_s
        then = "" if timeout is None else f"; the others land after {timeout:g} s without a decision"
        decide = f"leader NAME promotes another, rejoin {name} hands it back"
        text = f"leader {name} taken over: the formation holds ({decide}){then}"
        self.result.events.append(f"t={t:.2f} s {text}")
        self.progress(f"! {text}")

    def _wait_for_leader_decision(self) -> None:
        """In hold with the leader taken over and nobody to decide (`gcs-swarm run`): land the others once
        leader_takeover_timeout_s has passed."""
        since, timeout = self._leader_taken_since, self.leader_takeover_timeout_s
        if since is None or timeout is None or self.vehicle_time() - since < timeout:
            return
        text = f"leader taken over and no decision within {timeout:g} s: landing the others"
        self.result.events.append(f"t={self.vehicle_time():.2f} s {text}")
        self.progress(f"! {text}")
        self._set_phase(Phase.LAND)

    def _check_leader_flown(self) -> None:
        if self._leader_taken_since is not None:
            name = self.fleet.names[self.controller.leader]
            raise ValueError(f"the leader {name} is taken over: leader NAME promotes another, rejoin {name}")

    def _decided(self) -> None:
        """The operator decided about a leader taken over: fly on if that is what the hold was for."""
        self._leader_taken_since = None
        if self._held_for_leader and self.phase is Phase.HOLD:
            self._held_for_leader = False
            self.resume()
        self._held_for_leader = False

    def promote(self, row: int) -> None:
        """Console `leader NAME`: vehicle `row` (flown: alive, not taken over) leads from now on, on to the
        remaining waypoints; a formation held for its leader taken over flies on. ValueError (one sentence)
        when it cannot."""
        name = self.fleet.names[row]
        if not self.phase.in_formation:
            raise ValueError(f"leader needs formation flight or hold; the mission is in phase {self.phase}")
        if row == self.controller.leader:
            raise ValueError(f"{name} already leads")
        if not self.takeover.flown[row]:
            why = "taken over (rejoin it first)" if self.takeover.taken[row] else "not answering"
            raise ValueError(f"{name} is {why}: it cannot lead")
        self._pass_lead(row, f"{name} promoted to leader by the operator")
        self._decided()

    def rejoin(self, row: int) -> None:
        """Console `rejoin NAME`: the operator hands vehicle `row` back: GUIDED (commanded and confirmed by
        its HEARTBEAT), then it is flown to its slot again (its guidance rows restart from its measured state
        at the next tick, FleetController's returning vehicles); a leader back in GUIDED leads again.
        ValueError (one sentence) when it is not taken over; LinkError when it refuses GUIDED (it stays
        taken over)."""
        name = self.fleet.names[row]
        if not self.phase.in_formation:
            raise ValueError(f"rejoin needs formation flight or hold; the mission is in phase {self.phase}")
        if not self.takeover.taken[row]:
            raise ValueError(f"{name} is not taken over")
        if not self.fleet.alive[row]:
            raise ValueError(f"{name} is not answering")
        self.takeover.commanded(formation_mode, [row])
        self.fleet.take_control_all([row])
        self.takeover.rejoined(row, self.vehicle_time())
        self._reform(f"with {name} back")
        if row == self.controller.leader:
            self._decided()

    def release(self, row: int, mode: str) -> None:
        """The console is about to put vehicle `row` in `mode` (`mode`, `land`, `rtl` on one vehicle): the
        ground station's own change, never a takeover; while the mission flies, a mode other than GUIDED
        hands the vehicle to the operator (no longer flown, as if taken over; `rejoin` hands it back; during
        the climb the formation then starts without it)."""
        if not self.phase.airborne:
            self.takeover.commanded(mode, [row])
            return
        was_taken = bool(self.takeover.taken[row])
        self.takeover.release(row, mode, self.vehicle_time())
        if self.phase is Phase.LAUNCH:
            return
        if self.takeover.taken[row] and not was_taken and self.takeover.flown.any():
            self._reform("without the vehicles taken over")
            if row == self.controller.leader:
                self._leader_taken(self.vehicle_time())

    def _set_phase(self, phase: Phase) -> None:
        self.frames_missed.enter(phase)
        self.phase = phase
        self.result.phase_reached = phase
        self.progress(f"phase {phase}")

    def _report_progress(self, t: float, cmd: Command) -> None:
        now = time.monotonic()
        if now - self._last_progress_wall < self.progress_period_s:
            return
        self._last_progress_wall = now
        self.progress(
            f"t={t:7.1f} s  leader to goal {cmd.leader_goal_distance:8.1f} m  "
            f"formation rms {self.formation_rms:6.2f} m"
            + ("" if self.controller.shaper is None else f"  shape {self.controller.shaper.shape_name}")
            + self._command_mode_note()
        )

    def _command_mode_note(self) -> str:
        """The progress line's note of the command mode, when it is not the paper's attitude targets."""
        plan = self.fleet.command_plan
        if plan is None or plan.mode == ATTITUDE:
            return ""
        return f"  {plan.mode} targets {plan.setpoint_hz:g} Hz"
