"""Writing output files the way a command-line tool should: atomically (a temp file beside the
target, renamed over it) and readable as the user's umask allows (0644 under the usual 022), not
the 0600 that :func:`tempfile.mkstemp` gives every temp file."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["file_mode", "temp_beside"]


def file_mode() -> int:
    """The permission bits a new file gets under this process's umask (``0o666 & ~umask``)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def temp_beside(path, prefix: str | None = None, suffix: str = ".tmp") -> tuple[int, str]:
    """``(fd, name)`` of a new temp file in ``path``'s folder (created if missing) with the mode of
    :func:`file_mode`, to be renamed over ``path`` with :func:`os.replace` once written."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=prefix if prefix is not None else
                               "." + path.name + ".", suffix=suffix)
    os.fchmod(fd, file_mode())
    return fd, tmp
