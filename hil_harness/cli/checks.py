"""Checks the commands share: a recording's checksums before it is read (``--ignore-checksums``)
and a request's size before work starts (``--no-size-check``).

Every refusal is one line (``uvisi <command>: error: ...``) and exit status 2, through the
``ValueError`` the command raises (:func:`hil_harness.cli.main`).
"""
from __future__ import annotations

import sys

IGNORE_HELP = ("read the recording even where stored rows do not match their checksums (one "
               "line says what was ignored); by default a mismatch is refused naming the dataset "
               "and rows")
NO_SIZE_CHECK_HELP = ("lift the stated caps on the request's size (frames, runs); the check "
                      "against free memory and disk still applies")


def add_ignore_checksums(p) -> None:
    """``--ignore-checksums`` on a command that reads a recording."""
    p.add_argument("--ignore-checksums", action="store_true", help=IGNORE_HELP)


def add_no_size_check(p) -> None:
    """``--no-size-check`` on a command that renders, records or runs campaigns."""
    p.add_argument("--no-size-check", action="store_true", help=NO_SIZE_CHECK_HELP)


def verify_recording(path, args, command: str) -> dict:
    """Verify every stored row of the recording ``path`` before a command reads it
    (:func:`hil_harness.event.recording.open_checked`: the one checksum path); the note of
    ``--ignore-checksums`` (or of a recording without checksums) goes to stderr as one line.
    Returns what was verified (``{"frames", "rows", "damaged"}``)."""
    from hil_harness.event.recording import open_checked
    rec, verified, note = open_checked(path, bool(getattr(args, "ignore_checksums", False)))
    rec.close()
    if note:
        print(f"uvisi {command}: {note}", file=sys.stderr)
    return verified
