"""MAVLink endpoints: connection strings -> non-blocking sockets that yield parsed messages.

Forms (pymavlink / MAVProxy conventions):
  udpout:HOST:PORT   we send first to a vehicle listening there (the simulator's form)
  udpin:HOST:PORT    we listen; vehicles send to us. Several vehicles may share one udpin endpoint: it routes
                     by system id and answers each vehicle at the address its own packets come from
                     (pymavlink's udpin writes every packet to every sender it has seen, which breaks
                     per-vehicle traffic such as lockstep SYSTEM_TIME answers).
  udp:HOST:PORT      same as udpin
  tcp:HOST:PORT      TCP client (e.g. ArduPilot SITL's 5760)
  serial:DEVICE[:BAUD], /dev/DEVICE[,BAUD]   serial port (needs pyserial), baud 115200 by default

udpout, tcp and serial are opened by `pymavlink.mavutil.mavlink_connection`; the ground station reads and
writes the opened socket / port itself so that one poll loop serves every vehicle. Parsing uses pymavlink's
MAVLink 2 ardupilotmega dialect with robust parsing: garbage becomes BAD_DATA messages, counted by callers.
With a signing key every endpoint checks what it receives (swarm_common.signing, ArduPilot's rule): unsigned,
forged and replayed packets become BAD_DATA whose reason is SIGNATURE_REJECTED, and a shared udpin endpoint
learns a vehicle's address only from packets that pass.
"""

from __future__ import annotations

import contextlib
import re
import socket
from dataclasses import dataclass
from typing import Any, TypeAlias

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.mavlink_datagrams import decode_leading_packets
from swarm_common.signing import new_parser

MAVLinkMessage: TypeAlias = mavlink2.MAVLink_message
Address = tuple[str, int]

_MAX_READS_PER_POLL = 512
_UDP_MAX = 65535
_HOST_PORT = re.compile(r"^(?P<host>[^:]+):(?P<port>\d{1,5})$")
_USAGE = "udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT or serial:DEVICE[:BAUD]"


class LinkError(Exception):
    """A failure the user can cause or fix (endpoint, vehicle, command): one sentence naming the vehicle."""


@dataclass(frozen=True)
class ConnectionSpec:
    """A parsed connection string. `key` identifies the local resource (shared only for udpin)."""

    text: str
    kind: str  # "udpin", "udpout", "tcp" or "serial"
    host: str = ""
    port: int = 0
    device: str = ""
    baud: int = 115200

    @property
    def key(self) -> tuple[str, str, int]:
        return (self.kind, self.device or self.host, self.port)


def parse_connection(text: str) -> ConnectionSpec:
    """Parse a connection string; ValueError with the reason when it is not one of the supported forms."""
    s = text.strip()
    scheme, _, rest = s.partition(":")
    if scheme in ("udpin", "udp", "udpout", "tcp"):
        m = _HOST_PORT.match(rest)
        if m is None or not 0 < int(m["port"]) < 65536:
            raise ValueError(f"connection {text!r} needs HOST:PORT with a port in 1..65535 ({_USAGE})")
        kind = "udpin" if scheme == "udp" else scheme
        return ConnectionSpec(text=s, kind=kind, host=m["host"], port=int(m["port"]))
    if scheme == "serial":
        device, sep, baud = rest.rpartition(":")
        if not sep or not baud.isdigit():
            device, baud = rest, "115200"
        return _serial_spec(s, device, baud)
    if s.startswith("/dev/") or re.match(r"^COM\d+", s):
        device, sep, baud = s.partition(",")
        return _serial_spec(s, device, baud if sep else "115200")
    raise ValueError(f"connection {text!r} is not one of {_USAGE}")


def _serial_spec(text: str, device: str, baud: str) -> ConnectionSpec:
    if not device or not baud.isdigit() or int(baud) <= 0:
        raise ValueError(f"connection {text!r} needs serial:DEVICE[:BAUD] with a positive integer baud rate")
    return ConnectionSpec(text=text, kind="serial", device=device, baud=int(baud))


