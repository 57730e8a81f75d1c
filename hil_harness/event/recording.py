"""Event recordings: one HDF5 file per event, written in blocks that survive a kill at any moment.

Layout (every table is one compound dataset, one row per record, growing along axis 0)::

    /                   attrs: format, complete (bool), flush_every, then the caller's (scenario, ...)
    /tables/<name>      compound datasets (per-frame tables, candidates, ledger, ...)
    /arrays/<name>      stacked arrays (frames uint16[N, 244, 256], bus words, stage images)
    /host/<name>        host wall-clock timings: kept apart, since they differ run to run
    /checksums          (dataset, row, adler32): the Adler-32 of every stored row of every dataset
                        above, ``dataset`` being that dataset's attribute ``checksum_id``

Datasets written with ``per_frame=True`` carry the attribute ``per_frame`` and hold one row per
frame; the frames a recording holds are the rows every one of them has with its checksum.

Life cycle. The file is created as ``<stem>.partial<suffix>`` (``recording.partial.h5``) with
``complete = False`` and switched at once to HDF5's single-writer/multiple-reader mode (SWMR), whose
writes keep the file consistent on disk at every instant. Rows are buffered in memory and written as
one block every ``flush_every`` frames (:meth:`Recorder.end_frame`): no HDF5 call per frame (rows
handed over with ``borrow=True``, the frames, are kept by reference instead of copied). A kill
at any moment therefore leaves a readable ``recording.partial.h5`` holding every frame up to the last
written block. :meth:`Recorder.close` writes the rest, sets ``complete = True`` and renames the file to
its final name; :meth:`Recorder.keep` (an interrupt, a failure) writes the whole frames buffered and
leaves the file partial. Both first let a writer that holds frames back append them
(:meth:`Recorder.before_close`). A file whose writer was killed is still flagged open-for-writing:
h5py opens it with ``swmr=True`` (:func:`open_h5` does); HDF5 tools before 2.0 once the flags are
cleared (:func:`groundsim.assess.h5open.clear_write_flags`, ``uvisi replay --clear-flags``).

Format: HDF5 1.10 (:data:`LIBVER`), read by HDF5 1.10 and later. Reading: :class:`Recording`
checks every row it returns against its checksum (:meth:`Recording.check_rows`);
:func:`open_checked` verifies a whole recording first, for the commands.
"""
from __future__ import annotations

import json
import math
import os
import signal
from contextlib import contextmanager
from itertools import accumulate
from pathlib import Path

import h5py
import numpy as np

from groundsim.assess.h5open import open_h5

from .appendable import AppendableDataset, write_attr
from .checksum import ATTRS_DIGEST, adler32_rows, attrs_digest

FORMAT = "uvisi-recording/3"
#: formats this module reads: version 1 (before blocks and checksums) cannot be verified, version 2
#: (rows checksummed, root attributes not sealed) only in part; both read with a one-line "not
#: verified" (replay: a failed verdict unless --accept-unverified)
READ_FORMATS = ("uvisi-recording/1", "uvisi-recording/2", FORMAT)
#: rows read per step by :meth:`Recording.verify`
VERIFY_BLOCK_ROWS = 64
#: a recording's rows per inner chunk of a table (and of small arrays)
TABLE_CHUNK_ROWS = 256
#: arrays whose rows are at least this many bytes get one row per chunk (frames, stage images)
ROW_CHUNK_BYTES = 16384
#: the most bytes a chunk of one block of small per-frame rows holds
CHUNK_MAX_BYTES = 1 << 20
#: /checksums: one record per stored row of every dataset (``dataset`` is its ``checksum_id``)
CHECKSUM_DTYPE = np.dtype([("dataset", np.uint16), ("row", np.int64), ("adler32", np.uint32)])
_DEFERRED_SIGNALS = {signal.SIGINT, signal.SIGTERM}
#: HDF5 file-format bounds of a recording: the 1.10 format, the oldest SWMR writes (superblock
#: version 3) and the newest every HDF5 >= 1.10 reads; "latest" under HDF5 2.0 writes datatype
#: messages HDF5 1.10 - 1.14 cannot read (docs/formats.md lists the versions tested)
LIBVER = ("v110", "v110")


@contextmanager
def signals_deferred():
    """SIGINT and SIGTERM wait (are blocked) until the block exits: what runs inside is not cut
    short by an interrupt (its handler runs, and raises, on exit)."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _DEFERRED_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def checksum_records(written: list) -> np.ndarray:
    """The ``/checksums`` records of one block: ``written`` lists ``(checksum id, first row,
    checksums)`` per dataset (checksums: uint32 or ints, one per row); returns CHECKSUM_DTYPE[sum
    of the rows], dataset by dataset in order, rows ascending (built column by column: per-dataset
    structured arrays and their concatenation cost ~10 us a dataset)."""
    counts = [len(c) for _, _, c in written]
    total = sum(counts)
    out = np.empty(total, CHECKSUM_DTYPE)
    out["dataset"] = np.repeat([cid for cid, _, _ in written], counts)
    # a record's row: its index plus its dataset's first row less the dataset's first record
    # (the offsets in Python: numpy's cumulative sum, run cold once a block, took ~45 us)
    offsets = [n0 - i for (_, n0, _), i in zip(written, accumulate(counts, initial=0))]
    out["row"] = np.arange(total) + np.repeat(offsets, counts)
    out["adler32"] = np.concatenate([np.asarray(c, np.uint32) for _, _, c in written])
    return out


class RecordingDamaged(ValueError):
    """A recording whose stored data does not match its checksums, or cannot be read."""


def partial_path(path) -> Path:
    """The name a recording has while it is written: ``x/recording.h5`` -> ``x/recording.partial.h5``."""
    p = Path(path)
    return p.with_name(p.stem + ".partial" + p.suffix)


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def _attr_value(v):
    return json.dumps(v, default=_json_default) if isinstance(v, (dict, list, tuple)) else v


def row_dtype(row: dict) -> np.dtype:
    """The compound dtype of one row (strings fixed at 64 bytes, so the layout stays put)."""
    fields = []
    for k, v in row.items():
        a = np.asarray(v)
        if a.dtype.kind in "UOS":
            fields.append((k, "S64"))
        elif a.ndim == 0:
            fields.append((k, a.dtype))
        else:
            fields.append((k, a.dtype, a.shape))
    return np.dtype(fields)


def _encoded(v):
    """A string field's value as stored: UTF-8 bytes (cut to 64 bytes by the S64 field)."""
    return v.encode() if isinstance(v, str) else v


