"""Tracebacks kept in the run folder: an unexpected exception (a bug, not a user error) is appended with its
full traceback to `<run folder>/errors.log`, and the caller tells the user one line naming that file.

A user error (a bad mission, an unreachable vehicle, a refused command) is never logged here: it gets one
clear sentence and no traceback.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

ERRORS_FILE = "errors.log"
FORMAT = logging.Formatter("%(asctime)s %(levelname)s %(processName)s/%(threadName)s: %(message)s")

logger = logging.getLogger(__name__)


def log_exception(run_dir: Path | str, what: str) -> Path | None:
    """Append `what` and the traceback of the exception being handled (call it inside `except`) to
    run_dir/errors.log, creating the folder if needed; return that file, or None when it cannot be written
    (then the record goes to this module's logger instead, so the traceback is still not lost).

    Each call opens, appends and closes the file: nothing to set up, nothing held open between failures.
    """
    path = Path(run_dir) / ERRORS_FILE
    record = logger.makeRecord(logger.name, logging.ERROR, __file__, 0, what, (), sys.exc_info())
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handler = logging.FileHandler(path, encoding="utf-8")
    except OSError:
        logger.handle(record)
        return None
    handler.setFormatter(FORMAT)
    try:
        handler.handle(record)
    finally:
        handler.close()
    return path


def traceback_note(path: Path | None) -> str:
    """The words that send the user to the traceback: " (traceback in PATH)", or "" when none was written."""
    return "" if path is None else f" (traceback in {path})"
