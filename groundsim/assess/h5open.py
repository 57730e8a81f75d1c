"""Opening an event recording (HDF5) read-only for the ground tools and the harness alike: a
complete one directly, a partial one (``recording.partial.h5``, left by an interrupted event and
still flagged open-for-writing) through HDF5's SWMR read mode, and anything else as one error."""
from __future__ import annotations

from pathlib import Path

import h5py

__all__ = ["open_h5"]


def open_h5(path) -> h5py.File:
    """The recording at ``path``, read-only.

    ``FileNotFoundError`` when it does not exist; ``ValueError`` naming the file when it is a folder,
    not HDF5, or cut short (a truncated file is refused at once: opened in SWMR mode it would retry
    every metadata read for minutes; a partial recording is never truncated, SWMR keeps its end)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a recording")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        first = str(exc)
    if "truncated file" in first or "signature" in first:
        raise ValueError(f"{path}: not a readable HDF5 recording ({first.splitlines()[0]})")
    try:
        return h5py.File(path, "r", swmr=True)
    except OSError:
        raise ValueError(f"{path}: not a readable HDF5 recording ({first})") from None
