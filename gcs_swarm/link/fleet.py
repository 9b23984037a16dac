"""N vehicles over MAVLink in one single-threaded event loop, clocked by their telemetry.

Flight loop (spec 8; the same code runs against hardware in real time and against the simulator in lockstep):

    with Fleet(configs, origin, tlog_path=run_dir / "flight.tlog") as fleet:
        fleet.connect(timeout_s=10)
        ...preflight with fleet.wait_ready / param_set_all / set_mode_all / arm_all...
        while flying:
            if not fleet.wait_tick(timeout_s=0.5):   # every alive vehicle sent a new GLOBAL_POSITION_INT
                fleet.answer_frame()                 # keep a lockstep simulator going for the others
                continue
            roll, pitch, yaw, thrust = control(fleet.pos, fleet.vel, fleet.att)   # (N,) each, FLU/ENU
            fleet.send_attitude_targets(roll, pitch, yaw, thrust)   # answers this tick's frame
            fleet.answer_frame()                                    # answers vehicles not commanded

Lockstep (team brief): the simulator waits until each frame is answered by SYSTEM_TIME / SET_ATTITUDE_TARGET
/ SET_POSITION_TARGET_* carrying time_boot_ms >= the frame's. `wait_tick` and `pump` never answer (the flight
loop does, after its commands); every blocking wait of the link (`connect`, `run`, `wait_until` and all
`*_all` methods) answers each new frame itself when `lockstep_answers` is on.

Timeouts of the waits for the vehicles (`wait_until`, `wait_ready`, and every command, mode, arming and
parameter exchange) are seconds of vehicle time (operations.Timeout), with a wall-clock backstop for clocks
that stop; those of the waits for the link itself (`connect`, `wait_tick`, `pump`) are wall seconds.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict
from pathlib import Path
from types import TracebackType
from typing import Any, Generic, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gcs_swarm.link import attitude_commands, frames, intake_kernel
from gcs_swarm.link.autopilots import AutopilotDialect, ModeChoice, dialect_named, mode_name_in
from gcs_swarm.link.command_mode import DEFAULT_STEP_DOWN, POSITION, CommandModeWatch, CommandPlan, StepDown
from gcs_swarm.link.connection import LinkError
from gcs_swarm.link.forward import ForwardConfig
from gcs_swarm.link.housekeeping import Housekeeping
from gcs_swarm.link.link_use import LinkUse
from gcs_swarm.link.lockstep import frame_ready, take_new_frame
from gcs_swarm.link.network import Network
from gcs_swarm.link.operations import Operation, Timeout
from gcs_swarm.link.streams import telemetry_rates
from gcs_swarm.link.telemetry import Event, TelemetryState
from gcs_swarm.link.vehicle import VehicleConfig, VehicleLink

_POLL_S = 0.02  # longest single select() inside blocking waits; they return as soon as packets arrive
_FRAME_GRACE_S = 0.25  # wall s a blocking wait waits for a complete telemetry frame before acting anyway


_S = TypeVar("_S", bound=np.generic)


class _StateCopy(Generic[_S]):
    """A Fleet attribute that reads a copy of the fleet's TelemetryState array of the same name."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, fleet: Fleet, owner: type | None = None) -> NDArray[_S]:
        return getattr(fleet.state, self.name).copy()  # type: ignore[no-any-return]


