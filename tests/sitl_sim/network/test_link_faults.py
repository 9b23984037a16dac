"""Link faults: seeded per-packet fates, outages per vehicle, the --link-* options, a lockstep client."""

from __future__ import annotations

import math
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl_sim.autopilot.params import ParamTable, param_specs
from sitl_sim.cli import build_config, build_parser, main
from sitl_sim.network.link_faults import DOWN, UP, FaultChannel, LinkFaults, Outage, message_id, parse_outage

NO_FAULT = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # loss, dup, corrupt, reorder, delay_ms, jitter_ms


def _packet(t_ms: int) -> bytes:
    mav = mavlink.MAVLink(None, 255, 190)
    return mav.system_time_encode(0, t_ms).pack(mav)


def _run(channel: FaultChannel, rates: tuple[float, ...], frames: int = 500) -> list[tuple[int, bytes]]:
    """Push one packet per 20 ms frame, collect (delivery ms, packet) until everything is out."""
    out = []
    for k in range(frames + 200):
        now = 20 * k
        if k < frames:
            channel.push(DOWN, _packet(now), None, now, rates)
        out += [(now, packet) for packet, _ in channel.due(DOWN, now)]
    return out


def test_fates_are_seeded_and_repeat_exactly() -> None:
    rates = (0.1, 0.05, 0.05, 0.05, 30.0, 100.0)
    first = _run(FaultChannel(7, 0, ()), rates)
    assert first == _run(FaultChannel(7, 0, ()), rates)
    assert first != _run(FaultChannel(8, 0, ()), rates)
    assert first != _run(FaultChannel(7, 1, ()), rates)  # each vehicle has its own link


def test_loss_rate_and_counters_match_the_setting() -> None:
    channel = FaultChannel(0, 0, ())
    delivered = _run(channel, (0.1, 0.0, 0.0, 0.0, 0.0, 0.0), frames=2000)
    assert 1700 < len(delivered) < 1900
    assert channel.drops.lost == 2000 - len(delivered)


def test_delay_and_jitter_are_in_simulated_ms_and_reorder_packets() -> None:
    delivered = _run(FaultChannel(0, 0, ()), (0.0, 0.0, 0.0, 0.0, 40.0, 100.0))
    parser = mavlink.MAVLink(None)
    stamps = [(at, parser.decode(bytearray(p)).time_boot_ms) for at, p in delivered]
    assert len(stamps) == 500
    assert all(40 <= at - sent <= 160 for at, sent in stamps)  # frames of 20 ms round the due time up
    assert [s for _, s in stamps] != sorted(s for _, s in stamps)  # jitter reorders


def test_duplicates_and_corruption() -> None:
    channel = FaultChannel(0, 0, ())
    delivered = _run(channel, (0.0, 0.2, 0.2, 0.0, 0.0, 0.0))
    assert len(delivered) == 500 + channel.drops.duplicated and channel.drops.duplicated > 50
    parser = mavlink.MAVLink(None)
    parser.robust_parsing = True
    good = sum(1 for _, p in delivered for m in parser.parse_buffer(p) or [] if m.get_type() == "SYSTEM_TIME")
    assert channel.drops.corrupted > 50 and good < len(delivered)


def test_outage_silences_one_vehicle_both_ways_for_its_window() -> None:
    outage = Outage(1, 2.0, 3.0)
    assert outage.covers(1, 2.0) and outage.covers(1, 4.99) and not outage.covers(1, 5.0)
    assert not outage.covers(0, 3.0) and Outage(None, 0.0, float("inf")).covers(5, 1e9)
    channel = FaultChannel(0, 1, (outage, Outage(0, 0.0, 100.0)))
    for direction in (UP, DOWN):
        channel.push(direction, _packet(1), None, 2500, NO_FAULT)
        channel.push(direction, _packet(2), None, 5000, NO_FAULT)
        assert [p for p, _ in channel.due(direction, 5000)] == [_packet(2)]
    assert channel.drops.lost == 2


@pytest.mark.parametrize(
    ("text", "expected"),
    [("10:5", Outage(None, 10.0, 5.0)), ("2@20:inf", Outage(2, 20.0, float("inf")))],
)
def test_parse_outage(text: str, expected: Outage) -> None:
    assert parse_outage(text, vehicles=3) == expected


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--link-loss", "1.5"], "--link-loss must be a probability"),
        (["--link-dup", "nan"], "--link-dup must be a probability"),
        (["--link-jitter-ms", "-1"], "--link-jitter-ms must be 0..10000 ms"),
        (["--link-outage", "5@1:2"], "vehicle 5 does not exist"),
        (["--link-outage", "x@1:2"], "whole number"),
        (["--link-outage", "1-2"], "[I@]START:DURATION"),
        (["--link-outage", "1:0"], "duration must be > 0"),
        (["--link-from", "-1"], "--link-from must be >= 0"),
    ],
)
def test_bad_link_options_give_one_line_and_status_2(argv, fragment, capsys) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--vehicles", "2", *argv])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and fragment in err