def _row_bytes(rows: np.ndarray) -> np.ndarray:
    """The bytes of each row of ``rows`` (at least one row; a view, a copy if ``rows`` is not
    C-contiguous): uint8[len(rows), row size]."""
    return np.ascontiguousarray(rows).view(np.uint8).reshape(len(rows), -1)


class _Buffer:
    """One dataset's rows waiting for the next block: a preallocated array (a structured one for
    tables) whose rows ``[0, n)`` are used, grown by doubling, filled in place.

    Attributes
    ----------
    block : ndarray, shape (capacity, ...) or None before the first row
    bytes : uint8[capacity, row size]
        :attr:`block` seen as bytes (rows of the same dtype are copied in through it).
    keys : tuple of str or None
        Dict rows: their field names, in order (a row with other names is refused).
    strings : tuple of int
        Dict rows: positions of the string (S64) fields, encoded to UTF-8 before they are stored.
    held : list of ndarray or None
        Borrowed rows (:meth:`Recorder.append_array` with ``borrow=True``): the caller's arrays,
        kept by reference; ``sums`` their Adler-32, taken when they were appended.
    """

    def __init__(self, per_frame: bool):
        self.per_frame = per_frame
        self.block = self.bytes = None
        self.keys = None
        self.strings: tuple = ()
        self.n = 0
        self.held = None
        self.sums: list = []
        self.row_layout = None        # (dtype, shape) of a borrowed row

    def _room(self, rows: int) -> None:
        need = self.n + rows
        if need > len(self.block):
            old = self.bytes
            self.start(self.block.dtype, self.block.shape[1:], max(need, 2 * len(self.block)))
            self.bytes[:self.n] = old[:self.n]

    def start(self, dtype: np.dtype, row_shape: tuple, rows_hint: int) -> None:
        self.block = np.empty((max(rows_hint, 1),) + tuple(row_shape), dtype)
        self.bytes = _row_bytes(self.block)

    def add_row(self, row: dict) -> None:
        """Store a dict row (its keys already checked against :attr:`keys`)."""
        vals = tuple(row.values())
        if self.strings:
            vals = list(vals)
            for i in self.strings:
                vals[i] = _encoded(vals[i])
            vals = tuple(vals)
        self._room(1)
        self.block[self.n] = vals
        self.n += 1

    def add_values(self, values: tuple) -> None:
        """Store a row given as a tuple in :attr:`block`'s field order."""
        self._room(1)
        self.block[self.n] = values
        self.n += 1

    def add_rows(self, rows: np.ndarray) -> None:
        """Store a block of rows of :attr:`block`'s row shape (and dtype, else cast)."""
        m = len(rows)
        if not m:
            return
        self._room(m)
        if rows.dtype is self.block.dtype or rows.dtype == self.block.dtype:
            # as bytes: numpy copies a structured array field by field (~3 us for 23 rows)
            self.bytes[self.n:self.n + m] = _row_bytes(rows)
        else:
            self.block[self.n:self.n + m] = rows
        self.n += m

    def take(self) -> np.ndarray | list | None:
        """The rows buffered (a view, valid until the next append; borrowed rows: the list of
        arrays), and the buffer emptied."""
        if not self.n:
            return None
        if self.held is not None:
            out, self.held, self.n = self.held[:self.n], [], 0
            return out
        out, self.n = self.block[:self.n], 0
        return out


