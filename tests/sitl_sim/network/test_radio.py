"""The radio model (sitl_sim.network.radio) through the link's FaultChannel: air time, FIFO queueing, transmit
buffers that drop when full, half duplex, a shared medium timed independently of the order sockets are
read, RADIO_STATUS's txbuf as SiK computes it; the --link-* radio options. Expected times are worked by hand
in each test from eq. 1 of docs/radio.md:
    air time = (L + overhead_bytes) * bits_per_byte / capacity_bps + overhead_us.
"""

from __future__ import annotations

import itertools
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink import mavutil

from sitl_sim.cli import build_config, build_parser
from sitl_sim.network.link_faults import DOWN, UP, FaultChannel
from sitl_sim.network.radio import NS_PER_MS, CapacityChange, Medium, RadioLink, TxBuffer, fleet_radios
from swarm_common.radio_presets import RADIO_PRESETS, RadioSpec

CLEAN = (0.0,) * 6  # no loss, dup, corrupt, reorder, delay or jitter


def _channel(spec: RadioSpec, vehicle: int = 0, radio: RadioLink | None = None) -> FaultChannel:
    return FaultChannel(0, vehicle, (), radio or RadioLink(Medium(spec), TxBuffer(spec.buffer_limit)))


def _deliveries(channel: FaultChannel, direction: int, until_ms: int) -> list[tuple[int, bytes]]:
    """(ms, packet) of every delivery, asking the channel once per simulated ms as the simulator does."""
    out = []
    for t in range(until_ms + 1):
        if channel.radio is not None:
            channel.radio.medium.settle(t)
        out += [(t, packet) for packet, _ in channel.due(direction, t)]
    return out


def _packet(k: int, size: int) -> bytes:
    return bytes([k]) * size


def test_packets_through_an_empty_queue_leave_one_air_time_apart() -> None:
    """5 packets of 100 bytes at 80 kbit/s, 8 bits a byte: 800 bits = 10 ms each, back to back from t = 0:
    the k-th (k = 1..5) is off the air at 10 k ms."""
    channel = _channel(RadioSpec(80_000.0, buffer_bytes=10_000))
    for k in range(5):
        channel.push(DOWN, _packet(k, 100), None, 0, CLEAN)
    got = _deliveries(channel, DOWN, 60)
    assert [t for t, _ in got] == [10, 20, 30, 40, 50]
    assert [p[0] for _, p in got] == [0, 1, 2, 3, 4]  # FIFO
    counts = channel.radio.counts[DOWN]  # type: ignore[union-attr]
    # waits 0, 10, 20, 30, 40 ms: mean 20, max 40
    assert (counts.packets, counts.bytes, counts.dropped) == (5, 500, 0)
    assert counts.delay_ns_sum == 100 * NS_PER_MS and counts.delay_ns_max == 40 * NS_PER_MS


def test_radio_overheads_count_per_byte_and_per_packet() -> None:
    """96-byte packets, 4 bytes of radio header, 10 bit times a byte, 100 kbit/s, 0.5 ms per packet:
    (96 + 4) * 10 = 1000 bits = 10 ms + 0.5 ms = 10.5 ms each, so off the air at 10.5, 21, 31.5 ms,
    delivered at the first whole ms after: 11, 21, 32."""
    spec = RadioSpec(100_000.0, bits_per_byte=10.0, overhead_bytes=4, overhead_us=500.0, buffer_bytes=10_000)
    channel = _channel(spec)
    for k in range(3):
        channel.push(DOWN, _packet(k, 96), None, 0, CLEAN)
    assert [t for t, _ in _deliveries(channel, DOWN, 40)] == [11, 21, 32]


def test_a_full_buffer_drops_exactly_the_packets_that_do_not_fit() -> None:
    """100-byte packets at 8 kbit/s (100 ms each), a 250-byte buffer; a packet leaves the buffer when it
    starts on the air. At t = 0, five packets: #0 goes on the air at once (buffer 0), #1 and #2 wait (100, 200
    bytes), #3 and #4 would make 300 > 250: dropped. At t = 100 ms #1 is on the air (buffer 100), so #5 fits
    and goes after #2: off the air at 100, 200, 300, 400 ms."""
    channel = _channel(RadioSpec(8_000.0, buffer_bytes=250))
    for k in range(5):
        channel.push(DOWN, _packet(k, 100), None, 0, CLEAN)
    channel.push(DOWN, _packet(5, 100), None, 100, CLEAN)
    got = _deliveries(channel, DOWN, 500)
    assert [(t, p[0]) for t, p in got] == [(100, 0), (200, 1), (300, 2), (400, 5)]
    counts = channel.radio.counts[DOWN]  # type: ignore[union-attr]
    assert counts.dropped == 2 and counts.packets == 4
    # waits: 0, 100, 200 ms (t = 0) and 300 - 100 = 200 ms (#5): mean 125, max 200
    assert counts.delay_ns_sum / counts.packets == 125 * NS_PER_MS and counts.delay_ns_max == 200 * NS_PER_MS


