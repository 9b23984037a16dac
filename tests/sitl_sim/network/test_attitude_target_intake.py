"""The endpoint's short cut for the ground station's answer to every frame, a datagram that is one unsigned
SET_ATTITUDE_TARGET (`endpoint.lone_attitude_target` -> `SetpointHandlers.attitude_target`, no pymavlink
message), must do exactly what the general path does (`parse_datagram` -> `_handle_message` ->
`_on_attitude_target`): same datagrams taken, same field values (bit for bit), same counters, refusals,
autopilot state and lockstep answers, for valid, NaN/inf, non-unit, foreign, refused-by-mode, damaged and
garbage input. And the endpoint's cheap decision whether the faulty link applies (`_faulty_link_rates`) must
be FaultChannel.active(link_rates()) whatever the SIM_LINK_* parameters, outages and clock say."""

from __future__ import annotations

import logging
import math
import struct
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sitl_sim.autopilot import modes
from sitl_sim.clock import plan_timing
from sitl_sim.network.endpoint import LINK_PARAMS, lone_attitude_target, parse_datagram
from sitl_sim.network.link_faults import Outage
from sitl_sim.simulator import Simulator
from swarm_common.mavlink_codec import Packer
from swarm_common.signing import new_parser
from tests.sitl_sim.sim_process import in_process_config

FUZZ = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
GCS = ("127.0.0.1", 14550)
ATTITUDE_TARGET = mavlink2.MAVLink_set_attitude_target_message
MODES = [modes.GUIDED, modes.GUIDED, modes.GUIDED_NOGPS, modes.LOITER, modes.STABILIZE, modes.ALT_HOLD]
DAMAGE = ["none"] * 6 + [
    "flip",
    "truncate",
    "extend",
    "empty",
    "flags",
    "compat",
    "twice",
    "mavlink1",
    "junk",
]


@st.composite
def attitude_targets(draw: st.DrawFn) -> mavlink2.MAVLink_set_attitude_target_message:
    """SET_ATTITUDE_TARGET, mostly one the vehicle obeys, else with one field wrong for a check: NaN/inf in
    the quaternion, thrust or rates, a rate beyond MAX_RATE, a quaternion off unit length (and about the
    1e-3 bound); any type_mask, own, broadcast and foreign targets."""
    special = st.sampled_from([math.nan, math.inf, -math.inf, 3.4e38])
    q = [draw(st.floats(-1.0, 1.0)) for _ in range(4)]
    norm = math.sqrt(sum(c * c for c in q)) or 1.0
    q = [c / norm for c in q] if norm > 0.1 else [1.0, 0.0, 0.0, 0.0]
    rates = [draw(st.floats(-50.0, 50.0, width=32)) for _ in range(3)]
    thrust = draw(st.floats(-0.5, 1.5, width=32))
    wrong = draw(st.sampled_from(["nothing"] * 5 + ["q", "norm", "rate", "thrust"]))
    if wrong == "q":
        q[draw(st.integers(0, 3))] = draw(special)
    elif wrong == "norm":  # |q|^2 - 1: about +-8e-4 (taken), +-1.2e-3 (refused), -0.75
        q = [c * draw(st.sampled_from([1.0004, 0.9996, 1.0006, 0.9994, 0.5])) for c in q]
    elif wrong == "rate":
        rates[draw(st.integers(0, 2))] = draw(st.one_of(special, st.sampled_from([50.001, -51.0])))
    elif wrong == "thrust":
        thrust = draw(special)
    # rates ignored (as gcs_swarm sends), none ignored, attitude or throttle ignored, some rates ignored, any
    mask = st.one_of(
        st.sampled_from([0b111, 0, 0b1000_0000, 0b1000_0111, 0b0100_0111, 0b101]), st.integers(0, 255)
    )
    return ATTITUDE_TARGET(
        draw(st.integers(0, 2**32 - 1)),
        draw(st.sampled_from([1, 1, 1, 1, 0, 2, 255])),
        draw(st.sampled_from([1, 1, 1, 0, 2, 190])),
        draw(mask),
        q,
        *rates,
        thrust,
    )


