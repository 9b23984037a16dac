"""swarm_common.ports: a free block is really free, whole, on loopback."""

from __future__ import annotations

import socket

import pytest

from swarm_common.ports import free_udp_base


def test_free_udp_base_gives_bindable_ports() -> None:
    base = free_udp_base(5)
    socks = []
    try:
        for i in range(5):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            socks.append(s)
            s.bind(("127.0.0.1", base + i))  # raises OSError if any port of the block is taken
    finally:
        for s in socks:
            s.close()


def test_blocks_lie_under_the_ephemeral_ports_that_outgoing_sockets_get() -> None:
    """Linux hands unbound sockets ports from 32768 up (ip_local_port_range's default; Windows and macOS
    from 49152), so no block may reach them."""
    for _ in range(200):
        base = free_udp_base(9)
        assert 20000 <= base and base + 8 < 32768


@pytest.mark.parametrize("count", [0, 70000])
def test_a_block_that_cannot_exist_is_a_clear_error(count: int) -> None:
    with pytest.raises(ValueError, match=f"a block of {count} UDP ports cannot be found"):
        free_udp_base(count)  # 70000: more ports than 0..65535 holds