@pytest.mark.parametrize(("half_duplex", "down_due_ms"), [(True, 200), (False, 110)])
def test_half_duplex_uplink_delays_the_downlink_by_its_air_time(half_duplex: bool, down_due_ms: int) -> None:
    """8 kbit/s, 100-byte packets (100 ms). An uplink packet arrives at 0 ms, a downlink one at 10 ms. Half
    duplex: the uplink holds the air 0..100 ms, the downlink waits 90 ms and is off at 200 ms. Full duplex:
    the downlink has its own time line, 10..110 ms. The uplink is off at 100 ms either way."""
    channel = _channel(RadioSpec(8_000.0, half_duplex=half_duplex, buffer_bytes=1000))
    channel.push(UP, _packet(1, 100), "gcs", 0, CLEAN)
    channel.push(DOWN, _packet(2, 100), None, 10, CLEAN)
    assert [t for t, _ in _deliveries(channel, DOWN, 300)] == [down_due_ms]
    assert [t for t, _ in _deliveries(channel, UP, 300)] == [100]


def test_a_shared_medium_times_same_ms_arrivals_by_vehicle_whatever_order_they_were_read() -> None:
    """Two vehicles on one 8 kbit/s medium; both uplink datagrams (100 bytes, 100 ms) reach their sockets in
    ms 0. Whichever socket is read first, vehicle 0's goes first: off the air at 100 ms, vehicle 1's at
    200."""
    spec = RadioSpec(8_000.0, shared=True, buffer_bytes=1000)
    for order in ((0, 1), (1, 0)):
        radios = fleet_radios(spec, 2)
        assert radios[0].medium is radios[1].medium and radios[0].buffers[UP] is radios[1].buffers[UP]  # type: ignore[union-attr]
        channels = [_channel(spec, i, radios[i]) for i in range(2)]
        for i in order:
            channels[i].push(UP, _packet(i, 100), "gcs", 0, CLEAN)
        firsts = []
        for t in range(301):
            radios[0].medium.settle(t)  # type: ignore[union-attr]
            firsts += [(t, i) for i in range(2) for _ in channels[i].due(UP, t)]
        assert firsts == [(100, 0), (200, 1)]


def test_a_lost_packet_still_took_the_air_and_an_outage_did_not() -> None:
    """Loss acts on what left the air: with loss 1, two 100-ms packets still take the air (the third, sent at
    0 ms too, waits 200 ms); an outage silences before the radio: nothing is timed."""
    channel = _channel(RadioSpec(8_000.0, buffer_bytes=1000))
    for k in range(3):
        channel.push(DOWN, _packet(k, 100), None, 0, (1.0, 0, 0, 0, 0, 0))
    assert channel.due(DOWN, 1000) == [] and channel.drops.lost == 3
    counts = channel.radio.counts[DOWN]  # type: ignore[union-attr]
    assert counts.packets == 3 and counts.delay_ns_max == 200 * NS_PER_MS


def test_txbuf_is_sik_serial_read_space() -> None:
    """SiK serial.c serial_read_space: (100 * (free / 8)) / (size / 8), integers. 1850-byte buffer: empty ->
    100; 925 bytes held -> (100 * 115) / 231 = 49.78 -> 49; 1850 held -> 0."""
    buffer = TxBuffer(1850)
    assert buffer.free_percent(0) == 100
    buffer.hold(10 * NS_PER_MS, 925)
    assert buffer.free_percent(0) == 49
    buffer.hold(20 * NS_PER_MS, 925)
    assert buffer.free_percent(0) == 0
    assert buffer.free_percent(10 * NS_PER_MS) == 49 and buffer.free_percent(20 * NS_PER_MS) == 100


def _radio_of(argv: list[str]) -> RadioSpec | None:
    parser = build_parser()
    return build_config(parser, parser.parse_args(argv)).link.radio


