"""Blocking exchanges with one vehicle as `Operation` generators, and its commands (COMMAND_LONG + ACK, modes,
arming, takeoff).

An operation sends, then yields while it waits; the fleet pumps every link (and answers lockstep frames)
between steps (gcs_swarm.link.fleet.Fleet.run), so many vehicles can wait at once in one thread and the
simulator is never left waiting.

Timeouts count vehicle time (`Timeout`: the vehicle's time_boot_ms as it advances), so a retry means the
same against hardware in real time and against a lockstep simulator running 20x faster, and a lockstep run
resends at the same frames whatever the machine's speed. Repeats are safe because ArduCopter answers them
idempotently (arm when armed, disarm when disarmed, the current mode: ACCEPTED); the one exception, a repeated
NAV_TAKEOFF refused because the first one (whose ACK was lost) already started the climb, is recognised by
`Commands.op_takeoff`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Generator
from typing import TypeVar

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.autopilots import ModeChoice, mode_name_in
from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import LinkError, MAVLinkMessage
from gcs_swarm.link.telemetry import VehicleTelemetry

T = TypeVar("T")
Operation = Generator[None, None, T]
"""A blocking exchange with one vehicle; yields while it waits, returns its result (see module doc)."""

STATUSTEXT_GRACE_S = 0.3  # vehicle s: ArduPilot queues the "PreArm: ..." text, so it may follow the ACK
CLOCK_STALL_S = 2.0  # [add] wall s a vehicle clock must stand still before timeouts also end on wall time
COMMAND_RETRIES = 10  # [add] resends after a silent timeout: at 10 % loss each way 11 attempts fail ~1e-8
CONFIRM_TIMEOUT_S = 5.0  # [add] vehicle s for a 1 Hz HEARTBEAT to show a new mode / arming state
TAKEOFF_EVIDENCE_S = 3.0  # [add] vehicle s to wait for signs of a climb after a repeated takeoff is refused
TAKEOFF_CLIMB_M = 0.5  # [add] climb since the first NAV_TAKEOFF that shows the vehicle is taking off


class Timeout:
    """`seconds` of vehicle time, read from `clock()` -> (ms of vehicle time elapsed since some start, never
    decreasing; monotonic wall s at which it last advanced).

    Vehicle time makes a timeout mean the same in lockstep at any simulator speed and in real time against
    hardware. Backstop for a clock that stands still (no stamped telemetry: link down, nothing streamed): once
    it has not advanced for CLOCK_STALL_S wall seconds, `seconds` of wall time since the start also end it.
    """

    def __init__(self, seconds: float, clock: Callable[[], tuple[int, float]]) -> None:
        self.seconds = seconds
        self._clock = clock
        self.restart()

    def restart(self) -> None:
        """Count from now."""
        self._start_ms = self._clock()[0]
        self._start_wall = time.monotonic()

    def expired(self) -> bool:
        ms, advanced_wall = self._clock()
        if ms - self._start_ms >= self.seconds * 1000.0:
            return True
        now = time.monotonic()
        return now - self._start_wall >= self.seconds and now - advanced_wall >= CLOCK_STALL_S


def message_id(message: str | int) -> int:
    """MAVLink message name (e.g. "ATTITUDE") or id -> id; ValueError if this dialect does not know it."""
    if isinstance(message, int):
        if message in mavlink2.mavlink_map:
            return message
    else:
        msg_id = getattr(mavlink2, f"MAVLINK_MSG_ID_{message.strip().upper()}", None)
        if isinstance(msg_id, int):
            return msg_id
    raise ValueError(f"unknown MAVLink message {message!r}")


def _enum_name(enum: str, value: int, prefix: str) -> str:
    entry = mavlink2.enums[enum].get(value)
    return entry.name.removeprefix(prefix) if entry is not None else f"{prefix}{value}"


def command_name(command: int) -> str:
    """MAV_CMD number -> "MAV_CMD_..." name."""
    return _enum_name("MAV_CMD", command, "")


def result_name(result: int) -> str:
    """MAV_RESULT number -> short name, e.g. "FAILED"."""
    return _enum_name("MAV_RESULT", result, "MAV_RESULT_")


def require_alive(channel: Channel, telemetry: VehicleTelemetry) -> None:
    """LinkError unless the vehicle is connected, identified and its link alive."""
    if channel.endpoint is None or channel.sysid is None:
        raise LinkError(f"{channel.name} is not connected")
    if not telemetry.state.alive[telemetry.index]:
        raise LinkError(f"{channel.name} is not responding (its link is down)")


class Commands:
    """COMMAND_LONG exchanges with the vehicle behind `channel`, and the operations built on them."""

    def __init__(self, channel: Channel, telemetry: VehicleTelemetry) -> None:
        self.channel = channel
        self.telemetry = telemetry
        self.name = channel.name
        self._acks: dict[int, MAVLinkMessage] = {}
        self._pending: set[int] = set()

    def on_command_ack(self, m: MAVLinkMessage) -> None:
        """A COMMAND_ACK for us (or broadcast): kept for the exchange waiting on its command."""
        if m.target_system in (0, self.channel.gcs_sysid):
            self._acks[m.command] = m

    def op_command(
        self,
        command: int,
        *params: float,
        retries: int = COMMAND_RETRIES,
        timeout_s: float = 1.0,
        in_progress_timeout_s: float = 10.0,
    ) -> Operation[int]:
        """COMMAND_LONG until COMMAND_ACK: resend with `confirmation` + 1 after each silent `timeout_s`.

        MAV_RESULT_IN_PROGRESS stops the resending and waits up to `in_progress_timeout_s` for the final
        result. Both are seconds of vehicle time (`Timeout`). Returns MAV_RESULT_ACCEPTED; any other result
        raises LinkError with the result's name and the vehicle's last STATUSTEXT (ArduPilot explains refusals
        there).
        """
        texts_before = self.telemetry.statustexts
        result, _ = yield from self._op_exchange(command, params, retries, timeout_s, in_progress_timeout_s)
        if result != mavlink2.MAV_RESULT_ACCEPTED:
            raise (yield from self._op_refusal(command, result, texts_before))
        return result

    def _op_exchange(
        self,
        command: int,
        params: tuple[float, ...],
        retries: int,
        timeout_s: float,
        in_progress_timeout_s: float,
    ) -> Operation[tuple[int, int]]:
        """The COMMAND_LONG / COMMAND_ACK exchange of `op_command`; returns (final MAV_RESULT, attempts)."""
        if len(params) > 7:
            raise ValueError("COMMAND_LONG has 7 parameters")
        if command in self._pending:
            raise RuntimeError(f"{command_name(command)} is already pending on {self.name}")
        require_alive(self.channel, self.telemetry)
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        if any(math.isinf(v) for v in values):  # NaN is MAVLink's "unchanged / default" (PX4 takeoff)
            raise ValueError(f"non-finite parameter in {command_name(command)} for {self.name}: {values}")
        self._acks.pop(command, None)
        self._pending.add(command)
        clock = self.telemetry.vehicle_clock
        try:
            attempt, in_progress = 0, False
            self.channel.send_command(command, attempt, values)
            timeout = Timeout(timeout_s, clock)
            while True:
                yield
                ack = self._acks.pop(command, None)
                if ack is not None and ack.result != mavlink2.MAV_RESULT_IN_PROGRESS:
                    return int(ack.result), attempt + 1
                if ack is not None:
                    in_progress, timeout = True, Timeout(in_progress_timeout_s, clock)
                elif timeout.expired():
                    if in_progress:
                        raise LinkError(
                            f"{self.name} did not finish {command_name(command)} within "
                            f"{in_progress_timeout_s:g} s of reporting it in progress"
                        )
                    if attempt >= retries:
                        raise LinkError(
                            f"{self.name} did not acknowledge {command_name(command)} "
                            f"({attempt + 1} attempts, {timeout_s:g} s each)"
                        )
                    attempt += 1
                    self.channel.send_command(command, attempt, values)
                    timeout.restart()
        finally:
            self._pending.discard(command)

    def _op_refusal(self, command: int, result: int, texts_before: int) -> Operation[LinkError]:
        """The LinkError for a refused command, once the STATUSTEXT that may explain it had time to arrive."""
        telemetry = self.telemetry
        grace = Timeout(STATUSTEXT_GRACE_S, telemetry.vehicle_clock)
        while telemetry.statustexts == texts_before and not grace.expired():
            yield
        reason = f" ({telemetry.last_statustext})" if telemetry.statustexts > texts_before else ""
        return LinkError(f"{self.name} refused {command_name(command)}: {result_name(result)}{reason}")

    def _op_wait(
        self, done: Callable[[], bool], timeout_s: float, failure: Callable[[], str]
    ) -> Operation[None]:
        timeout = Timeout(timeout_s, self.telemetry.vehicle_clock)
        while not done():
            if timeout.expired():
                raise LinkError(failure())
            yield

    def op_set_mode(self, mode: ModeChoice, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """MAV_CMD_DO_SET_MODE (the autopilot's custom mode, named in its dialect, or a ModeChoice function
        of the dialect); done once a HEARTBEAT shows the new mode, which must happen within `timeout_s` of
        vehicle time after the ACK. PX4 (since 2025, mavlink_receiver.cpp) ACKs the command ACCEPTED at once
        and its commander answers again with the real result: a second ACK that refuses, while the HEARTBEAT
        is awaited, is the answer."""
        dialect = self.channel.autopilot
        try:
            number = dialect.mode_number(mode_name_in(dialect, mode))
        except ValueError as err:
            raise LinkError(f"{self.name}: {err}") from None
        st, i = self.telemetry.state, self.telemetry.index
        if st.mode[i] == number:
            return
        command, texts_before = mavlink2.MAV_CMD_DO_SET_MODE, self.telemetry.statustexts
        yield from self.op_command(command, *dialect.set_mode_params(number))
        timeout = Timeout(timeout_s, self.telemetry.vehicle_clock)
        while st.mode[i] != number:
            late = self._acks.pop(command, None)
            if late is not None and late.result not in (
                mavlink2.MAV_RESULT_ACCEPTED,
                mavlink2.MAV_RESULT_IN_PROGRESS,
            ):
                raise (yield from self._op_refusal(command, int(late.result), texts_before))
            if timeout.expired():
                raise LinkError(
                    f"{self.name} accepted mode {dialect.mode_name(number)} but its HEARTBEAT still shows "
                    f"{dialect.mode_name(int(st.mode[i]))} after {timeout_s:g} s"
                )
            yield

    def op_land(self, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """Land where the vehicle is: its dialect's `land_mode` (`op_set_mode`)."""
        return self.op_set_mode(self.channel.autopilot.land_mode, timeout_s)

    def _op_arm_disarm(self, arm: bool, force: bool, timeout_s: float) -> Operation[None]:
        st, i = self.telemetry.state, self.telemetry.index
        if bool(st.armed[i]) == arm:
            return
        dialect = self.channel.autopilot
        yield from self.op_command(
            mavlink2.MAV_CMD_COMPONENT_ARM_DISARM,
            1.0 if arm else 0.0,
            (dialect.force_arm_param2 if arm else dialect.force_disarm_param2) if force else 0.0,
        )
        word = "armed" if arm else "disarmed"
        yield from self._op_wait(
            lambda: bool(st.armed[i]) == arm,
            timeout_s,
            lambda: (
                f"{self.name} accepted the {word[:-2]} command but its HEARTBEAT does not show it {word} "
                f"after {timeout_s:g} s"
            ),
        )

    def op_arm(self, force: bool = False, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """Arm (force skips pre-arm checks); done once a HEARTBEAT shows the vehicle armed (within `timeout_s`
        vehicle seconds of the ACK). A repeat after a lost ACK is harmless: ArduCopter accepts arming an armed
        vehicle (AP_Arming_Copter::arm)."""
        return self._op_arm_disarm(True, force, timeout_s)

    def op_disarm(self, force: bool = False, timeout_s: float = CONFIRM_TIMEOUT_S) -> Operation[None]:
        """Disarm (force also in flight: the motors stop); done once a HEARTBEAT shows it disarmed."""
        return self._op_arm_disarm(False, force, timeout_s)

    def op_takeoff(
        self, alt_m: float, retries: int = COMMAND_RETRIES, timeout_s: float = 1.0
    ) -> Operation[int]:
        """MAV_CMD_NAV_TAKEOFF to `alt_m` above the ground the vehicle stands on (ArduCopter: GUIDED and
        armed; PX4: armed; the parameters are the dialect's `takeoff_params`: PX4's param7 is AMSL).

        ArduCopter refuses a takeoff once the vehicle has left the ground (Mode::do_user_takeoff, "can't
        takeoff again"). So when the first command's ACK was lost and a repeat is refused, the takeoff counts
        as done (ACCEPTED, with an event) if within TAKEOFF_EVIDENCE_S of vehicle time the vehicle, on the
        ground at the first command, is evidently taking off: armed, in the same mode, and EXTENDED_SYS_STATE
        shows it taking off or in the air, or it has climbed TAKEOFF_CLIMB_M.
        """
        st, i = self.telemetry.state, self.telemetry.index
        mode, alt0 = int(st.mode[i]), float(st.geodetic[i, 2])
        on_ground = st.landed_state[i] in (
            mavlink2.MAV_LANDED_STATE_UNDEFINED,
            mavlink2.MAV_LANDED_STATE_ON_GROUND,
        )
        command, texts_before = mavlink2.MAV_CMD_NAV_TAKEOFF, self.telemetry.statustexts
        params = self.channel.autopilot.takeoff_params(float(alt_m), alt0)
        if not math.isfinite(params[6]):
            raise LinkError(f"{self.name} cannot take off: its altitude is not known yet")
        result, attempts = yield from self._op_exchange(
            command, params, retries, timeout_s, in_progress_timeout_s=10.0
        )
        if result == mavlink2.MAV_RESULT_ACCEPTED:
            return result

        def taking_off() -> bool:
            if not (on_ground and st.armed[i] and st.mode[i] == mode):
                return False
            lifted = st.landed_state[i] in (
                mavlink2.MAV_LANDED_STATE_TAKEOFF,
                mavlink2.MAV_LANDED_STATE_IN_AIR,
            )
            return bool(lifted or st.geodetic[i, 2] - alt0 >= TAKEOFF_CLIMB_M)

        if attempts > 1:
            evidence = Timeout(TAKEOFF_EVIDENCE_S, self.telemetry.vehicle_clock)
            while not evidence.expired():
                if taking_off():
                    self.telemetry.add_event(
                        "a repeated NAV_TAKEOFF was refused while the first one (its ACK lost) is climbing",
                        mavlink2.MAV_SEVERITY_INFO,
                    )
                    return mavlink2.MAV_RESULT_ACCEPTED
                yield
        raise (yield from self._op_refusal(command, result, texts_before))
