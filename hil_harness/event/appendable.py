"""One HDF5 dataset grown along axis 0 in blocks of rows, with as few HDF5 calls as a block allows.

Used by the event recorder (:mod:`.recording`). Two costs dominate a small block write through h5py
and are avoided here:

- h5py builds the HDF5 memory type from the numpy dtype on every write (~190 us for the TP table's
  compound of 30 fields): built once per dataset and passed on every write;
- HDF5 compares the memory and file compound types and runs its conversion path on every write
  (~50-100 us for a compound of 30 fields, whatever the row count): blocks are written with
  ``H5Dwrite_chunk`` (h5py ``write_direct_chunk``), raw bytes straight into the file, one call per
  chunk, no conversion. The bytes are the rows as numpy stores them, which is the file type's
  layout (the file type is made from the same dtype). A chunk a block fills only in part is
  written whole, its rows past the block zero (as HDF5's fill value would be, beyond the extent);
  its rows are kept in memory and the next block writes the chunk again whole, the earlier rows
  with the same bytes: what ``H5Dwrite`` itself does to a partly written chunk (read, modify,
  write the whole chunk).

Filtered (compressed) datasets go through ``H5Dwrite``: their chunks are not raw rows.
"""
from __future__ import annotations

import h5py
import numpy as np


class AppendableDataset:
    """A chunked dataset of shape ``(rows, *row_shape)``, appended to with :meth:`append`.

    Parameters
    ----------
    group : h5py.Group or h5py.File
        Where the dataset is created.
    name : str
        Its path in ``group``.
    dtype : numpy dtype
        Row dtype (structured for tables).
    row_shape : tuple of int
        Shape of one row.
    chunk_rows : int
        Rows per chunk (>= 1): blocks of exactly this many rows, or of a multiple, go straight into
        their chunks.
    compression : str, optional
        HDF5 filter ("gzip", "lzf"); such a dataset is written through ``H5Dwrite`` only.

    Attributes
    ----------
    ds : h5py.Dataset
    rows : int
        Rows written.
    """

    def __init__(self, group, name: str, dtype: np.dtype, row_shape: tuple, chunk_rows: int,
                 compression: str | None = None):
        self.dtype = np.dtype(dtype)
        self.row_shape = tuple(int(x) for x in row_shape)
        self.chunk_rows = max(1, int(chunk_rows))
        shape, chunks = (0,) + self.row_shape, (self.chunk_rows,) + self.row_shape
        if compression is None:
            tid = h5_type(self.dtype)
            self.ds = h5py.Dataset(_create(group, name, tid, shape, chunks))
        else:
            self.ds = group.create_dataset(name, shape=shape, maxshape=(None,) + self.row_shape,
                                           dtype=self.dtype, chunks=chunks,
                                           compression=compression)
        # built from numpy's own offsets, the file type (when HDF5 kept it: H5Tequal) stores a
        # row in the bytes numpy does, so raw chunks are the rows as they are; whether it keeps
        # the type of a dtype is asked once a process (~20 us a dataset)
        kept = compression is None and _KEPT.get(self.dtype)
        if kept:
            self._mtype = tid
        else:
            self._mtype = self.ds.id.get_type()     # the file type
            if compression is None:
                kept = _KEPT[self.dtype] = self._mtype == tid
        self._direct = bool(kept)
        self._zeros = (0,) * len(self.row_shape)
        self._tail = np.zeros(chunks, self.dtype)    # rows of the last, partly filled chunk
        self.rows = 0

    def append(self, data: np.ndarray) -> None:
        """Write ``data`` (``(m, *row_shape)``, this dataset's dtype) as rows
        ``[rows, rows + m)``; the dataset's extent grows first, as SWMR readers require."""
        if data.dtype != self.dtype or data.shape[1:] != self.row_shape:
            raise ValueError(f"{self.ds.name}: layout changed from {self.dtype}{self.row_shape} "
                             f"to {data.dtype}{data.shape[1:]}")
        m = len(data)
        if not m:
            return
        data = np.ascontiguousarray(data)
        n = self.rows
        self.ds.id.set_extent((n + m,) + self.row_shape)
        if self._direct:
            self._write_chunks(n, data)
        else:
            fs = self.ds.id.get_space()
            fs.select_hyperslab((n,) + self._zeros, data.shape)
            self.ds.id.write(h5py.h5s.create_simple(data.shape), fs, data, mtype=self._mtype)
        self.rows = n + m

    def append_each(self, rows: list) -> None:
        """Write the arrays ``rows`` (each C-contiguous, ``row_shape``, this dataset's dtype) as
        the next rows. With one row per chunk and no filter each goes straight into its chunk,
        no stacked copy; otherwise they are stacked and written by :meth:`append`."""
        if not rows:
            return
        if not (self._direct and self.chunk_rows == 1):
            self.append(np.stack(rows))
            return
        for r in rows:
            if r.dtype != self.dtype or r.shape != self.row_shape or not r.flags.c_contiguous:
                raise ValueError(f"{self.ds.name}: layout changed from {self.dtype}"
                                 f"{self.row_shape} to {r.dtype}{r.shape}")
        n = self.rows
        self.ds.id.set_extent((n + len(rows),) + self.row_shape)
        for i, r in enumerate(rows):
            self.ds.id.write_direct_chunk((n + i,) + self._zeros, r)
        self.rows = n + len(rows)

    def _write_chunks(self, n: int, data: np.ndarray) -> None:
        """Rows ``[n, n + len(data))`` as whole raw chunks: the partly filled chunk they start in
        is written again whole (its earlier rows, kept in :attr:`_tail`, with the same bytes);
        whole chunks of ``data`` go as they are; the last partial chunk is kept for next time,
        its rows past the data zero."""
        cr, tail = self.chunk_rows, self._tail
        # copied as bytes: numpy copies a structured array field by field (several us a block)
        tail_bytes = tail.view(np.uint8).reshape(cr, -1)
        data_bytes = data.view(np.uint8).reshape(len(data), -1)
        j, fill = 0, n % cr
        while j < len(data):
            start = n + j - fill
            k = min(cr - fill, len(data) - j)
            if fill == 0 and k == cr:
                self.ds.id.write_direct_chunk((start,) + self._zeros, data[j:j + cr])
            else:
                tail_bytes[fill:fill + k] = data_bytes[j:j + k]
                self.ds.id.write_direct_chunk((start,) + self._zeros, tail)
                if fill + k == cr:
                    tail_bytes[:] = 0
            j += k
            fill = (fill + k) % cr


