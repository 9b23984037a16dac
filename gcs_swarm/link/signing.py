"""MAVLink 2 message signing of the ground station's outgoing packets (pymavlink's MAVLinkSigning).

The key file (swarm_common.signing_keys) is named by the mission (`run.signing_key_file`) or the environment
variable SWARM_GCS_SIGNING_KEY_FILE. The key is never printed nor logged: the tlog holds signed packets, whose
signature is a truncated SHA-256, never the key.
"""

from __future__ import annotations

import os
from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from swarm_common.signing_keys import SigningKeyError, read_key, timestamp_now

__all__ = ["KEY_ENV", "SigningKeyError", "key_file", "read_key", "sign_outgoing"]

KEY_ENV = "SWARM_GCS_SIGNING_KEY_FILE"


def key_file(mission_key_file: Path | None) -> Path | None:
    """The key file: the mission's `run.signing_key_file`, else $SWARM_GCS_SIGNING_KEY_FILE, else None."""
    if mission_key_file is not None:
        return mission_key_file
    from_env = os.environ.get(KEY_ENV, "").strip()
    return Path(from_env).expanduser() if from_env else None


def sign_outgoing(mav: mavlink2.MAVLink, key: bytes, link_id: int = 0) -> None:
    """Make every packet packed with `mav` signed with `key` on link `link_id` (0..255)."""
    mav.signing.secret_key = key
    mav.signing.link_id = link_id
    mav.signing.timestamp = timestamp_now()
    mav.signing.sign_outgoing = True
