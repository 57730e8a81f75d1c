"""Event recordings: one HDF5 file per event, written atomically.

Layout (every table is one compound dataset, one row per record, growing along axis 0)::

    /                 attrs: format, scenario name and TOML text, seed, software versions, created
    /tables/<name>    compound datasets: per-frame tables (candidates, tp, commands, truth, ledger...)
    /arrays/<name>    stacked per-frame arrays (frames uint16[N, 244, 256], stage images), compressed
    /host/<name>      host wall-clock timings: kept apart, since they differ run to run

The file is written under a temporary name beside the target and renamed over it only when the
recorder closes cleanly, so a failed or interrupted event never leaves a half-written recording under
the final name. Rows are buffered and flushed every ``flush_every`` appends, after which what is on
disk is complete up to that frame (a reader of the temporary file sees whole frames only).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np

FORMAT = "uvisi-recording/1"


def _as_row(values: dict) -> np.ndarray:
    """One structured row from a dict of scalars / small fixed-size arrays."""
    fields = []
    for k, v in values.items():
        a = np.asarray(v)
        if a.dtype.kind in "UOS":
            fields.append((k, "S64"))        # fixed width keeps the row layout stable
        elif a.ndim == 0:
            fields.append((k, a.dtype))
        else:
            fields.append((k, a.dtype, a.shape))
    row = np.zeros(1, dtype=fields)
    for k, v in values.items():
        row[k] = v.encode() if isinstance(v, str) else v
    return row


class Recorder:
    """Append-only writer of one event recording.

    Parameters
    ----------
    path : str or Path
        Final file name (``.h5``). Parent directories are created.
    attrs : dict
        Root attributes (strings, numbers; dicts are stored as JSON).
    flush_every : int
        Buffered rows per table before they are written.
    compression : str
        HDF5 filter for the image arrays ("gzip" level 4 by default, "lzf" faster).
    """

    def __init__(self, path, attrs: dict | None = None, flush_every: int = 20,
                 compression: str = "gzip"):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = self.path.with_name(self.path.name + ".tmp")
        self._f = h5py.File(self.tmp, "w")
        self._f.attrs["format"] = FORMAT
        for k, v in (attrs or {}).items():
            self._f.attrs[k] = json.dumps(v) if isinstance(v, (dict, list, tuple)) else v
        self._buf: dict[str, list] = {}
        self.flush_every = int(flush_every)
        self.compression = compression
        self._closed = False

    # ---------------------------------------------------------------- tables
    def append(self, table: str, row: dict) -> None:
        """Append one row (dict of scalars / fixed-shape arrays) to ``/tables/<table>``."""
        self.append_rows(table, _as_row(row))

    def append_rows(self, table: str, rows: np.ndarray) -> None:
        """Append a structured array of rows to ``/tables/<table>`` (same dtype every call)."""
        if rows.dtype.names is None:
            raise ValueError(f"table {table!r}: rows must be a structured array")
        buf = self._buf.setdefault(table, [])
        buf.append(np.asarray(rows))
        if sum(len(b) for b in buf) >= self.flush_every:
            self._flush(table)

    def _flush(self, table: str) -> None:
        buf = self._buf.get(table)
        if not buf:
            return
        rows = np.concatenate(buf)
        self._buf[table] = []
        name = f"tables/{table}"
        if name not in self._f:
            self._f.create_dataset(name, data=rows, maxshape=(None,), chunks=True)
            return
        ds = self._f[name]
        if ds.dtype != rows.dtype:
            raise ValueError(f"table {table!r}: row layout changed from {ds.dtype} to {rows.dtype}")
        n = ds.shape[0]
        ds.resize(n + len(rows), axis=0)
        ds[n:] = rows

    # ---------------------------------------------------------------- arrays
    def append_array(self, name: str, arr: np.ndarray, host: bool = False) -> None:
        """Append one frame-sized array to the stacked dataset ``/arrays/<name>`` (or ``/host``)."""
        arr = np.asarray(arr)
        key = f"{'host' if host else 'arrays'}/{name}"
        if key not in self._f:
            self._f.create_dataset(key, data=arr[None], maxshape=(None,) + arr.shape,
                                   chunks=(1,) + arr.shape,
                                   compression=self.compression if arr.ndim >= 2 else None)
            return
        ds = self._f[key]
        if ds.shape[1:] != arr.shape:
            raise ValueError(f"array {name!r}: shape changed from {ds.shape[1:]} to {arr.shape}")
        ds.resize(ds.shape[0] + 1, axis=0)
        ds[-1] = arr

    def host(self, row: dict) -> None:
        """Append a row of host timings to ``/host/timing`` (excluded from determinism checks)."""
        self.append("__host__", row)

    def set_attr(self, key: str, value) -> None:
        self._f.attrs[key] = json.dumps(value) if isinstance(value, (dict, list, tuple)) else value

    def flush(self) -> None:
        for t in list(self._buf):
            self._flush(t)
        self._f.flush()

    # ---------------------------------------------------------------- life cycle
    def close(self) -> Path:
        """Write what is buffered and move the file to its final name."""
        if self._closed:
            return self.path
        self.flush()
        if "tables/__host__" in self._f:            # host timings live under /host
            self._f.move("tables/__host__", "host/timing")
        self._f.close()
        os.replace(self.tmp, self.path)
        self._closed = True
        return self.path

    def abort(self) -> None:
        """Discard the recording (nothing is left under the final name)."""
        if self._closed:
            return
        try:
            self._f.close()
        finally:
            self.tmp.unlink(missing_ok=True)
            self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


class Recording:
    """Read access to a recording: ``rec.attrs``, ``rec.table(name)``, ``rec.array(name)``."""

    def __init__(self, path):
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(f"no recording at {self.path}")
        try:
            self._f = h5py.File(self.path, "r")
        except OSError as exc:
            raise ValueError(f"{self.path} is not an HDF5 recording ({exc})") from None
        fmt = self._f.attrs.get("format")
        if fmt != FORMAT:
            self._f.close()
            raise ValueError(f"{self.path} is not a uvisi recording (format attribute "
                             f"{fmt!r} != {FORMAT!r})")

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

    def table(self, name: str) -> np.ndarray:
        try:
            return self._f[f"tables/{name}"][()]
        except KeyError:
            raise KeyError(f"recording {self.path.name} has no table {name!r}; "
                           f"it has {self.tables()}") from None

    def array(self, name: str) -> h5py.Dataset:
        """The stacked dataset (lazy: index it to read frames)."""
        try:
            return self._f[f"arrays/{name}"]
        except KeyError:
            raise KeyError(f"recording {self.path.name} has no array {name!r}; "
                           f"it has {self.arrays()}") from None

    def host_timing(self) -> np.ndarray | None:
        return self._f["host/timing"][()] if "host/timing" in self._f else None

    def close(self) -> None:
        self._f.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
