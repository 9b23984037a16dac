"""Frames missed: a vehicle's GLOBAL_POSITION_INT replaced by a newer one before the ground station ticked on
it (or answered it in lockstep). Counted per vehicle against what arrived, never against an ideal 50 Hz
grid: a frame lost on the radio, a duplicate and a late packet are no frames missed. Hand-worked sequences
of frames arriving and ticks consuming them, fed straight into the intake of an unconnected fleet."""

from __future__ import annotations

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import _DatagramParser
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig
from tests.gcs_swarm.link.test_link_fuzz_intake import ORIGIN, Discard, heartbeat, position


class FedFleet:
    """An unconnected fleet of n vehicles (sysid k + 1), each heard (one HEARTBEAT), no position yet."""

    def __init__(self, n: int = 2) -> None:
        configs = [VehicleConfig(f"v{k}", "udpout:127.0.0.1:9", sysid=k + 1) for k in range(n)]
        self.fleet = Fleet(configs, ORIGIN)
        self.mavs = [mavlink2.MAVLink(None, k + 1, 1) for k in range(n)]
        self.parsers = [_DatagramParser() for _ in range(n)]
        for k, link in enumerate(self.fleet.links):
            link.channel.endpoint = Discard()  # type: ignore[assignment]
            self.feed(k, heartbeat(self.mavs[k]))

    def feed(self, k: int, data: bytes) -> None:
        for msg in self.parsers[k].parse(data):
            self.fleet.network.accept(self.fleet.links[k], msg, 0.0)

    def arrive(self, k: int, t_ms: int) -> None:
        """Vehicle k's GLOBAL_POSITION_INT stamped t_ms reaches the ground station."""
        self.feed(k, position(self.mavs[k], t_ms))

    def tick(self) -> None:
        """The ground station ticks on the frame in hand (it is complete: no waiting)."""
        assert self.fleet.wait_tick(timeout_s=0.0)

    @property
    def missed(self) -> list[int]:
        return self.fleet.state.frames_missed.tolist()


def test_a_frame_replaced_before_the_tick_is_missed() -> None:
    f = FedFleet(1)
    f.arrive(0, 1020)
    f.tick()  # on 1020
    f.arrive(0, 1040)
    f.arrive(0, 1060)  # 1040 is replaced before any tick used it
    f.tick()  # on 1060
    assert f.fleet.state.tick_ms[0] == 1060
    assert f.missed == [1]


def test_every_frame_but_the_newest_of_a_backlog_is_missed() -> None:
    f = FedFleet(1)
    for t in (1020, 1040, 1060, 1080):
        f.arrive(0, t)
    f.tick()  # on 1080: 1020, 1040 and 1060 were never used
    f.arrive(0, 1100)
    f.tick()
    assert f.missed == [3]


def test_a_frame_lost_on_the_radio_is_no_frame_missed() -> None:
    f = FedFleet(2)
    f.arrive(0, 1020)
    f.arrive(1, 1020)
    f.tick()
    f.arrive(0, 1040)
    f.arrive(0, 1060)  # v0: 1040 replaced
    f.arrive(1, 1060)  # v1: 1040 never arrived (lost on the way): nothing the ground station could answer
    f.tick()
    assert f.missed == [1, 0]


def test_duplicates_and_late_packets_are_no_frames_missed() -> None:
    f = FedFleet(1)
    f.arrive(0, 1020)
    f.arrive(0, 1020)  # the radio duplicated it: the same frame
    f.tick()
    f.arrive(0, 1060)
    f.arrive(0, 1040)  # late, behind 1060: dropped as late (channel stats), never the frame in hand
    f.tick()  # on 1060
    assert f.missed == [0]
    assert f.fleet.links[0].channel.stats.late == 1


def test_a_frame_answered_in_lockstep_is_not_missed() -> None:
    f = FedFleet(1)
    f.arrive(0, 1020)
    f.fleet.answer_frame()  # a blocking wait answered 1020 (SYSTEM_TIME) without a tick
    f.arrive(0, 1040)
    f.tick()
    assert f.missed == [0]


def test_after_a_reboot_the_count_starts_from_the_new_frames() -> None:
    f = FedFleet(1)
    f.arrive(0, 20_000)
    f.tick()
    f.arrive(0, 100)  # rebooted (more than 5 s back): frames start again, nothing of before is pending
    f.arrive(0, 120)  # 100 replaced before a tick
    f.tick()
    assert f.missed == [1]


def test_pump_splits_its_time_into_waiting_and_work(monkeypatch) -> None:
    """select returns at 10.30 s after the pump started at 10.00 s; the pump ends at 10.35 s: 0.30 s waited,
    0.05 s worked (decoding and housekeeping), added to what the pump counted before."""
    fleet = Fleet([VehicleConfig("v0", "udpout:127.0.0.1:9", sysid=1)], ORIGIN)

    class Network:
        connected = True

        def receive(self, timeout_s: float) -> float:
            return 10.30  # time.monotonic() when select returned

    fleet.network = Network()  # type: ignore[assignment]
    fleet.pump_wait_s, fleet.pump_work_s = 1.0, 2.0
    clock = iter([10.00, 10.35])
    monkeypatch.setattr("gcs_swarm.link.fleet.time.monotonic", lambda: next(clock))
    fleet.pump(0.5)
    assert np.isclose(fleet.pump_wait_s, 1.30) and np.isclose(fleet.pump_work_s, 2.05)
