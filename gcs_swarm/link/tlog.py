"""Telemetry log writer in the standard .tlog format (MAVProxy / Mission Planner / pymavlink).

Each record is an 8-byte big-endian timestamp (microseconds since the UNIX epoch, wall clock) followed by
one raw MAVLink packet. The fleet writes every packet it receives and every packet it sends, for all
vehicles, into one file; `mavlogdump.py FILE` and `pymavlink.mavutil.mavlink_connection(FILE)` read it.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from types import TracebackType

_TIMESTAMP = struct.Struct(">Q")
FLUSH_PERIOD_S = 1.0  # wall s between flushes to the OS


class TlogWriter:
    """Append MAVLink packets with their wall-clock timestamps to a .tlog file (created or truncated)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = self.path.open("wb")
        self.records = 0
        self._flushed_at = time.monotonic()

    def write(self, packet: bytes | bytearray, unix_time_s: float | None = None) -> None:
        """Record one packet; `unix_time_s` defaults to now."""
        t = time.time() if unix_time_s is None else unix_time_s
        self._file.write(_TIMESTAMP.pack(int(t * 1e6)) + packet)
        self.records += 1
        if time.monotonic() - self._flushed_at >= FLUSH_PERIOD_S:  # a killed process loses at most this much
            self.flush()

    def flush(self) -> None:
        self._file.flush()
        self._flushed_at = time.monotonic()

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
