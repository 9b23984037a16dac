"""Communication topology (spec 6, Sec 5.2): adjacency, Laplacian (with the degrees), hops, and the relay
delay line that makes the topology matter to the controller.

Convention: `A[i, j] != 0` means vehicle i hears vehicle j (information flows j -> i).
"""

from __future__ import annotations

from collections import deque

import numpy as np

TOPOLOGIES = ("broadcast", "relay")

# The paper's 6-UAV graph as printed in Sec 5.2 (undirected ring 1-2-4-5-6-3-1), spec 6.
PAPER_SIX_UAV_ADJACENCY = np.array(
    [
        [0, 1, 1, 0, 0, 0],
        [1, 0, 0, 1, 0, 0],
        [1, 0, 0, 0, 0, 1],
        [0, 1, 0, 0, 1, 0],
        [0, 0, 0, 1, 0, 1],
        [0, 0, 1, 0, 1, 0],
    ],
    dtype=float,
)


def laplacian(adjacency: np.ndarray) -> np.ndarray:
    """L = D - A, (N, N), D = diag(row sums of A) the degree matrix."""
    a = np.asarray(adjacency, dtype=float)
    return np.diag(a.sum(axis=1)) - a


def star_adjacency(n: int, leader: int) -> np.ndarray:
    """Every follower linked to the leader (the broadcast graph), (N, N)."""
    a = np.zeros((n, n))
    a[leader, :] = 1.0
    a[:, leader] = 1.0
    a[leader, leader] = 0.0
    return a


def hop_counts(adjacency: np.ndarray, source: int) -> np.ndarray:
    """Fewest links from `source` to each vehicle along A (breadth first), (N,) int; -1 if unreachable."""
    a = np.asarray(adjacency) != 0
    hops = np.full(a.shape[0], -1, dtype=int)
    hops[source] = 0
    queue = deque([source])
    while queue:
        j = queue.popleft()
        for i in np.flatnonzero(a[:, j] & (hops < 0)):
            hops[i] = hops[j] + 1
            queue.append(int(i))
    return hops


def check_adjacency(adjacency: np.ndarray, n: int, leader: int) -> np.ndarray:
    """Validate an adjacency matrix for relaying: shape (N, N), finite, zero diagonal, every vehicle reachable
    from the leader. Returns the hop counts (N,)."""
    a = np.asarray(adjacency, dtype=float)
    if a.shape != (n, n):
        raise ValueError(f"adjacency must have shape ({n}, {n}), got {a.shape}")
    if not np.isfinite(a).all() or np.any(a < 0):
        raise ValueError("adjacency entries must be finite and >= 0")
    if np.any(np.diag(a) != 0):
        raise ValueError("adjacency diagonal must be zero (no self-links)")
    hops = hop_counts(a, leader)
    if np.any(hops < 0):
        lost = ", ".join(str(i) for i in np.flatnonzero(hops < 0))
        raise ValueError(f"vehicles {lost} cannot hear the leader {leader} through the adjacency graph")
    return hops


class LeaderRelay:
    """Delay line: the leader state reaches vehicle i after `delays[i]` ticks (one link period per hop in
    relay mode, 0 for broadcast). Feed it once per tick with `push`, read every vehicle's copy with `read`."""

    def __init__(self, delays: np.ndarray, state: np.ndarray) -> None:
        """`delays` (N,) int ticks >= 0; `state` (S,) the leader state the line starts filled with."""
        self.delays = np.asarray(delays, dtype=int)
        self._history = np.repeat(np.asarray(state, dtype=float)[None, :], int(self.delays.max()) + 1, axis=0)

    def push(self, state: np.ndarray) -> None:
        """Enter the newest leader state (S,); the oldest falls out."""
        self._history[1:] = self._history[:-1]  # numpy copies overlapping slices as if through a buffer
        self._history[0] = state

    def read(self) -> np.ndarray:
        """Leader state as each vehicle knows it now, (N, S)."""
        return self._history[self.delays]
