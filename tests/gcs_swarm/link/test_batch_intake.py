"""The batch intake (gcs_swarm.link.batch_intake, its kernel link.intake_kernel) against the per-packet paths:
fleets of three vehicles on real loopback sockets (intake_harness) receive the same streams of datagrams,
mostly the plain 50 Hz frames the kernel takes (time running on, GCS HEARTBEATs falling due), mixed with
everything it must hand back (late packets, reboots, other messages, other systems, signed, damaged and
truncated packets, garbage, invalid values), and end with the same state, counters, events, tlog records
of the vehicles' packets and packets sent back to the vehicles."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gcs_swarm.link import batch_intake
from tests.gcs_swarm.link.intake_harness import SYSID, FleetUnderTest, bind, datagram, encoder, same

pytestmark = pytest.mark.skipif(not batch_intake.available(), reason="needs numba on a little-endian machine")

VEHICLES = 3


def frame(
    sysid: int, t_ms: int, roll: float = 0.1, vz: int = -3, lat: int | None = None, parts: str = "pa"
) -> bytes:
    """The datagram a vehicle streams every 20 ms: GLOBAL_POSITION_INT ("p" in `parts`) and ATTITUDE ("a")
    stamped `t_ms`."""
    mav = encoder(sysid)
    lat = 473977420 + t_ms if lat is None else lat
    position = mav.global_position_int_encode(t_ms, lat, 85455940, 498000, 10000, 120, -40, vz, 0)
    attitude = mav.attitude_encode(t_ms, roll, -0.2, 3.0, 0.0, 0.0, 0.0)
    return (position.pack(mav) if "p" in parts else b"") + (attitude.pack(mav) if "a" in parts else b"")


@st.composite
def streams(draw: st.DrawFn) -> tuple[list[bytes], list[int]]:
    """Datagrams of VEHICLES vehicles in a random interleaving, and who sends each. Each vehicle's clock
    runs on by 20 ms a datagram as a rule, now and then standing still, stepping back a little (late) or
    over 5 s (a reboot), or jumping ahead; most datagrams are its plain frame at that time, the rest
    anything a link carries, stamped near it."""
    count = draw(st.integers(1, 40))
    senders = draw(st.lists(st.integers(0, VEHICLES - 1), min_size=count, max_size=count))
    clocks = [draw(st.integers(0, 1000)) for _ in range(VEHICLES)]
    datagrams = []
    for i in senders:
        clocks[i] = max(0, clocks[i] + draw(st.sampled_from([20] * 12 + [0, -20, -6000, 480, 3000])))
        sysid = SYSID + i
        if draw(st.integers(0, 9)) < 7:
            roll = draw(st.sampled_from([0.1] * 9 + [math.nan]))
            lat = draw(st.sampled_from([None] * 9 + [900_000_000, -900_000_001]))
            vz = draw(st.sampled_from([-3, -32768]))
            parts = draw(st.sampled_from(["pa"] * 6 + ["p", "a", "ap"]))
            datagrams.append(frame(sysid, clocks[i], roll, vz, lat, parts))
        else:
            near = st.integers(max(0, clocks[i] - 40), clocks[i] + 40)
            datagrams.append(draw(datagram(sysid, near)))
    return datagrams, senders


def assert_agree(
    tmp_path: Path,
    steps: list[tuple[list[bytes], list[int]]],
    bound: bool = True,
    lose: tuple[int, int] | None = None,
) -> None:
    """A batch fleet and a general one, given the same `steps` (datagrams, senders: one feed each), end
    alike; `lose` (vehicle, step): that vehicle marked lost before that step (its loss check run past the
    wall timeout)."""
    fleets = {mode: FleetUnderTest(tmp_path, mode, VEHICLES) for mode in ("batch", "general")}
    try:
        for fleet in fleets.values():
            if bound:
                bind(fleet)
            for k, (datagrams, senders) in enumerate(steps):
                if lose is not None and lose[1] == k:
                    fleet.fleet.links[lose[0]].telemetry.check_loss(time.monotonic() + 100.0, 3.0, 3.0)
                    assert not fleet.fleet.state.alive[lose[0]]
                fleet.feed(datagrams, senders)
        batch_seen, general_seen = fleets["batch"].observed(), fleets["general"].observed()
        different = [k for k in general_seen if not same(batch_seen[k], general_seen[k])]
        assert not different, {k: (batch_seen[k], general_seen[k]) for k in different}
        assert fleets["general"].batch is None
    finally:
        for fleet in fleets.values():
            fleet.close()


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(stream=streams(), bound=st.booleans())
def test_batch_and_per_packet_intake_agree(
    tmp_path: Path, stream: tuple[list[bytes], list[int]], bound: bool
) -> None:
    assert_agree(tmp_path, [stream], bound)


def test_a_reboot_seen_in_another_kind_of_packet(tmp_path: Path) -> None:
    """A vehicle whose attitude ran on for 6 s after its last position: a position stamped 5.001 s before its
    time is not late for its kind, it is a reboot (and 5 s before, exactly, is not)."""
    for back in (5001, 5000):
        attitude_only = [frame(SYSID, 1000 + 20 * k, parts="a") for k in range(10)]
        attitude_only.append(frame(SYSID, 7000, parts="a"))
        steps = [([frame(SYSID, 1000, parts="p")], [0]), (attitude_only, [0] * 11)]
        steps.append(([frame(SYSID, 7000 - back, parts="p"), frame(SYSID, 7000 - back + 20)], [0, 0]))
        assert_agree(tmp_path, steps)


def test_a_lost_vehicle_heard_again(tmp_path: Path) -> None:
    """A vehicle marked lost is regained by its next frame, with the event the per-packet path adds."""
    steps = [([frame(SYSID + 1, 1000 + 20 * k)], [1]) for k in range(4)]
    assert_agree(tmp_path, steps, lose=(1, 2))


def test_the_kernel_takes_a_plain_stream(tmp_path: Path) -> None:
    """Without this, the comparison above could hold because the kernel hands everything back: of a steady
    stream of frames from three bound vehicles, it takes all but those on which a GCS HEARTBEAT falls due
    (one per vehicle per 500 ms of its time: 25 frames), and the state is the frames' (values by hand)."""
    fleet = FleetUnderTest(tmp_path, "batch", VEHICLES)
    try:
        bind(fleet)
        frames = 50  # 1 s of each vehicle's time, from t = 1000 ms
        datagrams = [frame(SYSID + i, 1000 + 20 * k) for k in range(frames) for i in range(VEHICLES)]
        fleet.feed(datagrams, [i for _ in range(frames) for i in range(VEHICLES)])
        batch = fleet.batch
        heartbeats_due = [len(sent) for sent in fleet.from_gcs]
        assert all(n in (2, 3) for n in heartbeats_due), heartbeats_due  # the first, then 500 ms periods
        assert batch.datagrams_passed == sum(heartbeats_due) + VEHICLES  # + the binding HEARTBEATs
        assert batch.datagrams_taken + batch.datagrams_passed == frames * VEHICLES + VEHICLES
        state = fleet.fleet.state
        last = 1000 + 20 * (frames - 1)
        assert list(state.time_ms) == [last] * VEHICLES and list(state.position_ms) == [last] * VEHICLES
        assert list(state.position_count) == [frames] * VEHICLES
        assert state.geodetic[:, 0] == pytest.approx([(473977420 + last) * 1e-7] * VEHICLES)
        assert state.vel[0] == pytest.approx([-0.40, 1.20, 0.03])  # ENU from NED cm/s (vz -3: up)
        assert state.att[0] == pytest.approx([0.1, 0.2, math.pi / 2 - 3.0], abs=1e-6)  # FLU/ENU
        assert list(state.progress_ms) == [last - 1000] * VEHICLES
        assert state.clock_ms == last - 1000 and list(state.heard_clock_ms) == [last - 1000] * VEHICLES
        assert [link.channel.stats.received for link in fleet.fleet.links] == [2 * frames + 1] * VEHICLES
        assert len(fleet.vehicle_packets()) == (2 * frames + 1) * VEHICLES
        assert state.frames_missed.tolist() == [frames - 1] * VEHICLES  # no tick consumed any of them
    finally:
        fleet.close()


