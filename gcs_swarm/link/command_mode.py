"""How the ground station commands the fleet over the link it has (issue 38 item 3, docs/command-modes.md).

The link budget per vehicle (`link_budget`) comes from the mission: `world.link.budget_bps` when given, else
the capacity of the radio the mission names (`world.link.radio` and its overrides, docs/radio.md), else none
(unlimited). Before take-off `command_plan` turns it into a `CommandPlan`: the command mode and the telemetry
rates the ground station asks for (Fleet asks for them as soon as a vehicle is heard, so preflight's
parameter exchanges already run over the slowed link):

- ATTITUDE: the paper's SET_ATTITUDE_TARGET at the control rate, with the state telemetry (ATTITUDE,
  GLOBAL_POSITION_INT) at the same rate. Chosen without a budget (the flight of today) and whenever its
  bytes fit within MARGIN of the budget.
- POSITION: SET_POSITION_TARGET_GLOBAL_INT carrying the guidance's reference position, velocity and
  acceleration (the autopilot closes the loop: ArduCopter GUIDED's pos-vel-accel controller, PX4 OFFBOARD),
  one per position report, with the state telemetry at the fastest rate of POSITION_RATES_HZ that fits
  within MARGIN (the slowest, if only that fits the budget at all).

`world.link.command_mode` may force either mode.

In flight (`CommandModeWatch`, once per link_use window) the chosen mode steps down when the measured
downlink degrades: from ATTITUDE to POSITION, and from one POSITION rate to the next slower one, never back
up (no mode fight; docs/command-modes.md "In flight" says why), each step an event "command mode: ...
because ..." and a row of flight.json `command_mode_changes`; its thresholds, and whether it acts at all,
are the mission's `world.link.step_down` (`StepDown`).

Bytes are counted as on the wire: MAVLink 2 framing (10 header + 2 checksum bytes, + 13 signed) around each
message's full payload (pymavlink's struct size: the longest it can be; MAVLink 2 trims trailing zeros), and
per packet the radio's own overhead (its bytes, and its fixed air time as bytes at the radio's byte rate).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.link_use import TXBUF_LOW, WINDOW_MS, LinkUse
from gcs_swarm.link.streams import telemetry_rates
from swarm_common.radio_presets import RADIO_OVERRIDES, radio_spec

if TYPE_CHECKING:
    from gcs_swarm.link.vehicle import VehicleLink

ATTITUDE, POSITION = "attitude", "position"  # command modes (flight.json `command_mode.mode`)
MARGIN = 0.5  # share of the budget the planned streams may use: the rest is for parameter and command
# exchanges, retries, STATUSTEXTs and bursts
POSITION_RATES_HZ = (10.0, 5.0, 4.0)  # position-target (and state telemetry) rates tried, fastest first: at
# most 10 Hz (ArduCopter propagates its target with the velocity and acceleration sent between two), at
# least 4 Hz (PX4 OFFBOARD leaves the mode below 2 Hz: one lost setpoint in a row is ridden out)
STATUS_HZ = 2.0  # health telemetry (SYS_STATUS, EKF_STATUS_REPORT, EXTENDED_SYS_STATE, GPS_RAW_INT), Hz,
# as streams.telemetry_rates asks by default
STATUS_HZ_SLOW = 1.0  # ... in position mode
HEARTBEAT_HZ = 1.0  # each side's HEARTBEAT
# streams some autopilots send unasked (PX4's default set: ATTITUDE_QUATERNION and LOCAL_POSITION_NED at
# tens of Hz) with nothing the ground station does not also have from ATTITUDE and GLOBAL_POSITION_INT:
# stopped in the position mode
UNREAD_STREAMS = ("ATTITUDE_QUATERNION", "LOCAL_POSITION_NED")
MAVLINK2_FRAMING = 12  # bytes around a MAVLink 2 payload: 10 header + 2 checksum
SIGNATURE = 13  # bytes a MAVLink 2 signature adds
SETPOINT_MESSAGE = {ATTITUDE: "SET_ATTITUDE_TARGET", POSITION: "SET_POSITION_TARGET_GLOBAL_INT"}
# the in-flight watch (CommandModeWatch), per link_use window (1 s of vehicle time); its thresholds are the
# mission's (StepDown, world.link.step_down)
SETTLE_WINDOWS = 2  # windows after a step that are not judged: the new rates take effect, the queues drain
REASK_RATIO = 1.5  # positions still arriving above this times the rate asked after a step: ask again


@dataclass(frozen=True)
class StepDown:
    """When the command mode steps down in flight (CommandModeWatch; the mission's world.link.step_down,
    docs/command-modes.md "In flight"). The defaults are this project's choices, not the paper's."""

    enabled: bool = True  # False: the mode chosen before take-off is flown to the end
    # s of queueing: telemetry older at a window's end than this plus one report period is waiting on the air
    # (a SiK buffer full at 64 kbit/s holds 1850 B * 10.2 / 64000 = 0.29 s); the lockstep radio adds 1-2
    # frames (20-40 ms), quickstart_faulty's jitter at most 100 ms
    queue_age_s: float = 0.15
    # s (whole link_use windows of WINDOW_MS) a vehicle's downlink stays degraded before the fleet steps
    # down: the dwell, one bad window is a burst; the stale-telemetry watch holds vehicles at 1 s of age
    after_s: int = 2

    @property
    def windows(self) -> int:
        """after_s in link_use windows (at least one)."""
        return max(1, math.ceil(self.after_s * 1000 / WINDOW_MS))


DEFAULT_STEP_DOWN = StepDown()  # a mission without world.link.step_down


class CommandModeError(Exception):
    """The link budget cannot carry even the slowest command mode (one sentence)."""


@dataclass(frozen=True)
class LinkBudget:
    """What one vehicle's link carries, up and down together: bytes_per_s MAVLink bytes a second, and
    packet_bytes more counted for each packet (a radio's overhead); `source` says where it comes from."""

    bytes_per_s: float
    packet_bytes: float
    source: str


def link_budget(link: object, n_vehicles: int) -> LinkBudget | None:
    """The budget of each vehicle's link from a mission's `world.link` (model.LinkSpec): budget_bps / 8 when
    given; else the radio's capacity in MAVLink bytes, capacity_bps / bits_per_byte (eq. 1 of docs/radio.md,
    up and down together: conservative for a full-duplex radio), divided among n_vehicles when the medium is
    shared, each packet counted with overhead_bytes plus overhead_us of air time as bytes; None without
    either (unlimited)."""
    budget_bps = getattr(link, "budget_bps", None)
    if budget_bps is not None:
        return LinkBudget(float(budget_bps) / 8.0, 0.0, f"world.link.budget_bps {float(budget_bps):g} bit/s")
    overrides = {key: getattr(link, key, None) for key in RADIO_OVERRIDES}
    spec = radio_spec(getattr(link, "radio", None), overrides)
    if spec is None:
        return None
    byte_rate = spec.capacity_bps / spec.bits_per_byte  # bytes/s on the air
    share = n_vehicles if spec.shared else 1
    name = getattr(link, "radio", None) or "radio"
    return LinkBudget(
        byte_rate / share,
        spec.overhead_bytes + spec.overhead_us * 1e-6 * byte_rate,
        f"{name} {spec.capacity_bps:g} bit/s / {spec.bits_per_byte:g} bit times a byte"
        + (f" shared by {n_vehicles}" if spec.shared else ""),
    )


def wire_bytes(message: str, signed: bool = False) -> int:
    """Bytes of one MAVLink 2 packet of `message` (a name) at its full payload."""
    cls = mavlink2.mavlink_map[getattr(mavlink2, f"MAVLINK_MSG_ID_{message}")]
    return cls.unpacker.size + MAVLINK2_FRAMING + (SIGNATURE if signed else 0)


@dataclass(frozen=True)
class CommandPlan:
    """The command mode (ATTITUDE | POSITION), the setpoint rate Hz (one per state report in POSITION), the
    state and health telemetry rates Hz asked for, the bytes/s the planned streams need up and down (with the
    radio's packet overhead), what ATTITUDE would need, the budget (None: unlimited), and whether the mission
    forced the mode."""

    mode: str
    setpoint_hz: float
    state_hz: float
    status_hz: float
    up_B_s: float
    down_B_s: float
    attitude_B_s: float
    budget: LinkBudget | None
    forced: bool = False  # chosen by world.link.command_mode, not from the budget
    signed: bool = False  # the bytes counted with MAVLink 2 signatures

    @property
    def telemetry(self) -> dict[str, float]:
        """Message name -> rate Hz to ask each vehicle for (streams.Streams.op_request_streams; 0: stop)."""
        rates = telemetry_rates(self.state_hz, self.status_hz)
        if self.mode == POSITION:
            rates.update({name: 0.0 for name in UNREAD_STREAMS})
        return rates

    def text(self) -> str:
        """The event that says which mode was chosen and why."""
        need = f"{self.up_B_s + self.down_B_s:.0f} B/s"
        why = " (world.link.command_mode)" if self.forced else ""
        if self.mode == ATTITUDE:
            head = f"command mode: attitude targets at {self.setpoint_hz:g} Hz{why}"
            if self.budget is None:
                return f"{head}, no link budget"
            return f"{head}, {need} of a {self.budget.bytes_per_s:.0f} B/s budget ({self.budget.source})"
        head = f"command mode: position targets at {self.setpoint_hz:g} Hz{why} ({need})"
        if self.budget is None:
            return f"{head}, no link budget"
        budget = self.budget.bytes_per_s
        margin = "" if self.up_B_s + self.down_B_s <= MARGIN * budget else f", beyond the {MARGIN:.0%} margin"
        return (
            f"{head}, attitude targets need {self.attitude_B_s:.0f} B/s of a {budget:.0f} B/s budget "
            f"({self.budget.source}){margin}"
        )

    def as_json(self) -> dict[str, object]:
        """flight.json `command_mode`."""
        return {
            "mode": self.mode,
            "setpoint_hz": self.setpoint_hz,
            "state_hz": self.state_hz,
            "status_hz": self.status_hz,
            "planned_up_B_s": round(self.up_B_s, 1),
            "planned_down_B_s": round(self.down_B_s, 1),
            "attitude_B_s": round(self.attitude_B_s, 1),
            "budget_B_s": None if self.budget is None else round(self.budget.bytes_per_s, 1),
            "budget_source": None if self.budget is None else self.budget.source,
            "forced": self.forced,
        }


def stream_bytes(
    mode: str, setpoint_hz: float, state_hz: float, status_hz: float, packet_bytes: float, signed: bool
) -> tuple[float, float]:
    """(up, down) bytes/s of one vehicle's planned streams: the setpoints and the ground station's HEARTBEAT
    up; the state and health telemetry (streams.telemetry_rates) and the vehicle's HEARTBEAT down; each packet
    plus packet_bytes."""

    def rate(message: str, hz: float) -> float:
        return hz * (wire_bytes(message, signed) + packet_bytes)

    up = rate(SETPOINT_MESSAGE[mode], setpoint_hz) + rate("HEARTBEAT", HEARTBEAT_HZ)
    telemetry = telemetry_rates(state_hz, status_hz)
    down = sum(rate(m, hz) for m, hz in telemetry.items()) + rate("HEARTBEAT", HEARTBEAT_HZ)
    return up, down


def command_plan(
    budget: LinkBudget | None, control_hz: float, signed: bool = False, mode: str = "auto"
) -> CommandPlan:
    """The command mode and telemetry rates for a link of `budget` at the control rate control_hz Hz, packets
    signed or not (see the module doc). `mode` (world.link.command_mode): "auto" chooses ATTITUDE when it
    fits within MARGIN of the budget, else POSITION (position_plan); "attitude" or "position" force the mode.
    CommandModeError (one sentence) when POSITION is to be flown and not even its slowest rate fits the
    budget."""
    packet = 0.0 if budget is None else budget.packet_bytes
    attitude = stream_bytes(ATTITUDE, control_hz, control_hz, STATUS_HZ, packet, signed)
    fits = budget is None or sum(attitude) <= MARGIN * budget.bytes_per_s
    forced = mode != "auto"
    if mode == ATTITUDE or (mode == "auto" and fits):
        return CommandPlan(
            ATTITUDE, control_hz, control_hz, STATUS_HZ, *attitude, sum(attitude), budget, forced, signed
        )
    plan = position_plan(budget, control_hz, signed, sum(attitude), forced)
    assert plan is not None  # no rate is excluded here
    need = plan.up_B_s + plan.down_B_s
    if budget is not None and need > budget.bytes_per_s:
        raise CommandModeError(
            f"the link budget of {budget.bytes_per_s:.0f} B/s per vehicle ({budget.source}) cannot carry "
            f"position targets at {plan.setpoint_hz:g} Hz with their telemetry ({need:.0f} B/s): "
            "raise world.link.budget_bps or choose a faster radio"
        )
    return plan


def position_plan(
    budget: LinkBudget | None,
    control_hz: float,
    signed: bool,
    attitude_B_s: float,
    forced: bool = False,
    below_hz: float = math.inf,
) -> CommandPlan | None:
    """POSITION at the fastest of POSITION_RATES_HZ (each capped at control_hz Hz, only those below below_hz)
    whose streams need at most MARGIN of the budget, else at the slowest of them (which may not fit: the
    caller decides); the fastest without a budget; None when no rate is below below_hz. attitude_B_s: what
    ATTITUDE would need (for the event)."""
    rates = [r for r in dict.fromkeys(min(hz, control_hz) for hz in POSITION_RATES_HZ) if r < below_hz]
    if not rates:
        return None
    packet = 0.0 if budget is None else budget.packet_bytes
    needs = [stream_bytes(POSITION, hz, hz, STATUS_HZ_SLOW, packet, signed) for hz in rates]
    within = [k for k, need in enumerate(needs) if budget is None or sum(need) <= MARGIN * budget.bytes_per_s]
    choice = within[0] if within else len(rates) - 1
    hz = rates[choice]
    return CommandPlan(POSITION, hz, hz, STATUS_HZ_SLOW, *needs[choice], attitude_B_s, budget, forced, signed)


def change_row(
    t_s: float, was: CommandPlan, now: CommandPlan, vehicle: str, reason: str
) -> dict[str, object]:
    """One row of flight.json `command_mode_changes`: at vehicle time t_s s the fleet went from plan `was`
    to plan `now` because `vehicle`'s downlink was degraded (`reason`, as in the event); the bytes/s the new
    plan needs each way."""
    return {
        "t_s": round(t_s, 3),
        "from_mode": was.mode,
        "from_hz": was.setpoint_hz,
        "to_mode": now.mode,
        "to_hz": now.setpoint_hz,
        "vehicle": vehicle,
        "reason": reason,
        "planned_up_B_s": round(now.up_B_s, 1),
        "planned_down_B_s": round(now.down_B_s, 1),
    }


class CommandModeWatch:
    """Steps the command mode down in flight when a vehicle's downlink stays degraded (module doc).

    After each link_use window (`sample`), a vehicle that delivered positions in it is degraded when its
    telemetry queues (older than step_down.queue_age_s plus one report period, 1 / state_hz, at the window's
    end) or its radio's RADIO_STATUS txbuf (where one reports) is below link_use.TXBUF_LOW. The positions'
    arrival rate is not a trigger by itself: random loss and reordering lower it as much as congestion does
    (quickstart_faulty's 100 ms of jitter makes many positions late, which the intake drops), while only
    congestion makes the telemetry wait. A window without any position (an outage, a reboot, a lost vehicle:
    the stale-telemetry and loss watches' business, which a slower mode would not help) clears the vehicle's
    count. step_down.after_s of such windows in a row of any vehicle step the whole fleet down one step:
    ATTITUDE -> POSITION, or POSITION -> its next slower rate, the rate chosen by position_plan against what
    the degraded link carried in its last window, up and down (its capacity, when full); never back up. A mode
    the mission forced is kept, and so is every mode when step_down.enabled is false. After a step the
    telemetry of the new plan is asked for without waiting (Streams.ask), asked again each window a vehicle
    still sends positions above REASK_RATIO times the new rate, and SETTLE_WINDOWS windows are not judged.
    Each step is a row of `changes` (flight.json command_mode_changes)."""

    def __init__(
        self, links: Sequence[VehicleLink], use: LinkUse, step_down: StepDown = DEFAULT_STEP_DOWN
    ) -> None:
        self.links = links
        self.use = use
        self.step_down = step_down
        self.changes: list[dict[str, object]] = []  # one row per step (`change_row`), oldest first
        self.degraded = np.zeros(len(links), dtype=np.int64)  # (N,) consecutive degraded windows
        self.settle = 0  # windows still not judged after a step
        self.windows = 0  # use.windows at the last sample
        self.steps = 0  # steps down taken
        self.exhausted = False  # at the slowest rate and degraded again: said once, nothing more to do

    def sample(self, plan: CommandPlan | None) -> CommandPlan | None:
        """The plan to fly after the latest link_use window (`plan` itself, or the next step down, whose
        telemetry is then asked for and whose event is out)."""
        use = self.use
        if plan is None or plan.forced or not self.step_down.enabled or use.windows == self.windows:
            return plan
        self.windows = use.windows
        if plan.mode == POSITION and self.steps:
            self._reask(plan)
        if self.settle > 0:
            self.settle -= 1
            self.degraded[:] = 0
            return plan
        reasons = self._judge(plan)
        worst = int(np.argmax(self.degraded))
        if self.degraded[worst] < self.step_down.windows or self.exhausted:
            return plan
        carried = float(np.nansum(use.rate[worst]))
        budget = LinkBudget(
            carried,
            0.0 if plan.budget is None else plan.budget.packet_bytes,
            f"{self.links[worst].name}'s link carried {carried:.0f} B/s",
        )
        below = plan.setpoint_hz if plan.mode == POSITION else math.inf
        step = position_plan(budget, plan.setpoint_hz, plan.signed, plan.attitude_B_s, below_hz=below)
        because = f"because {self.links[worst].name}'s {reasons[worst]} for {self.step_down.after_s} s"
        if step is None:
            self.exhausted = True
            use.fleet_event(
                f"command mode: position targets at {plan.setpoint_hz:g} Hz are the slowest, kept {because}"
            )
            return plan
        # the measured budget chose the rate; the budget the link use is held against stays the mission's
        step = replace(step, budget=plan.budget)
        self.steps += 1
        self.settle = SETTLE_WINDOWS
        self.degraded[:] = 0
        for link in self.links:
            if link.sysid is not None:
                link.streams.ask(step.telemetry)
        was = "attitude targets" if plan.mode == ATTITUDE else "position targets"
        need = step.up_B_s + step.down_B_s
        t_s = use.fleet_event(
            f"command mode: position targets at {step.setpoint_hz:g} Hz ({need:.0f} B/s), telemetry at "
            f"{step.state_hz:g} Hz, instead of {was} at {plan.setpoint_hz:g} Hz {because}"
        )
        self.changes.append(change_row(t_s, plan, step, self.links[worst].name, reasons[worst]))
        return step

    def _judge(self, plan: CommandPlan) -> list[str]:
        """Count each vehicle's degraded windows (class doc) after the latest; what was wrong, per vehicle."""
        use = self.use
        reasons = []
        for i, link in enumerate(self.links):
            hz, age, txbuf = float(use.position_hz[i]), float(use.age_s[i]), link.radio.txbuf
            wrong = []
            if age > self.step_down.queue_age_s + 1.0 / plan.state_hz:
                wrong.append(f"telemetry was {age:.2f} s old (positions at {hz:.0f} of {plan.state_hz:g} Hz)")
            if txbuf is not None and txbuf < TXBUF_LOW:
                wrong.append(f"radio buffer was {txbuf}% free")
            silent = not hz > 0
            self.degraded[i] = 0 if silent or not wrong else self.degraded[i] + 1
            reasons.append(", ".join(wrong))
        return reasons

    def _reask(self, plan: CommandPlan) -> None:
        """Ask again for the plan's telemetry where positions still come faster than REASK_RATIO times its
        rate (the request after a step was lost on the congested link)."""
        for i, link in enumerate(self.links):
            if link.sysid is not None and self.use.position_hz[i] > REASK_RATIO * plan.state_hz:
                link.streams.ask(plan.telemetry)