RADIO_MISSION = """
vehicles:
  - role: leader
    start: {position: [0, 0, 0]}
goal: [10, 0, 10]
world:
  link:
    radio: sik64
    buffer_bytes: 1024
"""


def test_radio_options_and_the_mission_radio(tmp_path) -> None:
    assert _radio_of(["--vehicles", "1"]) is None
    assert _radio_of(["--vehicles", "1", "--link-radio", "sik64"]) == RADIO_PRESETS["sik64"]
    wide = _radio_of(["--vehicles", "1", "--link-capacity-bps", "1e6", "--link-shared"])
    assert wide == RadioSpec(1e6, shared=True, source="given")
    mission = tmp_path / "radio.yaml"
    mission.write_text(RADIO_MISSION)
    sik = RADIO_PRESETS["sik64"]
    assert _radio_of(["--mission", str(mission)]) == RadioSpec(**{**vars(sik), "buffer_bytes": 1024})
    # one figure overridden on top of the mission's; --link-radio replaces the preset and its overrides
    faster = _radio_of(["--mission", str(mission), "--link-capacity-bps", "128000", "--no-link-half-duplex"])
    assert faster == RadioSpec(
        **{**vars(sik), "buffer_bytes": 1024, "capacity_bps": 128000.0, "half_duplex": False}
    )
    assert _radio_of(["--mission", str(mission), "--link-radio", "wifi"]) == RADIO_PRESETS["wifi"]
    assert _radio_of(["--mission", str(mission), "--link-radio", "none"]) is None


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--link-radio", "sik65"], "--link-radio: unknown radio 'sik65' (presets: sik64,"),
        (["--link-shared"], "--link-shared: shared without a radio preset needs capacity_bps"),
        (
            ["--link-radio", "wifi", "--link-capacity-bps", "0"],
            "--link-capacity-bps: capacity_bps must be in 1",
        ),
        (
            ["--link-radio", "wifi", "--link-buffer-bytes", "-1"],
            "--link-buffer-bytes: buffer_bytes must be in 0",
        ),
        (
            ["--link-radio", "wifi", "--link-bits-per-byte", "nan"],
            "--link-bits-per-byte: bits_per_byte must be",
        ),
    ],
)
def test_bad_radio_options_give_one_line_and_status_2(argv, fragment, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        _radio_of(["--vehicles", "1", *argv])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and fragment in err and err.count("\n") == 1


def test_the_ground_radio_reports_txbuf_and_a_full_buffer_drops(sitl) -> None:
    """Real time over sik64: the client hears the ground radio's RADIO_STATUS (sysid '3' = 51, compid 'D' =
    68) with txbuf 98..100: its uplink buffer holds at most the client's one heartbeat a second (21 bytes:
    (100 * ((1850 - 21) // 8)) // (1850 // 8) = 98; empty: 100).
    With a 1-byte buffer no packet fits: the vehicle's greeting (HEARTBEAT, SYSTEM_TIME) and the client's
    heartbeats never get through, while RADIO_STATUS, which the ground radio writes to its own serial port,
    still arrives (and shows that the greeting was sent), its txbuf (100 * (1 // 8)) // 1 = 0; the counters
    at exit show the drops."""
    for args, txbuf in (
        (("--link-radio", "sik64"), (98, 99, 100)),
        (("--link-radio", "wifi", "--link-buffer-bytes", "1", "--link-radio-status"), (0,)),
    ):
        sim = sitl(*args)
        link = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{sim.port(0)}", source_system=255, source_component=190
        )
        try:
            status, deadline = None, time.monotonic() + 20
            while status is None and time.monotonic() < deadline:
                link.mav.heartbeat_send(6, 8, 0, 0, 4)
                status = link.recv_match(type="RADIO_STATUS", blocking=True, timeout=1.0)
            assert status is not None
            assert (status.get_srcSystem(), status.get_srcComponent()) == (51, 68) and status.txbuf in txbuf
        finally:
            link.close()
    code, err = sim.stop()
    assert code == 0 and "received=0 " in err
    assert "radio_up_packets=0 " in err  # dropped, or still staged when the stop came: never delivered
    assert "radio_down_packets=0 " in err and "radio_down_dropped=0 " not in err


