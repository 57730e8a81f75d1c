"""Opening an event recording (HDF5) read-only for the ground tools and the harness alike: a
complete one directly, a partial one (``recording.partial.h5``, left by an interrupted event and
still flagged open-for-writing) through HDF5's SWMR read mode, and anything else as one error."""
from __future__ import annotations

import os
from pathlib import Path

import h5py

__all__ = ["open_h5", "write_flags", "clear_write_flags", "lookup3"]


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


#: where HDF5 looks for a superblock: byte 0, then 512, 1024, 2048, ... (after a user block)
_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: superblock versions 2 and 3: the file consistency flags byte and the fields after it
_FLAGS_AT = 11
_M32 = 0xFFFFFFFF


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _M32


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle`` of ``data`` (the checksum HDF5 stores after a version 2
    or 3 superblock and its other metadata, ``H5_checksum_lookup3``): uint32."""
    n = len(data)
    a = b = c = (0xDEADBEEF + n + initval) & _M32
    i = 0
    while n - i > 12:
        x, y, z = (int.from_bytes(data[j:j + 4], "little") for j in (i, i + 4, i + 8))
        a, b, c = (a + x) & _M32, (b + y) & _M32, (c + z) & _M32
        a = (a - c) & _M32; a ^= _rot(c, 4); c = (c + b) & _M32      # noqa: E702 - mix()
        b = (b - a) & _M32; b ^= _rot(a, 6); a = (a + c) & _M32      # noqa: E702
        c = (c - b) & _M32; c ^= _rot(b, 8); b = (b + a) & _M32      # noqa: E702
        a = (a - c) & _M32; a ^= _rot(c, 16); c = (c + b) & _M32     # noqa: E702
        b = (b - a) & _M32; b ^= _rot(a, 19); a = (a + c) & _M32     # noqa: E702
        c = (c - b) & _M32; c ^= _rot(b, 4); b = (b + a) & _M32      # noqa: E702
        i += 12
    rest = data[i:]
    if not rest:
        return c
    rest = rest + bytes(12 - len(rest))
    x, y, z = (int.from_bytes(rest[j:j + 4], "little") for j in (0, 4, 8))
    a, b, c = (a + x) & _M32, (b + y) & _M32, (c + z) & _M32
    c ^= b; c = (c - _rot(b, 14)) & _M32                              # noqa: E702 - final()
    a ^= c; a = (a - _rot(c, 11)) & _M32                              # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & _M32                              # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & _M32                              # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & _M32                               # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & _M32                              # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & _M32                              # noqa: E702
    return c


def _superblock(fh, path) -> tuple[int, bytes]:
    """``(offset, bytes)`` of the version 2 or 3 superblock of an open file (its checksum
    included); ValueError naming ``path`` for anything else."""
    size = fh.seek(0, 2)
    at = 0
    while at + 8 <= size:
        fh.seek(at)
        if fh.read(8) == _SIGNATURE:
            head = _SIGNATURE + fh.read(4)
            if len(head) < 12 or head[8] not in (2, 3):
                version = head[8] if len(head) > 8 else "?"
                raise ValueError(f"{path}: HDF5 superblock version {version} has no "
                                 f"open-for-write flags (a recording's is 3)")
            n = 12 + 4 * head[9] + 4              # four addresses, then the checksum
            fh.seek(at)
            block = fh.read(n)
            if len(block) < n or lookup3(block[:-4]) != int.from_bytes(block[-4:], "little"):
                raise ValueError(f"{path}: the HDF5 superblock is damaged (checksum mismatch)")
            return at, block
        at = 512 if at == 0 else 2 * at
    raise ValueError(f"{path}: not an HDF5 file (no superblock signature)")


def write_flags(path) -> int:
    """The file consistency flags of the HDF5 file at ``path`` (superblock version 2 or 3):
    0 for a file closed properly; bit 0 (open for writing) and bit 2 (open for SWMR writing) stay
    set in a file whose writer was killed, and HDF5 before 2.0 and its tools then refuse to open it
    (h5py opens it with ``swmr=True``)."""
    path = Path(path)
    with open(path, "rb") as fh:
        return _superblock(fh, path)[1][_FLAGS_AT]


def clear_write_flags(path) -> int:
    """Clear the open-for-write flags a killed writer left in the HDF5 file at ``path``, as
    ``h5clear -s`` does: the superblock's consistency-flags byte set to 0 and its lookup3
    checksum rewritten; nothing else changes. Returns the flags found (0: nothing done).

    Only for a file no process writes any more (a writer still running would be corrupted).
    h5py offers no call for it: HDF5 opens such a file read-only (SWMR) only, and
    ``h5clear`` sets a library-private property."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a recording")
    with open(path, "r+b") as fh:
        at, block = _superblock(fh, path)
        flags = block[_FLAGS_AT]
        if flags:
            new = bytearray(block)
            new[_FLAGS_AT] = 0
            new[-4:] = lookup3(bytes(new[:-4])).to_bytes(4, "little")
            fh.seek(at)
            fh.write(new)
            fh.flush()
            os.fsync(fh.fileno())
    return flags