def framed(payload: bytes, incompat: int = 0, compat: int = 0) -> bytes:
    """A MAVLink 2 SET_ATTITUDE_TARGET packet around `payload` (any length), CRC by pymavlink's x25crc."""
    header = struct.pack(
        "<BBBBBBBHB", 253, len(payload), incompat, compat, 7, 255, 190, ATTITUDE_TARGET.id, 0
    )
    crc = mavlink2.x25crc(header[1:] + payload + bytes((ATTITUDE_TARGET.crc_extra,)))
    return header + payload + struct.pack("<H", crc.crc)


@st.composite
def datagrams(draw: st.DrawFn) -> bytes:
    """A datagram as it may reach a vehicle: mostly a lone SET_ATTITUDE_TARGET, else one damaged, padded
    beyond the dialect's payload, emptied, flagged, doubled, in MAVLink 1, or junk."""
    msg = draw(attitude_targets())
    mav = mavlink2.MAVLink(None, 255, 190)
    packet = bytearray(msg.pack(mav))
    damage = draw(st.sampled_from(DAMAGE))
    if damage == "flip":
        packet[draw(st.integers(0, len(packet) - 1))] ^= draw(st.integers(1, 255))
    elif damage == "truncate":
        packet = packet[: draw(st.integers(0, len(packet) - 1))]
    elif damage == "extend":  # a longer payload, e.g. fields of a newer dialect
        payload = ATTITUDE_TARGET.unpacker.pack(*msg_wire_values(msg)) + draw(
            st.binary(min_size=1, max_size=20)
        )
        packet = bytearray(framed(payload))
    elif damage == "empty":  # every field zero: the whole payload cut as trailing zeros
        packet = bytearray(framed(b""))
    elif damage in ("flags", "compat"):
        payload = bytes(packet[10:-2])
        flags = draw(st.sampled_from([1, 2, 0x80]))
        packet = bytearray(
            framed(payload, incompat=flags) if damage == "flags" else framed(payload, compat=flags)
        )
    elif damage == "twice":
        packet += msg.pack(mav)
    elif damage == "mavlink1":
        packet = bytearray(msg.pack(mavlink1.MAVLink(None, 255, 190)))
    elif damage == "junk":
        packet = bytearray(draw(st.binary(min_size=0, max_size=60)))
    return bytes(packet)


def msg_wire_values(msg: mavlink2.MAVLink_set_attitude_target_message) -> list[Any]:
    """The field values of msg in wire order, arrays flattened."""
    time_boot_ms, q, *rest = (getattr(msg, name) for name in ATTITUDE_TARGET.ordered_fieldnames)
    return [time_boot_ms, *q, *rest]


def bits(values: list[Any] | tuple[Any, ...]) -> list[Any]:
    """Values with floats as their 8 bytes (NaN payloads and -0.0 compared exactly)."""
    return [struct.pack("<d", v) if isinstance(v, float) else v for v in values]


@FUZZ
@given(data=datagrams())
def test_lone_attitude_target_takes_exactly_what_parse_datagram_decodes_alone(data: bytes) -> None:
    parser = new_parser(None)
    fields = lone_attitude_target(data)
    messages = parse_datagram(parser, data)
    alone = (
        len(messages) == 1
        and messages[0].get_msgId() == ATTITUDE_TARGET.id
        and parser.buf_len() == 0
        and data[0] == mavlink2.PROTOCOL_MARKER_V2
        and data[2] == 0
    )
    assert (fields is not None) == alone
    if fields is not None:
        assert bits(fields) == bits(msg_wire_values(messages[0]))


