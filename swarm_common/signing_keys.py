"""MAVLink 2 signing keys and timestamps, as both the ground station and the simulated vehicles use them.

A key file holds 32 bytes as 64 hex characters (surrounding whitespace allowed). Signing timestamps are units
of 10 us since 2015-01-01 (MAVLink signing spec), from the wall clock, so a recording replayed later is
refused. The key is never printed nor logged.
"""

from __future__ import annotations

import time
from pathlib import Path

KEY_BYTES = 32
SIGNING_EPOCH_UNIX_S = 1420070400  # 2015-01-01T00:00:00Z


class SigningKeyError(ValueError):
    """The signing key file cannot be used (one sentence, never quoting the file's content)."""


def read_key(path: str | Path) -> bytes:
    """The 32-byte key of a file holding 64 hex characters; SigningKeyError when unreadable or malformed."""
    try:
        text = Path(path).read_text(encoding="ascii").strip()
    except UnicodeDecodeError:
        raise SigningKeyError(f"signing key file {path} must hold 64 hex characters") from None
    except OSError as exc:
        raise SigningKeyError(f"cannot read signing key file {path}: {exc.strerror or exc}") from None
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != KEY_BYTES or len(text) != 2 * KEY_BYTES:
        raise SigningKeyError(f"signing key file {path} must hold 64 hex characters (a 32-byte key)")
    return key


def timestamp_now() -> int:
    """Signing timestamp of the wall clock now (10 us units since 2015-01-01)."""
    return int((max(time.time(), SIGNING_EPOCH_UNIX_S) - SIGNING_EPOCH_UNIX_S) * 100_000)
