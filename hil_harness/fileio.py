"""Writing output files the way a command-line tool should: atomically (a temp file beside the
target, renamed over it) and readable as the user's umask allows (0644 under the usual 022), not
the 0600 that :func:`tempfile.mkstemp` gives every temp file; and one writer at a time per output
folder (:class:`FolderLock`)."""
from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

__all__ = ["file_mode", "temp_beside", "write_text_atomic", "FolderLock", "LOCK_NAME", "check_output",
           "OutputError"]

#: the lock file a command holds in its output folder while it writes there
LOCK_NAME = ".uvisi.lock"


def file_mode() -> int:
    """The permission bits a new file gets under this process's umask (``0o666 & ~umask``)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


class OutputError(ValueError):
    """An output path that cannot be written: one line naming the user's path and why."""


def _why(exc: OSError) -> str:
    return exc.strerror or type(exc).__name__


def temp_beside(path, prefix: str | None = None, suffix: str = ".tmp") -> tuple[int, str]:
    """``(fd, name)`` of a new temp file in ``path``'s folder (created if missing) with the mode of
    :func:`file_mode`, to be renamed over ``path`` with :func:`os.replace` once written.
    :class:`OutputError` names ``path`` (not the temp file) when the folder cannot be made or
    written."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=prefix if prefix is not None else
                                   "." + path.name + ".", suffix=suffix)
    except (FileExistsError, NotADirectoryError) as exc:
        raise OutputError(f"{path}: cannot write it: {exc.filename or path.parent} is not a "
                          f"folder") from None
    except OSError as exc:
        raise OutputError(f"{path}: cannot write in {path.parent} ({_why(exc)})") from None
    os.fchmod(fd, file_mode())
    return fd, tmp


def write_text_atomic(path, text: str, durable: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` through a temp file beside it (:func:`temp_beside`; its
    folder made if missing), renamed over ``path`` once complete: a reader, or a kill at any
    moment, finds the old file or the new one, never a part. ``durable``: also flush the temp
    file to the disk before the rename (``fsync``), so that a power cut after it cannot leave an
    empty file. Returns ``path``; the temp file is removed on any failure."""
    path = Path(path)
    fd, tmp = temp_beside(path)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            if durable:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def check_output(path, kind: str = "file", option: str = "") -> None:
    """Refuse, before any work, an output that could not be written: ``kind`` "file" (its folder,
    created by the writer if missing) or "folder" (the folder itself). The deepest existing folder
    on the way must be a folder and take a new file (probed with a temp file, removed at once: an
    answer that holds for root and read-only file systems alike). :class:`OutputError` names the
    option and the user's path."""
    p = Path(path)
    name = f"{option} {p}" if option else str(p)
    if kind == "file" and p.is_dir():
        raise OutputError(f"{name}: is a folder, not a file")
    if kind == "folder" and p.exists() and not p.is_dir():
        raise OutputError(f"{name}: is a file, not a folder")
    base = p.parent if kind == "file" else p
    base = base.absolute()
    while not base.exists():
        base = base.parent
    if not base.is_dir():
        raise OutputError(f"{name}: cannot be made: {base} is a file, not a folder")
    try:
        fd, tmp = tempfile.mkstemp(dir=base, prefix=".uvisi-probe.")
    except OSError as exc:
        raise OutputError(f"{name}: cannot write in {base} ({_why(exc)})") from None
    os.close(fd)
    os.unlink(tmp)


class FolderLock:
    """An exclusive ``fcntl.flock`` on ``<folder>/.uvisi.lock`` (the file holds the holder's pid),
    held while ``command`` (``"uvisi event"``, ``"uvisi campaign"``) writes to the folder; the
    kernel releases it when the process ends, however it ends.

    :meth:`acquire` creates the folder; ``ValueError`` (one line naming the folder) when it is a
    file, cannot be created or written, or another process holds the lock."""

    def __init__(self, path, command: str):
        self.path, self.command = Path(path), command
        self._fd = None

    def acquire(self) -> "FolderLock":
        p = self.path
        if p.exists() and not p.is_dir():
            raise ValueError(f"{p}: exists and is a file, not an output folder")
        try:
            p.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"{p}: cannot create the output folder ({exc.strerror})") from None
        try:
            fd = os.open(p / LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise ValueError(f"{p}: cannot write to the output folder ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise ValueError(f"{p}: another {self.command} (pid {holder}) is writing to this "
                             f"folder") from None
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._fd = fd
        return self

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
        return False


def read_toml(path, what: str) -> dict:
    """The table of the TOML file ``path``; one line naming the file otherwise:
    ``FileNotFoundError`` "<path>: no such <what>" (a folder too), ``ValueError`` for bad TOML."""
    import tomllib
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such {what}")
    try:
        return tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{p}: not valid TOML: {exc}") from None
