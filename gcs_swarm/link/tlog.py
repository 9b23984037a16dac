"""Telemetry log writer in the standard .tlog format (MAVProxy / Mission Planner / pymavlink).

Each record is an 8-byte big-endian timestamp (microseconds since the UNIX epoch, wall clock) followed by
one raw MAVLink packet. The fleet writes every packet it receives and every packet it sends, for all
vehicles, into one file; `mavlogdump.py FILE` and `pymavlink.mavutil.mavlink_connection(FILE)` read it.
Records are gathered in memory and handed to a writer thread (swarm_common.background_writer) every
CHUNK_BYTES or FLUSH_PERIOD_S, whichever comes first: the control loop never waits on the disk.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from types import TracebackType

from swarm_common.background_writer import BackgroundWriter

_TIMESTAMP = struct.Struct(">Q")
FLUSH_PERIOD_S = 1.0  # wall s at most between hand-overs to the writer thread (what a killed process loses)
CHUNK_BYTES = 65536  # records handed over at once (about a frame's worth at 200 vehicles)


class TlogWriter:
    """Append MAVLink packets with their wall-clock timestamps to a .tlog file (created or truncated)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = BackgroundWriter(self.path, "tlog")
        self._pending = bytearray()  # records not yet handed over
        self.records = 0
        self._handed_at = time.monotonic()

    def write(self, packet: bytes | bytearray, unix_time_s: float | None = None) -> None:
        """Record one packet; `unix_time_s` defaults to now."""
        t = time.time() if unix_time_s is None else unix_time_s
        self._pending += _TIMESTAMP.pack(int(t * 1e6))
        self._pending += packet
        self.records += 1
        if len(self._pending) >= CHUNK_BYTES or time.monotonic() - self._handed_at >= FLUSH_PERIOD_S:
            self._hand_over()

    def write_records(self, records: bytes, count: int) -> None:
        """Append `count` records already framed (8-byte big-endian unix us, then the packet, each), e.g. a
        batch of packets stamped together (link.intake)."""
        self._pending += records
        self.records += count
        if len(self._pending) >= CHUNK_BYTES or time.monotonic() - self._handed_at >= FLUSH_PERIOD_S:
            self._hand_over()

    def _hand_over(self) -> None:
        if self._pending:
            self._writer.write(bytes(self._pending))
            self._pending.clear()
        self._handed_at = time.monotonic()

    def flush(self) -> None:
        """Return once every record so far is in the file."""
        self._hand_over()
        self._writer.flush()

    def close(self) -> None:
        """Write every record and close the file (idempotent)."""
        if not self._writer.closed:
            self._hand_over()
            self._writer.close()

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