class Fleet:
    """MAVLink links to N vehicles and their state as arrays (row i = vehicles[i]).

    origin: mission origin (lat deg, lon deg, alt m AMSL) of the local ENU frame.
    loss_timeout_s: a vehicle is lost after this much fleet vehicle time without a packet, or after
    `loss_wall_timeout_s` of wall time (default: the same value); it is regained at its next packet.
    signing_key: 32-byte MAVLink 2 signing key; every packet sent is then signed (link.signing), and every
    packet received must be signed with it (swarm_common.signing; refusals counted in `stats`).
    forwards: other ground stations watching (and, read-write, commanding) through this one (link.forward).
    spin_s: wall s each wait for packets polls before it blocks (swarm_common.spin_wait; worth it only
    against a lockstep simulator, whose next frame comes within a fraction of a millisecond).
    """

    def __init__(
        self,
        vehicles: Sequence[VehicleConfig],
        origin: frames.Origin,
        gcs_sysid: int = 255,
        gcs_compid: int = 190,
        tlog_path: Path | None = None,
        lockstep_answers: bool = True,
        loss_timeout_s: float = 3.0,
        loss_wall_timeout_s: float | None = None,
        signing_key: bytes | None = None,
        stream_rate_hz: float = 50.0,
        forwards: Sequence[ForwardConfig] = (),
        spin_s: float = 0.0,
        link_budget_bps: float | None = None,
        command_plan: CommandPlan | None = None,
        step_down: StepDown = DEFAULT_STEP_DOWN,
    ) -> None:
        """`stream_rate_hz`: the rate of the state telemetry asked for as soon as a vehicle is heard
        (`telemetry_rates`; the control loop's rate). `link_budget_bps`: bit/s each vehicle's link carries
        for the ground station, up and down together (link.link_use; None: no budget). `command_plan`: the
        command mode and telemetry rates chosen for the link (link.command_mode); its telemetry is asked
        for instead (None: attitude targets, telemetry at stream_rate_hz). `step_down`: when that plan steps
        down in flight (CommandModeWatch)."""
        _validate(vehicles, gcs_sysid, gcs_compid)
        self.stream_rate_hz = stream_rate_hz
        self.command_plan = command_plan
        self._trajectory_ms = np.full(len(vehicles), -1, dtype=np.int64)  # position report of the last
        # trajectory target sent to each vehicle (send_trajectory_targets)
        self.configs = list(vehicles)
        self.lockstep_answers = lockstep_answers
        self.loss_timeout_s = loss_timeout_s
        self.loss_wall_timeout_s = loss_timeout_s if loss_wall_timeout_s is None else loss_wall_timeout_s
        self.tlog_path = tlog_path
        self.state = TelemetryState(len(self.configs), origin)
        self.events: deque[Event] = deque(maxlen=10_000)
        self.links = [
            VehicleLink(i, cfg, self.state, self.events, gcs_sysid, gcs_compid, signing_key)
            for i, cfg in enumerate(self.configs)
        ]
        self._by_name = {link.name: link for link in self.links}
        self.network = Network(self.links, signing_key, forwards, spin_s=spin_s)
        self.housekeeping = Housekeeping(self.links, self.state)  # heartbeats, loss checks, stream watchdog
        self.link_use = LinkUse(self.links, link_budget_bps)  # bytes/s each way per vehicle, the budget
        # steps command_plan down in flight
        self.command_watch = CommandModeWatch(self.links, self.link_use, step_down)
        self.on_pump: Callable[[], None] | None = None  # called at the end of every pump (e.g. a UI refresh)
        # wall s every pump so far spent blocked in select for packets, and the rest of its time (decoding
        # what arrived, heartbeats, loss checks, on_pump): read as differences (flight.tick_timing)
        self.pump_wait_s = 0.0
        self.pump_work_s = 0.0

    # ------------------------------------------------------------------ state arrays (copies)

    @property
    def names(self) -> list[str]:
        return [link.name for link in self.links]

    # copies of the TelemetryState arrays (row i = vehicles[i]), so a caller cannot change the link's state
    pos: _StateCopy[np.float64] = _StateCopy()  # (N,3) ENU m around the origin, from GLOBAL_POSITION_INT
    vel: _StateCopy[np.float64] = _StateCopy()  # (N,3) ENU m/s
    # (N,3) roll, pitch, yaw rad, body FLU in world ENU (yaw 0 = facing East)
    att: _StateCopy[np.float64] = _StateCopy()
    time_ms: _StateCopy[np.int64] = _StateCopy()  # (N,) latest time_boot_ms of each vehicle (-1 before any)
    alive: _StateCopy[np.bool_] = _StateCopy()
    armed: _StateCopy[np.bool_] = _StateCopy()
    # (N,) the autopilots' custom_mode from HEARTBEAT (-1 unknown); names via VehicleLink.mode_name
    mode: _StateCopy[np.int64] = _StateCopy()
    # (N,) usable position estimate and pre-arm checks passing (EKF_STATUS_REPORT, SYS_STATUS)
    ready: _StateCopy[np.bool_] = _StateCopy()
    # (N,) wall ms of each link's latest TIMESYNC round trip (NaN until measured)
    rtt_ms: _StateCopy[np.float64] = _StateCopy()
    # (N,) MAV_LANDED_STATE from EXTENDED_SYS_STATE (0 undefined, 1 on ground, 2 in air, ...)
    landed_state: _StateCopy[np.int64] = _StateCopy()
    system_status: _StateCopy[np.int64] = _StateCopy()  # (N,) MAV_STATE from HEARTBEAT (-1 unknown)

    def in_mode(self, mode: ModeChoice) -> NDArray[np.bool_]:
        """(N,) each vehicle's HEARTBEAT shows flight mode `mode`, named in its autopilot's dialect or a
        ModeChoice function of it (ValueError if a dialect has no such mode)."""
        return np.array(
            [self.state.mode[link.index] == self.mode_number(link.index, mode) for link in self.links],
            dtype=bool,
        )

    def mode_number(self, i: int, mode: ModeChoice) -> int:
        """custom_mode of `mode` for vehicle i, in its dialect (ValueError if it has no such mode)."""
        dialect = self.links[i].channel.autopilot
        return dialect.mode_number(mode_name_in(dialect, mode))

    @property
    def dialects(self) -> list[AutopilotDialect]:
        """Each vehicle's autopilot dialect (from its HEARTBEAT or the mission; ArduPilot until heard)."""
        return [link.channel.autopilot for link in self.links]

    def vehicle(self, key: int | str) -> VehicleLink:
        """The link of vehicle `key` (index or name)."""
        if isinstance(key, str):
            if key in self._by_name:
                return self._by_name[key]
        elif 0 <= key < len(self.links):
            return self.links[key]
        raise LinkError(f"there is no vehicle {key!r} (vehicles: {', '.join(self.names)})")

    def stats(self) -> dict[str, dict[str, int]]:
        """Per-vehicle packet counters (channel.LinkStats: received, sent, bad, ignored, lost, ...)."""
        return {link.name: asdict(link.channel.stats) for link in self.links}

    def link_summary(self) -> list[str]:
        """One line per vehicle that refused packets by signature and per forward (what it got and did), for
        the end of a run."""
        lines = [
            f"{link.name}: refused {s.unsigned} unsigned and {s.bad_signature} forged or replayed packets"
            for link in self.links
            if (s := link.channel.stats).unsigned or s.bad_signature
        ]
        for forward in self.network.forwards:
            f = forward.stats
            mode = "read-write" if forward.config.read_write else "read-only"
            lines.append(
                f"forward {forward.name} ({mode}): {f.sent} frames sent; of {f.received} received, "
                f"{f.routed} passed to the vehicles, {f.commands_refused} commands refused, "
                f"{f.reserved} reserved, {f.unsigned + f.bad_signature} refused by signature"
            )
        return lines

    def forward_stats(self) -> dict[str, dict[str, int]]:
        """Per forward (by connection string): frames sent to it, and of its own frames those routed to the
        vehicles and those dropped (forward.ForwardStats)."""
        return {forward.name: asdict(forward.stats) for forward in self.network.forwards}

    # ------------------------------------------------------------------ connection

    def connect(self, timeout_s: float = 10.0) -> None:
        """Open every endpoint and wait for each vehicle's HEARTBEAT; refuse sysid mismatches/duplicates."""
        if self.network.connected:
            raise RuntimeError("the fleet is already connected")
        # what the ticks run compiled is compiled now (or loaded from numba's cache), not in the first tick
        frames.warm_up()
        attitude_commands.warm_up()
        intake_kernel.warm_up()
        take_new_frame(np.zeros(1, dtype=bool), *np.full((3, 1), -1, dtype=np.int64))
        try:
            self.network.open(min(timeout_s, 5.0), self.tlog_path)
            deadline = time.monotonic() + timeout_s
            while True:
                self.network.check_identities()
                if all(link.sysid is not None for link in self.links):
                    break
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    self.network.check_identities(wrong_sysid_heartbeats=1)
                    missing = [f"{v.name} ({v.config.connection})" for v in self.links if v.sysid is None]
                    raise LinkError(
                        f"no HEARTBEAT within {timeout_s:g} s from {', '.join(missing)}; "
                        "is it running and reachable?"
                    )
                self._pump_answering(min(remaining, _POLL_S))
            for link in self.links:
                if link.state.time_ms[link.index] < 0:
                    link.streams.request_message("SYSTEM_TIME")  # learn the frame time to answer in lockstep
            self._request_streams()
        except BaseException:
            self.close()
            raise

    def _request_streams(self) -> None:
        """Ask every vehicle for the telemetry the ground station needs, as soon as it is heard: ArduCopter
        streams nothing on a link until a ground station asks (its MAVn_* / SRn_* rates are 0 by default),
        and MAVProxy and QGroundControl ask at the first HEARTBEAT too. A vehicle that refuses is reported
        (an event) and asked again by the stream watchdog; nothing here stops the connection."""
        plan = self.command_plan
        rates = telemetry_rates(self.stream_rate_hz) if plan is None else plan.telemetry
        results = self.run((link.streams.op_request_streams(rates) for link in self.links), strict=False)
        for link, result in zip(self.links, results, strict=True):
            if isinstance(result, LinkError):
                link.add_event(f"telemetry not set up: {result}")

    def close(self) -> None:
        """Close every endpoint and the tlog (idempotent)."""
        self.network.close()

    def __enter__(self) -> Fleet:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    # ------------------------------------------------------------------ event loop

    def pump(self, timeout_s: float = 0.0) -> None:
        """Wait up to `timeout_s` for packets, decode all that are readable, send due heartbeats, detect loss.

        Never answers lockstep frames (see the module doc). Then calls `on_pump`, if set: every blocking wait
        pumps, so the fleet's owner can, e.g., publish its state from inside one (it must not pump itself).
        """
        if not self.network.connected:
            raise RuntimeError("the fleet is not connected")
        start = time.monotonic()
        now = self.network.receive(timeout_s)  # time.monotonic() once select returned
        self.housekeeping.run(now, self.loss_timeout_s, self.loss_wall_timeout_s)
        if self.state.clock_ms >= self.link_use.next_ms:
            self.link_use.sample(self.state.clock_ms)
            self.command_plan = self.command_watch.sample(self.command_plan)
        if self.on_pump is not None:
            self.on_pump()
        self.pump_wait_s += now - start
        self.pump_work_s += time.monotonic() - now

    def _frame_ready(self) -> bool:
        """Every alive vehicle has a telemetry frame no answer has covered yet (lockstep.frame_ready)."""
        return frame_ready(
            [link.lockstep for link in self.links], [link.channel.endpoint is not None for link in self.links]
        )

    def _next_frame(self, deadline: float) -> None:
        """Pump until a complete unanswered frame is here (immediately if one already is), or a short
        wall-clock grace passes (so vehicles that do not stream keep a real fleet moving), or the deadline."""
        if not self.lockstep_answers:
            self.pump(max(0.0, min(deadline - time.monotonic(), _POLL_S)))
            return
        limit = min(deadline, time.monotonic() + _FRAME_GRACE_S)
        while not self._frame_ready():
            remaining = limit - time.monotonic()
            if remaining <= 0:
                return
            self.pump(min(remaining, _POLL_S))

    def _pump_answering(self, timeout_s: float) -> None:
        """Answer the current frame (the caller has checked its condition on it and sent its commands), then
        pump until the next complete frame. Deciding only on complete frames, and acting before answering
        them, is what makes a lockstep run deterministic: every command takes effect at the frame it was
        decided on, however the packets interleave on the wire."""
        if self.lockstep_answers:
            self.answer_frame()
        self._next_frame(time.monotonic() + timeout_s)

    def wait_tick(self, timeout_s: float) -> bool:
        """Pump until every alive vehicle has a GLOBAL_POSITION_INT (or a lockstep clock tick, which marks a
        frame whose telemetry the link lost or delayed) newer than its last tick or lockstep answer (True),
        or `timeout_s` passes (False). Does not answer: the caller does, after its commands.

        A lost vehicle whose clock ticks were current at the last tick is waited for as well: a lockstep
        simulator waits for its answer, which the flight loop sends after this tick's commands.
        """
        deadline = time.monotonic() + timeout_s
        st = self.state
        while not take_new_frame(st.alive, st.position_ms, st.frame_ms, st.tick_ms):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self.pump(remaining)
        return True

    def wait_until(self, predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
        """Pump (answering frames) until `predicate()`; LinkError "timed out after T s waiting for {what}"
        after `timeout_s` of fleet vehicle time (operations.Timeout).

        The predicate is evaluated on complete frames, and the frame on which it first holds is left
        unanswered, so the caller's next commands take effect at that very frame.
        """
        timeout = Timeout(timeout_s, self.state.vehicle_clock)
        self._next_frame(time.monotonic() + _FRAME_GRACE_S)
        while not predicate():
            if timeout.expired():
                raise LinkError(f"timed out after {timeout_s:g} s waiting for {what}")
            self._pump_answering(_FRAME_GRACE_S)

    def run(self, ops: Iterable[Operation[Any]], strict: bool = True) -> list[Any]:
        """Drive several vehicle operations together, pumping (and answering frames) between their steps.

        Returns their results in order. strict: raise one LinkError naming every failure; otherwise a
        failed operation's slot holds its LinkError.
        """
        ops = list(ops)
        results: list[Any] = [None] * len(ops)
        pending = list(range(len(ops)))
        self._next_frame(time.monotonic() + _FRAME_GRACE_S)  # start (send) on a complete frame
        while pending:
            still = []
            for k in pending:
                try:
                    next(ops[k])
                    still.append(k)
                except StopIteration as stop:
                    results[k] = stop.value
                except LinkError as err:
                    results[k] = err
            pending = still
            if pending:
                self._pump_answering(_FRAME_GRACE_S)
        errors = [r for r in results if isinstance(r, LinkError)]
        if strict and errors:
            raise errors[0] if len(errors) == 1 else LinkError("; ".join(str(e) for e in errors))
        return results

    # ------------------------------------------------------------------ flight-loop output

    def answer_frame(self, mask: ArrayLike | None = None) -> None:
        """SYSTEM_TIME answer to each vehicle (in `mask`, default all) whose latest frame is unanswered.

        An answered frame is consumed: the next `wait_tick` waits for a newer one from that vehicle.
        """
        selected = self._mask(mask)
        for link in self.links:
            if selected[link.index] and link.channel.endpoint is not None:
                link.lockstep.answer_frame()

    def send_attitude_targets(
        self,
        roll: ArrayLike,
        pitch: ArrayLike,
        yaw: ArrayLike,
        thrust: ArrayLike,
        mask: ArrayLike | None = None,
    ) -> None:
        """SET_ATTITUDE_TARGET to each connected vehicle in `mask` (default all), echoing its time_boot_ms.

        roll, pitch, yaw: (N,) rad, body FLU in world ENU (spec 1.1); thrust: (N,) normalised, clipped to
        [0, 1] (AutopilotDialect.thrust). A NaN or inf in a selected row is a bug upstream:
        ValueError naming the vehicles, and nothing is sent to any vehicle (each keeps its previous target
        until the caller decides, e.g. BRAKE).
        """
        n = len(self.links)
        angles = [np.asarray(a, dtype=float) for a in (roll, pitch, yaw)]
        if any(a.shape != (n,) for a in angles):  # scalars and other shapes (the tick's are (N,) already)
            angles = list(np.broadcast_arrays(*angles))
        euler = np.stack(angles, axis=-1)
        thr = np.asarray(thrust, dtype=float)
        thr = thr if thr.shape == (n,) else np.broadcast_to(thr, (n,))
        if euler.shape != (n, 3):
            raise ValueError(f"attitude targets need shape ({n},) per angle, got {euler.shape[:-1]}")
        selected = self._mask(mask)
        bad = selected & ~(np.all(np.isfinite(euler), axis=1) & np.isfinite(thr))
        if bad.any():
            names = ", ".join(self.links[i].name for i in np.flatnonzero(bad))
            raise ValueError(f"non-finite attitude target for {names}; nothing sent")
        q, thrust_list = frames.attitude_target_quaternion(euler).tolist(), thr.tolist()
        for link in self.links:
            i = link.index
            if selected[i] and link.sysid is not None:
                link.setpoints.send_attitude_quaternion(q[i], thrust_list[i])

    def send_trajectory_targets(
        self,
        pos: NDArray[np.float64],
        vel: NDArray[np.float64],
        acc: NDArray[np.float64],
        yaw: NDArray[np.float64],
        mask: NDArray[np.bool_],
    ) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT with position (N, 3) ENU m, velocity (N, 3) m/s, acceleration
        (N, 3) m/s^2 and yaw (N,) rad ENU to each connected vehicle in the (N,) bool `mask` whose latest
        GLOBAL_POSITION_INT is not the one its last target was sent on: one target per position report, so
        the setpoints go at the state telemetry's rate (CommandPlan.state_hz), whatever the tick rate.
        Each echoes its vehicle's time_boot_ms (Setpoints.send_trajectory_target; a non-finite row raises
        ValueError)."""
        st = self.state
        fresh = np.asarray(mask, dtype=bool) & (st.position_ms >= 0) & (st.position_ms != self._trajectory_ms)
        for link in self.links:
            i = link.index
            if fresh[i] and link.sysid is not None:
                link.setpoints.send_trajectory_target(pos[i], vel[i], acc[i], float(yaw[i]))
                self._trajectory_ms[i] = st.position_ms[i]

    def _mask(self, mask: ArrayLike | None) -> NDArray[np.bool_]:
        n = len(self.links)
        if mask is None:
            return np.ones(n, dtype=bool)
        m = np.asarray(mask, dtype=bool)
        if m.shape != (n,):
            raise ValueError(f"vehicle mask needs shape ({n},), got {m.shape}")
        return m

    # ------------------------------------------------------------------ fleet-wide operations

    def select(self, vehicles: Iterable[int | str] | None = None) -> list[VehicleLink]:
        """Links for `vehicles` (indices or names); None = every vehicle whose link is alive."""
        if vehicles is None:
            return [link for link in self.links if self.state.alive[link.index]]
        return [self.vehicle(v) for v in vehicles]

    def wait_ready(
        self,
        timeout_s: float,
        vehicles: Iterable[int | str] | None = None,
        progress: Callable[[str], None] | None = None,
        progress_period_s: float = 10.0,
    ) -> None:
        """Wait until each vehicle (default: all) is ready to arm; after `timeout_s` of fleet vehicle time
        (operations.Timeout), LinkError naming the others and why, in the vehicles' own words where they give
        them (EKF flags, GPS fix, the latest PreArm text). `progress` hears the same every
        `progress_period_s` s of vehicle time while it waits (a real ArduCopter takes about a minute)."""
        links = self.links if vehicles is None else self.select(vehicles)
        timeout = Timeout(timeout_s, self.state.vehicle_clock)
        report = Timeout(progress_period_s, self.state.vehicle_clock)
        self._next_frame(time.monotonic() + _FRAME_GRACE_S)
        while True:
            reasons = [(link, link.not_ready_reason()) for link in links]
            late = [(link, why) for link, why in reasons if why is not None]
            if not late:
                return
            detail = "; ".join(f"{link.name}: {why}" for link, why in late)
            if timeout.expired():
                raise LinkError(f"not ready to fly after {timeout_s:g} s: {detail}")
            if progress is not None and report.expired():
                progress(f"waiting for {detail}")
                report.restart()
            self._pump_answering(_FRAME_GRACE_S)

    def set_mode_all(self, mode: ModeChoice, vehicles: Iterable[int | str] | None = None) -> None:
        """Set a flight mode (named in each vehicle's autopilot dialect, or a ModeChoice function of it),
        confirmed by HEARTBEAT."""
        self.run(link.commands.op_set_mode(mode) for link in self.select(vehicles))

    def take_control_all(self, vehicles: Iterable[int | str] | None = None) -> None:
        """Each vehicle into its formation mode (GUIDED; PX4's OFFBOARD after the setpoint stream it needs:
        VehicleLink.op_take_control, at the position command mode's setpoint rate), confirmed by HEARTBEAT."""
        plan = self.command_plan
        period_ms = int(1000 / plan.setpoint_hz) if plan is not None and plan.mode == POSITION else 0
        self.run(link.op_take_control(period_ms) for link in self.select(vehicles))

    def arm_all(self, force: bool = False, vehicles: Iterable[int | str] | None = None) -> None:
        self.run(link.commands.op_arm(force) for link in self.select(vehicles))

    def takeoff_all(self, alt_m: ArrayLike, vehicles: Iterable[int | str] | None = None) -> None:
        """MAV_CMD_NAV_TAKEOFF; alt_m (m above each home) is a scalar or one value per selected vehicle."""
        links = self.select(vehicles)
        alts = np.broadcast_to(np.asarray(alt_m, dtype=float), (len(links),))
        self.run(link.commands.op_takeoff(float(a)) for link, a in zip(links, alts, strict=True))

    def land_all(self, vehicles: Iterable[int | str] | None = None) -> None:
        """Land each vehicle where it is (its dialect's landing mode), confirmed by HEARTBEAT."""
        self.run(link.commands.op_land() for link in self.select(vehicles))

    def param_set_all(self, name: str, value: float, vehicles: Iterable[int | str] | None = None) -> None:
        """Set and read back a parameter on each vehicle."""
        self.run(link.parameters.op_set(name, value) for link in self.select(vehicles))

    def param_get_all(self, name: str, vehicles: Iterable[int | str] | None = None) -> NDArray[np.float64]:
        """Read a parameter from each vehicle, in selection order."""
        return np.array(self.run(link.parameters.op_get(name) for link in self.select(vehicles)), dtype=float)


def _validate(vehicles: Sequence[VehicleConfig], gcs_sysid: int, gcs_compid: int) -> None:
    if not vehicles:
        raise LinkError("the fleet needs at least one vehicle")
    if not (1 <= gcs_sysid <= 255 and 0 <= gcs_compid <= 255):
        raise LinkError(
            f"ground station sysid {gcs_sysid} / compid {gcs_compid} out of range (1-255 / 0-255)"
        )
    names: set[str] = set()
    sysids: dict[int, str] = {}
    for cfg in vehicles:
        if not cfg.name or cfg.name in names:
            raise LinkError(f"vehicle name {cfg.name!r} is empty or used twice")
        names.add(cfg.name)
        if cfg.autopilot != "auto":
            try:
                dialect_named(cfg.autopilot)
            except ValueError as err:
                raise LinkError(f"{cfg.name}: {err}") from None
        if cfg.sysid is not None:
            if not 1 <= cfg.sysid <= 254 or cfg.sysid == gcs_sysid:
                raise LinkError(
                    f"{cfg.name}: sysid {cfg.sysid} must be 1-254 and differ from the ground station's"
                )
            if cfg.sysid in sysids:
                raise LinkError(f"{sysids[cfg.sysid]} and {cfg.name} are both given sysid {cfg.sysid}")
            sysids[cfg.sysid] = cfg.name
