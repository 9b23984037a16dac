"""Hostile input to a simulated vehicle's MAVLink intake (VehicleEndpoint.handle_datagram, in-process):
random bytes, truncated and oversized frames, valid frames with NaN/inf/extreme fields, spoofed sysids,
floods. No exception, the physical state stays finite, what is dropped is counted, valid commands are still
obeyed, and no handler raises (`handler_errors` stays 0: bad input is refused by the handlers' own checks,
an exception is a bug of the simulator and fails these tests)."""

from __future__ import annotations

import logging
import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl_sim.autopilot import modes
from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import in_process_config

FUZZ = settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
EXTREME = st.sampled_from([math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 1e9, 0.0])
GCS = ("127.0.0.1", 1)


def gcs(sysid: int = 255) -> M.MAVLink:
    return M.MAVLink(None, srcSystem=sysid, srcComponent=190)


def dropped(sim: Simulator) -> int:
    c = sim.endpoints[0].counters
    return c.bad_frames + c.foreign + c.invalid + c.refused


def assert_still_served(sim: Simulator) -> None:
    """No handler raised, physics finite after a few ticks, and a valid PARAM_SET is still obeyed."""
    assert sim.endpoints[0].counters.handler_errors == 0
    for _ in range(3):
        sim._tick()
    state = sim.dyn.state
    for array in (state.pos, state.vel, state.quat, state.omega):
        assert np.isfinite(array).all()
    value = 500.0 if sim.params.value(0, "WPNAV_SPEED") != 500.0 else 600.0
    mav = gcs()
    sim.endpoints[0].handle_datagram(
        M.MAVLink_param_set_message(1, 1, b"WPNAV_SPEED", value, M.MAV_PARAM_TYPE_REAL32).pack(mav), GCS, 0.0
    )
    assert sim.params.value(0, "WPNAV_SPEED") == value


@FUZZ
@given(data=st.binary(min_size=1, max_size=600))
def test_random_bytes(sim, data: bytes) -> None:
    before = dropped(sim) + sim.endpoints[0].counters.received
    sim.endpoints[0].handle_datagram(data, GCS, 0.0)
    assert dropped(sim) + sim.endpoints[0].counters.received > before
    assert_still_served(sim)


@FUZZ
@given(cut=st.integers(min_value=1, max_value=30), tail=st.binary(max_size=300))
def test_truncated_and_oversized_frames(sim, cut: int, tail: bytes) -> None:
    endpoint = sim.endpoints[0]
    frame = M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, modes.LAND).pack(gcs())
    before = endpoint.counters.bad_frames
    endpoint.handle_datagram(frame[: min(cut, len(frame) - 1)], GCS, 0.0)
    assert endpoint.counters.bad_frames > before
    endpoint.handle_datagram(frame[:-1] + tail, GCS, 0.0)  # CRC cut short or followed by junk
    sim.autopilot.set_mode(0, modes.GUIDED)
    assert_still_served(sim)


@FUZZ
@given(v=st.lists(EXTREME, min_size=8, max_size=8), mask=st.integers(0, 0xFFF), target=st.integers(0, 255))
def test_valid_frames_with_extreme_fields(sim, v: list[float], mask: int, target: int) -> None:
    endpoint = sim.endpoints[0]
    sim.autopilot.set_mode(0, modes.GUIDED)
    mav = gcs()
    packets = [
        M.MAVLink_set_attitude_target_message(1, target, 1, mask & 0xFF, v[:4], v[4], v[5], v[6], v[7]),
        M.MAVLink_set_position_target_local_ned_message(1, target, 1, 1, mask, *v, *v[:3]),
        M.MAVLink_set_position_target_global_int_message(1, target, 1, 6, mask, 0, 0, *v, v[0]),
        M.MAVLink_command_long_message(target, 1, M.MAV_CMD_NAV_TAKEOFF, 0, *v[:7]),
        M.MAVLink_command_long_message(target, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, *v[:7]),
        M.MAVLink_param_set_message(target, 1, b"WPNAV_SPEED", v[0], M.MAV_PARAM_TYPE_REAL32),
    ]
    before = endpoint.counters.received + dropped(sim)
    for packet in packets:
        endpoint.handle_datagram(packet.pack(mav), GCS, 0.0)
    assert endpoint.counters.received + dropped(sim) >= before + len(packets)
    assert math.isfinite(sim.params.value(0, "WPNAV_SPEED"))
    if target not in (0, 1):
        assert endpoint.counters.foreign >= len(packets)
    assert_still_served(sim)