def test_message_id_reads_both_mavlink_versions() -> None:
    assert message_id(_packet(5)) == mavlink.MAVLINK_MSG_ID_SYSTEM_TIME
    assert message_id(b"\xfe\x00\x00\x01\x01\x21") == 0x21 and message_id(b"junk") == -1


def test_lockstep_client_keeps_the_clock_through_a_dead_link(sitl) -> None:
    """The vehicle's link dies at 1 s for good: the client hears only clock ticks, answers them, and the
    lockstep simulator keeps running; the radio drops everything and counts it."""
    sim = sitl("--lockstep", "--link-outage", "0@1:inf", "--link-loss", "0.2")
    link = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{sim.port(0)}", source_system=255, source_component=190
    )
    try:
        link.mav.heartbeat_send(6, 8, 0, 0, 4)
        latest, ticks, deadline = 0, 0, time.monotonic() + 20
        while latest < 3000 and time.monotonic() < deadline:
            msg = link.recv_match(blocking=True, timeout=1.0)
            stamp = getattr(msg, "time_boot_ms", 0) if msg is not None else 0
            if stamp > latest:
                latest = stamp
                link.mav.system_time_send(0, stamp)
                ticks += latest > 1000 and msg.get_type() == "SYSTEM_TIME" and msg.time_unix_usec == 0
        assert latest >= 3000 and ticks > 50
    finally:
        link.close()
    status, err = sim.stop()
    assert status == 0 and "link_lost=" in err and "link_lost=0 " not in err


def test_link_settings_are_per_vehicle_params_with_ranges() -> None:
    """SIM_LINK_* are ordinary parameters (PARAM_SET at run time, per vehicle, checked ranges)."""
    table = ParamTable(2, param_specs(0.4))
    for name, value in LinkFaults(loss=0.1, jitter_ms=100.0).params().items():
        table.values[:, table.column_index(name)] = value
    assert table.value(1, "SIM_LINK_LOSS") == pytest.approx(0.1) and table.value(0, "SIM_LINK_JITTER") == 100
    assert table.check("SIM_LINK_LOSS", 1.5) is not None and table.check("SIM_LINK_DELAY", 250.0) is None
    table.set(0, "SIM_LINK_LOSS", 1.0)
    assert table.value(0, "SIM_LINK_LOSS") == 1.0 and table.value(1, "SIM_LINK_LOSS") == pytest.approx(0.1)


FAULTY_MISSION = """vehicles:
  - {name: lead, role: leader, start: {position: [0, 0, 0]}}
  - {name: wing, start: {position: [-10, 0, 0]}}
goal: [100, 50, 10]
world:
  link:
    loss: 0.1
    jitter_ms: 100
    from_s: 12
    outages:
      - {vehicle: wing, start_s: 15, duration_s: inf}
      - {start_s: 30, duration_s: 2}
"""


def _link_of(argv: list[str]) -> LinkFaults:
    parser = build_parser()
    return build_config(parser, parser.parse_args(argv)).link


def test_mission_link_section_sets_the_faults(tmp_path) -> None:
    mission = tmp_path / "faulty.yaml"
    mission.write_text(FAULTY_MISSION)
    assert _link_of(["--mission", str(mission)]) == LinkFaults(
        loss=0.1,
        jitter_ms=100.0,
        start_s=12.0,
        outages=(Outage(1, 15.0, math.inf), Outage(None, 30.0, 2.0)),
    )


def test_link_options_override_the_mission_one_by_one(tmp_path) -> None:
    """Each --link-* option given replaces the mission's value; any --link-outage replaces its outages."""
    mission = tmp_path / "faulty.yaml"
    mission.write_text(FAULTY_MISSION)
    link = _link_of(["--mission", str(mission), "--link-loss", "0", "--link-delay-ms", "20"])
    assert (link.loss, link.delay_ms, link.jitter_ms, link.start_s) == (0.0, 20.0, 100.0, 12.0)
    assert len(link.outages) == 2
    link = _link_of(["--mission", str(mission), "--link-outage", "0@5:1"])
    assert link.outages == (Outage(0, 5.0, 1.0),) and link.loss == 0.1


def test_without_mission_or_options_the_link_is_clean() -> None:
    assert _link_of(["--vehicles", "2"]) == LinkFaults()
