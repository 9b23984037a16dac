"""A stand-in Fleet for unit tests of the mission runner's decisions (gcs_swarm.flight.runner): three
ArduCopters whose state the test writes (positions, velocities, HEARTBEAT modes, telemetry ages) and whose
every command is recorded, so a test can say exactly what the ground station sent to whom and when.

Each `wait_tick` advances every live vehicle's time_boot_ms by one control period (20 ms at the missions'
50 Hz); positions move only when the test moves them. Mode, arm and land commands take effect at once (the
real link waits for the HEARTBEAT that confirms them; here it is there immediately).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from gcs_swarm.link.autopilots import DEFAULT_DIALECT, AutopilotDialect, ModeChoice, mode_name_in
from gcs_swarm.link.connection import LinkError

TICK_MS = 20  # one control period at run.control_rate_hz 50


@dataclass(frozen=True)
class Sent:
    """One command the runner sent: the vehicle time `t_ms` (ms) at which, the vehicle `row`, its `kind`
    ("attitude", "position", "velocity", "mode", "arm", "takeoff") and `value` (the mode name, the position
    target (3,) ENU m, or None)."""

    t_ms: int
    row: int
    kind: str
    value: object = None


@dataclass
class ScriptedFleet:
    """The parts of gcs_swarm.link.fleet.Fleet the runner uses, for `names` vehicles at `pos` (N, 3) ENU m,
    each heading `yaw` rad (ENU). The test writes the state in `state`, as the telemetry would: pos (N, 3)
    ENU m, vel (N, 3) ENU m/s, att (N, 3) rad, mode (N,) custom_mode (-1 before a HEARTBEAT), armed, alive
    (N,) bool, time_ms and position_ms (N,) the newest time_boot_ms and that of the latest position; the
    properties return copies, as Fleet's do."""

    names: list[str]
    pos0: np.ndarray
    yaw: float = 0.0
    sent: list[Sent] = field(default_factory=list)
    on_tick: Callable[[], None] | None = None  # called after each tick's clock step: the test's script
    pump_wait_s: float = 0.0  # Fleet's pump clock (flight.tick_timing): no time passes here
    pump_work_s: float = 0.0
    command_plan: None = None  # Fleet.command_plan: None, the paper's attitude targets (link.command_mode)

    def __post_init__(self) -> None:
        n = len(self.names)
        att = np.zeros((n, 3))
        att[:, 2] = self.yaw
        self.state = SimpleNamespace(
            pos=np.array(self.pos0, dtype=float),
            vel=np.zeros((n, 3)),
            att=att,
            mode=np.full(n, -1, dtype=np.int64),
            armed=np.zeros(n, dtype=bool),
            alive=np.ones(n, dtype=bool),
            time_ms=np.full(n, 100_000, dtype=np.int64),
            position_ms=np.full(n, 100_000, dtype=np.int64),
            frames_missed=np.zeros(n, dtype=np.int64),
        )
        self._links = [self._link(i) for i in range(n)]

    # ----- what the test reads

    def sent_to(self, row: int, since_ms: int = 0) -> list[Sent]:
        """Every command sent to vehicle `row` at vehicle time >= since_ms."""
        return [s for s in self.sent if s.row == row and s.t_ms >= since_ms]

    def kinds_at(self, t_ms: int) -> dict[int, set[str]]:
        """{row: kinds of command} sent at vehicle time t_ms."""
        out: dict[int, set[str]] = {}
        for s in self.sent:
            if s.t_ms == t_ms:
                out.setdefault(s.row, set()).add(s.kind)
        return out

    @property
    def now_ms(self) -> int:
        return int(self.state.time_ms.max())

    # ----- what the runner calls

    @property
    def pos(self) -> np.ndarray:
        return self.state.pos.copy()

    @property
    def vel(self) -> np.ndarray:
        return self.state.vel.copy()

    @property
    def att(self) -> np.ndarray:
        return self.state.att.copy()

    @property
    def mode(self) -> np.ndarray:
        return self.state.mode.copy()

    @property
    def armed(self) -> np.ndarray:
        return self.state.armed.copy()

    @property
    def alive(self) -> np.ndarray:
        return self.state.alive.copy()

    @property
    def time_ms(self) -> np.ndarray:
        return self.state.time_ms.copy()

    @property
    def dialects(self) -> list[AutopilotDialect]:
        return [DEFAULT_DIALECT] * len(self.names)

    def mode_number(self, i: int, mode: ModeChoice) -> int:
        return DEFAULT_DIALECT.mode_number(mode_name_in(DEFAULT_DIALECT, mode))

    def in_mode(self, mode: ModeChoice) -> np.ndarray:
        return self.state.mode == self.mode_number(0, mode)

    def vehicle(self, i: int) -> SimpleNamespace:
        return self._links[i]

    def wait_tick(self, timeout_s: float) -> bool:
        st = self.state
        st.time_ms[st.alive] += TICK_MS
        st.position_ms[st.alive] += TICK_MS
        if self.on_tick is not None:
            self.on_tick()
        return True

    def answer_frame(self, mask: object = None) -> None:
        pass

    def pump(self, timeout_s: float = 0.0) -> None:
        pass

    def wait_until(self, predicate: Callable[[], bool], timeout_s: float, what: str) -> None:
        for _ in range(round(timeout_s * 1000 / TICK_MS)):
            if predicate():
                return
            self.wait_tick(0.0)
        raise LinkError(f"timed out after {timeout_s:g} s waiting for {what}")

    def send_attitude_targets(
        self, roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray, thrust: np.ndarray, mask: np.ndarray
    ) -> None:
        for i in np.flatnonzero(mask):
            self.sent.append(Sent(self.now_ms, int(i), "attitude"))

    def set_mode_all(self, mode: ModeChoice, vehicles: Iterable[int] | None = None) -> None:
        name = mode_name_in(DEFAULT_DIALECT, mode)
        for i in self._rows(vehicles):
            self.sent.append(Sent(self.now_ms, i, "mode", name))
            self.state.mode[i] = DEFAULT_DIALECT.mode_number(name)

    def take_control_all(self, vehicles: Iterable[int] | None = None) -> None:
        """ArduCopter: GUIDED (no setpoint stream needed)."""
        self.set_mode_all(DEFAULT_DIALECT.formation_mode, vehicles)

    def arm_all(self, force: bool = False, vehicles: Iterable[int] | None = None) -> None:
        for i in self._rows(vehicles):
            self.sent.append(Sent(self.now_ms, i, "arm"))
            self.state.armed[i] = True

    def takeoff_all(self, alt_m: np.ndarray, vehicles: Iterable[int] | None = None) -> None:
        for i in self._rows(vehicles):
            self.sent.append(
                Sent(self.now_ms, i, "takeoff", float(np.broadcast_to(alt_m, len(self.names))[i]))
            )

    def land_all(self, vehicles: Iterable[int] | None = None) -> None:
        """LAND, and (as if at once on the ground) disarmed."""
        for i in self._rows(vehicles):
            self.sent.append(Sent(self.now_ms, i, "mode", "LAND"))
            self.state.mode[i] = DEFAULT_DIALECT.mode_number("LAND")
            self.state.armed[i] = False

    def _rows(self, vehicles: Iterable[int] | None) -> list[int]:
        return list(range(len(self.names))) if vehicles is None else [int(i) for i in vehicles]

    def _link(self, i: int) -> SimpleNamespace:
        def position_target(pos: np.ndarray, yaw: float | None = None) -> None:
            self.sent.append(Sent(self.now_ms, i, "position", np.array(pos, dtype=float)))

        def velocity_target(vel: np.ndarray, yaw: float | None = None) -> None:
            self.sent.append(Sent(self.now_ms, i, "velocity", np.array(vel, dtype=float)))

        return SimpleNamespace(
            name=self.names[i],
            channel=SimpleNamespace(autopilot=DEFAULT_DIALECT),
            mode_name=lambda: DEFAULT_DIALECT.mode_name(int(self.state.mode[i])),
            setpoints=SimpleNamespace(
                send_position_target=position_target, send_velocity_target=velocity_target
            ),
        )
