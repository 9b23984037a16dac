"""Free UDP ports on the loopback interface, for simulators and tests started side by side."""

from __future__ import annotations

import random
import socket

# where probed blocks lie: under the ephemeral ports the operating system gives to sockets that do not bind
# one themselves (Linux 32768-60999, Windows and macOS 49152-65535), so that a block found free is not taken
# by another process's outgoing socket before the caller binds it (a test's simulator failed so, with another
# build running beside it); only another caller of this function can still race for it
PORT_RANGE = (20000, 32768)
PORT_TRIES = 200


def free_udp_base(count: int, host: str = "127.0.0.1") -> int:
    """A base port with base..base+count-1 all free on `host`, probed from a random start so that concurrent
    workers rarely pick the same block. The ports are released before returning: a caller that loses a race
    for them gets an error from its own bind and may ask again. ValueError for a count outside
    1..PORT_RANGE span; RuntimeError when no block is found."""
    if not 1 <= count < PORT_RANGE[1] - PORT_RANGE[0]:
        raise ValueError(f"a block of {count} UDP ports cannot be found in {PORT_RANGE[0]}..{PORT_RANGE[1]}")
    rng = random.Random()
    for _ in range(PORT_TRIES):
        base = rng.randrange(PORT_RANGE[0], PORT_RANGE[1] - count)
        socks: list[socket.socket] = []
        try:
            for i in range(count):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind((host, base + i))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise RuntimeError(f"no block of {count} free UDP ports found")