@settings(max_examples=200, deadline=None)
@given(
    half_duplex=st.booleans(),
    buffer_bytes=st.integers(20, 600),
    packets=st.lists(
        st.tuples(st.sampled_from((UP, DOWN)), st.integers(1, 300), st.integers(0, 40)),
        min_size=1,
        max_size=60,
    ),
)
def test_the_air_is_never_double_booked_never_idle_while_packets_wait_and_buffers_hold(
    half_duplex: bool, buffer_bytes: int, packets: list[tuple[int, int, int]]
) -> None:
    """Any packets (direction, bytes, ms after the previous one) through one 64 kbit/s radio: each is put on
    the air or dropped; on each time line no two packets overlap, none starts before it arrived, and the
    line is never idle while one waits (it starts on arrival or as another leaves the air); a packet is
    dropped exactly when the bytes accepted and not yet on the air, plus its own, exceed the buffer."""
    spec = RadioSpec(64_000.0, half_duplex=half_duplex, buffer_bytes=buffer_bytes)
    link = RadioLink(Medium(spec), TxBuffer(spec.buffer_limit))
    now_ms = 0
    sent: list[tuple[int, int, int, int, int]] = []  # (direction, arrival ns, start ns, end ns, bytes)
    for direction, size, gap_ms in packets:
        now_ms += gap_ms
        arrival = now_ms * NS_PER_MS
        waiting = sum(b for d, _, start, _, b in sent if d == direction and start > arrival)
        end = link.send(direction, size, now_ms)
        assert (end is None) == (waiting + size > buffer_bytes)
        if end is not None:
            sent.append((direction, arrival, end - spec.air_time_ns(size), end, size))
    lines = [[s for s in sent if half_duplex or s[0] == d] for d in ((UP,) if half_duplex else (UP, DOWN))]
    for line in lines:
        ends = {end for *_, end, _ in line}
        for (_, _, _, end_a, _), (_, _, start_b, _, _) in itertools.pairwise(
            sorted(line, key=lambda s: s[2])
        ):
            assert start_b >= end_a  # no overlap
        for _, arrival, start, _, _ in line:
            assert start >= arrival and (start == arrival or start in ends)
    counts = link.counts
    assert counts[UP].packets + counts[DOWN].packets == len(sent)
    assert sum(c.packets + c.dropped for c in counts) == len(packets)


def test_a_capacity_change_times_the_packets_that_start_after_it_at_the_new_capacity() -> None:
    """100-byte packets at 80 kbit/s, 8 bits a byte: 10 ms each; from 25 ms on 40 kbit/s: 20 ms each. Five
    queued at t = 0 start at 0, 10, 20 ms (the third still at 80 kbit/s: it started before the change) and
    end at 10, 20, 30; the fourth starts at 30 and ends at 50, the fifth at 70. The buffer keeps its size."""
    spec = RadioSpec(80_000.0, buffer_bytes=10_000)
    medium = Medium(spec, [CapacityChange(0.025, 40_000.0)])
    channel = _channel(spec, radio=RadioLink(medium, TxBuffer(spec.buffer_limit)))
    for k in range(5):
        channel.push(DOWN, _packet(k, 100), None, 0, CLEAN)
    assert [t for t, _ in _deliveries(channel, DOWN, 80)] == [10, 20, 30, 50, 70]
    # every vehicle's medium changes the same way (one pair of radios each here)
    radios = fleet_radios(spec, 2, [CapacityChange(0.025, 40_000.0)])
    assert all(
        r is not None and r.medium.send(DOWN, 100, 30, r.buffers[DOWN], r.counts[DOWN]) == 50 * NS_PER_MS
        for r in radios
    )


def test_the_capacity_change_option() -> None:
    parser = build_parser()
    argv = ["--vehicles", "1", "--link-radio", "sik64", "--link-capacity-change", "20:32000"]
    argv += ["--link-capacity-change", "40.5:16000"]
    link = build_config(parser, parser.parse_args(argv)).link
    assert link.capacity_changes == (CapacityChange(20.0, 32000.0), CapacityChange(40.5, 16000.0))


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["--link-capacity-change", "20:32000"], "--link-capacity-change needs a radio"),
        (["--link-radio", "sik64", "--link-capacity-change", "20"], "must be START:BPS (s, bit/s), not '20'"),
        (["--link-radio", "sik64", "--link-capacity-change=-1:100"], "start must be >= 0 s, not '-1'"),
        (["--link-radio", "sik64", "--link-capacity-change", "5:0"], "capacity must be > 0 bit/s, not '0'"),
    ],
)
def test_bad_capacity_changes_give_one_line_and_status_2(argv, fragment, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        _radio_of(["--vehicles", "1", *argv])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and fragment in err and err.count("\n") == 1
