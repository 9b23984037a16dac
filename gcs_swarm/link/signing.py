"""MAVLink 2 message signing of the ground station's outgoing packets (pymavlink's MAVLinkSigning).

The key is a file holding 32 bytes as 64 hex characters, named by the mission (`run.signing_key_file`) or the
environment variable SWARM_GCS_SIGNING_KEY_FILE. Signing timestamps are 10 us units since 2015-01-01 from the
wall clock, so a vehicle refuses recordings replayed later. The key is never printed nor logged: the tlog
holds signed packets, whose signature is a truncated SHA-256, never the key.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

KEY_ENV = "SWARM_GCS_SIGNING_KEY_FILE"
KEY_BYTES = 32
SIGNING_EPOCH_UNIX_S = 1420070400  # 2015-01-01T00:00:00Z


class SigningKeyError(Exception):
    """The signing key file cannot be used (one sentence, never quoting the file's content)."""


def read_key(path: str | Path) -> bytes:
    """The 32-byte key of a file holding 64 hex characters (surrounding whitespace allowed)."""
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


def key_file(mission_key_file: Path | None) -> Path | None:
    """The key file: the mission's `run.signing_key_file`, else $SWARM_GCS_SIGNING_KEY_FILE, else None."""
    if mission_key_file is not None:
        return mission_key_file
    from_env = os.environ.get(KEY_ENV, "").strip()
    return Path(from_env).expanduser() if from_env else None


def timestamp_now() -> int:
    """Signing timestamp of the wall clock now (10 us units since 2015-01-01)."""
    return int((max(time.time(), SIGNING_EPOCH_UNIX_S) - SIGNING_EPOCH_UNIX_S) * 100_000)


def sign_outgoing(mav: mavlink2.MAVLink, key: bytes, link_id: int = 0) -> None:
    """Make every packet packed with `mav` signed with `key` on link `link_id` (0..255)."""
    mav.signing.secret_key = key
    mav.signing.link_id = link_id
    mav.signing.timestamp = timestamp_now()
    mav.signing.sign_outgoing = True