def _create(group, name: str, tid, shape: tuple, chunks: tuple):
    """An uncompressed chunked dataset of type ``tid`` and unlimited rows through HDF5's own calls
    (h5py's ``create_dataset`` costs ~0.25 ms a dataset more in Python); intermediate groups
    created."""
    space = h5py.h5s.create_simple(shape, (h5py.h5s.UNLIMITED,) + shape[1:])
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_chunk(chunks)
    return h5py.h5d.create(group.id, name.encode(), tid, space, dcpl=dcpl, lcpl=_LCPL)


#: link creation: intermediate groups made as needed (one property list for every dataset)
_LCPL = h5py.h5p.create(h5py.h5p.LINK_CREATE)
_LCPL.set_create_intermediate_group(True)
#: numpy dtype -> HDF5 type of every dtype met so far (read only once built: HDF5 copies a
#: dataset's or attribute's type when it creates one)
_TYPES: dict = {}
#: numpy dtype -> whether a dataset created with its type keeps that type as its file type
_KEPT: dict = {}
#: the dataspace of a scalar attribute
_SCALAR = h5py.h5s.create(h5py.h5s.SCALAR)


def h5_type(dtype: np.dtype):
    """The HDF5 type h5py makes of ``dtype`` (``h5py.h5t.py_create(dtype, logical=True)``: the
    same type, ``H5Tequal``), built member by member, once a process for each dtype (a
    recording creates ~20 datasets of the same dtypes every event): a compound of 25 fields in
    ~70 us the first time instead of ~320 us, then a dict look-up.

    Parameters
    ----------
    dtype : numpy dtype
        Scalar, string, subarray or structured (members at numpy's offsets, nested allowed).

    Returns
    -------
    h5py.h5t.TypeID
    """
    dtype = np.dtype(dtype)
    tid = _TYPES.get(dtype)
    if tid is not None:
        return tid
    if dtype.names is not None:
        tid = h5py.h5t.create(h5py.h5t.COMPOUND, dtype.itemsize)
        for name in dtype.names:
            member, offset = dtype.fields[name][:2]
            tid.insert(name.encode(), offset, h5_type(member))
    elif dtype.subdtype is not None:
        base, shape = dtype.subdtype
        tid = h5py.h5t.array_create(h5_type(base), shape)
    else:
        tid = h5py.h5t.py_create(dtype, logical=True)
    _TYPES[dtype] = tid
    return tid


def write_attr(ds: h5py.Dataset, name: str, value) -> None:
    """Create the attribute ``name`` of a new dataset (one without it) holding the scalar
    ``value``, of the type ``ds.attrs[name] = value`` would give it (a bool an h5py boolean
    enum, an int int64), through HDF5's calls: ~8 us instead of ~25 us."""
    data = np.asarray(value)
    if data.ndim or data.dtype.kind not in "biuf":
        raise ValueError(f"{ds.name}: attribute {name!r}: a numeric or bool scalar, not {value!r}")
    tid = h5_type(data.dtype)
    attr = h5py.h5a.create(ds.id, name.encode(), tid, _SCALAR)
    attr.write(data, mtype=tid)
