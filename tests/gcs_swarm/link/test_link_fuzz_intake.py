"""Hostile input to the ground station's intake: datagram parsing (connection._DatagramParser) then
VehicleLink.handle. No exception, the fleet state stays finite, what is dropped is counted, and valid
telemetry after the garbage is still decoded."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import _DatagramParser
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig

ORIGIN = (47.397742, 8.545594, 488.0)
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
EXTREME = st.sampled_from([math.nan, math.inf, -math.inf, 1e38, -1e38, 0.0])


def vehicle(sysid: int = 1) -> mavlink2.MAVLink:
    return mavlink2.MAVLink(None, sysid, 1)


def heartbeat(mav: mavlink2.MAVLink) -> bytes:
    return mav.heartbeat_encode(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3, 3
    ).pack(mav)


def position(mav: mavlink2.MAVLink, t_ms: int) -> bytes:
    return mav.global_position_int_encode(t_ms, 473977420, 85455940, 498000, 10000, 100, 200, 0, 9000).pack(
        mav
    )


class Discard:
    """Stands in for the link's endpoint: what the ground station sends (its heartbeats) goes nowhere."""

    def send(self, packet: bytes, sysid: int | None) -> bool:
        return True


class Intake:
    """One unconnected fleet of one vehicle fed datagrams straight into its parse + handle path."""

    def __init__(self) -> None:
        self.fleet = Fleet([VehicleConfig("v0", "udpout:127.0.0.1:9", sysid=1)], ORIGIN)
        self.link = self.fleet.links[0]
        self.link.channel.endpoint = Discard()  # type: ignore[assignment]
        self.parser = _DatagramParser()
        self.mav = vehicle()
        self.t_ms = 1000
        self.feed(heartbeat(self.mav))
        self.feed(self.mav.attitude_encode(self.t_ms, 0.1, -0.1, 1.0, 0, 0, 0).pack(self.mav))
        self.feed(position(self.mav, self.t_ms))

    def feed(self, data: bytes) -> None:
        for msg in self.parser.parse(data):
            self.fleet.network.accept(self.link, msg, 0.0)

    def dropped(self) -> int:
        c = self.link.channel.stats
        return c.bad + c.ignored + c.invalid + c.late

    def assert_still_served(self) -> None:
        """State finite, and a fresh valid position is decoded."""
        st_ = self.fleet.state
        for array in (st_.pos, st_.vel, st_.att, st_.geodetic):
            assert np.isfinite(np.asarray(array, dtype=float)).all()
        count = int(st_.position_count[0])
        self.t_ms += 5_000_000
        self.feed(heartbeat(self.mav) + position(self.mav, self.t_ms))
        assert int(st_.position_count[0]) == count + 1


@FUZZ
@given(data=st.binary(min_size=1, max_size=600))
def test_random_bytes(data: bytes) -> None:
    intake = Intake()
    before = intake.dropped()
    intake.feed(data)
    assert intake.dropped() > before or intake.link.channel.stats.received > 2
    intake.assert_still_served()


@FUZZ
@given(cut=st.integers(min_value=1, max_value=39), tail=st.binary(max_size=300))
def test_truncated_and_oversized_frames(cut: int, tail: bytes) -> None:
    intake = Intake()
    frame = position(intake.mav, intake.t_ms + 20)
    before = intake.link.channel.stats.bad
    intake.feed(frame[:cut])
    assert intake.link.channel.stats.bad > before
    intake.feed(frame[:-1] + tail)  # the CRC cut short or followed by junk
    intake.assert_still_served()


@FUZZ
@given(values=st.lists(EXTREME, min_size=6, max_size=6), sysid=st.integers(0, 255))
def test_valid_frames_with_extreme_fields_and_spoofed_sysids(values: list[float], sysid: int) -> None:
    intake = Intake()
    mav = vehicle(sysid)
    t = intake.t_ms + 20
    intake.feed(mav.attitude_encode(t, *values).pack(mav))
    intake.feed(mav.attitude_quaternion_encode(t, *values[:4], 0, 0, 0, [0.0] * 4).pack(mav))
    intake.feed(mav.param_value_encode(b"MOT_THST_HOVER", values[0], 9, 1, 0).pack(mav))
    lat = int(np.clip(np.nan_to_num(values[1]), -(2**31), 2**31 - 1))
    intake.feed(mav.global_position_int_encode(t, lat, lat, 0, 0, 0, 0, 0, 0).pack(mav))
    intake.assert_still_served()
    if sysid != 1:
        assert intake.link.channel.stats.ignored >= 4  # another system's packets never touch this vehicle
    assert all(math.isfinite(v) for v in intake.link.parameters.values.values())


def test_flood_of_garbage_then_valid_traffic() -> None:
    intake = Intake()
    rng = np.random.default_rng(7)
    for _ in range(2000):
        intake.feed(rng.integers(0, 256, size=int(rng.integers(1, 300)), dtype=np.uint8).tobytes())
    assert intake.link.channel.stats.bad >= 2000
    intake.assert_still_served()
