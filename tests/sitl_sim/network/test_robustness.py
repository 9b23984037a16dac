"""Hostile input: garbage, truncated frames, bad CRCs, MAVLink 1, other sysids, NaN/absurd fields, fuzzed
messages with valid CRCs. Nothing crashes, everything is counted, valid traffic keeps flowing, and no handler
raises (`handler_errors` 0: an exception in a handler is a simulator bug and fails these tests)."""

from __future__ import annotations

import math
import re
import select
import socket
import struct

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v10 import ardupilotmega as mavlink1

from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import GCS_COMPID, GCS_SYSID, M, Vehicle, in_process_config


def test_garbage_is_counted_and_traffic_continues(sitl, pilot_for):
    sim = sitl("--speedup", "5")
    pilot = pilot_for(sim, lockstep=False)
    v = pilot[0]
    pilot.spin(lambda: "HEARTBEAT" in v.latest, 5.0)
    gcs = M.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
    heartbeat = gcs.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(gcs)
    bad_crc = heartbeat[:-1] + bytes([heartbeat[-1] ^ 0xFF])
    v1 = mavlink1.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
    datagrams = [
        b"\x00\x01 not mavlink at all \xff" * 20,
        heartbeat[:7],  # truncated
        bad_crc,
        bytes(np.random.default_rng(1).integers(0, 256, 60000, dtype=np.uint8)),
        b"\xfd\xff" + b"\x00" * 20,  # claims 255 bytes of payload, has 20
        gcs.command_long_encode(9, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0).pack(
            gcs
        ),  # other sysid
        gcs.command_long_encode(1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, math.nan, 1e5, 0, 0, 0, 0, 0).pack(
            gcs
        ),
        gcs.set_attitude_target_encode(0, 1, 1, 0, [math.nan, 0, 0, 0], 0, 0, 0, 0.5).pack(gcs),
        gcs.set_position_target_local_ned_encode(0, 1, 1, 1, 0, 1e12, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0).pack(gcs),
        v1.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(v1),  # MAVLink 1 is fine
        v1.param_request_read_encode(1, 1, b"ANGLE_MAX", -1).pack(v1),
    ]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
        for datagram in datagrams:
            raw.sendto(datagram, ("127.0.0.1", sim.port(0)))
        pilot.spin(lambda: "ANGLE_MAX" in v.params, 5.0)  # answered to MAVLink 1, after all the garbage
    before = v.latest["HEARTBEAT"]
    pilot.spin(lambda: v.latest["HEARTBEAT"] is not before, 3.0)
    assert any(
        a.command == M.MAV_CMD_SET_MESSAGE_INTERVAL and a.result == M.MAV_RESULT_DENIED for a in v.acks
    )
    status, err = sim.stop()
    assert status == 0
    line = next(text for text in err.splitlines() if text.startswith("sitl-sim: vehicle 0 (sysid 1): "))
    counters = dict(item.split("=") for item in line.split(": ", 2)[-1].split())
    # seconds of --speedup 5 were paced before the stop: the exit report says how far behind they fell
    assert re.search(r"^sitl-sim: real-time pacing: worst lag [\d.]+ ms, \d+ of [1-9]\d* ticks", err, re.M)
    assert int(counters["bad_frames"]) >= 4
    assert int(counters["foreign"]) >= 1
    assert int(counters["invalid"]) >= 3
    assert int(counters["handler_errors"]) == 0


def test_two_clients_at_once_both_get_telemetry(sitl):
    sim = sitl("--speedup", "5", "--ready-delay", "1")  # positions come with the EKF's, after the delay
    clients = [Vehicle(sim.port(0), 1), Vehicle(sim.port(0), 1, source_system=254)]
    try:
        for client in clients:
            client.heartbeat()
            client.request_streams()
        wanted = {"HEARTBEAT", "ATTITUDE", "GLOBAL_POSITION_INT"}
        for _ in range(200):  # at most ~10 s
            for client in clients:
                client.drain()
            if all(wanted <= set(c.latest) for c in clients):
                break
            select.select([c.conn.port for c in clients], [], [], 0.05)
        assert all(wanted <= set(c.latest) for c in clients)
    finally:
        for client in clients:
            client.close()


def _frame(msg_id: int, payload: bytes) -> bytes:
    """A MAVLink 2 frame from the ground station with a valid CRC around an arbitrary payload."""
    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, 0, GCS_SYSID, GCS_COMPID, msg_id & 0xFFFF, 0)
    crc = M.x25crc(header[1:] + payload)
    crc.accumulate(bytes([M.mavlink_map[msg_id].crc_extra]))
    return header + payload + struct.pack("<H", crc.crc)


HANDLED = sorted(
    [
        M.MAVLINK_MSG_ID_HEARTBEAT,
        M.MAVLINK_MSG_ID_SYSTEM_TIME,
        M.MAVLINK_MSG_ID_TIMESYNC,
        M.MAVLINK_MSG_ID_COMMAND_LONG,
        M.MAVLINK_MSG_ID_COMMAND_INT,
        M.MAVLINK_MSG_ID_SET_MODE,
        M.MAVLINK_MSG_ID_PARAM_REQUEST_READ,
        M.MAVLINK_MSG_ID_PARAM_SET,
        M.MAVLINK_MSG_ID_REQUEST_DATA_STREAM,
        M.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED,
        M.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT,
        M.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET,
        M.MAVLINK_MSG_ID_MISSION_COUNT,
        M.MAVLINK_MSG_ID_MISSION_WRITE_PARTIAL_LIST,
        M.MAVLINK_MSG_ID_MISSION_ITEM,
        M.MAVLINK_MSG_ID_MISSION_ITEM_INT,
        M.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
        M.MAVLINK_MSG_ID_MISSION_REQUEST,
        M.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
        M.MAVLINK_MSG_ID_MISSION_CLEAR_ALL,
        M.MAVLINK_MSG_ID_MISSION_ACK,
    ]
)


def _fuzz_simulator() -> Simulator:
    config = in_process_config([[0.0, 0.0, 0.0], [5.0, 0.0, 10.0]])
    return Simulator(config)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(msg_id=st.sampled_from(HANDLED), data=st.data(), mode=st.sampled_from([0, 2, 4, 5, 6, 9, 17, 20]))
def test_fuzzed_messages_with_valid_crc_never_crash(msg_id, data, mode):
    sim = _fuzz_simulator()
    try:
        for i in range(2):
            sim.autopilot.set_mode(i, mode)
            sim.autopilot.arm(i, force=True)
        size = M.mavlink_map[msg_id].unpacker.size
        payload = data.draw(st.binary(min_size=size, max_size=size))
        parser = M.MAVLink(None)
        msg = parser.decode(bytearray(_frame(msg_id, payload)))
        for field_name in ("target_system", "target_component"):
            if hasattr(msg, field_name):
                setattr(msg, field_name, data.draw(st.sampled_from([0, 1])))
        gcs = M.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        for endpoint in sim.endpoints:
            endpoint.handle_datagram(msg.pack(gcs), ("127.0.0.1", 1), 0.0)
            counted = endpoint.counters
            assert counted.received + counted.bad_frames + counted.foreign >= 1
            assert counted.handler_errors == 0
        for _ in range(5):
            sim._tick()
        state = sim.dyn.state
        assert np.isfinite(state.pos).all() and np.isfinite(state.quat).all()
    finally:
        sim.close()