class _DatagramParser:
    """Parses whole UDP datagrams: a truncated packet ending a datagram is garbage, not joined to the next.

    The whole MAVLink 2 packets a datagram starts with (usually all of it) are decoded one by one
    (swarm_common.mavlink_datagrams: the checks of `parse_buffer` without its byte-buffer bookkeeping, the
    streamed telemetry built cheaper without a signing key); from the first thing that is not such a packet
    on, `parse_buffer` takes the rest. A datagram may be handed over in pieces cut at packet boundaries.
    """

    def __init__(self, key: bytes | None = None) -> None:
        self._key = key
        self._parser = new_parser(key)

    @property
    def parser(self) -> mavlink2.MAVLink:
        """The pymavlink parser now in use (its signing state is the stream timestamps accepted so far)."""
        return self._parser

    def parse(self, data: bytes) -> list[MAVLinkMessage]:
        """The messages of one datagram (or of its tail from a packet boundary on)."""
        msgs, start = decode_leading_packets(self._parser, data)
        if start < len(data):
            msgs += self._parse_buffer(data[start:])
        return msgs

    def _parse_buffer(self, data: bytes) -> list[MAVLinkMessage]:
        msgs = self._parser.parse_buffer(data) or []
        if self._parser.buf_len() > 0:
            tail = bytearray(data[-self._parser.buf_len() :])
            msgs.append(mavlink2.MAVLink_bad_data(tail, "truncated packet"))
            signing_state = self._parser.signing  # the streams' last timestamps: no replay after garbage
            self._parser = new_parser(self._key)
            self._parser.signing = signing_state
        return msgs


class Endpoint:
    """One local socket or serial port. Subclasses implement `fileno`, `read_into`, `parse`, `send`,
    `close`, and `parser`.

    Reading and decoding are apart so that link.intake can gather every endpoint's bytes in one buffer and
    take the plain telemetry from them itself: `read_into` reads one datagram (or one chunk of a stream),
    `parse` decodes bytes from a packet boundary on (the general path)."""

    reads_per_poll = 1  # datagrams / chunks `read_into` may be called for in one receive
    stream = False  # a byte stream (tcp, serial): a packet may continue in the next chunk

    def __init__(self, spec: ConnectionSpec) -> None:
        self.spec = spec
        self.closed = False  # the peer closed a stream connection; nothing more will arrive

    def fileno(self) -> int:
        raise NotImplementedError

    def read_into(self, buffer: memoryview) -> tuple[int, Any] | None:
        """Read one datagram (or stream chunk) into `buffer`: (its size, the peer address or None); None when
        nothing more is readable now."""
        raise NotImplementedError

    def parse(self, data: bytes, peer: Any = None) -> list[MAVLinkMessage]:
        """The messages in `data` (BAD_DATA included), read from `peer`; it starts at a packet boundary."""
        raise NotImplementedError

    @property
    def parser(self) -> mavlink2.MAVLink:
        """The pymavlink parser `parse` uses now."""
        raise NotImplementedError

    @property
    def busy(self) -> bool:
        """The parser holds the start of a packet that the next bytes complete (a stream's)."""
        return False

    def check_signature(self, packet: bytearray, sysid: int, compid: int) -> bool:
        """The signature check `parse` applies to a signed packet (swarm_common.signing.VerifyingParser:
        a good one advances the stream's timestamp); True without a signing key, as pymavlink accepts."""
        parser = self.parser
        if parser.signing.secret_key is None:
            return True
        return bool(parser.check_signature(packet, sysid, compid))

    def learn(self, sysid: int, peer: Any) -> None:
        """A packet of `sysid` that passed came from `peer` (UdpRouter answers it there)."""

    def receive(self) -> list[tuple[MAVLinkMessage, Any]]:
        """Drain what is readable now: (message, peer address or None) pairs, BAD_DATA included."""
        out: list[tuple[MAVLinkMessage, Any]] = []
        buffer = memoryview(bytearray(_UDP_MAX))
        for _ in range(self.reads_per_poll):
            got = self.read_into(buffer)
            if got is None:
                break
            size, peer = got
            out.extend((msg, peer) for msg in self.parse(bytes(buffer[:size]), peer))
        return out

    def send(self, packet: bytes | bytearray, sysid: int | None) -> bool:
        """Send one packet towards vehicle `sysid`; False when there is nowhere to send it yet."""
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError


class UdpRouter(Endpoint):
    """A listening UDP socket shared by vehicles, routed by system id.

    Each vehicle's replies go to the address its latest packet came from; `addresses[sysid]` keeps every
    address a sysid was heard from so the fleet can refuse two endpoints claiming one sysid.
    """

    def __init__(self, spec: ConnectionSpec, key: bytes | None = None) -> None:
        super().__init__(spec)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((spec.host, spec.port))
        except OSError:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self._parser = _DatagramParser(key)
        self.addresses: dict[int, list[Address]] = {}
        self.sysid_of: dict[Address, int] = {}

    def fileno(self) -> int:
        return self._sock.fileno()

    reads_per_poll = _MAX_READS_PER_POLL

    def read_into(self, buffer: memoryview) -> tuple[int, Any] | None:
        while True:
            try:
                return self._sock.recvfrom_into(buffer, _UDP_MAX)
            except (BlockingIOError, InterruptedError):
                return None
            except OSError:  # e.g. ICMP port unreachable reported on the socket
                continue

    @property
    def parser(self) -> mavlink2.MAVLink:
        return self._parser.parser

    def parse(self, data: bytes, peer: Any = None) -> list[MAVLinkMessage]:
        msgs = self._parser.parse(data)
        for msg in msgs:
            if msg.get_type() != "BAD_DATA":
                self.learn(msg.get_srcSystem(), peer)
        return msgs

    def learn(self, sysid: int, addr: Address) -> None:
        known = self.addresses.setdefault(sysid, [])
        if not known or known[-1] != addr:
            if addr in known:
                known.remove(addr)
            known.append(addr)
        self.sysid_of[addr] = sysid

    def send(self, packet: bytes | bytearray, sysid: int | None) -> bool:
        known = self.addresses.get(sysid) if sysid is not None else None
        if not known:
            return False
        try:
            self._sock.sendto(packet, known[-1])
        except OSError:
            return False
        return True

    def send_to_all(self, packet: bytes | bytearray) -> bool:
        """Send one packet to every address heard from (a forward listening for its ground stations)."""
        sent = False
        for addr in list(self.sysid_of):
            try:
                self._sock.sendto(packet, addr)
                sent = True
            except OSError:
                continue
        return sent

    def close(self) -> None:
        self._sock.close()


