"""What a blocking wait costs a lockstep exchange: a UDP ping-pong between two processes on loopback
(prints a table; no assertions).

Two processes bounce one 60-byte datagram back and forth `--rounds` times; each waits for the other's with
swarm_common.spin_wait.select_spinning over an epoll selector, as the ground station and the simulator do:

- `block`: spin 0, a plain blocking select (each hop wakes a sleeping process);
- `spin`: spin --spin-us with os.sched_yield between polls (what the lockstep waits use);
- `spin, no yield`: the same polls without the yield (for comparison only).

Per mode: the round trip in us (median, min-max over --repeats invocations of the whole ping-pong), and the
`sendto` that answers a ping, timed in the process that sends it (median of the last invocation): against a
blocked peer it includes waking that peer.

    python benchmarks/bench_wakeup.py [--rounds 20000] [--repeats 3] [--spin-us 1000]
"""

from __future__ import annotations

import argparse
import os
import selectors
import socket
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from swarm_common import spin_wait  # noqa: E402

PAYLOAD = b"x" * 60


def _wait(sock: socket.socket, selector: selectors.BaseSelector, spin_s: float) -> bytes:
    while True:
        try:
            return sock.recv(100)
        except BlockingIOError:
            spin_wait.select_spinning(selector, 1.0, spin_s)


def ping_pong(rounds: int, spin_s: float, yield_cpu: bool) -> tuple[float, float]:
    """(round trip us, median sendto us of the pinger) over `rounds` exchanges between two processes."""
    if not yield_cpu:
        spin_wait.os.sched_yield = lambda: None  # type: ignore[attr-defined,assignment]
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for sock in (a, b):
        sock.bind(("127.0.0.1", 0))
        sock.setblocking(False)
    a_addr, b_addr = a.getsockname(), b.getsockname()
    pid = os.fork()
    if pid == 0:  # the ponger: answer every ping
        selector = selectors.DefaultSelector()
        selector.register(b, selectors.EVENT_READ)
        for _ in range(rounds):
            _wait(b, selector, spin_s)
            b.sendto(PAYLOAD, a_addr)
        os._exit(0)
    selector = selectors.DefaultSelector()
    selector.register(a, selectors.EVENT_READ)
    send_times = []
    start = time.perf_counter()
    for _ in range(rounds):
        t0 = time.perf_counter()
        a.sendto(PAYLOAD, b_addr)
        send_times.append(time.perf_counter() - t0)
        _wait(a, selector, spin_s)
    elapsed = time.perf_counter() - start
    os.waitpid(pid, 0)
    spin_wait.os.sched_yield = os.sched_yield  # type: ignore[attr-defined]
    a.close()
    b.close()
    return 1e6 * elapsed / rounds, 1e6 * statistics.median(send_times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--spin-us", type=float, default=1000.0)
    args = parser.parse_args()
    spin_s = args.spin_us * 1e-6
    modes = [("block", 0.0, True), ("spin", spin_s, True), ("spin, no yield", spin_s, False)]
    results: dict[str, list[tuple[float, float]]] = {name: [] for name, _, _ in modes}
    for _ in range(args.repeats):  # interleaved
        for name, spin_s, yield_cpu in modes:
            results[name].append(ping_pong(args.rounds, spin_s, yield_cpu))
    print(f"UDP ping-pong on loopback, {args.rounds} round trips x {args.repeats} invocations per mode")
    print("| wait | round trip us, median (min-max) | sendto us (last invocation, median) |")
    print("|---|---|---|")
    for name, rows in results.items():
        trips = [r for r, _ in rows]
        print(
            f"| {name} | {statistics.median(trips):.1f} ({min(trips):.1f}-{max(trips):.1f}) "
            f"| {rows[-1][1]:.1f} |"
        )


if __name__ == "__main__":
    main()
