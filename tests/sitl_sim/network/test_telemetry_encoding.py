"""The fast telemetry streams packed for the whole fleet at once (TelemetryView's *_payloads, framed by
Framer.frame_payload) against pymavlink's own encoder and against framing each vehicle's field values one at a
time (Framer.frame, the per-vehicle path): the same bytes, the same sequence numbers, the same None cases.

The expected field values are computed here, vehicle by vehicle, with Python scalars from the simulated state
(velocity NED straight from the ENU state; attitude from ned_telemetry, position from Geodesy.to_geodetic, the
shared conversions tested in test_streams.py) and rounded as MAVLink's integer fields are: half to even,
velocity clamped to int16 cm/s, heading wrapped into [0, 36000) cdeg.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sitl_sim.network.streams import STREAM_IDS, Framer, TelemetryView, ned_telemetry
from sitl_sim.simulator import Simulator
from swarm_common.rotations import euler_to_quaternion
from tests.sitl_sim.sim_process import M, in_process_config

PERSONAS = ("ardupilot", "ardupilot", "px4", "ardupilot")  # vehicle 2 speaks PX4 (no EKF_STATUS_REPORT)
N = len(PERSONAS)
FAST = {
    M.MAVLINK_MSG_ID_ATTITUDE: M.MAVLink_attitude_message,
    M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: M.MAVLink_attitude_quaternion_message,
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: M.MAVLink_local_position_ned_message,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: M.MAVLink_global_position_int_message,
}
POSITION_STREAMS = {  # sent only once the EKF has a position (None before)
    M.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
    M.MAVLINK_MSG_ID_HOME_POSITION,
    M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN,
}


@pytest.fixture(scope="module")
def fleet() -> Iterator[Simulator]:
    """N vehicles (one PX4) in process; each example overwrites their state."""
    simulator = Simulator(in_process_config([[5.0 * i, 0.0, 10.0] for i in range(N)], autopilots=PERSONAS))
    yield simulator
    simulator.close()


def cm_s(v: float) -> int:
    """A velocity component (m/s) as GLOBAL_POSITION_INT's int16 cm/s: rounded half to even, clamped."""
    return max(-32768, min(32767, round(v * 100.0)))


def expected_fields(sim: Simulator, view: TelemetryView, i: int) -> dict[int, dict[str, object] | None]:
    """Field values of vehicle i's fast streams by msg_id (None: not sent), one vehicle, Python scalars."""
    state = sim.autopilot.state
    row = ned_telemetry(state.pos, state.vel, state.quat, state.omega, sim.autopilot.origin)[i].tolist()
    t = view.time_boot_ms
    rates = dict(zip(("rollspeed", "pitchspeed", "yawspeed"), row[7:10], strict=True))
    fields: dict[int, dict[str, object] | None] = {
        M.MAVLINK_MSG_ID_ATTITUDE: dict(time_boot_ms=t, roll=row[4], pitch=row[5], yaw=row[6], **rates),
        M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: dict(
            time_boot_ms=t, q1=row[0], q2=row[1], q3=row[2], q4=row[3], **rates, repr_offset_q=[0.0] * 4
        ),
        M.MAVLINK_MSG_ID_LOCAL_POSITION_NED: None,
        M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: None,
    }
    if sim.autopilot.ready[i]:
        east, north, up = state.vel[i].tolist()
        x, y, z = row[10:13]
        fields[M.MAVLINK_MSG_ID_LOCAL_POSITION_NED] = dict(
            time_boot_ms=t, x=x, y=y, z=z, vx=north, vy=east, vz=-up
        )
        lat, lon, alt = sim.geodesy.to_geodetic(state.pos[i : i + 1])[0].tolist()
        fields[M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT] = dict(
            time_boot_ms=t,
            lat=round(lat * 1e7),
            lon=round(lon * 1e7),
            alt=round(alt * 1000.0),
            relative_alt=round((state.pos[i, 2] - sim.autopilot.home[i, 2]) * 1000.0),
            vx=cm_s(north),
            vy=cm_s(east),
            vz=cm_s(-up),
            hdg=round(math.degrees(row[6]) * 100.0) % 36000,
        )
    return fields


