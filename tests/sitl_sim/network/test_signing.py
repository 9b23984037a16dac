"""MAVLink 2 signing of the simulated vehicles (sitl_sim.network.signing, --signing-key): only correctly
signed, fresh messages command a vehicle (RADIO_STATUS excepted); replays are refused; the vehicle signs what
it sends.

In-process: datagrams are fed straight into a vehicle endpoint's handler, no sockets except one capture.
"""

from __future__ import annotations

import socket
import time

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sitl_sim.autopilot import modes
from sitl_sim.autopilot.outer_loop import CTRL_ANGLE
from sitl_sim.cli import build_config, build_parser
from sitl_sim.network import signing
from sitl_sim.simulator import Simulator
from swarm_common.signing import VerifyingParser
from tests.sitl_sim.sim_process import in_process_config

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
GCS = ("127.0.0.1", 1)


@pytest.fixture
def sim():
    config = in_process_config([[0.0, 0.0, 10.0]], signing_key=KEY)  # airborne, GUIDED, armed
    simulator = Simulator(config)
    yield simulator
    simulator.close()


def client(key: bytes | None, timestamp: int | None = None) -> M.MAVLink:
    """A ground station encoder (sysid 255, compid 190), signing with key when given."""
    mav = M.MAVLink(None, srcSystem=255, srcComponent=190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = signing.timestamp_now() if timestamp is None else timestamp
    return mav


def commands(mav: M.MAVLink) -> dict[str, bytes]:
    """Packets that would disarm, change mode, set a param and steer vehicle 1."""
    q = [0.9659258, 0.2588190, 0.0, 0.0]  # 30 deg roll
    return {
        "disarm": M.MAVLink_command_long_message(
            1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, modes.FORCE_DISARM, 0, 0, 0, 0, 0
        ).pack(mav),
        "mode": M.MAVLink_set_mode_message(1, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, modes.LAND).pack(mav),
        "param": M.MAVLink_param_set_message(1, 1, b"WPNAV_SPEED", 1234.0, M.MAV_PARAM_TYPE_REAL32).pack(mav),
        "steer": M.MAVLink_set_attitude_target_message(1, 1, 1, 0b111, q, 0, 0, 0, 0.9).pack(mav),
        "heartbeat": M.MAVLink_heartbeat_message(M.MAV_TYPE_GCS, 8, 0, 0, 4, 3).pack(mav),
    }


def vehicle_state(sim: Simulator) -> tuple:
    a = sim.autopilot
    return (bool(a.armed[0]), int(a.mode[0]), sim.params.value(0, "WPNAV_SPEED"), int(a.control[0]))


@pytest.mark.parametrize("key", [None, OTHER_KEY], ids=["unsigned", "wrong-key"])
def test_unsigned_or_wrongly_signed_commands_are_dropped(sim, key):
    endpoint = sim.endpoints[0]
    before = vehicle_state(sim)
    heartbeat_before = float(sim.autopilot.last_gcs_heartbeat[0])
    sim.autopilot.t = heartbeat_before + 1.0
    packets = commands(client(key))
    for packet in packets.values():
        endpoint.handle_datagram(packet, GCS, 0.0)
    assert vehicle_state(sim) == before
    assert float(sim.autopilot.last_gcs_heartbeat[0]) == heartbeat_before  # no failsafe refresh either
    assert endpoint.counters.unsigned == len(packets)
    assert endpoint.counters.received == 0


def test_signed_commands_are_obeyed(sim):
    endpoint = sim.endpoints[0]
    mav = client(KEY)  # packed in order of delivery: timestamps must increase
    endpoint.handle_datagram(commands(mav)["steer"], GCS, 0.0)
    assert sim.autopilot.control[0] == CTRL_ANGLE
    endpoint.handle_datagram(commands(mav)["param"], GCS, 0.0)
    assert sim.params.value(0, "WPNAV_SPEED") == 1234.0
    endpoint.handle_datagram(commands(mav)["mode"], GCS, 0.0)
    assert sim.autopilot.mode[0] == modes.LAND
    endpoint.handle_datagram(commands(mav)["disarm"], GCS, 0.0)
    assert not sim.autopilot.armed[0]
    assert endpoint.counters.unsigned == 0


def test_radio_status_is_accepted_unsigned(sim):
    endpoint = sim.endpoints[0]
    radio = M.MAVLink_radio_status_message(200, 190, 50, 40, 30, 0, 0).pack(client(None))
    endpoint.handle_datagram(radio, GCS, 0.0)
    assert endpoint.counters.unsigned == 0
    assert endpoint.counters.received == 1


def test_replayed_signed_command_is_refused(sim):
    endpoint = sim.endpoints[0]
    mav = client(KEY)
    recorded = commands(mav)["mode"]  # LAND
    endpoint.handle_datagram(recorded, GCS, 0.0)
    assert sim.autopilot.mode[0] == modes.LAND
    sim.autopilot.set_mode(0, modes.GUIDED)
    endpoint.handle_datagram(recorded, GCS, 0.0)  # the same packet again
    assert sim.autopilot.mode[0] == modes.GUIDED
    assert endpoint.counters.unsigned == 1
    endpoint.handle_datagram(commands(mav)["mode"], GCS, 0.0)  # a fresh one still works
    assert sim.autopilot.mode[0] == modes.LAND


def test_recording_replayed_to_a_fresh_vehicle_is_refused(sim):
    endpoint = sim.endpoints[0]
    two_minutes_ago = signing.timestamp_now() - 12_000_000
    endpoint.handle_datagram(commands(client(KEY, two_minutes_ago))["mode"], GCS, 0.0)
    assert sim.autopilot.mode[0] == modes.GUIDED
    assert endpoint.counters.unsigned == 1


def test_forged_future_timestamp_does_not_lock_out_the_ground_station(sim):
    endpoint = sim.endpoints[0]
    forged = commands(client(OTHER_KEY, signing.timestamp_now() + 10**12))["mode"]
    endpoint.handle_datagram(forged, GCS, 0.0)
    endpoint.handle_datagram(commands(client(KEY))["mode"], GCS, 0.0)
    assert sim.autopilot.mode[0] == modes.LAND


def test_vehicle_signs_what_it_sends(sim):
    endpoint = sim.endpoints[0]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as capture:
        capture.bind(("127.0.0.1", 0))
        capture.settimeout(5.0)
        endpoint.peers[capture.getsockname()] = time.monotonic()
        sim._send_now(0, (M.MAVLINK_MSG_ID_HEARTBEAT, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT))
        endpoint.outbox.send(endpoint.outbox.tx.statustext_encode(6, b"hello"))
        endpoint.flush(time.monotonic())
        data = capture.recv(65535)
    verifier = VerifyingParser(KEY)
    messages = verifier.parse_buffer(data)
    assert [m.get_type() for m in messages] == ["HEARTBEAT", "GLOBAL_POSITION_INT", "STATUSTEXT"]
    assert all(m._signed for m in messages)
    assert KEY not in data


@pytest.mark.parametrize(
    "content", ["", "00" * 31, "zz" * 32, "00" * 33], ids=["empty", "short", "not-hex", "long"]
)
def test_bad_key_file_is_one_line_error(tmp_path, capsys, content):
    path = tmp_path / "key.hex"
    path.write_text(content)
    parser = build_parser()
    with pytest.raises(SystemExit) as exit_info:
        build_config(parser, parser.parse_args(["--vehicles", "1", "--signing-key", str(path)]))
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "--signing-key" in err and "64 hex characters" in err and len(err.splitlines()) == 1


def test_missing_key_file_is_one_line_error(tmp_path, capsys):
    parser = build_parser()
    with pytest.raises(SystemExit) as exit_info:
        build_config(parser, parser.parse_args(["--vehicles", "1", "--signing-key", str(tmp_path / "none")]))
    assert exit_info.value.code == 2
    assert "cannot read signing key file" in capsys.readouterr().err


def test_key_file_is_read_and_never_shown(tmp_path):
    path = tmp_path / "key.hex"
    path.write_text(KEY.hex() + "\n")
    parser = build_parser()
    config = build_config(parser, parser.parse_args(["--vehicles", "1", "--signing-key", str(path)]))
    assert config.signing_key == KEY
    assert KEY.hex() not in repr(config)
