"""The command line contract: argument errors, READY lines, heartbeats on every port, clean SIGTERM/SIGINT."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from sitl_sim.cli import build_config, build_parser, main
from tests.sitl_sim.sim_process import M


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        ([], "--vehicles N is required"),
        (["--vehicles", "0"], "--vehicles must be >= 1"),
        (["--vehicles", "2", "--speedup", "2", "--lockstep"], "not allowed with argument"),
        (["--vehicles", "2", "--speedup", "-1"], "--speedup"),
        (["--vehicles", "2", "--home", "1,2"], "--home must be LAT,LON,ALT"),
        (["--vehicles", "2", "--home", "95,0,0"], "latitude"),
        (["--vehicles", "2", "--bind", "not-an-ip"], "--bind"),
        (["--vehicles", "300"], "exceed sysid 255"),
        (["--vehicles", "2", "--base-port", "65535"], "exceed port 65535"),
        (["--vehicles", "1", "--lockstep", "--lockstep-hz", "30"], "--lockstep-hz"),
        (["--vehicles", "1", "--truth-rate-hz", "7"], "--truth-rate-hz"),
        (["--vehicles", "1", "--truth-log", "/nonexistent/dir/t.csv"], "does not exist"),
        (["--vehicles", "1", "--mission", "/nonexistent.yaml"], "mission"),
        (["--vehicles", "x"], "invalid int value"),
        (["--vehicles", "1", "--lockstep", "--lockstep-spin-us", "-1"], "--lockstep-spin-us"),
        (["--vehicles", "1", "--lockstep", "--lockstep-spin-us", "nan"], "--lockstep-spin-us"),
        (["--vehicles", "1", "--lockstep", "--lockstep-spin-us", "20001"], "--lockstep-spin-us"),
    ],
)
def test_bad_arguments_give_one_line_and_status_2(argv, fragment, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("sitl-sim: error: ")
    assert fragment in err


def test_mission_vehicle_count_must_match(tmp_path, capsys):
    mission = tmp_path / "m.yaml"
    mission.write_text("vehicles:\n  - {role: leader, start: {position: [0, 0, 0]}}\ngoal: [50, 0, 10]\n")
    with pytest.raises(SystemExit):
        main(["--mission", str(mission), "--vehicles", "3"])
    assert "mission has 1 vehicles" in capsys.readouterr().err


def test_mission_link_mistake_is_one_line_naming_the_field(tmp_path, capsys):
    mission = tmp_path / "m.yaml"
    mission.write_text(
        "vehicles:\n  - {role: leader, start: {position: [0, 0, 0]}}\ngoal: [50, 0, 10]\n"
        "world: {link: {outages: [{vehicle: nobody, start_s: 1, duration_s: 2}]}}\n"
    )
    with pytest.raises(SystemExit) as exit_info:
        main(["--mission", str(mission)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{mission}:4: world.link.outages[0].vehicle: " in err


def test_port_in_use_is_a_clear_error(sitl):
    sim = sitl("--speedup", "1")
    result = subprocess.run(
        [sys.executable, "-m", "sitl_sim", "--vehicles", "1", "--base-port", str(sim.port(0))],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 1
    assert result.stderr.startswith("sitl-sim: error: cannot open udp 127.0.0.1")


def test_every_vehicle_heartbeats_on_its_port_with_its_sysid(sitl, pilot_for):
    sim = sitl("--speedup", "4", "--sysid-base", "11", vehicles=3)
    assert sim.stdout[-1] == "READY"
    expected = [f"vehicle {i} sysid {11 + i} udp 127.0.0.1:{sim.port(i)}" for i in range(3)]
    assert sim.stdout[:3] == expected
    pilot = pilot_for(sim, lockstep=False, sysid_base=11)
    pilot.spin(lambda: all("HEARTBEAT" in v.latest for v in pilot.vehicles), 10.0)
    for vehicle in pilot.vehicles:
        hb = vehicle.latest["HEARTBEAT"]
        assert hb.get_srcSystem() == vehicle.sysid and hb.get_srcComponent() == 1
        assert (hb.type, hb.autopilot) == (M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA)
        assert hb.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        assert not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
        assert hb.get_msgbuf()[0] == 0xFD  # MAVLink 2 out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_exits_cleanly_with_the_truth_log_closed(sitl, tmp_path, sig):
    log = tmp_path / "truth.csv"
    sim = sitl("--speedup", "20", "--truth-log", str(log), vehicles=2)
    status, err = sim.stop(sig)
    assert status == 0
    assert "vehicle 1 (sysid 2): received=" in err
    text = log.read_text()
    assert text.endswith("\n") and text.startswith("t,vehicle,sysid,")
    assert all(line.count(",") == 23 for line in text.splitlines())
    assert (tmp_path / "truth.obstacles.csv").read_text() == "t,obstacle,x,y,z,radius\n"


def test_lockstep_spin_reaches_the_config() -> None:
    parser = build_parser()
    default = build_config(parser, parser.parse_args(["--vehicles", "1", "--lockstep"]))
    assert default.lockstep_spin_s == pytest.approx(1e-3)  # the documented default, 1000 us
    argv = ["--vehicles", "1", "--lockstep", "--lockstep-spin-us", "0"]
    off = build_config(parser, parser.parse_args(argv))
    assert off.lockstep_spin_s == 0.0
