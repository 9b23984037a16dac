"""Connection strings and endpoints (no vehicle needed)."""

from __future__ import annotations

import select
import socket

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from gcs_swarm.link.connection import LinkError, open_endpoint, parse_connection
from gcs_swarm.link.fleet import Fleet
from gcs_swarm.link.vehicle import VehicleConfig
from swarm_common.ports import free_udp_base
from tests.gcs_swarm.link.simulated_vehicles import ORIGIN


@pytest.mark.parametrize(
    ("text", "kind", "host", "port"),
    [
        ("udpout:127.0.0.1:14541", "udpout", "127.0.0.1", 14541),
        ("udpin:0.0.0.0:14550", "udpin", "0.0.0.0", 14550),
        ("udp:0.0.0.0:14550", "udpin", "0.0.0.0", 14550),
        ("tcp:localhost:5760", "tcp", "localhost", 5760),
    ],
)
def test_network_forms(text: str, kind: str, host: str, port: int) -> None:
    spec = parse_connection(text)
    assert (spec.kind, spec.host, spec.port) == (kind, host, port)


@pytest.mark.parametrize(
    ("text", "device", "baud"),
    [
        ("serial:/dev/ttyACM0:57600", "/dev/ttyACM0", 57600),
        ("serial:/dev/ttyUSB1", "/dev/ttyUSB1", 115200),
        ("/dev/ttyUSB0,921600", "/dev/ttyUSB0", 921600),
        ("COM3", "COM3", 115200),
    ],
)
def test_serial_forms(text: str, device: str, baud: int) -> None:
    spec = parse_connection(text)
    assert (spec.kind, spec.device, spec.baud) == ("serial", device, baud)


@pytest.mark.parametrize(
    "text",
    ["udpout:127.0.0.1", "udpout:127.0.0.1:0", "udpout:127.0.0.1:70000", "http://x", "tcp:host:port", ""],
)
def test_bad_strings_are_refused_with_the_accepted_forms(text: str) -> None:
    with pytest.raises(ValueError, match="udpin:HOST:PORT"):
        parse_connection(text)


def test_fleet_names_the_vehicle_of_a_bad_string() -> None:
    with Fleet([VehicleConfig("lead", "udpout:nowhere")], ORIGIN) as fleet:
        with pytest.raises(LinkError, match="^lead: connection 'udpout:nowhere'"):
            fleet.connect(timeout_s=1.0)


def test_unreachable_tcp_endpoint_is_a_link_error() -> None:
    port = free_udp_base(1)  # nothing listens on this TCP port either (very likely)
    with pytest.raises(LinkError, match=f"cannot open lead's connection tcp:127.0.0.1:{port}"):
        open_endpoint(parse_connection(f"tcp:127.0.0.1:{port}"), "lead", connect_timeout_s=1.0)


def test_udpin_port_in_use_is_a_link_error() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        with pytest.raises(LinkError, match=f"cannot open f1, f2's connection udpin:127.0.0.1:{port}"):
            open_endpoint(parse_connection(f"udpin:127.0.0.1:{port}"), "f1, f2")


def test_router_parses_each_datagram_alone_and_learns_sender_addresses() -> None:
    address = ("127.0.0.1", free_udp_base(1))
    router = open_endpoint(parse_connection(f"udpin:127.0.0.1:{address[1]}"), "test")
    try:
        mav = mavlink2.MAVLink(None, 7, 1)
        heartbeat = bytes(mav.heartbeat_encode(2, 3, 0, 0, 3).pack(mav))
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            sender.bind(("127.0.0.1", 0))
            sender.sendto(
                b"\xfd\x09\x00\x00garbage", address
            )  # truncated packet start: must not eat the next
            sender.sendto(heartbeat, address)
            received = []
            for _ in range(50):
                select.select([router.fileno()], [], [], 0.1)
                received += router.receive()
                if any(m.get_type() == "HEARTBEAT" for m, _ in received):
                    break
            types = [m.get_type() for m, _ in received]
            assert "BAD_DATA" in types and "HEARTBEAT" in types
            assert router.addresses[7] == [sender.getsockname()]  # type: ignore[attr-defined]
            assert router.send(heartbeat, 7) and not router.send(heartbeat, 8)
    finally:
        router.close()


def test_missing_serial_device_is_a_link_error() -> None:
    # without pyserial: "serial connections need pyserial"; with it: the OS error for the missing device
    with pytest.raises(LinkError, match="^cannot open lead's connection serial:/dev/ttyNOPE0:57600: "):
        open_endpoint(parse_connection("serial:/dev/ttyNOPE0:57600"), "lead")
