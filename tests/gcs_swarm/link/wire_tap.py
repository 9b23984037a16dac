"""A scripted radio between a ground station and one vehicle of a running sitl_sim, for the link tests.

`WireTap` is a UDP relay on 127.0.0.1 in its own thread. It forwards every datagram both ways and records
every message it saw (`uplink`: what the ground station sent, `downlink`: what the vehicle sent, dropped or
not). It changes the traffic only as a test scripts it, for what a healthy simulator never does: lose
chosen packets (`drop_uplink`, `drop_downlink`, `silent`), answer a command in the vehicle's place
(`answer_instead`), or put raw bytes on the wire (`inject_downlink`). It knows no autopilot and no lockstep
rule: the vehicle behind it is the real simulator, and the tap's vehicle-side socket is, to the simulator,
simply the client's address.

Server mode (default): the ground station sends to `connection` (udpout:) and the tap answers whoever spoke
last. Client mode (`gcs_address`): the tap sends the vehicle's traffic to a ground station's udpin: port; it
greets the vehicle once with a HEARTBEAT of its own so that the simulator (which talks only to peers that
spoke first) starts sending.
"""

from __future__ import annotations

import select
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

TAP_SYSID = 254  # the tap's own greeting in client mode: neither the ground station (255) nor a vehicle

Message = Any  # a pymavlink message


@dataclass
class _Drop:
    """Lose the next `count` messages of type `kind` for which `where(message)` holds."""

    kind: str
    count: int
    where: Callable[[Message], bool]


def _parse(data: bytes) -> list[Message]:
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    return [m for m in parser.parse_buffer(data) or [] if m.get_type() != "BAD_DATA"]


