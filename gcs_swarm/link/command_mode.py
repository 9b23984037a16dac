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

Bytes are counted as on the wire: MAVLink 2 framing (10 header + 2 checksum bytes, + 13 signed) around each
message's full payload (pymavlink's struct size: the longest it can be; MAVLink 2 trims trailing zeros), and
per packet the radio's own overhead (its bytes, and its fixed air time as bytes at the radio's byte rate).
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.streams import telemetry_rates
from swarm_common.radio_presets import RADIO_OVERRIDES, radio_spec

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
    fits within MARGIN of the budget, else POSITION at the fastest of POSITION_RATES_HZ that fits within
    MARGIN, else at the slowest if that fits the budget at all; "attitude" or "position" force the mode (at
    that rate rule). CommandModeError (one sentence) when POSITION is to be flown and not even its slowest
    rate fits the budget."""
    packet = 0.0 if budget is None else budget.packet_bytes
    attitude = stream_bytes(ATTITUDE, control_hz, control_hz, STATUS_HZ, packet, signed)
    fits = budget is None or sum(attitude) <= MARGIN * budget.bytes_per_s
    if mode == ATTITUDE or (mode == "auto" and fits):
        return CommandPlan(
            ATTITUDE, control_hz, control_hz, STATUS_HZ, *attitude, sum(attitude), budget, mode != "auto"
        )
    rates = [min(hz, control_hz) for hz in POSITION_RATES_HZ]
    needs = [stream_bytes(POSITION, hz, hz, STATUS_HZ_SLOW, packet, signed) for hz in rates]
    if budget is None:
        choice = 0
    else:
        within = [k for k, need in enumerate(needs) if sum(need) <= MARGIN * budget.bytes_per_s]
        choice = within[0] if within else len(rates) - 1
        if sum(needs[choice]) > budget.bytes_per_s:
            raise CommandModeError(
                f"the link budget of {budget.bytes_per_s:.0f} B/s per vehicle ({budget.source}) cannot carry "
                f"position targets at {rates[-1]:g} Hz with their telemetry ({sum(needs[-1]):.0f} B/s): "
                "raise world.link.budget_bps or choose a faster radio"
            )
    hz = rates[choice]
    return CommandPlan(
        POSITION, hz, hz, STATUS_HZ_SLOW, *needs[choice], sum(attitude), budget, mode != "auto"
    )
