"""The fence side of the mission protocol (sitl_sim.network.mission_protocol) as ArduPilot answers it
(MissionItemProtocol.cpp, MissionItemProtocol_Fence.cpp): upload, download, clear, partial write;
out-of-order, duplicate, foreign and broken items; the timeouts; other mission types. An in-process
simulator is driven message by message (fast and exact); garbage is fuzzed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sitl_sim.autopilot import fence as f
from sitl_sim.simulator import Simulator
from tests.sitl_sim.sim_process import GCS_COMPID, GCS_SYSID, M, in_process_config

FENCE = M.MAV_MISSION_TYPE_FENCE
ADDR = ("127.0.0.1", 40000)
LAT, LON = -350_000_000, 1_490_000_000  # the in-process simulator's home, degE7


class Bench:
    """One in-process vehicle; `send` hands it a message from a ground station, `got` collects its answers."""

    def __init__(self, autopilots: tuple[str, ...] = ()) -> None:
        self.sim = Simulator(in_process_config([[0.0, 0.0, 0.0]], autopilots=autopilots))
        self.endpoint = self.sim.endpoints[0]
        self.gcs = M.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        self.other = M.MAVLink(None, srcSystem=254, srcComponent=GCS_COMPID)
        self.rx = M.MAVLink(None)
        self.got: list[M.MAVLink_message] = []
        self.texts: list[str] = []
        self.endpoint.flush = lambda wall_now, clock_ms=None: self._collect()  # type: ignore[method-assign]

    def _collect(self) -> None:
        for packet in self.endpoint.outbox.packets:
            self.got += self.rx.parse_buffer(packet) or []
        self.endpoint.outbox.packets.clear()
        self.texts += [text for _, text in self.sim.autopilot.texts[0]]
        self.sim.autopilot.texts[0].clear()

    def send(self, msg: M.MAVLink_message, sender: M.MAVLink | None = None) -> None:
        self.endpoint.handle_datagram(msg.pack(sender or self.gcs), ADDR, 0.0)
        self._collect()

    def tick(self, seconds: float) -> None:
        for _ in range(round(seconds / self.sim.timing.tick_s)):
            self.sim._tick()
        self._collect()

    def take(self, kind: str) -> list[M.MAVLink_message]:
        found = [m for m in self.got if m.get_type() == kind]
        self.got = [m for m in self.got if m.get_type() != kind]
        return found

    def acks(self) -> list[int]:
        return [m.type for m in self.take("MISSION_ACK")]

    def item(self, seq: int, command: int, param1: float, lat: int = LAT, lon: int = LON, frame: int = 0):
        return self.gcs.mission_item_int_encode(
            1, 1, seq, frame, command, 0, 0, param1, 0, 0, 0, lat, lon, 0, FENCE
        )

    def upload(self, items: list[tuple[int, float, int, int]]) -> list[int]:
        """A well-behaved upload of (command, param1, lat, lon) items; returns the MISSION_ACK results."""
        self.send(self.gcs.mission_count_encode(1, 1, len(items), FENCE))
        for _ in range(len(items)):
            (request,) = self.take("MISSION_REQUEST")
            command, param1, lat, lon = items[request.seq]
            self.send(self.item(request.seq, command, param1, lat, lon))
        return self.acks()

    def download(self) -> list[tuple[int, float, int, int]]:
        self.send(self.gcs.mission_request_list_encode(1, 1, FENCE))
        (count,) = self.take("MISSION_COUNT")
        items = []
        for seq in range(count.count):
            self.send(self.gcs.mission_request_int_encode(1, 1, seq, FENCE))
            (item,) = self.take("MISSION_ITEM_INT")
            assert item.seq == seq and item.mission_type == FENCE and item.frame == M.MAV_FRAME_GLOBAL
            items.append((item.command, item.param1, item.x, item.y))
        return items

    def close(self) -> None:
        self.sim.close()


def _bench() -> Bench:
    return Bench()


CIRCLE = (f.CIRCLE_EXCLUSION, 12.5, LAT + 3000, LON + 4000)
SQUARE = [
    (f.POLYGON_EXCLUSION, 4.0, LAT + dy, LON + dx) for dx, dy in ((0, 0), (500, 0), (500, 500), (0, 500))
]


def test_upload_download_round_trip_as_arducopter():
    bench = _bench()
    try:
        items = [CIRCLE, *SQUARE, (f.CIRCLE_INCLUSION, 300.0, LAT, LON), (f.RETURN_POINT, 0.0, LAT, LON)]
        bench.send(bench.gcs.mission_count_encode(1, 1, len(items), FENCE))
        asked = []
        while not bench.got or bench.got[-1].get_type() != "MISSION_ACK":
            (request,) = bench.take("MISSION_REQUEST")  # ArduPilot asks with MISSION_REQUEST, not _INT
            assert request.mission_type == FENCE and request.target_system == GCS_SYSID
            asked.append(request.seq)
            command, param1, lat, lon = items[request.seq]
            bench.send(bench.item(request.seq, command, param1, lat, lon))
        assert asked == list(range(len(items)))
        (ack,) = bench.take("MISSION_ACK")
        assert (ack.type, ack.mission_type, ack.target_system) == (M.MAV_MISSION_ACCEPTED, FENCE, GCS_SYSID)
        assert bench.download() == items
        assert len(bench.sim.autopilot.fence.items[0]) == 7
        # the deprecated MISSION_REQUEST is answered with MISSION_ITEM (degrees) and a warning, once
        bench.send(bench.gcs.mission_request_encode(1, 1, 0, FENCE))
        (item,) = bench.take("MISSION_ITEM")
        assert abs(item.x - (LAT + 3000) * 1e-7) < 5e-6 and item.param1 == 12.5
        assert "got MISSION_REQUEST; use MISSION_REQUEST_INT!" in bench.texts
    finally:
        bench.close()


def test_out_of_order_and_duplicate_items_are_refused_and_the_upload_goes_on():
    bench = _bench()
    try:
        bench.send(bench.gcs.mission_count_encode(1, 1, 2, FENCE))
        assert [r.seq for r in bench.take("MISSION_REQUEST")] == [0]
        bench.send(bench.item(1, *CIRCLE))  # too early
        assert bench.acks() == [M.MAV_MISSION_INVALID_SEQUENCE]
        bench.send(bench.item(0, *CIRCLE))
        assert [r.seq for r in bench.take("MISSION_REQUEST")] == [1]
        bench.send(bench.item(0, *CIRCLE))  # a duplicate of the previous one
        assert bench.acks() == [M.MAV_MISSION_INVALID_SEQUENCE]
        bench.send(bench.item(1, *CIRCLE))
        assert bench.acks() == [M.MAV_MISSION_ACCEPTED]
        bench.send(bench.item(1, *CIRCLE))  # the last one again, after the transfer: nothing to receive
        assert bench.acks() == [M.MAV_MISSION_ERROR]
        assert bench.endpoint.counters.refused == 3
        assert len(bench.sim.autopilot.fence.items[0]) == 2
    finally:
        bench.close()


def test_refused_items_end_the_upload_with_arducopters_codes():
    bench = _bench()
    try:
        for bad, code in (
            (bench.item(0, M.MAV_CMD_NAV_WAYPOINT, 0.0), M.MAV_MISSION_UNSUPPORTED),
            (
                bench.item(0, f.CIRCLE_EXCLUSION, 5.0, frame=M.MAV_FRAME_LOCAL_NED),
                M.MAV_MISSION_UNSUPPORTED_FRAME,
            ),
            (bench.item(0, f.POLYGON_EXCLUSION, 300.0), M.MAV_MISSION_INVALID_PARAM1),
        ):
            bench.send(bench.gcs.mission_count_encode(1, 1, 3, FENCE))
            bench.take("MISSION_REQUEST")
            bench.send(bad)
            assert bench.acks() == [code]
            bench.send(bench.item(1, *CIRCLE))
            assert bench.acks() == [M.MAV_MISSION_ERROR]  # the upload is over
        bench.send(bench.gcs.mission_count_encode(1, 1, 71, FENCE))
        assert bench.acks() == [M.MAV_MISSION_NO_SPACE] and "Only 70 items are supported" in bench.texts
        assert len(bench.sim.autopilot.fence.items[0]) == 0
    finally:
        bench.close()


def test_an_invalid_fence_is_refused_whole_with_the_reason():
    bench = _bench()
    try:
        assert bench.upload([(f.POLYGON_EXCLUSION, 2.0, LAT, LON)] * 2) == [M.MAV_MISSION_ERROR]
        assert bench.texts[-2:] == ["Invalid vertex count (2)", "Fence validation failed"]
        assert bench.upload([(f.CIRCLE_EXCLUSION, float("nan"), LAT, LON)]) == [M.MAV_MISSION_ERROR]
        assert bench.texts[-2] == "Non-positive circle radius" and bench.endpoint.counters.invalid == 1
        assert len(bench.sim.autopilot.fence.items[0]) == 0
    finally:
        bench.close()


def test_a_stalled_upload_is_asked_again_then_cancelled_after_8_s():
    bench = _bench()
    try:
        assert bench.upload([CIRCLE]) == [M.MAV_MISSION_ACCEPTED]
        bench.send(bench.gcs.mission_count_encode(1, 1, 3, FENCE))
        bench.tick(2.55)
        assert [r.seq for r in bench.take("MISSION_REQUEST")] == [0, 0, 0]  # at once, then every second
        bench.send(bench.item(0, *CIRCLE))  # an item restarts the 8 s
        bench.tick(7.9)
        assert bench.acks() == []
        bench.tick(0.2)
        assert bench.acks() == [M.MAV_MISSION_OPERATION_CANCELLED] and "Fence upload timeout" in bench.texts
        assert bench.download() == [CIRCLE]  # the stored fence is untouched
    finally:
        bench.close()


def test_others_are_denied_while_an_upload_runs():
    bench = _bench()
    try:
        bench.send(bench.gcs.mission_count_encode(1, 1, 2, FENCE))
        bench.take("MISSION_REQUEST")
        for msg in (
            bench.other.mission_count_encode(1, 1, 1, FENCE),
            bench.other.mission_clear_all_encode(1, 1, FENCE),
        ):
            bench.send(msg, bench.other)
        bench.send(bench.item(0, *CIRCLE), bench.other)  # the awaited seq, from someone else
        bench.send(bench.gcs.mission_request_list_encode(1, 1, FENCE))
        bench.send(bench.gcs.mission_request_int_encode(1, 1, 0, FENCE))
        assert bench.acks() == [M.MAV_MISSION_DENIED] * 5
        # the uploader itself may start over: a new MISSION_COUNT restarts at seq 0
        bench.send(bench.gcs.mission_count_encode(1, 1, 1, FENCE))
        assert [r.seq for r in bench.take("MISSION_REQUEST")] == [0]
        bench.send(bench.item(0, *CIRCLE))
        assert bench.acks() == [M.MAV_MISSION_ACCEPTED]
    finally:
        bench.close()


def test_clear_partial_write_and_requests_out_of_range():
    bench = _bench()
    try:
        second = (f.CIRCLE_EXCLUSION, 7.0, LAT - 3000, LON)
        assert bench.upload([CIRCLE, second]) == [M.MAV_MISSION_ACCEPTED]
        bench.send(bench.gcs.mission_request_int_encode(1, 1, 5, FENCE))
        assert [m.count for m in bench.take("MISSION_COUNT")] == [2]  # "educates" the ground station
        assert bench.acks() == [M.MAV_MISSION_INVALID_SEQUENCE]
        bench.send(bench.gcs.mission_write_partial_list_encode(1, 1, 1, 1, FENCE))
        assert [r.seq for r in bench.take("MISSION_REQUEST")] == [1]
        bench.send(bench.item(1, f.CIRCLE_EXCLUSION, 9.0, LAT - 3000, LON))
        assert bench.acks() == [M.MAV_MISSION_ACCEPTED]
        assert bench.download() == [CIRCLE, (f.CIRCLE_EXCLUSION, 9.0, LAT - 3000, LON)]
        bench.send(bench.gcs.mission_clear_all_encode(1, 1, FENCE))
        assert bench.acks() == [M.MAV_MISSION_ACCEPTED] and bench.download() == []
        assert bench.upload([]) == [M.MAV_MISSION_ACCEPTED]  # an empty upload also clears
    finally:
        bench.close()


def test_other_mission_types_are_unsupported():
    bench = _bench()
    try:
        for mission_type in (M.MAV_MISSION_TYPE_MISSION, M.MAV_MISSION_TYPE_ALL):
            bench.send(bench.gcs.mission_count_encode(1, 1, 1, mission_type))
            bench.send(bench.gcs.mission_request_list_encode(1, 1, mission_type))
            bench.send(bench.gcs.mission_clear_all_encode(1, 1, mission_type))
            bench.send(bench.gcs.mission_request_int_encode(1, 1, 0, mission_type))  # no answer
            acks = bench.take("MISSION_ACK")
            assert [(a.type, a.mission_type) for a in acks] == [(M.MAV_MISSION_UNSUPPORTED, mission_type)] * 3
        assert not bench.got
    finally:
        bench.close()


RALLY = M.MAV_MISSION_TYPE_RALLY


def _rally(
    bench: Bench, seq: int, lat: int, lon: int, z: float, frame: int = M.MAV_FRAME_GLOBAL_RELATIVE_ALT
):
    return bench.gcs.mission_item_int_encode(
        1, 1, seq, frame, M.MAV_CMD_NAV_RALLY_POINT, 0, 0, 0, 0, 0, 0, lat, lon, z, RALLY
    )


def test_rally_points_upload_download_and_clear_as_arducopter():
    # MissionItemProtocol_Rally: NAV_RALLY_POINT items above home, z kept as an int16 of metres (C truncation:
    # 12.7 -> 12), read back in frame GLOBAL_RELATIVE_ALT; RALLY_TOTAL follows the count (AP_Rally::append)
    bench = _bench()
    try:
        points = [(LAT + 3000, LON + 4000, 12.7), (LAT - 900, LON, 30.0)]
        bench.send(bench.gcs.mission_count_encode(1, 1, len(points), RALLY))
        for _ in points:
            (request,) = bench.take("MISSION_REQUEST")
            assert request.mission_type == RALLY
            bench.send(_rally(bench, request.seq, *points[request.seq]))
        assert bench.acks() == [M.MAV_MISSION_ACCEPTED]
        assert bench.sim.params.value(0, "RALLY_TOTAL") == 2
        bench.send(bench.gcs.mission_request_list_encode(1, 1, RALLY))
        (count,) = bench.take("MISSION_COUNT")
        assert (count.count, count.mission_type) == (2, RALLY)
        for seq, (lat, lon, _) in enumerate(points):
            bench.send(bench.gcs.mission_request_int_encode(1, 1, seq, RALLY))
            (item,) = bench.take("MISSION_ITEM_INT")
            assert (item.command, item.frame, item.x, item.y, item.mission_type) == (
                M.MAV_CMD_NAV_RALLY_POINT, M.MAV_FRAME_GLOBAL_RELATIVE_ALT, lat, lon, RALLY,
            )  # fmt: skip
            assert item.z == [12.0, 30.0][seq]
        assert bench.download() == []  # the fence is another list
        # (12.7 m above home; 4000e-7 deg east is ~36.4 m at 35 deg S, 3000e-7 deg north ~33.3 m)
        assert bench.sim.autopilot.rally.xyz[0][0] == pytest.approx([36.4, 33.3, 12.0], abs=0.2)
        bench.send(bench.gcs.mission_clear_all_encode(1, 1, RALLY))
        assert bench.acks() == [M.MAV_MISSION_ACCEPTED] and bench.sim.autopilot.rally.items[0] == ()
        assert bench.sim.params.value(0, "RALLY_TOTAL") == 0
    finally:
        bench.close()


def test_rally_items_refused_with_arducopters_codes():
    bench = _bench()
    try:
        wrong_frame = _rally(bench, 0, LAT, LON, 10.0, frame=M.MAV_FRAME_GLOBAL)
        not_rally = bench.item(0, f.CIRCLE_EXCLUSION, 5.0)
        not_rally.mission_type = RALLY
        too_high = _rally(bench, 0, LAT, LON, 40000.0)
        for item, result in (
            (wrong_frame, M.MAV_MISSION_UNSUPPORTED_FRAME),
            (not_rally, M.MAV_MISSION_UNSUPPORTED),
            (too_high, M.MAV_MISSION_INVALID_PARAM7),
        ):
            bench.send(bench.gcs.mission_count_encode(1, 1, 1, RALLY))
            bench.take("MISSION_REQUEST")
            bench.send(item)
            assert bench.acks() == [result]
        assert bench.sim.autopilot.rally.items[0] == ()
    finally:
        bench.close()


MISSION_IDS = sorted(
    {
        M.MAVLINK_MSG_ID_MISSION_COUNT,
        M.MAVLINK_MSG_ID_MISSION_ITEM_INT,
        M.MAVLINK_MSG_ID_MISSION_ITEM,
        M.MAVLINK_MSG_ID_MISSION_REQUEST_LIST,
        M.MAVLINK_MSG_ID_MISSION_REQUEST_INT,
        M.MAVLINK_MSG_ID_MISSION_REQUEST,
        M.MAVLINK_MSG_ID_MISSION_CLEAR_ALL,
        M.MAVLINK_MSG_ID_MISSION_WRITE_PARTIAL_LIST,
        M.MAVLINK_MSG_ID_MISSION_ACK,
    }
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    steps=st.lists(st.tuples(st.sampled_from(MISSION_IDS), st.binary(min_size=60, max_size=60)), max_size=8)
)
def test_fuzzed_mission_messages_never_crash(steps):
    bench = _bench()
    try:
        for msg_id, noise in steps:
            cls = M.mavlink_map[msg_id]
            payload = bytearray(noise[: cls.unpacker.size].ljust(cls.unpacker.size, b"\0"))
            msg = bench.rx.decode(bytearray(_frame(msg_id, bytes(payload))))
            for name in ("target_system", "target_component"):
                if hasattr(msg, name):
                    setattr(msg, name, 1)
            if hasattr(msg, "mission_type"):
                msg.mission_type = FENCE if noise[0] % 2 else msg.mission_type
            bench.send(msg)
            bench.tick(0.05)
        counters = bench.endpoint.counters
        assert counters.received == len(steps) and counters.bad_frames == 0
        assert np.isfinite(bench.sim.dyn.state.pos).all()
    finally:
        bench.close()


def _frame(msg_id: int, payload: bytes) -> bytes:
    """A MAVLink 2 frame from the ground station with a valid CRC around an arbitrary payload."""
    import struct

    header = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, 0, GCS_SYSID, GCS_COMPID, msg_id & 0xFFFF, 0)
    crc = M.x25crc(header[1:] + payload)
    crc.accumulate(bytes([M.mavlink_map[msg_id].crc_extra]))
    return header + payload + struct.pack("<H", crc.crc)


def test_a_small_fence_over_a_bigger_one_is_erased_as_by_arducopter_sitl():
    """FENCE_TOTAL (circles and vertices + 2, 0 below 3) going to 0 formats the fence storage in ArduPilot's
    SITL builds (AC_POLYFENCE_FENCE_POINT_PROTOCOL_SUPPORT): seen on a real V4.7.0-dev SITL too."""
    bench = _bench()
    try:
        three = [
            CIRCLE,
            (f.CIRCLE_EXCLUSION, 7.0, LAT - 3000, LON),
            (f.CIRCLE_EXCLUSION, 8.0, LAT, LON - 3000),
        ]
        assert bench.upload(three) == [M.MAV_MISSION_ACCEPTED]
        assert bench.sim.params.value(0, "FENCE_TOTAL") == 5
        bench.tick(0.1)  # the loader sees FENCE_TOTAL 5
        assert bench.upload([CIRCLE]) == [M.MAV_MISSION_ACCEPTED]
        assert bench.download() == [CIRCLE]  # at once it is there...
        bench.tick(0.1)
        assert bench.download() == []  # ...then the loader's update formats the storage
        assert bench.upload([CIRCLE]) == [
            M.MAV_MISSION_ACCEPTED
        ]  # over an empty fence (FENCE_TOTAL 0) it stays
        bench.tick(0.1)
        assert bench.download() == [CIRCLE]
    finally:
        bench.close()


def _requests_of_an_upload(bench: Bench, items: list[tuple[int, float, int, int]]) -> list[str]:
    """Upload `items` answering each request with MISSION_ITEM_INT; the request messages' types, in order."""
    bench.send(bench.gcs.mission_count_encode(1, 1, len(items), FENCE))
    kinds = []
    for _ in range(len(items)):
        (request,) = [m for m in bench.got if m.get_type().startswith("MISSION_REQUEST")]
        bench.got.remove(request)
        kinds.append(request.get_type())
        command, param1, lat, lon = items[request.seq]
        bench.send(bench.item(request.seq, command, param1, lat, lon))
    assert bench.acks() == [M.MAV_MISSION_ACCEPTED]
    return kinds


