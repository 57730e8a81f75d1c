"""An event's output folder: one writer at a time (an OS lock), and no older run mistaken for this one.

:class:`RunFolder` is held for the whole of an event: it takes an exclusive ``fcntl.flock`` on
``<folder>/.uvisi.lock`` (released by the kernel when the process ends, however it ends), then
refuses a folder holding another run's products unless told to replace them, in which case it
removes them first, so that a stale ``recording.partial.h5`` or ``summary.json`` never sits beside
the new run's.
"""
from __future__ import annotations

import fcntl
import os
from pathlib import Path

from hil_harness.fileio import LOCK_NAME, FolderLock

__all__ = ["RunFolder", "RUN_PRODUCTS", "LOCK_NAME"]

#: the files ``uvisi event`` writes into its folder (and so removes when replacing a run)
RUN_PRODUCTS = ("recording.h5", "recording.partial.h5", "recording.h5.tmp", "summary.json",
                "summary.json.tmp", "stages.png", "centroid_track.png", "track_error.png",
                "gates.png", "budget.png", "event.gif", "view.html", "view.html.tmp")


class RunFolder:
    """The output folder of one event, locked while the event runs.

    Parameters
    ----------
    path : str or Path
        The folder (created with its parents). A file of that name is an error.
    replace : bool
        Remove another run's products instead of refusing the folder (``--force``, or the default
        folder, which is simply replaced).

    ``ValueError`` (one line naming the folder) when the folder is a file, holds another run and
    ``replace`` is False, or another process holds the lock.
    """

    def __init__(self, path, replace: bool = False):
        self.path = Path(path)
        self.replace = bool(replace)
        self._lock = None

    def acquire(self) -> "RunFolder":
        self._lock = FolderLock(self.path, "uvisi event").acquire()
        try:
            self._clear_old_run()
        except BaseException:
            self.release()
            raise
        return self

    def _clear_old_run(self) -> None:
        old = [n for n in RUN_PRODUCTS if (self.path / n).exists()]
        if old and not self.replace:
            raise ValueError(f"{self.path}: holds another run ({', '.join(old)}); use --force to "
                             f"replace it, or another --out")
        for n in old:
            try:
                (self.path / n).unlink()
            except OSError as exc:
                raise ValueError(f"{self.path / n}: cannot remove the old run's file "
                                 f"({exc.strerror})") from None

    def release(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
        return False


def writer_pid(path) -> str | None:
    """The pid of the ``uvisi event`` writing to the folder ``path`` now (it holds the folder's
    lock), None when none does (no lock file, or its lock free). The lock file is not created."""
    try:
        fd = os.open(Path(path) / LOCK_NAME, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return os.read(fd, 32).decode(errors="replace").strip() or "?"
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