class WireTap:
    """See the module docstring. Start with `start()` (or `with`), end with `close()`."""

    def __init__(self, vehicle_port: int, sysid: int, gcs_address: tuple[str, int] | None = None) -> None:
        self.vehicle = ("127.0.0.1", vehicle_port)
        self.sysid = sysid  # the vehicle's, for messages the tap sends in its place
        self.uplink: list[Message] = []
        self.downlink: list[Message] = []
        self.silent = False  # lose everything the vehicle sends
        self._drops: dict[str, list[_Drop]] = {"up": [], "down": []}
        self._pending: list[tuple[int, bytes]] = []  # (downlink datagrams still to pass, packet) to inject
        self._answers: dict[int, list[tuple[int, int]]] = {}  # command -> the tap's answers in its place
        self.vehicle_encoder = mavlink2.MAVLink(None, sysid, mavlink2.MAV_COMP_ID_AUTOPILOT1)
        """Encodes messages in the vehicle's name, for `inject_downlink`."""
        self._gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._gcs_sock.bind(("127.0.0.1", 0))
        self._vehicle_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._vehicle_sock.bind(("127.0.0.1", 0))
        self.gcs: tuple[str, int] | None = gcs_address
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"wire-tap-{vehicle_port}", daemon=True)

    @property
    def connection(self) -> str:
        """The ground station's connection string for this vehicle (server mode)."""
        return f"udpout:127.0.0.1:{self._gcs_sock.getsockname()[1]}"

    @property
    def client_address(self) -> tuple[str, int]:
        """The address the simulator sees as this client (its lockstep client key)."""
        host, port = self._vehicle_sock.getsockname()
        return host, port

    def start(self) -> WireTap:
        if self.gcs is not None:
            hello = mavlink2.MAVLink(None, TAP_SYSID, mavlink2.MAV_COMP_ID_UDP_BRIDGE)
            msg = hello.heartbeat_encode(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            self._vehicle_sock.sendto(msg.pack(hello), self.vehicle)
        self._thread.start()
        return self

    def __enter__(self) -> WireTap:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop relaying and close both sockets."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self._vehicle_sock.close()
        self._gcs_sock.close()

    # ------------------------------------------------------------------ what the test scripts

    def drop_uplink(self, kind: str, count: int, where: Callable[[Message], bool] = lambda _: True) -> None:
        """Lose the next `count` messages of type `kind` (and `where`) on their way to the vehicle."""
        with self._lock:
            self._drops["up"].append(_Drop(kind, count, where))

    def drop_downlink(self, kind: str, count: int, where: Callable[[Message], bool] = lambda _: True) -> None:
        """Lose the next `count` messages of type `kind` (and `where`) on their way to the ground station."""
        with self._lock:
            self._drops["down"].append(_Drop(kind, count, where))

    def answer_instead(self, command: int, answers: list[tuple[int, int]], count: int = 1) -> None:
        """The next `count` COMMAND_LONGs `command` never reach the vehicle; the tap answers each with
        COMMAND_ACKs (result, after this many further downlink datagrams) in the vehicle's name."""
        with self._lock:
            self._drops["up"].append(_Drop("COMMAND_LONG", count, lambda m: m.command == command))
            self._answers[command] = answers

    def inject_downlink(self, data: bytes) -> None:
        """Send `data` as one datagram to the ground station, as if from the vehicle."""
        with self._lock:
            self._pending.append((0, data))

    # ------------------------------------------------------------------ views of the record

    def sent(self, kind: str) -> list[Message]:
        """Uplink messages of one type, in order."""
        return [m for m in list(self.uplink) if m.get_type() == kind]

    def received(self, kind: str) -> list[Message]:
        """Downlink messages of one type, in order."""
        return [m for m in list(self.downlink) if m.get_type() == kind]

    def commands(self, command: int) -> list[Message]:
        """COMMAND_LONGs of one command the ground station sent (those the tap lost included)."""
        return [m for m in self.sent("COMMAND_LONG") if m.command == command]

    def results(self, command: int) -> list[int]:
        """Results of the vehicle's COMMAND_ACKs for one command (those the tap lost included)."""
        return [m.result for m in self.received("COMMAND_ACK") if m.command == command]

    # ------------------------------------------------------------------ relay

    def _run(self) -> None:
        while not self._stop.is_set():
            readable, _, _ = select.select([self._gcs_sock, self._vehicle_sock], [], [], 0.05)
            if not readable:
                self._inject_due()
            for sock in readable:
                try:
                    data, addr = sock.recvfrom(65535)
                except OSError:
                    continue
                if sock is self._gcs_sock:
                    if self.gcs is None or addr != self.gcs:
                        self.gcs = addr
                    self._relay(data, "up", self._vehicle_sock, self.vehicle)
                else:
                    self._relay(data, "down", self._gcs_sock, self.gcs)

    def _relay(self, data: bytes, direction: str, out: socket.socket, to: tuple[str, int] | None) -> None:
        messages = _parse(data)
        kept: list[Message] = []
        due: list[tuple[int, bytes]] = []
        with self._lock:
            (self.uplink if direction == "up" else self.downlink).extend(messages)
            for msg in messages:
                if not self._lose(msg, direction):
                    kept.append(msg)
            if direction == "down":
                due = [p for p in self._pending if p[0] <= 0]
                self._pending = [(n - 1, p) for n, p in self._pending if n > 0]
        if to is None:
            return
        if len(kept) == len(messages) and not (direction == "down" and self.silent):
            out.sendto(data, to)
        elif kept and not (direction == "down" and self.silent):
            out.sendto(b"".join(bytes(m.get_msgbuf()) for m in kept), to)
        for _, packet in due:
            out.sendto(packet, to)

    def _inject_due(self) -> None:
        """Injections due while the vehicle is quiet (a lockstep simulator paused for an answer)."""
        with self._lock:
            due = [p for n, p in self._pending if n <= 0]
            self._pending = [(n, p) for n, p in self._pending if n > 0]
        if self.gcs is not None:
            for packet in due:
                self._gcs_sock.sendto(packet, self.gcs)

    def _lose(self, msg: Message, direction: str) -> bool:
        for drop in self._drops[direction]:
            if drop.count > 0 and msg.get_type() == drop.kind and drop.where(msg):
                drop.count -= 1
                if drop.kind == "COMMAND_LONG" and msg.command in self._answers:
                    self._answer(msg, self._answers[msg.command])
                return True
        return False

    def _answer(self, msg: Message, answers: list[tuple[int, int]]) -> None:
        for result, after in answers:
            ack = self.vehicle_encoder.command_ack_encode(
                msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
            )
            self._pending.append((after, bytes(ack.pack(self.vehicle_encoder))))