def wire_values(cls: type[M.MAVLink_message], fields: dict[str, object]) -> list[Any]:
    """Field values in wire order, arrays flattened (Framer.frame's arguments)."""
    values: list[Any] = []
    for name in cls.ordered_fieldnames:
        value = fields[name]
        values.extend(value if isinstance(value, list) else [value])
    return values


def parse(packet: bytes) -> M.MAVLink_message:
    """The one message in a packet, decoded by pymavlink (checks length and CRC)."""
    messages = M.MAVLink(None).parse_buffer(packet)
    assert messages is not None and len(messages) == 1
    return messages[0]


# ENU yaw -pi/2 is NED yaw +-pi (hdg 18000 cdeg either side), +pi/2 is hdg 0 (level: GLOBAL_POSITION_INT's
# last field is then a trailing zero, truncated)
yaws = st.one_of(
    st.floats(-math.pi, math.pi),
    st.floats(-math.pi / 2 - 1e-4, -math.pi / 2 + 1e-4),
    st.floats(math.pi / 2 - 1e-4, math.pi / 2 + 1e-4),
    st.sampled_from([math.pi / 2, -math.pi / 2, 0.0, math.pi]),
)
tilts = st.one_of(st.just(0.0), st.floats(-math.pi, math.pi))
# m/s: k/8 m/s is exactly 12.5 k cm/s, a half for odd k; beyond +-327.67 m/s the int16 cm/s field clamps;
# |v| <= 450 m/s keeps GPS_RAW_INT's uint16 ground speed in range
velocities = st.one_of(st.floats(-450.0, 450.0), st.integers(-3600, 3600).map(lambda k: k / 8), st.just(0.0))
vehicle = st.fixed_dictionaries(
    {
        # ENU m: up to 300 km away; up to 1000 km high (alt mm stays in int32)
        "pos": st.tuples(st.floats(-3e5, 3e5), st.floats(-3e5, 3e5), st.floats(-1e3, 1e6)),
        "vel": st.tuples(velocities, velocities, velocities),
        "euler": st.tuples(tilts, st.one_of(st.just(0.0), st.floats(-1.5, 1.5)), yaws),
        "omega": st.one_of(st.just((0.0, 0.0, 0.0)), st.tuples(*[st.floats(-20.0, 20.0)] * 3)),
        "ready": st.booleans(),
        "seq": st.integers(0, 255),
    }
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(vehicles=st.lists(vehicle, min_size=N, max_size=N), time_us=st.integers(0, (2**32 - 1) * 1000))
def test_fleet_packed_streams_are_pymavlink_bytes_in_sequence(fleet: Simulator, vehicles, time_us) -> None:
    """One frame of every stream per vehicle, in STREAM_IDS order: the fast streams' packets are pymavlink's
    and the per-vehicle path's bytes; every packet takes the next sequence number, the None cases none."""
    ap, state = fleet.autopilot, fleet.autopilot.state
    for i, v in enumerate(vehicles):
        state.pos[i], state.vel[i], state.omega[i] = v["pos"], v["vel"], v["omega"]
        state.quat[i] = euler_to_quaternion(v["euler"])
    ap.ready = np.array([v["ready"] for v in vehicles])
    view = TelemetryView(ap, time_us, fleet.geodesy, unix_epoch_us=1_700_000_000_000_000)
    for i, v in enumerate(vehicles):
        sysid = int(fleet.sysids[i])
        framer, one_by_one = Framer(sysid, 1), Framer(sysid, 1)
        reference = M.MAVLink(None, srcSystem=sysid, srcComponent=1)
        framer.mav.seq = one_by_one.mav.seq = reference.seq = v["seq"]
        fields = expected_fields(fleet, view, i)
        sent = 0
        for msg_id in STREAM_IDS:  # one frame of every stream, in the order the simulator queues them
            packet = view.encode(framer, msg_id, i)
            if msg_id == M.MAVLINK_MSG_ID_EKF_STATUS_REPORT and PERSONAS[i] == "px4":
                assert packet is None
            elif msg_id in POSITION_STREAMS and not v["ready"]:
                assert packet is None
            elif msg_id == M.MAVLINK_MSG_ID_FENCE_STATUS:
                assert packet is None  # no fence enabled
            else:
                assert packet is not None
            if packet is None:
                continue
            seq = (v["seq"] + sent) % 256
            assert packet[4] == seq  # header seq: one more per packet queued
            sent += 1
            assert parse(packet).get_msgId() == msg_id
            cls = FAST.get(msg_id)
            if cls is None:
                continue
            expected = fields[msg_id]
            assert expected is not None
            reference.seq = one_by_one.mav.seq = seq
            assert packet == cls(**expected).pack(reference)
            assert packet == one_by_one.frame(cls, *wire_values(cls, expected))
        assert framer.mav.seq == (v["seq"] + sent) % 256


def test_integer_fields_round_half_to_even_clamp_and_wrap(fleet: Simulator) -> None:
    """GLOBAL_POSITION_INT's hdg and velocity of chosen NED values (the view's NED rows given directly):
    exact halves go to the even integer, headings wrap into [0, 36000), velocities clamp to int16 cm/s."""
    ap = fleet.autopilot
    ap.ready = np.ones(N, dtype=bool)
    half_yaw = exact_yaw(0.125)  # rad whose degrees x 100 is exactly 12.5
    cases = [  # NED yaw (rad), velocity NED (m/s), expected hdg (cdeg), vx, vy, vz (cm/s)
        (half_yaw, (0.125, 0.375, -0.125), 12, 12, 38, -12),
        (-half_yaw, (327.67, 327.675, -327.685), 35988, 32767, 32767, -32768),
        (math.pi, (400.0, -400.0, 0.005), 18000, 32767, -32768, 0),
        (-math.pi, (-0.005, 0.015, 1e6), 18000, 0, 2, 32767),
    ]
    rows = np.zeros((N, 16))
    for i, (yaw, velocity, *_) in enumerate(cases):
        rows[i, 6], rows[i, 13:16] = yaw, velocity
    view = TelemetryView(ap, 20_000, fleet.geodesy, unix_epoch_us=0)
    view.__dict__["ned"] = rows  # functools.cached_property: the instance's value stands for the computed one
    for i, (_, velocity, hdg, vx, vy, vz) in enumerate(cases):
        packet = view.encode(Framer(1, 1), M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, i)
        assert packet is not None
        msg = parse(packet)
        assert (msg.hdg, msg.vx, msg.vy, msg.vz) == (hdg, vx, vy, vz)
        assert hdg == round(math.degrees(rows[i, 6]) * 100.0) % 36000
        assert (vx, vy, vz) == tuple(cm_s(c) for c in velocity)


def exact_yaw(degrees: float) -> float:
    """A yaw (rad) near `degrees` whose math.degrees(yaw) * 100 is exactly degrees * 100."""
    yaw = math.radians(degrees)
    for _ in range(64):
        if math.degrees(yaw) * 100.0 == degrees * 100.0:
            return yaw
        yaw = math.nextafter(yaw, math.inf if math.degrees(yaw) < degrees else -math.inf)
    raise AssertionError(f"no float yaw at exactly {degrees} deg")


def test_a_vehicle_at_rest_heading_north_sends_a_truncated_payload(fleet: Simulator) -> None:
    """hdg 0 and zero velocity are trailing zeros: MAVLink 2 drops them (the length byte says so)."""
    ap, state = fleet.autopilot, fleet.autopilot.state
    ap.ready = np.ones(N, dtype=bool)
    state.pos[0], state.vel[0], state.omega[0] = (0.0, 0.0, ap.home[0, 2]), 0.0, 0.0
    state.quat[0] = (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5))  # ENU yaw 90 deg = heading north
    view = TelemetryView(ap, 0, fleet.geodesy, unix_epoch_us=0)
    packet = view.encode(Framer(1, 1), M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 0)
    # time_boot_ms, lat, lon, then alt 500 m AMSL = 0x0007A120 mm, whose high byte is a trailing zero too
    assert packet is not None and packet[1] == 15
    msg = parse(packet)
    assert (msg.relative_alt, msg.vx, msg.vy, msg.vz, msg.hdg) == (0, 0, 0, 0, 0)
