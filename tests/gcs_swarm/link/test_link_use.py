"""The ground station's link budget (link.link_use): MAVLink bytes counted each way per vehicle on real
loopback sockets, checked against what the vehicles' sockets sent and received (the bytes on the wire,
measured at the other end), the rates of a window worked out by hand, the budget and RADIO_STATUS events."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.link_use import TXBUF_LOW
from tests.gcs_swarm.link.loopback_fleet import KEY, LoopbackFleet, encoder, heartbeat

RADIO_SYSID, RADIO_COMPID = 51, 68  # SiK mavlink.c RADIO_SOURCE_SYSTEM '3', RADIO_SOURCE_COMPONENT 'D'


def position(mav: mavlink2.MAVLink, t_ms: int) -> bytes:
    return mav.global_position_int_encode(
        t_ms, 473977420, 85455940, 512345, 10000, 100, 200, -300, 9000
    ).pack(mav)


def attitude(mav: mavlink2.MAVLink, t_ms: int) -> bytes:
    return mav.attitude_encode(t_ms, 0.1, 0.2, 0.3, 0.01, 0.02, 0.03).pack(mav)


def radio_status(txbuf: int) -> bytes:
    radio = mavlink2.MAVLink(None, RADIO_SYSID, RADIO_COMPID)
    return radio.radio_status_encode(200, 190, txbuf, 40, 45, 3, 1).pack(radio)


@pytest.mark.parametrize(("shared", "key"), [(False, None), (True, None), (False, KEY)])
def test_bytes_each_way_are_the_bytes_on_the_wire(tmp_path: Path, shared: bool, key: bytes | None) -> None:
    """Two vehicles (own udpout endpoints, or sharing one udpin endpoint); telemetry the intake kernel takes,
    a HEARTBEAT and a STATUSTEXT that pymavlink decodes, and a RADIO_STATUS from the radio's own sysid: every
    byte each vehicle's socket sent is counted down for it, every byte it received from the ground station
    (heartbeats, lockstep answers) up; signed packets carry their 13-byte signature."""
    f = LoopbackFleet(tmp_path, vehicles=2, shared=shared, key=key)
    try:
        sent: list[list[bytes]] = [[], []]
        # the ground station's first HEARTBEAT, which taught each vehicle socket its address (LoopbackFleet)
        first = [f.stats(i).bytes_sent for i in range(2)]
        for i in range(2):
            mav = encoder(sysid=7 + i, key=key)
            datagrams = [heartbeat(mav)]
            datagrams += [position(mav, 100 * k) + attitude(mav, 100 * k) for k in range(1, 20)]
            datagrams.append(mav.statustext_encode(4, b"hello").pack(mav))
            if not shared:  # on a shared endpoint a packet of sysid 51 is nobody's (unrouted)
                datagrams.append(radio_status(80))
            f.feed(datagrams, [i] * len(datagrams))
            sent[i] = datagrams
        for i in range(2):
            stats = f.stats(i)
            assert stats.bytes_received == sum(len(d) for d in sent[i])
            assert stats.bytes_sent - first[i] == sum(len(d) for d in f.from_gcs[i]) > 0
            if key is not None:  # 19 positions and 19 attitudes signed: 28 + 12 + 13 bytes each on the wire
                assert len(sent[i][1]) == 2 * (28 + 12 + 13)
    finally:
        f.close()


def test_radio_status_is_kept_and_its_packet_still_ignored(tmp_path: Path) -> None:
    f = LoopbackFleet(tmp_path)
    try:
        f.feed([heartbeat(encoder()), radio_status(70), radio_status(35), radio_status(60)])
        radio = f.fleet.links[0].radio
        assert (radio.reports, radio.txbuf, radio.min_txbuf) == (3, 60, 35)
        assert radio.summary() == {
            "reports": 3,
            "txbuf_min_pct": 35,
            "txbuf_last_pct": 60,
            "rssi": 200,
            "remrssi": 190,
            "noise": 40,
            "remnoise": 45,
            "rxerrors": 3,
            "fixed": 1,
        }
        assert f.stats().ignored == 3  # not the vehicle's own packets
    finally:
        f.close()


def test_rates_peaks_means_and_the_budget_events(tmp_path: Path) -> None:
    """Windows by hand: from clock 0 to 1000 ms the vehicle sends 10 datagrams of a position and an attitude
    (each position 40 bytes, each attitude 40: 800 bytes), from 1000 to 3000 ms 5 more (400 bytes over 2 s),
    nothing sent up in between. Down rates 800 and 200 B/s; the mean 1200 B / 3 s = 400 B/s, the peak 800.
    A budget of 4000 bit/s (500 B/s): over in the first window, back within in the second."""
    f = LoopbackFleet(tmp_path)
    use = f.fleet.link_use
    use.budget_bps = 4000.0
    mav = encoder()
    try:
        f.feed([heartbeat(mav)])
        f.fleet.network.receive(0.0)
        use.sample(0)
        assert use.next_ms == 1000
        answered = len(f.from_gcs[0])
        f.feed([position(mav, 100 * k) + attitude(mav, 100 * k) for k in range(1, 11)])
        use.sample(1000)
        up = sum(len(d) for d in f.from_gcs[0][answered:])  # what the vehicle's socket got meanwhile
        assert len(position(mav, 1)) == 40 and len(attitude(mav, 1)) == 40
        assert use.rate[0].tolist() == [up / 1.0, 800.0]
        assert use.events[-1].endswith("over its budget of 500 B/s (4000 bit/s)")
        f.feed([position(mav, 1000 + 100 * k) + attitude(mav, 1000 + 100 * k) for k in range(1, 6)])
        use.sample(3000)
        assert use.rate[0, 1] == 200.0
        assert use.events[-1].endswith("link use back within its budget of 500 B/s")
        assert [e.text for e in f.fleet.events][-2:] == [e.split(": ", 1)[1] for e in use.events[-2:]]
        summary = use.summary()["v0"]
        assert summary["down_mean_B_s"] == 400.0 and summary["down_peak_B_s"] == 800.0
        assert summary["bytes_down"] == 1200 and summary["measured_s"] == 3.0
        assert summary["budget_B_s"] == 500.0 and summary["over_budget_s"] == 1.0
        assert summary["radio_status"] is None
    finally:
        f.close()


def test_a_radio_buffer_filling_up_is_an_event_once_until_it_drains(tmp_path: Path) -> None:
    f = LoopbackFleet(tmp_path)
    use = f.fleet.link_use
    try:
        f.feed([heartbeat(encoder())])
        use.sample(0)
        for clock_ms, txbuf in ((1000, 80), (2000, TXBUF_LOW - 1), (3000, 20), (4000, 85), (5000, 95)):
            f.feed([radio_status(txbuf)])
            use.sample(clock_ms)
        assert [e.split(": ", 1)[1] for e in use.events] == [
            f"radio transmit buffer {TXBUF_LOW - 1}% free: the link carries less than it is given",
            "radio transmit buffer 95% free again",
        ]
        assert use.summary()["v0"]["radio_status"]["txbuf_min_pct"] == 20
    finally:
        f.close()


def test_a_command_a_read_write_forward_routes_to_a_vehicle_counts_up(tmp_path: Path) -> None:
    """Another ground station on a read-write forward sends a COMMAND_LONG to the vehicle: its bytes go up
    the vehicle's link unchanged, and are counted there."""
    f = LoopbackFleet(tmp_path, forward=True)
    try:
        forward = f.fleet.network.forwards[0]
        forward.config = replace(forward.config, read_write=True)
        assert f.forward_socket is not None
        f.sockets[0].sendto(heartbeat(encoder()), f.gcs[0])
        f.forward_socket.settimeout(0.01)
        gcs_forward = None
        for _ in range(500):  # the forwarded HEARTBEAT comes from where the forward endpoint is
            f.fleet.network.receive(0.01)
            try:
                _, gcs_forward = f.forward_socket.recvfrom(2048)
                break
            except TimeoutError:
                continue
        assert gcs_forward is not None
        f.forward_socket.setblocking(False)
        other = mavlink2.MAVLink(None, 250, 190)
        command = other.command_long_encode(7, 1, mavlink2.MAV_CMD_DO_SET_MODE, 0, 1, 5, 0, 0, 0, 0, 0).pack(
            other
        )
        before, seen = f.stats().bytes_sent, len(f.from_gcs[0])
        f.forward_socket.sendto(command, gcs_forward)
        for _ in range(500):  # until the vehicle's socket has it
            f.feed([])
            if command in f.from_gcs[0][seen:]:
                break
        assert command in f.from_gcs[0][seen:]
        assert f.stats().bytes_sent - before == sum(len(d) for d in f.from_gcs[0][seen:])
    finally:
        f.close()
