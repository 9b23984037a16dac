"""GCS HEARTBEATs in vehicle time: one per GCS_HEARTBEAT_MS period per vehicle, and a fleet whose clocks run
in step (a lockstep or real-time simulator) spreads them over the frames instead of sending all in one."""

from __future__ import annotations

from collections import Counter

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import new_parser
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.intake_kernel import GCS_HEARTBEAT_MS
from gcs_swarm.link.vehicle import VehicleConfig

N = 100
FRAME_MS = 20


class Recorder:
    """Stands in for a vehicle's endpoint: keeps the time_boot_ms of each GCS HEARTBEAT sent."""

    def __init__(self, clock: list[int]) -> None:
        self.clock = clock
        self.heartbeats_ms: list[int] = []

    def send(self, packet: bytes, sysid: int | None) -> bool:
        if new_parser().parse_buffer(bytes(packet))[0].get_type() == "HEARTBEAT":
            self.heartbeats_ms.append(self.clock[0])
        return True


def test_heartbeats_of_a_fleet_in_step_are_spread_over_frames() -> None:
    fleet = Fleet(
        [VehicleConfig(f"v{i}", f"udpout:127.0.0.1:{9000 + i}", sysid=i + 1) for i in range(N)], (0, 0, 0)
    )
    clock = [0]
    senders = [mavlink2.MAVLink(None, i + 1, 1) for i in range(N)]
    for link, mav in zip(fleet.links, senders, strict=True):
        link.channel.endpoint = Recorder(clock)  # type: ignore[assignment]
        hb = mav.heartbeat_encode(
            mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3, 3
        )
        fleet.network.accept(link, new_parser().parse_buffer(bytes(hb.pack(mav)))[0], 0.0)
    for t_ms in range(1000, 4000, FRAME_MS):
        clock[0] = t_ms
        for link, mav in zip(fleet.links, senders, strict=True):
            packet = mav.system_time_encode(1, t_ms).pack(mav)  # stamped telemetry of this frame
            fleet.network.accept(link, new_parser().parse_buffer(bytes(packet))[0], 0.0)
    sent = [link.channel.endpoint.heartbeats_ms for link in fleet.links]  # type: ignore[union-attr]
    for times in sent:
        gaps = np.diff(times[1:])  # after the first (at the first stamped packet), one per period
        assert gaps.min() >= GCS_HEARTBEAT_MS - FRAME_MS and gaps.max() <= GCS_HEARTBEAT_MS + FRAME_MS
    per_frame = Counter(t for times in sent for t in times[1:])
    assert max(per_frame.values()) <= 8  # 100 vehicles spread over the 25 frames of a period, not 100 at once
