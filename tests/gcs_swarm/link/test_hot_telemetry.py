"""The byte-level intake of the 50 Hz telemetry (gcs_swarm.link.hot_telemetry) against the general path
(every packet a pymavlink message through Network.accept and VehicleLink.handle, `hot_intake=False`): two
fleets of one vehicle each, on real loopback sockets (tests/gcs_swarm/link/intake_harness.py; the batch
intake is off here, test_batch_intake.py compares it), receive the same random datagrams (valid, late,
rebooting, invalid values, other systems and components, corrupted, truncated, signed, garbage), and end with
the same state, counters, events and tlog records of the vehicle's packets."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from tests.gcs_swarm.link.intake_harness import FleetUnderTest, bind, datagram, encoder, same


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(datagrams=st.lists(datagram(), min_size=1, max_size=12), bound=st.booleans())
def test_hot_and_general_intake_agree(tmp_path: Path, datagrams: list[bytes], bound: bool) -> None:
    hot, general = FleetUnderTest(tmp_path, "hot"), FleetUnderTest(tmp_path, "general")
    try:
        for fleet in (hot, general):
            if bound:
                bind(fleet)
            fleet.feed(datagrams)
        hot_seen, general_seen = hot.observed(), general.observed()
        different = [k for k in general_seen if not same(hot_seen[k], general_seen[k])]
        assert not different, {k: (hot_seen[k], general_seen[k]) for k in different}
        assert general.taken == 0
    finally:
        hot.close()
        general.close()


def test_the_hot_path_takes_the_streamed_telemetry(tmp_path: Path) -> None:
    """Without this, the comparison above could hold because the byte path never takes anything: a bound
    vehicle's valid GLOBAL_POSITION_INT and ATTITUDE are taken, and turn into the state the general path
    makes of them (values worked out by hand from the fields)."""
    fleet = FleetUnderTest(tmp_path, "hot")
    try:
        bind(fleet)
        mav = encoder()
        position = mav.global_position_int_encode(2000, 473977420, 85455940, 498000, 10000, 120, -40, 3, 9000)
        attitude = mav.attitude_encode(2000, 0.1, -0.2, 0.0, 0.0, 0.0, 0.0)
        fleet.feed([position.pack(mav) + attitude.pack(mav)])
        assert fleet.taken == 2
        state = fleet.fleet.state
        assert state.geodetic[0] == pytest.approx([47.397742, 8.545594, 498.0])
        assert state.vel[0] == pytest.approx([-0.40, 1.20, -0.03])  # ENU from NED cm/s
        roll, pitch, yaw = state.att[0]
        assert (roll, pitch) == pytest.approx((0.1, 0.2), abs=1e-7) and yaw == pytest.approx(math.pi / 2)
        assert state.position_ms[0] == 2000 and fleet.link.channel.stats.received == 3
        assert fleet.vehicle_packets()[-2:] == [bytes(position.get_msgbuf()), bytes(attitude.get_msgbuf())]
    finally:
        fleet.close()


def test_the_field_order_is_pymavlinks() -> None:
    """The byte path picks handler arguments by field name from the wire-order unpack; a message whose
    payload is the struct of known values gives those values back."""
    from gcs_swarm.link.hot_telemetry import ATTITUDE_FIELDS, POSITION_FIELDS

    cls = mavlink2.MAVLink_global_position_int_message
    wire = dict(time_boot_ms=5, lat=6, lon=7, alt=8, relative_alt=9, vx=10, vy=11, vz=12, hdg=13)
    payload = struct.pack(cls.unpacker.format, *(wire[name] for name in cls.ordered_fieldnames))
    assert POSITION_FIELDS.pick(POSITION_FIELDS.unpacker.unpack(payload)) == (5, 6, 7, 8, 10, 11, 12)
    cls_att = mavlink2.MAVLink_attitude_message
    values = dict(time_boot_ms=3, roll=0.5, pitch=0.25, yaw=-0.125, rollspeed=1, pitchspeed=2, yawspeed=4)
    payload = struct.pack(cls_att.unpacker.format, *(values[name] for name in cls_att.ordered_fieldnames))
    assert ATTITUDE_FIELDS.pick(ATTITUDE_FIELDS.unpacker.unpack(payload)) == (3, 0.5, 0.25, -0.125)