def test_the_ground_stations_answer_takes_the_short_cut() -> None:
    """What gcs_swarm sends every frame (swarm_common.mavlink_codec.Packer, trailing zeros cut) is taken."""
    mav = mavlink2.MAVLink(None, 255, 190)
    packet = Packer(ATTITUDE_TARGET).pack(mav, 1234, 0.9998, 0.01, 0.01, 0.0, 0.0, 0.0, 0.0, 0.52, 1, 1, 7)
    fields = lone_attitude_target(packet)
    assert fields is not None
    assert bits(fields) == bits(msg_wire_values(mavlink2.MAVLink(None).decode(bytearray(packet))))


def lockstep_sim() -> Simulator:
    """One ArduPilot vehicle airborne in GUIDED, lockstep clock (answers are registered)."""
    config = in_process_config(
        [[0.0, 0.0, 10.0]], lockstep=True, timing=plan_timing(1000.0, 100.0, 50.0, 50.0)
    )
    return Simulator(config)


@pytest.fixture(scope="module")
def pair() -> Iterator[tuple[Simulator, Simulator]]:
    """(short cut, reference): two identical simulators, the second without the short cut."""
    fast, reference = lockstep_sim(), lockstep_sim()
    reference.endpoints[0]._attitude_target = None
    yield fast, reference
    fast.close()
    reference.close()


def observable(sim: Simulator) -> tuple[Any, ...]:
    """Counters, every autopilot array (bytes), texts and the lockstep clients of vehicle 0."""
    ap = sim.autopilot
    arrays = {name: (a.dtype.str, a.tobytes()) for name, a in vars(ap).items() if isinstance(a, np.ndarray)}
    assert sim.lockstep is not None
    clients = {addr: (c.answered_ms, c.dropped) for addr, c in sim.lockstep.by_vehicle[0].items()}
    return sim.endpoints[0].counters, arrays, ap.texts[0], clients, sim.lockstep.first_seen_wall


@FUZZ
@given(batch=st.lists(st.tuples(st.sampled_from(MODES), st.sampled_from([0, 8]), datagrams()), max_size=4))
def test_short_cut_leaves_what_the_general_path_leaves(pair, batch: list[tuple[int, int, bytes]]) -> None:
    fast, reference = pair
    for mode, guid_options, data in batch:
        for sim in pair:
            sim.autopilot.set_mode(0, mode)
            sim.params.set(0, "GUID_OPTIONS", guid_options)
            sim.endpoints[0].handle_datagram(data, GCS, 0.0)
        assert observable(fast) == observable(reference)
    assert fast.endpoints[0].counters.handler_errors == 0


def test_short_cut_counts_every_outcome(pair) -> None:
    """The short cut meets each outcome (taken, invalid, refused, foreign) with the reference's counters."""
    fast, reference = pair
    mav = mavlink2.MAVLink(None, 255, 190)
    unit, nan, half = [1.0, 0.0, 0.0, 0.0], [math.nan, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0]
    cases = [  # mode, message, the counters it moves
        (modes.GUIDED, ATTITUDE_TARGET(20, 1, 1, 7, unit, 0, 0, 0, 0.6), {"received"}),
        (modes.GUIDED, ATTITUDE_TARGET(40, 1, 1, 7, nan, 0, 0, 0, 0.6), {"received", "invalid"}),
        (modes.GUIDED, ATTITUDE_TARGET(60, 0, 0, 7, unit, 0, 0, 51.0, 0.6), {"received", "invalid"}),
        (modes.GUIDED, ATTITUDE_TARGET(80, 1, 1, 7, half, 0, 0, 0, 0.6), {"received", "refused"}),
        (modes.LOITER, ATTITUDE_TARGET(100, 1, 1, 7, unit, 0, 0, 0, 0.6), {"received", "refused"}),
        (modes.GUIDED, ATTITUDE_TARGET(120, 1, 1, 0b101, unit, 0, 0, 0, 0.6), {"received", "refused"}),
        (modes.GUIDED, ATTITUDE_TARGET(140, 2, 1, 7, unit, 0, 0, 0, 0.6), {"foreign"}),
        (modes.GUIDED, ATTITUDE_TARGET(160, 1, 190, 7, unit, 0, 0, 0, 0.6), {"foreign"}),
    ]
    for mode, msg, moved in cases:
        data = msg.pack(mav)
        assert lone_attitude_target(data) is not None
        for sim in pair:
            sim.autopilot.set_mode(0, mode)
            before = vars(sim.endpoints[0].counters).copy()
            sim.endpoints[0].handle_datagram(data, GCS, 0.0)
            after = vars(sim.endpoints[0].counters)
            assert {name for name, count in after.items() if count != before[name]} == moved
        assert observable(fast) == observable(reference)


