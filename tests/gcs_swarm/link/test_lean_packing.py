"""The ground station's hot outgoing packets (SET_ATTITUDE_TARGET from Setpoints, the lockstep's SYSTEM_TIME
answer) go out through swarm_common.mavlink_codec: byte for byte what pymavlink packed through Channel.send
before (endpoint and tlog), with the same encoder state after (sequence, signing timestamp), interleaved with
the pymavlink-packed rest of the link's traffic, signed or not."""

from __future__ import annotations

import math
import struct
from collections import deque
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_swarm.link.setpoints import ATTITUDE_TARGET_IGNORE_RATES
from gcs_swarm.link.telemetry import TelemetryState
from gcs_swarm.link.vehicle import VehicleConfig, VehicleLink

ORIGIN = (47.397742, 8.545594, 488.0)


class RecordingEndpoint:
    """Takes every packet (as Endpoint.send would) and keeps it."""

    def __init__(self) -> None:
        self.packets: list[bytes] = []

    def send(self, packet: bytes | bytearray, sysid: int | None) -> bool:
        self.packets.append(bytes(packet))
        return True


class RecordingTlog:
    def __init__(self) -> None:
        self.packets: list[bytes] = []

    def write(self, packet: bytes | bytearray) -> None:
        self.packets.append(bytes(packet))


def link(key: bytes | None, sysid: int, compid: int, seq: int, timestamp: int) -> VehicleLink:
    state = TelemetryState(1, ORIGIN)
    vehicle = VehicleLink(
        0, VehicleConfig("v", "udpout:127.0.0.1:14550", sysid), state, deque(), 255, 190, key
    )
    channel = vehicle.channel
    channel.endpoint = RecordingEndpoint()  # type: ignore[assignment]
    channel.tlog = RecordingTlog()  # type: ignore[assignment]
    channel.sysid, channel.compid = sysid, compid
    channel.mav.seq = seq
    channel.mav.signing.timestamp = timestamp
    return vehicle


def old_attitude_target(vehicle: VehicleLink, q: list[float], thrust: float) -> None:
    """Setpoints.send_attitude_quaternion as it was: pymavlink's encoder through Channel.send."""
    ch = vehicle.channel
    ch.send(
        ch.mav.set_attitude_target_encode(
            vehicle.lockstep.answer_time_ms(),
            ch.target_sysid,
            ch.compid,
            ATTITUDE_TARGET_IGNORE_RATES,
            q,
            0.0,
            0.0,
            0.0,
            min(max(float(thrust), 0.0), 1.0),
        )
    )


def old_answer_frame(vehicle: VehicleLink) -> None:
    """LockstepAnswer.answer_frame as it was."""
    if vehicle.lockstep.needs_answer:
        ch = vehicle.channel
        ch.send(ch.mav.system_time_encode(0, vehicle.lockstep.answer_time_ms()))


floats32 = st.floats(width=32) | st.sampled_from([0.0, -0.0, 1e-45, 1.0, math.nan, math.inf])
step = st.one_of(
    st.tuples(st.just("attitude"), st.lists(floats32, min_size=4, max_size=4), st.floats(-1.0, 2.0)),
    st.tuples(st.just("answer"), st.integers(1, 2**32 - 1)),
    st.tuples(st.just("heartbeat")),
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    signed=st.booleans(),
    key=st.binary(min_size=32, max_size=32),
    sysid=st.integers(1, 255),
    compid=st.integers(0, 255),
    seq=st.integers(0, 255),
    timestamp=st.integers(0, 2**48 - 300),
    time_ms=st.integers(1, 2**32 - 1),
    steps=st.lists(step, min_size=1, max_size=30),
)
def test_setpoints_and_answers_send_pymavlinks_bytes(
    signed: bool,
    key: bytes,
    sysid: int,
    compid: int,
    seq: int,
    timestamp: int,
    time_ms: int,
    steps: list[tuple[Any, ...]],
) -> None:
    links = [link(key if signed else None, sysid, compid, seq, timestamp) for _ in range(2)]
    old, new = links
    for vehicle in links:
        vehicle.state.time_ms[0] = time_ms
    for kind, *args in steps:
        if kind == "attitude":
            q, thrust = args
            old_attitude_target(old, q, thrust)
            new.setpoints.send_attitude_quaternion(q, thrust)
        elif kind == "answer":
            for vehicle in links:
                vehicle.state.time_ms[0] = args[0]
            old_answer_frame(old)
            new.lockstep.answer_frame()
        else:
            for vehicle in links:
                vehicle.heartbeat.send()  # pymavlink-packed on both
    assert new.channel.endpoint.packets == old.channel.endpoint.packets  # type: ignore[union-attr]
    assert new.channel.tlog.packets == old.channel.tlog.packets  # type: ignore[union-attr]
    assert (new.channel.mav.seq, new.channel.mav.signing.timestamp) == (
        old.channel.mav.seq,
        old.channel.mav.signing.timestamp,
    )
    assert (new.lockstep.answered_ms, int(new.state.tick_ms[0])) == (
        old.lockstep.answered_ms,
        int(old.state.tick_ms[0]),
    )
    assert new.channel.stats == old.channel.stats


def test_a_quaternion_is_sent_in_the_wire_order() -> None:
    """Reasoned: SET_ATTITUDE_TARGET's payload is time_boot_ms, q[4], three body rates, thrust (floats),
    then target system, component, type_mask (bytes): MAVLink's largest-first field order."""
    vehicle = link(None, 3, 1, 0, 0)
    vehicle.state.time_ms[0] = 1240
    vehicle.setpoints.send_attitude_quaternion([1.0, 0.0, 0.0, 0.5], 0.25)
    (packet,) = vehicle.channel.endpoint.packets  # type: ignore[union-attr]
    fields = struct.unpack("<I4fffffBBB", packet[10:-2])  # type_mask 7 last: nothing truncated
    assert fields == (1240, 1.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.25, 3, 1, ATTITUDE_TARGET_IGNORE_RATES)