def test_spoofed_sysid_heartbeats_do_not_refresh_the_gcs_failsafe(sim) -> None:
    sim.autopilot.t += 10.0
    before = float(sim.autopilot.last_gcs_heartbeat[0])
    for sysid in (1, 2, 254, 0):  # SYSID_MYGCS is 255
        mav = gcs(sysid)
        sim.endpoints[0].handle_datagram(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav), GCS, 0.0)
    assert float(sim.autopilot.last_gcs_heartbeat[0]) == before
    assert sim.endpoints[0].counters.handler_errors == 0


def test_flood_then_valid_traffic(sim) -> None:
    endpoint = sim.endpoints[0]
    rng = np.random.default_rng(3)
    before = endpoint.counters.bad_frames
    mav = gcs()
    for k in range(3000):
        if k % 2:
            endpoint.handle_datagram(
                rng.integers(0, 256, int(rng.integers(1, 300)), np.uint8).tobytes(), GCS, 0.0
            )
        else:
            endpoint.handle_datagram(M.MAVLink_param_request_list_message(1, 1).pack(mav), GCS, 0.0)
            endpoint.outbox.packets.clear()  # the replies would go to nobody
    assert endpoint.counters.bad_frames >= before + 1500
    assert_still_served(sim)


def test_a_handler_bug_is_counted_as_a_handler_error_not_as_invalid_input(monkeypatch, caplog) -> None:
    """An exception escaping a handler is a simulator bug: counted apart from bad input and logged with its
    traceback; the vehicle goes on serving the next message."""
    simulator = Simulator(in_process_config([[0.0, 0.0, 10.0]]))
    try:
        endpoint = simulator.endpoints[0]

        def broken_handler(msg: M.MAVLink_message, addr: tuple[str, int]) -> None:
            raise ZeroDivisionError("injected handler bug")

        monkeypatch.setitem(endpoint.handlers, M.MAVLINK_MSG_ID_TIMESYNC, broken_handler)
        with caplog.at_level(logging.ERROR, logger="sitl_sim"):
            endpoint.handle_datagram(M.MAVLink_timesync_message(0, 1).pack(gcs()), GCS, 0.0)
        counters = endpoint.counters
        assert (counters.handler_errors, counters.received, counters.invalid, counters.refused) == (
            1,
            1,
            0,
            0,
        )
        (record,) = [r for r in caplog.records if r.name == "sitl_sim.network.endpoint"]
        assert "TIMESYNC" in record.getMessage()
        assert record.exc_info is not None and record.exc_info[0] is ZeroDivisionError
        mav = gcs()
        endpoint.handle_datagram(
            M.MAVLink_param_set_message(1, 1, b"WPNAV_SPEED", 700.0, M.MAV_PARAM_TYPE_REAL32).pack(mav),
            GCS,
            0.0,
        )
        assert simulator.params.value(0, "WPNAV_SPEED") == 700.0 and counters.handler_errors == 1
    finally:
        simulator.close()


def test_an_interval_beyond_int32_is_refused_as_invalid(sim) -> None:
    """SET_MESSAGE_INTERVAL with 3.4e38 us (found by the fuzz test once handler exceptions stopped counting as
    invalid input): MESSAGE_INTERVAL.interval_us is an int32, so the handler denies it as malformed."""
    endpoint = sim.endpoints[0]
    before = endpoint.counters.invalid
    command = M.MAVLink_command_long_message(
        1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, 33, 3.4e38, 0, 0, 0, 0, 0
    )
    endpoint.handle_datagram(command.pack(gcs()), GCS, 0.0)
    acks = [M.MAVLink(None).decode(bytearray(packet)) for packet in endpoint.outbox.take()]
    assert [(a.command, a.result) for a in acks if a.get_type() == "COMMAND_ACK"] == [
        (M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAV_RESULT_DENIED)
    ]
    assert endpoint.counters.invalid == before + 1 and endpoint.counters.handler_errors == 0