def test_a_handler_bug_on_the_short_cut_is_counted_and_logged(caplog) -> None:
    sim = lockstep_sim()
    try:
        endpoint = sim.endpoints[0]

        def broken(*fields: object) -> None:
            raise ZeroDivisionError("injected handler bug")

        endpoint._attitude_target = broken
        mav = mavlink2.MAVLink(None, 255, 190)
        data = ATTITUDE_TARGET(20, 1, 1, 7, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, 0.5).pack(mav)
        with caplog.at_level(logging.ERROR, logger="sitl_sim"):
            endpoint.handle_datagram(data, GCS, 0.0)
        c = endpoint.counters
        assert (c.handler_errors, c.received, c.invalid, c.refused) == (1, 1, 0, 0)
        (record,) = [r for r in caplog.records if r.name == "sitl_sim.network.endpoint"]
        assert "SET_ATTITUDE_TARGET" in record.getMessage()
        assert record.exc_info is not None and record.exc_info[0] is ZeroDivisionError
        assert sim.lockstep is not None and sim.lockstep.by_vehicle[0] == {}  # no answer after a failure
    finally:
        sim.close()


@pytest.mark.parametrize("overrides", [{"autopilots": ("px4",)}, {"signing_key": bytes(range(32))}])
def test_no_short_cut_for_px4_or_with_a_signing_key(overrides: dict[str, object]) -> None:
    """PX4's handler checks more (OFFBOARD, its thrust rule); with a key the parser checks signatures."""
    sim = Simulator(in_process_config([[0.0, 0.0, 10.0]], **overrides))
    try:
        assert sim.endpoints[0]._attitude_target is None
    finally:
        sim.close()


@pytest.fixture(scope="module")
def link_sim() -> Iterator[Simulator]:
    sim = lockstep_sim()
    yield sim
    sim.close()


LINK_VALUES = st.sampled_from([0.0, 0.0, 0.0, 0.3, 1.0])


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    values=st.lists(LINK_VALUES, min_size=6, max_size=6),
    outage=st.booleans(),
    started=st.booleans(),
    step=st.sampled_from([0, 500, 20_000]),
    link_from_s=st.sampled_from([0.0, 1.0, 30.0]),
    set_twice=st.booleans(),
)
def test_faulty_link_rates_is_channel_active_of_link_rates(
    link_sim: Simulator,
    values: list[float],
    outage: bool,
    started: bool,
    step: int,
    link_from_s: float,
    set_twice: bool,
) -> None:
    endpoint = link_sim.endpoints[0]
    for name, value in zip(LINK_PARAMS, values, strict=True):
        link_sim.set_param(0, name, value)
    if set_twice:  # the decision follows every change, not only the first after a read
        endpoint._faulty_link_rates()
        link_sim.set_param(0, "SIM_LINK_LOSS", 0.0 if values[0] else 0.5)
    endpoint.channel.outages = (Outage(0, 100.0, 1.0),) if outage else ()
    link_sim.lockstep_started = started
    link_sim.step = step
    endpoint.link_from_s = link_from_s
    rates = endpoint.link_rates()
    expected = rates if endpoint.channel.active(rates) else None
    assert endpoint._faulty_link_rates() == expected
    endpoint.outbox.take()  # the PARAM_VALUE replies go to nobody