def test_a_full_buffer_is_flushed_before_the_next_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With room for only a few datagrams, the intake takes what it holds before reading on: every frame
    still lands, in order."""
    monkeypatch.setattr(batch_intake, "MAX_DATAGRAMS", 4)
    fleet = FleetUnderTest(tmp_path, "batch", 1)
    try:
        bind(fleet)
        fleet.feed([frame(SYSID, 1000 + 20 * k) for k in range(30)])
        assert fleet.fleet.state.position_count[0] == 30 and fleet.fleet.state.time_ms[0] == 1000 + 20 * 29
        assert fleet.batch.datagrams_taken >= 25
        times = [int.from_bytes(p[10:14], "little") for p in fleet.vehicle_packets()[1::2]]
        assert times == sorted(times) and len(times) == 30
    finally:
        fleet.close()


def test_no_batch_without_numba(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """The fleet falls back to the per-packet path when the kernel cannot run here."""
    monkeypatch.setattr(batch_intake, "intake_kernel", None)
    fleet = FleetUnderTest(tmp_path, "batch", 1)
    try:
        assert fleet.batch is None
        bind(fleet)
        fleet.feed([frame(SYSID, 1000)])
        assert fleet.fleet.state.position_count[0] == 1 and fleet.taken == 2  # the hot path took them
    finally:
        fleet.close()


def test_the_kernel_decodes_as_pymavlink() -> None:
    """The kernel's field offsets and conversions, on one datagram, against the values pymavlink decodes."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    data = frame(SYSID, 1234, roll=-0.75, vz=-32768)
    parser = mavlink2.MAVLink(None)
    position, attitude = parser.parse_buffer(data)
    buf = np.frombuffer(data, dtype=np.uint8).copy()
    n = 1
    times = np.zeros((8, n), dtype=np.int64)
    times[[0, 1, 2, 7]] = -1
    times[7] = 1234  # a GCS HEARTBEAT went at this time: none due
    times[0] = 1200
    geodetic, vel, att = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    received = np.zeros(n, dtype=np.int64)
    out = batch_intake.intake_kernel.take_datagrams(
        buf,
        np.array([0]),
        np.array([len(data)]),
        np.array([0]),
        0,
        1,
        np.array([[SYSID], [1]]),
        np.ones(n, dtype=np.bool_),
        times,
        np.full((n, 3), -1, dtype=np.int64),
        geodetic,
        vel,
        att,
        np.zeros((2, n)),
        np.zeros(2),
        received,
        np.zeros(len(data) * 2, dtype=np.uint8),
        np.arange(8, dtype=np.uint8),
        5.0,
        6.0,
    )
    assert out[:3] == (1, len(data) + 16, 2) and out[3]
    assert geodetic[0].tolist() == [position.lat * 1e-7, position.lon * 1e-7, position.alt * 1e-3]
    assert vel[0].tolist() == [position.vy * 0.01, position.vx * 0.01, -position.vz * 0.01]
    yaw = (0.5 * math.pi - attitude.yaw + math.pi) % (2.0 * math.pi) - math.pi
    assert att[0].tolist() == [attitude.roll, -attitude.pitch, yaw]
    assert times[0, 0] == 1234 and times[5, 0] == 34 and received[0] == 2
