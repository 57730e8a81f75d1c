"""What the ``uvisi`` command line says and how loudly: ``--quiet`` / ``--verbose`` set the level
once, and every command asks here whether to print notes and draw progress bars.

Progress bars (tqdm, on stderr) are drawn when stderr is a terminal and the level is not quiet;
``UVISI_PROGRESS=1`` forces them on (tests, logs), ``UVISI_PROGRESS=0`` off.
"""
from __future__ import annotations

import os
import sys

__all__ = ["QUIET", "NORMAL", "VERBOSE", "set_level", "level", "progress_enabled", "note", "debug"]

QUIET, NORMAL, VERBOSE = 0, 1, 2
_state = {"level": NORMAL}


def set_level(value: int) -> None:
    """Set the verbosity (:data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`)."""
    if value not in (QUIET, NORMAL, VERBOSE):
        raise ValueError(f"verbosity {value!r}: expected 0, 1 or 2")
    _state["level"] = value


def level() -> int:
    return _state["level"]


def progress_enabled(stream=None) -> bool:
    """Whether to draw progress bars on ``stream`` (default stderr)."""
    forced = os.environ.get("UVISI_PROGRESS")
    if forced in ("0", "1"):
        return forced == "1"
    if _state["level"] == QUIET:
        return False
    stream = stream if stream is not None else sys.stderr
    return bool(getattr(stream, "isatty", lambda: False)())


def note(message: str) -> None:
    """A one-line note on stderr (not shown with ``--quiet``)."""
    if _state["level"] >= NORMAL:
        print(message, file=sys.stderr, flush=True)


def debug(message: str) -> None:
    """A detail on stderr, shown only with ``--verbose``."""
    if _state["level"] >= VERBOSE:
        print(message, file=sys.stderr, flush=True)
