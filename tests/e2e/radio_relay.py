"""A rate-limited radio between the ground station and real vehicles (issue 38: real ArduCopter SITL at the
SiK budget): a UDP relay on 127.0.0.1 that passes each vehicle's datagrams through the simulator's radio model
(sitl_sim.network.radio via link_faults.FaultChannel: air time, transmit buffers that drop when full, half
duplex), timed by the wall clock in ms since the relay started. A test helper, not part of swarm-gcs.

Vehicle k sends to `vehicle_ports[k]` (ArduCopter's `--serial0 udpclient:127.0.0.1:PORT`); the relay passes
what leaves the air on to the ground station's `udpin:` port `gcs_ports[k]` from a socket of its own, and what
the ground station sends back to the vehicle's address. Each datagram is one packet on the air (ArduCopter
sends one MAVLink packet a datagram on UDP).
"""

from __future__ import annotations

import selectors
import socket
import threading
import time

from sitl_sim.network.link_faults import DOWN, UP, FaultChannel
from sitl_sim.network.radio import fleet_radios
from swarm_common.radio_presets import RadioSpec

CLEAN = (0.0,) * 6  # no loss, dup, corruption, reordering, delay or jitter beyond the radio's own
POLL_S = 0.001  # wall s the relay waits for datagrams before it delivers what left the air


class RadioRelay:
    """The relay for len(vehicle_ports) vehicles over radios of `spec` (one medium each, or one for all when
    spec.shared). `start` runs it on a thread, `stop` ends it; `summary()` the radios' counts per vehicle."""

    def __init__(self, spec: RadioSpec, vehicle_ports: list[int], gcs_ports: list[int]) -> None:
        radios = fleet_radios(spec, len(vehicle_ports))
        self.channels = [FaultChannel(0, k, (), radio) for k, radio in enumerate(radios)]
        self.gcs_ports = gcs_ports
        self.vehicle_socks = [self._bound(port) for port in vehicle_ports]
        self.gcs_socks = [self._bound(0) for _ in vehicle_ports]
        self.vehicle_addrs: list[tuple[str, int] | None] = [None] * len(vehicle_ports)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="radio-relay", daemon=True)
        self._t0 = time.monotonic()

    @staticmethod
    def _bound(port: int) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", port))
        sock.setblocking(False)
        return sock

    def start(self) -> None:
        self._t0 = time.monotonic()
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        for sock in self.vehicle_socks + self.gcs_socks:
            sock.close()

    def summary(self) -> list[str]:
        """Each vehicle's radio counts (RadioLink.summary: packets, bytes, dropped, waits each way)."""
        return [ch.radio.summary() if ch.radio is not None else "" for ch in self.channels]

    def _now_ms(self) -> int:
        return int((time.monotonic() - self._t0) * 1000)

    def _run(self) -> None:
        selector = selectors.DefaultSelector()
        for k, sock in enumerate(self.vehicle_socks):
            selector.register(sock, selectors.EVENT_READ, (k, DOWN))
        for k, sock in enumerate(self.gcs_socks):
            selector.register(sock, selectors.EVENT_READ, (k, UP))
        try:
            while not self._stop.is_set():
                for key, _ in selector.select(POLL_S):
                    k, direction = key.data
                    self._take(key.fileobj, k, direction)  # type: ignore[arg-type]
                self._deliver()
        finally:
            selector.close()

    def _take(self, sock: socket.socket, k: int, direction: int) -> None:
        while True:
            try:
                data, addr = sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            if direction == DOWN:
                self.vehicle_addrs[k] = addr
            self.channels[k].push(direction, data, None, self._now_ms(), CLEAN)

    def _deliver(self) -> None:
        now_ms = self._now_ms()
        for k, channel in enumerate(self.channels):
            if channel.radio is not None:
                channel.radio.medium.settle(now_ms + 1)  # time the uplink staged up to now
            for data, _ in channel.due(DOWN, now_ms):
                self._send(self.gcs_socks[k], data, ("127.0.0.1", self.gcs_ports[k]))
            addr = self.vehicle_addrs[k]
            for data, _ in channel.due(UP, now_ms):
                if addr is not None:
                    self._send(self.vehicle_socks[k], data, addr)

    @staticmethod
    def _send(sock: socket.socket, data: bytes, addr: tuple[str, int]) -> None:
        try:
            sock.sendto(data, addr)
        except OSError:  # the peer is gone or its buffer full: UDP loses it, as a radio would
            pass
