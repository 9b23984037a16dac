"""Ground-station signing (gcs_swarm.link.signing): key files, the mission/env choice, signed packets."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.cli.run import run_command
from gcs_swarm.flight.fly import EXIT_USER_ERROR, RunOptions
from gcs_swarm.link import signing

KEY = bytes(range(32))


@pytest.mark.parametrize("content", ["", "ab" * 31, "zz" * 32, "ab" * 33])
def test_malformed_key_files_are_one_sentence_without_the_content(tmp_path, content) -> None:
    path = tmp_path / "k"
    path.write_text(content)
    with pytest.raises(signing.SigningKeyError, match="64 hex characters") as err:
        signing.read_key(path)
    assert content not in str(err.value) or not content


def test_missing_key_file(tmp_path) -> None:
    with pytest.raises(signing.SigningKeyError, match="cannot read signing key file"):
        signing.read_key(tmp_path / "none")


def test_mission_key_file_wins_over_the_environment(tmp_path, monkeypatch) -> None:
    monkeypatch.delenv(signing.KEY_ENV, raising=False)
    assert signing.key_file(None) is None
    monkeypatch.setenv(signing.KEY_ENV, str(tmp_path / "env.key"))
    assert signing.key_file(None) == tmp_path / "env.key"
    assert signing.key_file(tmp_path / "mission.key") == tmp_path / "mission.key"


def test_signed_packets_verify_and_do_not_contain_the_key(tmp_path) -> None:
    path = tmp_path / "k"
    path.write_text(KEY.hex().upper() + "\n")
    key = signing.read_key(path)
    assert key == KEY
    sender = mavlink2.MAVLink(None, 255, 190)
    signing.sign_outgoing(sender, key)
    packet = sender.system_time_encode(0, 1234).pack(sender)
    assert packet[2] & mavlink2.MAVLINK_IFLAG_SIGNED and KEY not in packet
    receiver = mavlink2.MAVLink(None)
    receiver.signing.secret_key = KEY
    assert receiver.decode(bytearray(packet))._signed
    stranger = mavlink2.MAVLink(None)
    stranger.signing.secret_key = bytes(32)
    with pytest.raises(mavlink2.MAVError):
        stranger.decode(bytearray(packet))


def test_run_refuses_a_bad_key_file(tmp_path, capsys) -> None:
    mission = tmp_path / "m.yaml"
    vehicles = (
        "vehicles:\n  - {name: a, role: leader, start: {position: [0, 0, 0]}}\n"
        "  - {name: b, start: {position: [-10, 0, 0]}}\n"
    )
    mission.write_text(vehicles + "goal: [100, 50, 10]\nrun:\n  signing_key_file: missing.key\n")
    assert run_command(str(mission), RunOptions(out_dir=tmp_path / "run", quiet=True)) == EXIT_USER_ERROR
    assert "cannot read signing key file" in capsys.readouterr().out
