"""The pump's housekeeping (link.housekeeping): skipping it while its bounds say nothing can act must send,
mark and ask exactly what calling every link's heartbeat, loss check and stream watchdog would have.

Two fleets get the same random history (packets heard, vehicle clocks running, reboots, silences, wall time
jumping by exactly the timeouts); after each pump one through `Housekeeping.run`, the other through the
plain loop it replaces, everything they sent, marked and recorded must agree."""

from __future__ import annotations

import types

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

import gcs_swarm.link.heartbeat as heartbeat_module
from gcs_swarm.link.connection import new_parser
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig

N = 4
LOSS_TIMEOUT_S = 3.0
LOSS_WALL_TIMEOUT_S = 2.0
START_WALL_S = 100.0  # the test's time.monotonic() when the vehicles are first heard


class Recorder:
    """Stands in for a vehicle's endpoint: keeps the type of every message sent, in order."""

    def __init__(self) -> None:
        self.sent: list[str] = []

    def send(self, packet: bytes, sysid: int | None) -> bool:
        self.sent.append(new_parser().parse_buffer(bytes(packet))[0].get_type())
        return True


def _fleet(loss_timeout_s: float = LOSS_TIMEOUT_S, loss_wall_timeout_s: float = LOSS_WALL_TIMEOUT_S) -> Fleet:
    fleet = Fleet(
        [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{9000 + i}", sysid=i + 1) for i in range(N)],
        (0, 0, 0),
        loss_timeout_s=loss_timeout_s,
        loss_wall_timeout_s=loss_wall_timeout_s,
    )
    for i, link in enumerate(fleet.links):
        link.channel.endpoint = Recorder()  # type: ignore[assignment]
        link.streams.rates = {"GLOBAL_POSITION_INT": 50.0}  # the watchdog may re-ask
        heard = new_parser().parse_buffer(_packet(i + 1, "heartbeat", 0))[0]
        fleet.network.accept(link, heard, START_WALL_S)  # bound to its sysid
    return fleet


def _plain_housekeeping(fleet: Fleet, now: float) -> None:
    """What every pump did before link.housekeeping: each link's three checks."""
    for link in fleet.links:
        if link.channel.endpoint is not None:
            link.heartbeat.send_if_due(now)
            link.telemetry.check_loss(now, fleet.loss_timeout_s, fleet.loss_wall_timeout_s)
            link.streams.check()


def _packet(sysid: int, kind: str, t_ms: int) -> bytes:
    mav = mavlink2.MAVLink(None, sysid, 1)
    if kind == "heartbeat":
        msg = mav.heartbeat_encode(
            mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3, 3
        )
    elif kind == "position":
        msg = mav.global_position_int_encode(t_ms, 0, 0, 10_000, 10_000, 0, 0, 0, 0)
    else:
        msg = mav.system_time_encode(1, t_ms)
    return bytes(msg.pack(mav))


def _outcome(fleet: Fleet) -> object:
    return (
        [link.channel.endpoint.sent for link in fleet.links],  # type: ignore[union-attr]
        fleet.state.alive.tolist(),
        [(link.channel.stats.lost, link.channel.stats.stream_requests) for link in fleet.links],
        [(e.vehicle, e.text) for e in fleet.events],
    )


STEP = st.tuples(
    st.sampled_from([0.0, 0.02, 0.3, 0.5, 0.6, 1.0, 1.5, 2.0, 2.5]),  # wall s before the pump
    st.lists(  # packets before the pump: (vehicle, kind, vehicle ms advanced before it; negative: reboot)
        st.tuples(
            st.integers(0, N - 1),
            st.sampled_from(["heartbeat", "position", "time"]),
            st.sampled_from([0, 20, 500, 1000, 2000, 2001, 3000, 3001, -100_000]),
        ),
        max_size=6,
    ),
)
TIMEOUTS = st.sampled_from(  # (loss_timeout_s, loss_wall_timeout_s): each bound the first to trip in some
    [(LOSS_TIMEOUT_S, LOSS_WALL_TIMEOUT_S), (0.5, LOSS_WALL_TIMEOUT_S), (LOSS_TIMEOUT_S, 0.6), (0.5, 0.6)]
)


EVERYONE_REPORTS = [(i, "position", 20) for i in range(N)]
EXACT_S = 1 / 64  # a wall step that keeps the test's wall times exact in binary


@settings(max_examples=400, deadline=None)
@given(timeouts=TIMEOUTS, steps=st.lists(STEP, min_size=1, max_size=40))
@example(  # the wall heartbeat due at exactly WALL_HEARTBEAT_S after the oldest one (>=, not >)
    timeouts=(LOSS_TIMEOUT_S, LOSS_WALL_TIMEOUT_S), steps=[(0.25, EVERYONE_REPORTS), (1.0, EVERYONE_REPORTS)]
)
@example(  # everyone lost at a pass; then one back and lost again by the fleet clock, another's running on
    timeouts=(0.5, 0.625),
    steps=[
        (0.25, EVERYONE_REPORTS),
        (1.0, []),
        (EXACT_S, [(0, "position", 20), (1, "position", 20)]),
        (EXACT_S, [(1, "position", 2000)]),
    ],
)
@example(  # everyone lost at a pass; then one back and lost again by the wall clock before a heartbeat is due
    timeouts=(0.5, 0.625),
    steps=[(0.25, EVERYONE_REPORTS), (1.0, []), (EXACT_S, [(0, "position", 20)]), (0.75, [])],
)
def test_skipped_pumps_act_as_the_full_pass(
    timeouts: tuple[float, float], steps: list[tuple[float, list[tuple[int, str, int]]]]
) -> None:
    wall = [START_WALL_S]
    clock = types.SimpleNamespace(monotonic=lambda: wall[0], monotonic_ns=lambda: 0)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(heartbeat_module, "time", clock)  # heartbeats stamped with the test's wall clock
        skipping, plain = _fleet(*timeouts), _fleet(*timeouts)
        vehicle_ms = [200_000] * N
        for dt, packets in steps:
            wall[0] += dt
            for i, kind, advance in packets:
                vehicle_ms[i] = max(vehicle_ms[i] + advance, 0)
                for fleet in (skipping, plain):
                    msg = new_parser().parse_buffer(_packet(i + 1, kind, vehicle_ms[i]))[0]
                    fleet.network.accept(fleet.links[i], msg, wall[0])
            skipping.housekeeping.run(wall[0], *timeouts)
            _plain_housekeeping(plain, wall[0])
            assert _outcome(skipping) == _outcome(plain)


def test_a_steady_fleet_skips_most_pumps() -> None:
    """Every vehicle reporting its position each 20 ms frame, three pumps per frame: nobody goes silent and
    the vehicle-time heartbeats (one per 500 ms) keep the wall-clock one from ever being due. Only the first
    pump and those where the heartbeat bound (the oldest heartbeat at the last full pass, at most 0.5 s old
    then) ages past WALL_HEARTBEAT_S make the full pass: one per 0.5 to 1 s."""
    wall = [START_WALL_S]
    clock = types.SimpleNamespace(monotonic=lambda: wall[0], monotonic_ns=lambda: 0)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(heartbeat_module, "time", clock)
        fleet = _fleet()
        for frame in range(500):  # 10 s
            wall[0] += 0.02
            for i, link in enumerate(fleet.links):
                msg = new_parser().parse_buffer(_packet(i + 1, "position", 200_000 + 20 * frame))[0]
                fleet.network.accept(link, msg, wall[0])
            for _ in range(3):
                fleet.housekeeping.run(wall[0], LOSS_TIMEOUT_S, LOSS_WALL_TIMEOUT_S)
        sent = [link.channel.endpoint.sent for link in fleet.links]  # type: ignore[union-attr]
    assert 1 + 9 <= fleet.housekeeping.full_passes <= 1 + 20
    assert all(messages.count("TIMESYNC") == 0 for messages in sent)  # the vehicle-time ones were enough
    assert fleet.state.alive.all()


def test_a_lost_vehicle_does_not_keep_the_pumps_busy() -> None:
    """Vehicle 0 goes silent while the others report each frame: it is marked lost once its wall silence
    passes LOSS_WALL_TIMEOUT_S, after which the pumps skip again (its stale marks no longer count); when it
    speaks again it is alive at once and nothing else happens."""
    wall = [START_WALL_S]
    clock = types.SimpleNamespace(monotonic=lambda: wall[0], monotonic_ns=lambda: 0)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(heartbeat_module, "time", clock)
        fleet = _fleet()
        passes_at = []
        for frame in range(400):  # 8 s; vehicle 0 silent from 1 s to 5 s
            wall[0] += 0.02
            for i, link in enumerate(fleet.links):
                if i == 0 and 50 <= frame < 250:
                    continue
                msg = new_parser().parse_buffer(_packet(i + 1, "position", 200_000 + 20 * frame))[0]
                fleet.network.accept(link, msg, wall[0])
            before = fleet.housekeeping.full_passes
            fleet.housekeeping.run(wall[0], LOSS_TIMEOUT_S, LOSS_WALL_TIMEOUT_S)
            if fleet.housekeeping.full_passes > before:
                passes_at.append(frame)
            if frame == 200:
                assert not fleet.state.alive[0]
        assert fleet.state.alive.all()
        assert fleet.links[0].channel.stats.lost == 1
    lost_at = 50 + round(LOSS_WALL_TIMEOUT_S / 0.02)  # the first pump past the wall timeout
    assert lost_at in passes_at or lost_at + 1 in passes_at
    assert len(passes_at) <= 1 + 2 * 8 + 2  # the first, about two a second for the heartbeat bound, the loss