def test_px4_asks_with_mission_request_int_once_the_peer_spoke_int():
    # mavlink_mission.cpp: send_mission_request uses MISSION_REQUEST_INT when _int_mode, which
    # MISSION_REQUEST_INT and MISSION_ITEM_INT set; ArduPilot always asks with MISSION_REQUEST
    triangle = [
        (f.POLYGON_INCLUSION, 3.0, LAT + dlat, LON + dlon) for dlat, dlon in ((0, 0), (900, 0), (0, 900))
    ]
    px4, apm = Bench(("px4",)), Bench()
    try:
        # a fresh PX4 vehicle: float mode until an _INT message; the items of this upload are _INT
        assert _requests_of_an_upload(px4, triangle) == ["MISSION_REQUEST"] + ["MISSION_REQUEST_INT"] * 2
        assert px4.download() == triangle  # stored as sent, read back with MISSION_REQUEST_INT
        assert _requests_of_an_upload(px4, triangle) == ["MISSION_REQUEST_INT"] * 3
        apm.download()
        assert _requests_of_an_upload(apm, triangle) == ["MISSION_REQUEST"] * 3
        # an item of the wrong seq: ArduPilot answers INVALID_SEQUENCE, PX4 nothing (handle_mission_item_both)
        for bench in (px4, apm):
            bench.send(bench.gcs.mission_count_encode(1, 1, 3, FENCE))
            bench.send(bench.item(2, f.POLYGON_INCLUSION, 3.0))
        assert px4.acks() == [] and apm.acks() == [M.MAV_MISSION_INVALID_SEQUENCE]
    finally:
        px4.sim.close()
        apm.sim.close()
