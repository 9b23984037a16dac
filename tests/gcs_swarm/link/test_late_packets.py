"""Delayed and reordered telemetry: lateness is judged per kind of data, so a position report that arrives
after a newer attitude (or a lockstep clock tick) is still used, while an older position than the one in hand
is dropped and counted."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from tests.gcs_swarm.link.test_link_fuzz_intake import Intake, position


def clock_tick(mav: mavlink2.MAVLink, t_ms: int) -> bytes:
    return mav.system_time_encode(0, t_ms).pack(mav)


def attitude(mav: mavlink2.MAVLink, t_ms: int, roll: float) -> bytes:
    return mav.attitude_encode(t_ms, roll, 0.0, 0.0, 0, 0, 0).pack(mav)


def test_a_delayed_position_behind_newer_packets_of_other_kinds_is_still_taken() -> None:
    intake = Intake()  # position, attitude at 1000 ms
    st, i = intake.fleet.state, 0
    intake.feed(clock_tick(intake.mav, 1100))
    intake.feed(attitude(intake.mav, 1100, 0.2))
    intake.feed(position(intake.mav, 1040))  # sent at 1040 ms, delayed past the 1100 ms packets
    assert st.position_ms[i] == 1040 and st.time_ms[i] == 1100
    assert intake.link.channel.stats.late == 0


def test_an_older_packet_of_the_same_kind_is_dropped_and_counted() -> None:
    intake = Intake()
    st = intake.fleet.state
    intake.feed(position(intake.mav, 1060))
    intake.feed(attitude(intake.mav, 1060, 0.3))
    intake.feed(position(intake.mav, 1020))  # reordered: older than the position in hand
    intake.feed(attitude(intake.mav, 1020, 0.9))
    assert st.position_ms[0] == 1060
    assert abs(st.att[0, 0] - 0.3) < 1e-6
    assert intake.link.channel.stats.late == 2
