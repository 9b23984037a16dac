"""The simulator process's main loop: N vehicles, their endpoints, the world, the clock, the truth log.

One autopilot tick (outer loop, vectorised): autopilot.update -> physics for steps_per_tick steps (one fused
call) -> collisions -> truth log sample when due -> telemetry due. Network input is read between ticks in
real-time/speedup runs, and only at frame ends (while paused) in lockstep, so that a lockstep run depends on
the clients' messages and the seed only, never on wall-clock timing. Single-threaded, selectors over all
sockets.
"""

from __future__ import annotations

import logging
import math
import selectors
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot.copter import Autopilot
from sitl_sim.autopilot.fence import FenceItem
from sitl_sim.autopilot.params import ParamTable, param_specs
from sitl_sim.autopilot.persona import Persona
from sitl_sim.autopilot.registry import fleet_params, fleet_personas
from sitl_sim.clock import LockstepClients, RealTimePacer, Timing
from sitl_sim.network.endpoint import VehicleEndpoint
from sitl_sim.network.link_faults import UP, LinkFaults
from sitl_sim.network.radio import fleet_radios
from sitl_sim.network.streams import (
    STREAM_IDS,
    Geodesy,
    StreamSchedule,
    TelemetryView,
    ned_telemetry,
)
from sitl_sim.truth_log import TruthLog
from sitl_sim.vehicle_model.airframe import QuadParams
from sitl_sim.vehicle_model.dynamics import FleetDynamics, FleetState
from sitl_sim.vehicle_model.wind import Wind
from sitl_sim.world import Obstacles, find_collisions
from swarm_common.spin_wait import select_spinning

logger = logging.getLogger(__name__)
KEEPALIVE_S = 1.0  # wall seconds between HEARTBEATs while paused for lockstep clients
STAMPED_MESSAGES = frozenset(  # streams that carry time_boot_ms
    {
        mavlink2.MAVLINK_MSG_ID_ATTITUDE,
        mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
        mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
        mavlink2.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,
    }
)


@dataclass(frozen=True)
class SimConfig:
    """Everything a run needs (validated by the CLI). Arrays: start_pos, start_vel (N,3) ENU m, m/s;
    start_yaw (N,) rad ENU. speedup applies when lockstep is False."""

    base_port: int
    bind: str
    sysid_base: int
    timing: Timing
    speedup: float
    lockstep: bool
    lockstep_timeout: float
    lockstep_delay: int  # frames between a lockstep answer and the frame whose commands it carries (0 or 1)
    home: tuple[float, float, float]
    start_pos: np.ndarray
    start_vel: np.ndarray
    start_yaw: np.ndarray
    obstacles: Obstacles
    wind: tuple[float, float, float]  # speed m/s, from-direction deg, turbulence m/s
    truth_log: Path | None
    seed: int
    # simulated s from boot to the position estimate, all vehicles; None: each its persona's ready_delay_s
    ready_delay: float | None
    link: LinkFaults = LinkFaults()  # link faults of every vehicle (SIM_LINK_* param defaults, outages)
    signing_key: bytes | None = field(
        default=None, repr=False
    )  # MAVLink 2 signing key (sitl_sim.network.signing)
    param_names: str = "4.7"  # ArduCopter release of the parameter names (autopilot/params.py)
    orphan_speedup: float = math.inf  # x real time once the parent is gone (sitl_sim.orphan); inf = at once
    orphan_grace_s: float = 300.0  # simulated s an orphan flies at most before it exits
    # wall s each lockstep wait for answers polls before it blocks (swarm_common.spin_wait; CLI default 1 ms)
    lockstep_spin_s: float = 0.0
    autopilots: tuple[str, ...] = ()  # persona name per vehicle (autopilot.persona); (): all ArduCopter

    @property
    def vehicles(self) -> int:
        """Number of vehicles N."""
        return len(self.start_pos)