class Recorder:
    """Append-only writer of one event recording (see the module docstring for the life cycle).

    Parameters
    ----------
    path : str or Path
        Final file name (``.h5``). Parent directories are created. Written as
        :func:`partial_path` until :meth:`close`.
    attrs : dict
        Root attributes (strings, numbers; dicts and lists are stored as JSON).
    flush_every : int
        Frames per block: rows are written every ``flush_every`` calls of :meth:`end_frame`
        (20 frames = 10 s of a 2 Hz event: the most a kill can lose).
    compression : str, optional
        HDF5 filter for the arrays of two or more dimensions (None by default: gzip costs ~3.7 ms a
        frame; "lzf" is cheaper).
    """

    def __init__(self, path, attrs: dict | None = None, flush_every: int = 20,
                 compression: str | None = None):
        if int(flush_every) < 1:
            raise ValueError(f"flush_every={flush_every!r}: must be >= 1")
        self.path = Path(path)
        self.partial = partial_path(self.path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.flush_every = int(flush_every)
        self.compression = compression
        # chunk cache off: a block's chunks are written once and never read back by the writer, so
        # the cache would only hold memory (CPU per block measured the same with and without)
        self._f = h5py.File(self.partial, "w", libver=LIBVER, rdcc_nbytes=0)
        self._f.attrs["format"] = FORMAT
        self._f.attrs["complete"] = False
        self._f.attrs["flush_every"] = self.flush_every
        for k, v in (attrs or {}).items():
            self._f.attrs[k] = _attr_value(v)
        self._seal()
        self._f.swmr_mode = True
        # the compiled checksum loads from numba's cache now (3-7 ms), with the file's opening,
        # not in the middle of the event's first block
        adler32_rows(np.zeros((1, 1), np.uint8))
        self._bufs: dict[str, _Buffer] = {}
        self._ds: dict[str, list] = {}        # key -> [AppendableDataset, checksum id]
        self._sums = None                     # the /checksums dataset
        self._before_close: list = []        # callables run first by close() and keep()
        self.frames = 0               # end_frame() calls
        self.frames_written = 0       # frames on disk
        self._closed = False

    # ---------------------------------------------------------------- appending (memory only)
    def _buf(self, key: str, per_frame: bool) -> _Buffer:
        b = self._bufs.get(key)
        if b is None:
            b = self._bufs[key] = _Buffer(per_frame)
        return b

    def _dict_row(self, key: str, row: dict, per_frame: bool, what: str) -> None:
        b = self._buf(key, per_frame)
        if b.keys is None:
            dtype = row_dtype(row)
            b.start(dtype, (), self.flush_every)
            b.keys = tuple(row)
            b.strings = tuple(i for i, name in enumerate(dtype.names) if dtype[name].kind == "S")
        elif tuple(row) != b.keys:
            raise ValueError(f"{what}: row layout changed from fields {list(b.keys)} to "
                             f"{list(row)}")
        b.add_row(row)

    def append(self, table: str, row: dict, per_frame: bool = False) -> None:
        """Append one row (dict of scalars / fixed-shape arrays / strings <= 64 bytes) to
        ``/tables/<table>``; every row of a table has the same fields. The row is copied into the
        block buffer at once."""
        self._dict_row(f"tables/{table}", row, per_frame, f"table {table!r}")

    def append_values(self, table: str, values: tuple, dtype: np.dtype,
                      per_frame: bool = False) -> None:
        """Append one row given as a tuple of values in the fields' order of ``dtype`` (the same
        dtype every call; strings as bytes): what :meth:`append` stores, without the dict and
        the numpy scalars (~2 us a row against ~10 us for a table of 25 fields)."""
        self._values(f"tables/{table}", values, dtype, per_frame, f"table {table!r}")

    def _values(self, key: str, values: tuple, dtype: np.dtype, per_frame: bool, what: str) -> None:
        b = self._buf(key, per_frame)
        if b.block is None:
            b.start(dtype, (), self.flush_every)
            b.keys = dtype.names
        elif dtype is not b.block.dtype and dtype != b.block.dtype:
            raise ValueError(f"{what}: row layout changed from {b.block.dtype} to {dtype}")
        b.add_values(values)

    def append_rows(self, table: str, rows: np.ndarray, per_frame: bool = False) -> None:
        """Append a structured array of rows to ``/tables/<table>`` (same dtype every call);
        the rows are copied into the block buffer at once."""
        self._rows(f"tables/{table}", rows, per_frame, f"table {table!r}")

    def _rows(self, key: str, rows: np.ndarray, per_frame: bool, what: str) -> None:
        rows = np.asarray(rows)
        if rows.dtype.names is None:
            raise ValueError(f"{what}: rows must be a structured array")
        b = self._buf(key, per_frame)
        if b.block is None:
            b.start(rows.dtype, (), 4 * self.flush_every)
            b.keys = rows.dtype.names
        elif rows.dtype is not b.block.dtype and rows.dtype != b.block.dtype:
            raise ValueError(f"{what}: row layout changed from {b.block.dtype} to {rows.dtype}")
        b.add_rows(rows.reshape(-1))

    def append_array(self, name: str, arr: np.ndarray, host: bool = False,
                     per_frame: bool = False, borrow: bool = False,
                     checksum: int | None = None) -> None:
        """Append one row (e.g. a frame) to the stacked dataset ``/arrays/<name>`` (or ``/host``);
        the array is copied into the block buffer.

        ``borrow=True`` (every call for that dataset): the caller hands a C-contiguous array over
        and never changes it again; it is kept by reference until its block is written, not
        copied (a frame is 125 kB). Its checksum is taken now, so a change made after all the
        same shows in :meth:`Recording.verify` as a damaged row. ``checksum``: that Adler-32
        (``adler32_rows(arr[None])[0]``) when the caller took it already (while the array was
        still in the CPU's caches, :class:`hil_harness.event.io.EventWriter`)."""
        arr = np.asarray(arr)
        key = f"{'host' if host else 'arrays'}/{name}"
        b = self._buf(key, per_frame)
        if borrow or b.held is not None:
            self._borrow(b, key, arr, borrow, checksum)
            return
        if b.block is None:
            b.start(arr.dtype, arr.shape, self.flush_every)
        elif b.block.shape[1:] != arr.shape:
            raise ValueError(f"array {name!r}: shape changed from {b.block.shape[1:]} to "
                             f"{arr.shape}")
        b.add_rows(arr[None])

    def append_arrays(self, name: str, rows: np.ndarray, per_frame: bool = False) -> None:
        """Append ``rows`` (``(m, *row shape)``) to the stacked dataset ``/arrays/<name>``: what
        ``m`` calls of :meth:`append_array` store, in one copy into the block buffer (a writer
        that builds a block's rows at once, :class:`hil_harness.event.io.EventWriter`)."""
        rows = np.asarray(rows)
        key = f"arrays/{name}"
        b = self._buf(key, per_frame)
        if b.held is not None:
            raise ValueError(f"{key}: borrow=False differs from the dataset's earlier rows")
        if b.block is None:
            b.start(rows.dtype, rows.shape[1:], self.flush_every)
        elif b.block.shape[1:] != rows.shape[1:]:
            raise ValueError(f"array {name!r}: shape changed from {b.block.shape[1:]} to "
                             f"{rows.shape[1:]}")
        b.add_rows(rows)

    def _borrow(self, b: _Buffer, key: str, arr: np.ndarray, borrow: bool,
                checksum: int | None = None) -> None:
        if not borrow or (b.block is not None and b.held is None):
            raise ValueError(f"{key}: borrow={borrow} differs from the dataset's earlier rows")
        if b.row_layout is None:
            b.row_layout, b.held = (arr.dtype, arr.shape), []
        elif (arr.dtype, arr.shape) != b.row_layout:
            raise ValueError(f"array {key!r}: layout changed from {b.row_layout[0]}"
                             f"{b.row_layout[1]} to {arr.dtype}{arr.shape}")
        if not arr.flags.c_contiguous:
            arr = np.ascontiguousarray(arr)
        b.held.append(arr)
        b.sums.append(adler32_rows(arr[None])[0] if checksum is None else checksum)
        b.n += 1

    def host(self, row: dict | tuple | np.ndarray, dtype: np.dtype | None = None) -> None:
        """Append host timings to ``/host/timing`` (excluded from determinism checks), one row per
        frame: a dict as :meth:`append` takes, a tuple of values in the fields' order of ``dtype``
        as :meth:`append_values` takes, or a structured array of rows (one per frame, the same
        dtype every call) as :meth:`append_rows` takes."""
        if isinstance(row, np.ndarray):
            self._rows("host/timing", row, True, "host timing")
        elif dtype is None:
            self._dict_row("host/timing", row, True, "host timing")
        else:
            self._values("host/timing", row, dtype, True, "host timing")

    def reserve(self, path: str, per_frame: bool = False) -> None:
        """Give the dataset ``path`` (``"tables/<name>"``, ``"arrays/<name>"``, ``"host/timing"``)
        its place now, before its first row: datasets are created, and numbered (their
        ``checksum_id``), in the order of their first rows, and a writer that appends a table's
        rows later, a block at once, reserves it where appending row by row would have met it
        (the recording's numbering then does not depend on how its rows were gathered)."""
        self._buf(path, per_frame)

    def before_close(self, fn) -> None:
        """Have :meth:`close` and :meth:`keep` call ``fn()`` first: a writer that holds frames back
        (:class:`hil_harness.event.io.EventWriter`) appends them and ends them then."""
        self._before_close.append(fn)

    def _run_before_close(self) -> None:
        for fn in self._before_close:
            fn()

    def set_attr(self, key: str, value) -> None:
        self._f.attrs[key] = _attr_value(value)
        self._seal()

    def _seal(self) -> None:
        """Write the digest of the root attributes (:func:`~.checksum.attrs_digest`) after any
        change to them."""
        self._f.attrs[ATTRS_DIGEST] = attrs_digest(dict(self._f.attrs))

    def end_frame(self) -> None:
        """One frame's rows are all appended; every ``flush_every`` frames they are written."""
        self.frames += 1
        if self.frames - self.frames_written >= self.flush_every:
            self.flush()

    # ---------------------------------------------------------------- writing (one block)
    def _dataset(self, key: str, dtype: np.dtype, row_shape: tuple, per_frame: bool) -> list:
        """``[AppendableDataset, checksum id]`` for ``key``, created on first use. Chunks: one row
        for rows of ``ROW_CHUNK_BYTES`` or more (frames, stage images: 2.5 MB chunks of 20
        frames measured no cheaper to write, and padded the last block); one block
        (``flush_every`` rows, at most ``CHUNK_MAX_BYTES``) for the other uncompressed per-frame
        datasets, so a block is one raw chunk write; up to ``TABLE_CHUNK_ROWS`` rows for the
        rest."""
        entry = self._ds.get(key)
        if entry is not None:
            return entry
        row_bytes = dtype.itemsize * math.prod(row_shape)
        comp = self.compression if len(row_shape) >= 2 else None
        if per_frame and comp is None and row_bytes < ROW_CHUNK_BYTES:
            rows = max(1, min(self.flush_every, CHUNK_MAX_BYTES // max(row_bytes, 1)))
        elif row_bytes >= ROW_CHUNK_BYTES:
            rows = 1
        else:
            rows = max(1, min(TABLE_CHUNK_ROWS, ROW_CHUNK_BYTES * 4 // max(row_bytes, 1)))
        out = AppendableDataset(self._f, key, dtype, row_shape, rows, comp)
        cid = len(self._ds)
        write_attr(out.ds, "per_frame", bool(per_frame))
        write_attr(out.ds, "checksum_id", cid)
        entry = self._ds[key] = [out, cid]
        return entry

    def _write(self, key: str, b: _Buffer) -> tuple | None:
        """Write one block of a dataset; returns ``(checksum id, first row, Adler-32 of each row
        written)`` (None: no rows)."""
        data = b.take()
        if data is None:
            return None
        borrowed = b.held is not None
        if borrowed:                  # the checksums leave with their rows, written or not
            sums, b.sums = b.sums[:len(data)], []
        dtype, shape = b.row_layout if borrowed else (data.dtype, data.shape[1:])
        out, cid = self._dataset(key, dtype, shape, b.per_frame)
        n = out.rows
        try:
            out.append_each(data) if borrowed else out.append(data)
        except ValueError as exc:
            raise ValueError(f"{key}: {exc}") from None
        return cid, n, sums if borrowed else adler32_rows(data)

    def flush(self) -> None:
        """Write every buffered row as one block: the data of every dataset, pushed to the file
        (``H5Fflush``), then the block's checksum records, pushed too. A row counts as recorded once
        its checksum is on disk, and by then every row of its block is. SIGINT and SIGTERM wait until
        the block is written."""
        with signals_deferred():
            written = []
            for key, b in self._bufs.items():
                w = self._write(key, b)
                if w is not None:
                    written.append(w)
            if written:
                self._f.flush()
                if self._sums is None:
                    self._sums = AppendableDataset(self._f, "checksums", CHECKSUM_DTYPE, (),
                                                   TABLE_CHUNK_ROWS * 4)
                self._sums.append(checksum_records(written))
            self._f.flush()
            self.frames_written = self.frames

    # ---------------------------------------------------------------- life cycle
    def close(self) -> Path:
        """Write what is buffered, mark the recording complete and move it to its final name."""
        if self._closed:
            return self.path
        self._run_before_close()
        self.flush()
        self._f.attrs["complete"] = True
        self._seal()
        self._f.close()
        os.replace(self.partial, self.path)
        self._closed = True
        return self.path

    def keep(self) -> Path:
        """Write the frames buffered and close, leaving the recording partial
        (``complete = False``, under :func:`partial_path`): what an interrupted event keeps."""
        if self._closed:
            return self.partial
        try:
            try:
                self._run_before_close()
            finally:                  # the whole frames are written even if a writer fails
                self._drop_unfinished_frame()
                self.flush()
        finally:
            self._f.close()
            self._closed = True
        return self.partial

    def _drop_unfinished_frame(self) -> None:
        """Forget per-frame rows appended after the last :meth:`end_frame` (a frame cut short)."""
        pending = self.frames - self.frames_written
        for b in self._bufs.values():
            if not b.per_frame:
                continue
            b.n = min(b.n, pending)
            if b.held is not None:
                del b.held[b.n:], b.sums[b.n:]

    def abort(self) -> None:
        """Discard the recording: the file is deleted (nothing left under either name)."""
        if self._closed:
            return
        try:
            self._f.close()
        finally:
            self.partial.unlink(missing_ok=True)
            self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.keep()
        return False


def _row_list(rows, more: int = 0) -> str:
    """``row 4`` / ``rows 4, 9, 12`` (``and N more``)."""
    words = ", ".join(str(int(r)) for r in rows)
    tail = f" and {more} more" if more else ""
    return f"row {words}" if len(rows) == 1 and not more else f"rows {words}{tail}"


class CheckedRows:
    """A recorded array read through its checksums: ``rec.array(name)`` of a
    :class:`Recording` that verifies. Indexing (``a[k]``, ``a[i:j]``, ``a[()]``, ``a[k, 20]``,
    an increasing index array) reads the whole rows selected along axis 0, checks each against its
    Adler-32 (:class:`RecordingDamaged` on a mismatch, one line naming the dataset and rows), then
    applies the rest of the index. ``shape``, ``dtype``, ``ndim``, ``chunks``, ``name``,
    ``attrs``, ``len()`` as the dataset's."""

    def __init__(self, rec: "Recording", key: str, ds: h5py.Dataset):
        self._rec, self.key, self.ds = rec, key, ds
        self.shape, self.dtype, self.attrs = ds.shape, ds.dtype, ds.attrs
        self.ndim, self.chunks, self.name = ds.ndim, ds.chunks, ds.name

    def __len__(self) -> int:
        return self.shape[0]

    def __array__(self, dtype=None, copy=None):
        a = self[()]
        return a if dtype is None else a.astype(dtype)

    def __getitem__(self, index):
        if index is Ellipsis or (isinstance(index, tuple) and not index):
            first, rest = slice(None), ()
        elif isinstance(index, tuple):
            first, rest = index[0], index[1:]
        else:
            first, rest = index, ()
        n = self.shape[0]
        if isinstance(first, (int, np.integer)):
            k = int(first) + (n if int(first) < 0 else 0)
            if not 0 <= k < n:
                raise IndexError(f"{self.key}: row {int(first)} out of range (0-{n - 1})")
            rows = self.ds[k:k + 1]
            self._rec.check_rows(self.key, k, rows)
            return rows[0][rest] if rest else rows[0]
        if isinstance(first, slice):
            i0, i1, step = first.indices(n)
            rows = self.ds[i0:max(i0, i1)] if step > 0 else self.ds[()]
            self._rec.check_rows(self.key, i0 if step > 0 else 0, rows)
            rows = rows[::step] if step > 0 else rows[first]
        else:
            ks = np.arange(n)[np.asarray(first)]
            if ks.ndim != 1 or np.any(np.diff(ks) <= 0):
                raise IndexError(f"{self.key}: rows must be increasing, not {first!r}")
            rows = self.ds[ks] if len(ks) else self.ds[0:0]
            for j, k in enumerate(ks):
                self._rec.check_rows(self.key, int(k), rows[j:j + 1])
        return rows[(slice(None),) + rest] if rest else rows


class Recording:
    """Read access to a recording: ``rec.attrs``, ``rec.table(name)``, ``rec.array(name)``,
    ``rec.complete``, ``rec.n_frames`` (frames held), ``rec.verify()``.

    Parameters
    ----------
    path : str or Path
    checksums : {"verify", "ignore"}
        "verify" (default): every row a table or array read returns is first checked against its
        Adler-32 (:meth:`check_rows`, the one checksum path of every reader);
        :class:`RecordingDamaged` names the dataset and rows that differ. "ignore": rows are read
        as stored (the ``--ignore-checksums`` of the commands).

    ``FileNotFoundError`` / ``ValueError`` (one line naming the file) when it is missing, a folder,
    not HDF5, cut short or an HDF5 file that is not a recording.
    """

    def __init__(self, path, checksums: str = "verify"):
        if checksums not in ("verify", "ignore"):
            raise ValueError(f"checksums={checksums!r}: 'verify' or 'ignore'")
        self.path = Path(path)
        self.checking = checksums == "verify"
        self._f = open_h5(self.path)
        try:
            fmt = self._f.attrs.get("format")
            if fmt not in READ_FORMATS:
                raise ValueError(f"{self.path}: not a uvisi recording (format attribute "
                                 f"{fmt!r} != {FORMAT!r})")
            self.complete = bool(self._f.attrs.get("complete", True))
            #: why the recording cannot be verified in full ("" for the current format)
            self.unverified = self._check_attrs(fmt)
            self._sums, self._sum_rows = self._checksums()
            self.n_frames = self._frames_held()
        except (OSError, KeyError, TypeError, AttributeError) as exc:
            self._f.close()
            why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise RecordingDamaged(f"{self.path}: not a readable uvisi recording ({why})") from None
        except BaseException:
            self._f.close()
            raise

    def _check_attrs(self, fmt) -> str:
        """The root attributes against their digest: the current format must carry a matching
        one (else :class:`RecordingDamaged`); an older format returns why it is not verified."""
        if fmt != FORMAT:
            return ("recorded without checksums" if fmt == "uvisi-recording/1" else
                    "root attributes not sealed") + f" (format {fmt!r}): not verified"
        want = self._f.attrs.get(ATTRS_DIGEST)
        if not self.checking:
            return ""
        if want is None or str(want) != attrs_digest(dict(self._f.attrs)):
            raise RecordingDamaged(f"{self.path}: root attributes: "
                                   + ("no digest (attrs_sha256) in a file that claims format "
                                      f"{FORMAT!r}" if want is None else
                                      "changed since they were written (attrs_sha256 does not "
                                      "match)"))
        return ""

    def _datasets(self) -> list[str]:
        out = []
        for top in ("tables", "arrays", "host"):
            if top in self._f:
                if not isinstance(self._f[top], h5py.Group):
                    raise RecordingDamaged(f"{self.path}: /{top} is not a group")
                out += [f"{top}/{k}" for k in self._f[top].keys()]
        return sorted(out)

    def _checksums(self) -> tuple:
        """``(sums, records)``: dataset -> the stored Adler-32 of its rows 0, 1, ... and dataset
        -> the row of ``/checksums`` holding each; ``(None, None)`` for a recording made before
        checksums."""
        if "checksums" not in self._f:
            return (None, None) if self._f.attrs.get("format") != FORMAT else ({}, {})
        try:
            recs = self._f["checksums"][()]
        except (OSError, ValueError) as exc:
            raise RecordingDamaged(f"{self.path}: checksums unreadable "
                                   f"({str(exc).splitlines()[0]})") from None
        if recs.dtype != CHECKSUM_DTYPE:
            raise RecordingDamaged(f"{self.path}: checksums: layout {recs.dtype} is not "
                                   f"{CHECKSUM_DTYPE}")
        ids = {}
        for key in self._datasets():
            cid = self._f[key].attrs.get("checksum_id")
            if cid is not None:
                ids[int(cid)] = key
        unknown = np.flatnonzero(~np.isin(recs["dataset"], list(ids)))
        if unknown.size:
            more = unknown.size - min(5, unknown.size)
            raise RecordingDamaged(f"{self.path}: checksums {_row_list(unknown[:5], more)}: name "
                                   f"no dataset (the checksum records are damaged)")
        out, where = {}, {}
        for cid, key in ids.items():
            at = np.flatnonzero(recs["dataset"] == cid)
            rows = recs["row"][at]
            n = len(rows)
            if n and not np.array_equal(rows, np.arange(n)):
                bad = int(np.flatnonzero(rows != np.arange(n))[0])
                raise RecordingDamaged(f"{self.path}: checksums row {int(at[bad])}: names {key} "
                                       f"row {int(rows[bad])} where row {bad} belongs (the "
                                       f"checksum records are damaged)")
            out[key], where[key] = recs["adler32"][at], at
        return out, where

    @property
    def has_checksums(self) -> bool:
        """False for a recording made before checksums (format version 1): it cannot be verified."""
        return self._sums is not None

    def _frames_held(self) -> int | None:
        """Rows every per-frame dataset holds with their checksums (None: no frames table)."""
        if self._sums is None:                    # version 1: no blocks, all rows are whole
            return self._f["tables/frames"].shape[0] if "tables/frames" in self._f else None
        n = None
        for key in self._datasets():
            ds = self._f[key]
            if not ds.attrs.get("per_frame", False):
                continue
            m = ds.shape[0]
            if self._sums is not None:
                m = min(m, len(self._sums.get(key, ())))
            n = m if n is None else min(n, m)
        return n

    @property
    def attrs(self) -> dict:
        out = {}
        for k, v in self._f.attrs.items():
            if isinstance(v, str) and v[:1] in "[{":
                try:
                    v = json.loads(v)
                except ValueError:
                    pass
            out[k] = v
        return out

    def tables(self) -> list[str]:
        return sorted(self._f["tables"].keys()) if "tables" in self._f else []

    def arrays(self) -> list[str]:
        return sorted(self._f["arrays"].keys()) if "arrays" in self._f else []

    def _held_rows(self, key: str, ds: h5py.Dataset) -> slice:
        """The rows of ``ds`` that belong to the frames held (all of them when complete; of a
        partial recording, per-frame datasets: the frames held, others: the rows whose checksums
        are on disk)."""
        if self.n_frames is None or self.complete:
            return slice(None)
        if ds.attrs.get("per_frame", False):
            return slice(0, self.n_frames)
        if self._sums is not None:
            return slice(0, min(ds.shape[0], len(self._sums.get(key, ()))))
        return slice(None)

    def _read(self, key: str, ds: h5py.Dataset, sel: slice) -> np.ndarray:
        """Rows ``sel`` of ``ds``, checked (:meth:`check_rows`); HDF5 read errors as
        :class:`RecordingDamaged` naming the dataset."""
        try:
            rows = ds[sel]
        except (OSError, ValueError) as exc:
            raise RecordingDamaged(f"{self.path}: {key}: unreadable "
                                   f"({str(exc).splitlines()[0]})") from None
        self.check_rows(key, sel.start or 0, rows)
        return rows

    def table(self, name: str) -> np.ndarray:
        """A table's rows (of a partial recording: the rows of the frames it holds), checked."""
        key = f"tables/{name}"
        try:
            ds = self._f[key]
        except KeyError:
            raise KeyError(f"recording {self.path.name} has no table {name!r}; "
                           f"it has {self.tables()}") from None
        rows = self._read(key, ds, self._held_rows(key, ds))
        if not self.complete and self.n_frames is not None and rows.dtype.names \
                and "k" in rows.dtype.names:
            rows = rows[rows["k"] < self.n_frames]
        return rows

    def array(self, name: str) -> "CheckedRows | h5py.Dataset":
        """The stacked dataset, lazy: index it to read rows (``n_frames`` of them are whole).
        Verifying (and recorded with checksums): a :class:`CheckedRows` that checks every row
        read; else the ``h5py.Dataset``."""
        key = f"arrays/{name}"
        try:
            ds = self._f[key]
        except KeyError:
            raise KeyError(f"recording {self.path.name} has no array {name!r}; "
                           f"it has {self.arrays()}") from None
        return CheckedRows(self, key, ds) if self.checking and self._sums is not None else ds

    def host_timing(self) -> np.ndarray | None:
        """``/host/timing`` (checked), None when absent."""
        if "host/timing" not in self._f:
            return None
        ds = self._f["host/timing"]
        return self._read("host/timing", ds, self._held_rows("host/timing", ds))

    def check_rows(self, key: str, first: int, rows: np.ndarray) -> None:
        """Check rows ``[first, first + len(rows))`` of dataset ``key`` (as read) against their
        stored Adler-32: the one checksum check every reader goes through. Nothing is checked when
        the recording is read with ``checksums="ignore"`` or was made before checksums.

        Raises
        ------
        RecordingDamaged
            One line naming the file, the dataset, the rows (and frames) that differ and the
            ``/checksums`` rows holding their checksums; or rows without a checksum.
        """
        if not self.checking or self._sums is None or not len(rows):
            return
        bad = self.mismatches(key, first, rows)
        if bad:
            raise RecordingDamaged(self._damage_line(key, bad, rows, first))

    def mismatches(self, key: str, first: int, rows: np.ndarray) -> list[int]:
        """Rows (absolute numbers) of ``rows`` (rows ``first``... of ``key``) that differ from
        their stored Adler-32 or have none."""
        want = self._sums.get(key, np.zeros(0, np.uint32))[first:first + len(rows)]
        got = adler32_rows(rows[:len(want)]) if len(want) else np.zeros(0, np.uint32)
        bad = (first + np.flatnonzero(got != want)).tolist()
        return bad + list(range(first + len(want), first + len(rows)))

    def _damage_line(self, key: str, bad: list, rows: np.ndarray | None, first: int) -> str:
        shown, more = bad[:5], len(bad) - min(5, len(bad))
        per_frame = bool(self._f[key].attrs.get("per_frame", False))
        if per_frame:
            where = f" (frame{'s' if len(shown) > 1 else ''} {', '.join(map(str, shown))})"
        elif rows is not None and rows.dtype.names and "k" in rows.dtype.names \
                and all(0 <= b - first < len(rows) for b in shown):
            ks = sorted({int(rows[b - first]["k"]) for b in shown})
            where = f" (frame{'s' if len(ks) > 1 else ''} {', '.join(map(str, ks))})"
        else:
            where = ""
        n_sums = len(self._sums.get(key, ()))
        no_sum = [b for b in shown if b >= n_sums]
        if no_sum and len(no_sum) == len(shown):
            return f"{self.path}: {key} {_row_list(shown, more)}{where}: no checksum recorded"
        recs = self._sum_rows[key][[b for b in shown if b < n_sums]]
        return (f"{self.path}: {key} {_row_list(shown, more)}{where}: stored data does not match "
                f"its checksum (checksums {_row_list(recs)})")

    def verify(self, collect: bool = False) -> dict:
        """Check every stored row of every dataset against its recorded Adler-32.

        Parameters
        ----------
        collect : bool
            Do not raise on a mismatch: list it in ``"damaged"`` and go on (what
            ``--ignore-checksums`` reports).

        Returns
        -------
        dict : ``{"frames": frames held and verified, "rows": {dataset: rows verified},
        "damaged": [one line per damaged dataset]}``.

        Raises
        ------
        RecordingDamaged
            (without ``collect``) on the first block of rows whose checksums differ, or a block
            HDF5 cannot read; the message is one line naming the file, the dataset, the rows and
            (where known) the frames.
        """
        if self._sums is None:
            raise RecordingDamaged(f"{self.path}: recorded without checksums (format "
                                   f"{self._f.attrs.get('format')!r}); cannot verify it")
        rows, damaged = {}, []
        for key in self._datasets():
            try:
                rows[key] = self._verify_dataset(key)
            except RecordingDamaged as exc:
                if not collect:
                    raise
                damaged.append(str(exc))
        return {"frames": self.n_frames or 0, "rows": rows, "damaged": damaged}

    def _unreadable_row(self, key: str, ds: h5py.Dataset, i0: int, i1: int, per_frame: bool):
        """Raise :class:`RecordingDamaged` naming the first row of ``[i0, i1)`` HDF5 cannot read."""
        for i in range(i0, i1):
            try:
                ds[i]
            except (OSError, ValueError) as exc:
                where = f" (frame {i})" if per_frame else ""
                raise RecordingDamaged(f"{self.path}: {key} row {i}{where}: unreadable "
                                       f"({str(exc).splitlines()[0]})") from None
        raise RecordingDamaged(f"{self.path}: {key} rows {i0}-{i1 - 1}: unreadable")

    def _verify_dataset(self, key: str) -> int:
        """Rows of ``key`` verified (all its rows; of a partial recording, the rows held); raises
        :class:`RecordingDamaged` naming every damaged row (up to 5) of the dataset."""
        ds = self._f[key]
        want_all = self._sums.get(key)
        if want_all is None:
            raise RecordingDamaged(f"{self.path}: {key} has no checksums")
        per_frame = bool(ds.attrs.get("per_frame", False))
        if self.complete:
            n = ds.shape[0]
            if len(want_all) != n:
                raise RecordingDamaged(f"{self.path}: {key} holds {n} rows but {len(want_all)} "
                                       f"checksums")
        else:
            n = self.n_frames if per_frame and self.n_frames is not None else \
                min(ds.shape[0], len(want_all))
        bad, first_rows = [], None
        for i0 in range(0, n, VERIFY_BLOCK_ROWS):
            i1 = min(n, i0 + VERIFY_BLOCK_ROWS)
            try:
                data = ds[i0:i1]
            except (OSError, ValueError):
                self._unreadable_row(key, ds, i0, i1, per_frame)
            found = self.mismatches(key, i0, data)
            if found and not bad:
                first_rows = (i0, data)
            bad += found
        if bad:
            i0, data = first_rows
            raise RecordingDamaged(self._damage_line(key, bad, data, i0))
        return n

    def close(self) -> None:
        self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


#: a live partial recording found inconsistent is read again this many times, ``LIVE_RETRY_S``
#: apart, before it is called damaged: its writer may be between a block's rows and their checksums
LIVE_RETRIES, LIVE_RETRY_S = 4, 0.25


def open_checked(path, ignore_checksums: bool = False) -> tuple[Recording, dict, str | None]:
    """:func:`open_checked_once`, read again (:data:`LIVE_RETRIES`) when a partial recording
    (``*.partial.h5``, perhaps still being written) looks damaged: a live file is never called
    damaged for a block its writer had not finished."""
    import time
    for _ in range(LIVE_RETRIES if str(path).endswith(".partial.h5") else 0):
        try:
            return open_checked_once(path, ignore_checksums)
        except (RecordingDamaged, OSError):
            time.sleep(LIVE_RETRY_S)
    return open_checked_once(path, ignore_checksums)


def open_checked_once(path, ignore_checksums: bool = False) -> tuple[Recording, dict, str | None]:
    """Open a recording for a command that reads it, and verify every stored row first (the
    commands' one checksum path: :meth:`Recording.verify`, whose row check
    :meth:`Recording.check_rows` the Python reader applies to every read).

    Parameters
    ----------
    path : recording (``recording.h5`` or a ``recording.partial.h5``)
    ignore_checksums : bool
        Read the rows as stored: mismatches are listed, not raised, and the recording is opened
        with ``checksums="ignore"``.

    Returns
    -------
    (Recording, verified, note) : the open recording (the caller closes it), what
    :meth:`Recording.verify` returned (``{"frames": 0, "rows": {}, "damaged": []}`` for a
    recording made before checksums) and a one-line note for the user, or None: what
    ``ignore_checksums`` ignored, or that the recording has no checksums.

    Raises
    ------
    RecordingDamaged, ValueError, FileNotFoundError
        One line naming the file (and the dataset and rows that differ).
    """
    rec = Recording(path, checksums="ignore" if ignore_checksums else "verify")
    try:
        if not rec.has_checksums:
            return rec, {"frames": 0, "rows": {}, "damaged": []}, \
                f"{rec.path}: recorded without checksums (format {rec.attrs.get('format')!r}): " \
                f"not verified"
        checked = rec.verify(collect=ignore_checksums)
        if rec.unverified and not ignore_checksums:
            return rec, checked, f"{rec.path}: {rec.unverified}"
    except BaseException:
        rec.close()
        raise
    note = None
    if ignore_checksums:
        bad = checked["damaged"]
        if bad:
            first = bad[0].split(": ", 1)[-1]
            more = f" (+{len(bad) - 1} more datasets)" if len(bad) > 1 else ""
            note = f"{rec.path}: --ignore-checksums: read as stored despite {first}{more}"
        else:
            note = (f"{rec.path}: --ignore-checksums: nothing to ignore, every row of "
                    f"{len(checked['rows'])} datasets matched its checksum")
    return rec, checked, note
