"""The ground station's side of the simulator's lockstep protocol (docs/sitl.md).

A lockstep simulator sends each frame's telemetry stamped with time_boot_ms (a SYSTEM_TIME when no stream
carries a stamped message in that frame) and waits until the frame is answered by a SYSTEM_TIME /
SET_ATTITUDE_TARGET / SET_POSITION_TARGET_* carrying time_boot_ms >= the frame's.
With link faults it also marks each frame's end with SYSTEM_TIME(time_unix_usec=0) (a clock tick), so a frame
is complete even when the vehicle's telemetry was lost or delayed. A real ArduPilot ignores the answers (it
refuses UNIX times before 2022) and sends no clock ticks, so all this is always safe.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.channel import Channel
from gcs_swarm.link.connection import MAVLinkMessage
from gcs_swarm.link.intake_kernel import CLOCK_KIND
from gcs_swarm.link.telemetry import TelemetryState, VehicleTelemetry
from swarm_common.jit import kernel
from swarm_common.mavlink_codec import Packer

_SYSTEM_TIME = Packer(mavlink2.MAVLink_system_time_message)


def is_clock_tick(msg: MAVLinkMessage) -> bool:
    """SYSTEM_TIME(time_unix_usec=0): a lockstep frame's end (no evidence that the radio link works)."""
    return msg.get_type() == "SYSTEM_TIME" and msg.time_unix_usec == 0


class LockstepAnswer:
    """Answers vehicle `index`'s frames: the time_boot_ms its outgoing targets echo; SYSTEM_TIME answers."""

    def __init__(self, index: int, channel: Channel, telemetry: VehicleTelemetry) -> None:
        self.index = index
        self.channel = channel
        self.telemetry = telemetry
        self.state: TelemetryState = telemetry.state
        self.answered_ms = -1  # time_boot_ms of the last lockstep answer sent

    def on_clock_tick(self, m: MAVLinkMessage) -> None:
        """A clock tick (`is_clock_tick`): the frame it ends is complete."""
        if self.telemetry.on_time(m.time_boot_ms, CLOCK_KIND):
            self.state.frame_ms[self.index] = max(int(self.state.frame_ms[self.index]), m.time_boot_ms)

    def on_system_time(self, m: MAVLinkMessage) -> None:
        """A SYSTEM_TIME that is no clock tick, already taken as the vehicle's time: a lockstep simulator
        stamps each frame whose streams carry no stamped message with one (telemetry slower than the frames,
        e.g. the position command mode's 10 Hz), so it completes that frame as a clock tick would. A late
        one (older than the vehicle's newest time) completes nothing."""
        t, i = int(m.time_boot_ms), self.index
        if t == int(self.state.time_ms[i]) and t > int(self.state.frame_ms[i]):
            self.state.frame_ms[i] = t

    @property
    def needs_answer(self) -> bool:
        """A telemetry frame (time_boot_ms) has arrived that no lockstep answer has covered yet."""
        t = int(self.state.time_ms[self.index])
        return t > 0 and t != self.answered_ms

    def answer_time_ms(self) -> int:
        """time_boot_ms to echo in an outgoing target: the latest frame, now answered (and consumed, so
        the next tick waits for a newer GLOBAL_POSITION_INT)."""
        t = max(int(self.state.time_ms[self.index]), 0)
        if t > 0:
            self.answered_ms = t
            self.state.tick_ms[self.index] = t
        return t

    def answer_frame(self) -> bool:
        """Answer the latest frame with SYSTEM_TIME(time_unix_usec=0, time_boot_ms=frame) unless answered."""
        if not self.needs_answer:
            return False
        self.channel.send_packed(_SYSTEM_TIME, 0, self.answer_time_ms())  # time_unix_usec, time_boot_ms
        return True


def frame_ready(answers: Sequence[LockstepAnswer], connected: Sequence[bool]) -> bool:
    """Every alive connected vehicle has a telemetry frame that no answer has covered yet: in lockstep, the
    fleet's frame is complete and the simulator waits for us. `answers[k]` and `connected[k]` belong to the
    same vehicle."""
    if not answers:
        return False
    st = answers[0].state
    alive = [a for a, c in zip(answers, connected, strict=True) if c and st.alive[a.index]]
    if not alive:
        return False
    last = max(a.answered_ms for a in alive)
    clocked = [  # lost, but a lockstep simulator still sends its clock ticks and waits for its answers
        a
        for a, c in zip(answers, connected, strict=True)
        if c and not st.alive[a.index] and st.frame_ms[a.index] >= last >= 0
    ]
    return all(a.needs_answer for a in alive + clocked)


@kernel
def take_new_frame(
    alive: np.ndarray, position_ms: np.ndarray, frame_ms: np.ndarray, tick_ms: np.ndarray
) -> bool:
    """Whether every vehicle expected in a new tick has a frame newer than its last tick: a
    GLOBAL_POSITION_INT or a lockstep clock tick or frame SYSTEM_TIME (position_ms, frame_ms: (N,) int64
    time_boot_ms, -1 for
    none) newer than tick_ms (N,), for every alive vehicle and every lost one whose clock ticks were current
    at the fleet's last tick (a lockstep simulator waits for its answer). If so, that frame is consumed: each
    expected vehicle's tick_ms becomes its newest frame's. `alive`: (N,) bool. False while nobody is alive.
    """
    n = alive.shape[0]
    last_tick = np.int64(-1)
    any_alive = False
    for i in range(n):
        if alive[i] and (not any_alive or tick_ms[i] > last_tick):
            last_tick = tick_ms[i]
            any_alive = True
    if not any_alive:
        return False
    for i in range(n):
        expected = alive[i] or (frame_ms[i] >= 0 and frame_ms[i] >= last_tick and tick_ms[i] >= last_tick)
        if expected and not max(position_ms[i], frame_ms[i]) > tick_ms[i]:
            return False
    for i in range(n):
        if alive[i] or (frame_ms[i] >= 0 and frame_ms[i] >= last_tick and tick_ms[i] >= last_tick):
            tick_ms[i] = max(position_ms[i], frame_ms[i])
    return True