class Simulator:
    """Owns the fleet and its sockets; `run` until stop() is true, then `close`."""

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        self.timing = config.timing
        n = config.vehicles
        warm_up_kernels()
        quad = QuadParams()
        self.sysids = config.sysid_base + np.arange(n)
        speed, direction, turbulence = config.wind
        direction %= 360.0  # a from-direction in SIM_WIND_DIR's range [0, 360)
        personas = fleet_personas(config.autopilots, n)
        self.params = simulator_params(quad.hover_fraction, config.param_names, personas)
        p = self.params
        for name, value in {
            "MAV_SYSID": self.sysids, "MAV_SYS_ID": self.sysids,
            "SIM_WIND_SPD": speed, "SIM_WIND_DIR": direction, "SIM_WIND_TURB": turbulence,
            **config.link.params(),
        }.items():  # fmt: skip
            p.values[:, p.column_index(name)] = value
        state = FleetState.at_rest(config.start_pos, config.start_yaw, config.start_vel, quad)
        self.dyn = FleetDynamics(n, quad, self.timing.rate_hz, state=state)
        origin = state.pos.copy()
        home = origin * np.array([1.0, 1.0, 0.0])
        airborne = ~state.landed
        # simulated s from boot to the position estimate: --ready-delay for all, else each persona's own
        ready_delay: float | np.ndarray = (
            np.array([persona.ready_delay_s for persona in personas])
            if config.ready_delay is None
            else config.ready_delay
        )
        self.autopilot = Autopilot(
            self.dyn,
            self.params,
            origin,
            home,
            airborne,
            config.start_vel,
            ready_delay,
            personas,
        )
        self.wind = Wind(n, config.seed, speed, direction, turbulence)
        self.obstacles = config.obstacles
        self.geodesy = Geodesy(config.home)
        rates = [persona.default_rates_hz for persona in personas]
        self.streams = StreamSchedule(
            n, round(self.timing.tick_s * 1e6), np.array([[r.get(m, 0.0) for m in STREAM_IDS] for r in rates])
        )
        self.lockstep = LockstepClients(n, config.lockstep_timeout) if config.lockstep else None
        self.lockstep_started = False
        self._previous_frame_ms = -1  # time_boot_ms of the last lockstep frame end, once its wait was over
        self._held_frame = False  # this frame's telemetry is queued until the previous frame is answered
        self.pacer = RealTimePacer(config.speedup)
        self.orphan_speedup = config.orphan_speedup if config.lockstep else config.speedup
        self.orphan_grace_s = config.orphan_grace_s
        self.orphaned_at: float | None = None  # simulated s at which the ground station was found gone
        self._parent_gone = False
        # GPS clock at boot, for SYSTEM_TIME only: the wall clock never enters the simulated world
        self.unix_epoch_us = int(time.time()) * 1_000_000
        self.step = 0
        self.ticks = 0
        self._view: TelemetryView | None = None
        self.selector = selectors.DefaultSelector()
        self.endpoints: list[VehicleEndpoint] = []
        self.truth: TruthLog | None = None
        radios = fleet_radios(config.link.radio, n, config.link.capacity_changes)
        # each medium once (a shared one serves every vehicle), for _serve's settle of staged uplink arrivals
        self._media = list({id(r.medium): r.medium for r in radios if r is not None}.values())
        try:
            for i in range(n):
                endpoint = VehicleEndpoint(
                    i,
                    int(self.sysids[i]),
                    config.bind,
                    config.base_port + i,
                    self,
                    config.signing_key,
                    config.seed,
                    config.link.outages,
                    config.link.start_s,
                    radios[i],
                )
                self.endpoints.append(endpoint)
                self.selector.register(endpoint, selectors.EVENT_READ)
            if config.truth_log is not None:
                self.truth = TruthLog(config.truth_log, self.sysids)
        except BaseException:
            self.close()
            raise
        # the live queues of every endpoint, for _serve's one-call checks (any() over lists and deques)
        self._inboxes = [endpoint.inbox for endpoint in self.endpoints]
        self._uplinks = [endpoint.channel.waiting(UP) for endpoint in self.endpoints]
        self._outboxes = [endpoint.outbox.packets for endpoint in self.endpoints]

    # --- clock ----------------------------------------------------------------------------------------------

    @property
    def t(self) -> float:
        """Simulated seconds since boot."""
        return self.step / self.timing.rate_hz

    @property
    def time_us(self) -> int:
        """Simulated microseconds since boot (exact integer)."""
        return self.step * 1_000_000 // round(self.timing.rate_hz)

    # --- main loop ------------------------------------------------------------------------------------------

    def run(self, stop: Callable[[], bool], wakeup: socket.socket | None = None) -> None:
        """Simulate until stop() returns True, or, once orphaned (`orphan`), until every vehicle is down or
        the grace time has passed; wakeup (a socket readable on signals) interrupts waits."""
        if wakeup is not None:
            self.selector.register(wakeup, selectors.EVENT_READ)
        self._write_truth()
        while not self._orphan_done():
            if self.orphaned_at is None and self._parent_gone:
                self._become_orphan()
            if self.lockstep is None and stop():
                break
            self._tick()
            if self.lockstep is None:
                self._pace(stop)
            elif self.ticks % self.timing.ticks_per_frame == 0 and not self._end_frame(stop):
                break  # stopped while waiting for the clients

    def mark_parent_gone(self) -> None:
        """The ground station that started the simulator has died (called from the CLI's sitl_sim.orphan
        watch thread): the main loop turns orphan at its next tick."""
        self._parent_gone = True

    def _become_orphan(self) -> None:
        """Stop waiting for lockstep answers and run free so that the vehicles' own failsafes play out."""
        self.orphaned_at = self.t
        self.lockstep = None
        self.pacer = RealTimePacer(self.orphan_speedup, self.pacer.lag)
        logger.warning(
            "the ground station is gone at t=%.2f s: flying the vehicles on their own autopilots until all "
            "are down (at most %g s)",
            self.t,
            self.orphan_grace_s,
        )

    def _orphan_done(self) -> bool:
        """Orphaned and every vehicle landed and disarmed or crashed, or the grace time is over."""
        if self.orphaned_at is None:
            return False
        down = (~self.autopilot.armed & self.dyn.state.landed) | self.dyn.state.crashed
        if not down.all() and self.t - self.orphaned_at < self.orphan_grace_s:
            return False
        self._write_truth()  # the final state, whatever the sample rate
        if down.all():
            logger.warning("every vehicle is down at t=%.2f s: exiting", self.t)
        else:
            up = ", ".join(str(i) for i in np.flatnonzero(~down))
            logger.warning(
                "grace time %g s over at t=%.2f s, vehicle(s) %s still flying: exit",
                self.orphan_grace_s,
                self.t,
                up,
            )
        return True

    def _tick(self) -> None:
        """One autopilot tick and the physics it covers."""
        timing = self.timing
        dt = timing.tick_s
        t0 = self.t
        state = self.dyn.state
        was_ready = self.autopilot.ready.copy()
        self.autopilot.update(t0, dt)
        before = state.pos.copy()
        self.dyn.step(self.wind.sample(dt), timing.steps_per_tick)
        self.step += timing.steps_per_tick
        self.ticks += 1
        for crashed, what in find_collisions(before, state.pos, self.obstacles, t0, self.t, state.crashed):
            self.autopilot.crash(crashed, what)
        self._fence_tick()
        if self.step % timing.steps_per_truth == 0:
            self._write_truth()
        for ready in np.flatnonzero(self.autopilot.ready & ~was_ready):  # EKF origin and home just got set
            self._send_now(
                int(ready), (mavlink2.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN, mavlink2.MAVLINK_MSG_ID_HOME_POSITION)
            )
        if self.lockstep is None or self.ticks % timing.ticks_per_frame == 0:  # lockstep: frame ends only
            self._emit_telemetry()
            if self._pipelined():
                self._held_frame = True
            else:
                self._flush_frame()

    def _fence_tick(self) -> None:
        """Fence uploads' timers; a new breach sends FENCE_STATUS at once and goes to the log."""
        for endpoint in self.endpoints:
            if endpoint.missions.receiving:
                endpoint.missions.update()
        fence = self.autopilot.fence
        for i in fence.status_now:
            self._send_now(i, (mavlink2.MAVLINK_MSG_ID_FENCE_STATUS,))
        fence.status_now = []
        for line in self.autopilot.fence_log:
            logger.warning("%s", line)
        self.autopilot.fence_log.clear()

    def store_fence(self, i: int, items: list[FenceItem]) -> None:
        """Store vehicle i's uploaded fence items, their lat/lon placed in the local ENU frame."""
        xy = np.zeros((len(items), 2))
        for k, item in enumerate(items):
            xy[k] = self.geodesy.to_enu(item.lat_e7 * 1e-7, item.lon_e7 * 1e-7, self.geodesy.alt0)[:2]
        self.autopilot.fence.store(i, items, xy)
        total = self.autopilot.fence.legacy_total(items)
        self.params.set(i, "FENCE_TOTAL", total)  # AC_PolyFence_loader::write_fence: _total.set_and_save

    def _emit_telemetry(self) -> None:
        """Queue the streams due now on every endpoint with a peer (vehicle, then STREAM_IDS order); in
        lockstep, an endpoint none of whose due streams carries time_boot_ms gets a SYSTEM_TIME."""
        view = self.telemetry_view()
        endpoints = self.endpoints
        stamped: set[int] = set()
        for i, msg_id in self.streams.due(self.time_us):
            endpoint = endpoints[i]
            if endpoint.peers:
                data = view.encode(endpoint.outbox.framer, msg_id, i)
                if data is not None:
                    endpoint.outbox.append(data)
                    if msg_id in STAMPED_MESSAGES:
                        stamped.add(i)
        if self.lockstep is not None:
            for endpoint in endpoints:  # every frame end carries a time_boot_ms to answer
                if endpoint.peers and endpoint.index not in stamped:
                    self._send_now(endpoint.index, (mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME,))

    def _flush_frame(self) -> None:
        """Send every endpoint's queued telemetry and replies (in lockstep ending with the frame's clock
        tick)."""
        wall = time.monotonic()
        clock_ms = self.time_us // 1000 if self.lockstep is not None else None
        for endpoint in self.endpoints:
            endpoint.flush(wall, clock_ms)
        self._held_frame = False

    def _pace(self, stop: Callable[[], bool]) -> None:
        """Serve the network until the current simulated time is due on the (sped-up) wall clock.

        Sleeps to the deadline, then reads what arrived: once per physics step, as an autopilot's scheduler
        reads its links once per loop (ArduCopter at 400 Hz), rather than waking for every datagram. What
        arrived acts on the same step either way; a reply leaves up to one step later. Waking per datagram
        made a client's burst of commands wake this process up to once per command, and a sendto that wakes
        a blocked process costs the sender far more than one that does not (benchmarks/bench_wakeup.py,
        BENCHMARKS.md)."""
        deadline = self.pacer.deadline(self.t, time.monotonic())
        while True:
            time.sleep(max(0.0, deadline - time.monotonic()))
            self._serve(0.0)
            if time.monotonic() >= deadline or stop():
                return

    def _pipelined(self) -> bool:
        """Lockstep with --lockstep-delay 1, once started: a frame end sends its telemetry only when the
        clients have answered the previous frame, and their answers steer the frame that starts now
        (sitl_sim.clock)."""
        return self.lockstep is not None and self.lockstep_started and self.config.lockstep_delay > 0

    def _end_frame(self, stop: Callable[[], bool]) -> bool:
        """Lockstep frame end: wait for every lockstep client's answer (see sitl_sim.clock), then send the
        frame's telemetry if it was held (pipelined). False when stop() ended the wait.

        A lockstep run stops only here, at the wait: where that is depends on the clients' answers alone,
        never on when the signal came, so the truth log of a stopped run is reproducible too."""
        assert self.lockstep is not None
        frame_ms = self.time_us // 1000
        awaited_ms = self._previous_frame_ms if self._pipelined() else frame_ms
        answered = self._wait_for_answers(stop, awaited_ms)
        if self._held_frame:
            self._flush_frame()
        self._previous_frame_ms = frame_ms
        return answered

    def _wait_for_answers(self, stop: Callable[[], bool], frame_ms: int) -> bool:
        """Serve the network until every active lockstep client has answered frame_ms (or is dropped, or the
        parent is gone); False when stop() ended the wait. While a frame is held, nothing is sent: not even a
        keepalive, which would show the clients the state of a frame they must not see before they answered
        the previous one."""
        clients = self.lockstep
        assert clients is not None
        frame_wall = keepalive = time.monotonic()
        while not (stop() or self._parent_gone):
            now = time.monotonic()
            if not self.lockstep_started:
                ready = clients.every_vehicle_has_client() and not clients.pending(frame_ms)
                late = (
                    clients.first_seen_wall is not None and now - clients.first_seen_wall > clients.timeout_s
                )
                if ready or late:
                    clients.drop(clients.pending(frame_ms))
                    self.lockstep_started = True
                    self.pacer.restart(self.t, now)
                    return True
            elif not clients.any_active():
                if self._held_frame:
                    self._flush_frame()
                self._pace(stop)  # nobody to wait for: real-time pace
                return True
            else:
                pending = clients.pending(frame_ms)
                if not pending:
                    self.pacer.restart(self.t, now)
                    return True
                if now - frame_wall > clients.timeout_s:
                    clients.drop(pending)
                    for vehicle, addr in pending:
                        client = f"{addr[0]}:{addr[1]} of vehicle {vehicle}"
                        logger.warning(
                            "lockstep client %s dropped (no answer for %g s)", client, clients.timeout_s
                        )
                    continue
            if now - keepalive >= KEEPALIVE_S and not self._held_frame:
                keepalive = now
                for i in range(len(self.endpoints)):
                    self._send_now(
                        i, (mavlink2.MAVLINK_MSG_ID_HEARTBEAT, mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME)
                    )
            # _serve polls for up to --lockstep-spin-us, yielding the CPU, then blocks: polling without the
            # yield made two flights at once (Monte Carlo --jobs 2 on 2 cores) slower (BENCHMARKS.md)
            self._serve(min(0.1, max(0.0, keepalive + KEEPALIVE_S - now)), frame_ms)
        return not stop()

    def _serve(self, timeout: float, frame_ms: int | None = None) -> None:
        """Wait up to timeout s for input, handle it, send replies (frame_ms: paused at that frame end)."""
        wall = time.monotonic()
        handled = 0
        now_ms = self.time_us // 1000
        for medium in self._media:  # uplink datagrams of earlier ms take the air (sitl_sim.network.radio)
            medium.settle(now_ms)
        if any(self._inboxes) or any(self._uplinks):  # first what arrived after the clients' previous answers
            for endpoint in self.endpoints:
                if endpoint.inbox or endpoint.channel.waiting(UP):
                    handled += endpoint.receive(wall, frame_ms)
        # waiting for lockstep answers (frame_ms), which come within a fraction of a millisecond: poll first
        spin_s = self.config.lockstep_spin_s if frame_ms is not None else 0.0
        events = select_spinning(self.selector, 0.0 if handled else timeout, spin_s)
        wall = time.monotonic()
        for key, _ in events:
            if isinstance(key.fileobj, VehicleEndpoint):
                key.fileobj.receive(wall, frame_ms)
            else:  # the signal wake-up socket: drain it, stop() tells the rest
                try:
                    key.fileobj.recv(4096)  # type: ignore[union-attr]
                except OSError:
                    pass
        if self._held_frame:  # replies leave with the held frame's telemetry, after it
            return
        texts = self.autopilot.texts
        if not any(self._outboxes) and not any(texts):  # a frame's commands ask for no reply
            return
        for endpoint in self.endpoints:
            if endpoint.outbox.packets or texts[endpoint.index]:
                endpoint.flush(wall)

    # --- services for the endpoints -------------------------------------------------------------------------

    def telemetry_view(self) -> TelemetryView:
        """The fleet's telemetry at the current instant (cached for the tick)."""
        if self._view is None or self._view.time_us != self.time_us:
            self._view = TelemetryView(self.autopilot, self.time_us, self.geodesy, self.unix_epoch_us)
        return self._view

    def on_new_peer(self, vehicle: int) -> None:
        """A client spoke to `vehicle` for the first time: greet it at once (it may wait while the clock is
        paused)."""
        self._send_now(vehicle, (mavlink2.MAVLINK_MSG_ID_HEARTBEAT, mavlink2.MAVLINK_MSG_ID_SYSTEM_TIME))

    def _send_now(self, i: int, msg_ids: tuple[int, ...]) -> None:
        endpoint = self.endpoints[i]
        for msg_id in msg_ids:
            data = self.telemetry_view().encode(endpoint.outbox.framer, msg_id, i)
            if data is not None:
                endpoint.outbox.append(data)

    def set_param(self, i: int, name: str, value: float) -> None:
        """Store a checked parameter value set on vehicle i; world parameters change the world at once."""
        j = self.params.index[name]
        for row in self.params.set(i, name, value):
            bytewise = self.autopilot.persona(row).bytewise_params
            self.endpoints[row].outbox.send_param(self.params, row, j, bytewise=bytewise)
        self.autopilot.persona(i).parameter_set(self.params, i, name)  # a mirrored one drives the shared loop
        if name.startswith("SIM_WIND_"):
            p = self.params
            self.wind.set(p.value(i, "SIM_WIND_SPD"), p.value(i, "SIM_WIND_DIR"), p.value(i, "SIM_WIND_TURB"))

    # --- truth log and shutdown -----------------------------------------------------------------------------

    def _write_truth(self) -> None:
        if self.truth is None:
            return
        s = self.dyn.state
        ap = self.autopilot
        flags = np.column_stack((ap.mode, ap.armed, s.crashed, ap.land_complete))
        self.truth.write(
            self.t,
            s.pos,
            s.vel,
            s.quat,
            s.euler(),
            s.motor,
            flags,
            self.obstacles.at(self.t),
            self.obstacles.radii,
        )

    def counters_report(self) -> list[str]:
        """One line per vehicle with its link counters, then how far behind the wall clock a paced (real-time,
        --speedup or orphaned) run fell, when any of it was paced. Uplink datagrams a radio still holds staged
        are timed first (sitl_sim.network.radio), so that its counts do not depend on whether the stop came
        before or after the simulator's last look at the network."""
        for medium in self._media:
            medium.settle(sys.maxsize)
        lines = [
            f"vehicle {ep.index} (sysid {ep.sysid}): {ep.counters.summary()} {ep.channel.summary()}"
            for ep in self.endpoints
        ]
        if self.pacer.lag.paced_ticks:
            lines.append(self.pacer.lag.summary())
        return lines

    def close(self) -> None:
        """Free the ports, flush and close the truth log (idempotent)."""
        for endpoint in self.endpoints:
            endpoint.close()
        self.endpoints = []
        self.selector.close()
        if self.truth is not None:
            self.truth.close()