class MavutilEndpoint(Endpoint):
    """udpout / tcp / serial opened with pymavlink's mavlink_connection; one vehicle behind it."""

    def __init__(self, spec: ConnectionSpec, connect_timeout_s: float, key: bytes | None = None) -> None:
        super().__init__(spec)
        if spec.kind == "serial":
            try:
                import serial  # noqa: F401  (pymavlink imports it lazily; fail with a clear sentence instead)
            except ImportError as err:
                raise OSError("serial connections need pyserial (pip install pyserial)") from err
            self._conn = mavutil.mavlink_connection(spec.device, baud=spec.baud, source_system=255)
        elif spec.kind == "tcp":
            previous = socket.getdefaulttimeout()
            socket.setdefaulttimeout(connect_timeout_s)  # bound mavtcp's blocking connect()
            try:
                self._conn = mavutil.mavlink_connection(spec.text, retries=0)
            finally:
                socket.setdefaulttimeout(previous)
        else:
            self._destination = (socket.gethostbyname(spec.host), spec.port)
            self._conn = mavutil.mavlink_connection(spec.text)
            self.reads_per_poll = _MAX_READS_PER_POLL
        self._datagrams = spec.kind == "udpout"
        self.stream = not self._datagrams
        self._udp_parser = _DatagramParser(key)
        self._stream_parser = new_parser(key)

    def fileno(self) -> int:
        fd = self._conn.fd
        if fd is None:
            raise OSError(f"{self.spec.text} has no pollable file descriptor")
        return int(fd)

    def read_into(self, buffer: memoryview) -> tuple[int, Any] | None:
        if self._datagrams:
            while True:
                try:
                    return self._conn.port.recv_into(buffer, _UDP_MAX), None
                except (BlockingIOError, InterruptedError):
                    return None
                except OSError:  # ECONNREFUSED: nothing listens at the destination (yet)
                    continue
        if self.spec.kind == "tcp":
            try:
                size = self._conn.port.recv_into(buffer, _UDP_MAX)
            except (BlockingIOError, InterruptedError):
                return None
            except OSError:
                size = 0
            self.closed = size == 0
            return (size, None) if size else None
        chunk = self._conn.recv(4096)
        if not chunk:
            return None
        buffer[: len(chunk)] = chunk
        return len(chunk), None

    @property
    def parser(self) -> mavlink2.MAVLink:
        return self._udp_parser.parser if self._datagrams else self._stream_parser

    @property
    def busy(self) -> bool:
        return not self._datagrams and self._stream_parser.buf_len() > 0

    def parse(self, data: bytes, peer: Any = None) -> list[MAVLinkMessage]:
        if self._datagrams:
            return self._udp_parser.parse(data)
        return self._stream_parser.parse_buffer(data) or []

    def send(self, packet: bytes | bytearray, sysid: int | None) -> bool:
        try:
            if self._datagrams:
                self._conn.port.sendto(packet, self._destination)
            elif self.spec.kind == "tcp":
                self._conn.port.sendall(packet)
            else:
                self._conn.write(packet)
        except OSError:
            return False
        return True

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._conn.close()


def open_endpoint(
    spec: ConnectionSpec, owner: str, connect_timeout_s: float = 5.0, key: bytes | None = None
) -> Endpoint:
    """Open `spec` for the vehicle(s) named in `owner`, checking signatures with `key` when given; LinkError
    (one sentence) when that fails."""
    try:
        if spec.kind == "udpin":
            return UdpRouter(spec, key)
        return MavutilEndpoint(spec, connect_timeout_s, key)
    except OSError as err:
        reason = err.strerror or str(err)
        raise LinkError(f"cannot open {owner}'s connection {spec.text}: {reason}") from err