def warm_up_kernels() -> None:
    """Compile (or load from numba's cache) every kernel a run calls, on a throwaway one-vehicle fleet, so
    that the first frames after READY are not late by the JIT. The outer loop's kernel holds every persona's
    rules as data, so one vehicle of the default persona compiles what every persona needs."""
    quad = QuadParams()
    dyn = FleetDynamics(1, quad)
    params = simulator_params(quad.hover_fraction, "4.7", fleet_personas((), 1))
    zeros = np.zeros((1, 3))
    Autopilot(dyn, params, zeros, zeros, np.zeros(1, dtype=bool), zeros, 0.0).update(0.0, 0.01)
    dyn.step(zeros, 1)
    Geodesy((0.0, 0.0, 0.0)).to_geodetic(zeros)
    ned_telemetry(zeros, zeros, np.array([[1.0, 0.0, 0.0, 0.0]]), zeros, zeros)
    find_collisions(zeros, zeros, Obstacles(zeros, np.ones(1), zeros), 0.0, 0.01, np.zeros(1, dtype=bool))


def simulator_params(
    hover_fraction: float, param_names: str, personas: tuple[type[Persona], ...]
) -> ParamTable:
    """The fleet's parameter table: the shared table of ArduCopter's `param_names` release (hover_fraction:
    MOT_THST_HOVER's default) and each persona's own (autopilot.registry.fleet_params)."""
    return fleet_params(param_specs(hover_fraction, param_names), hover_fraction, personas)
