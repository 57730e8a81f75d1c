"""Landmark measurement tables for the INR assessment (issue 11): the in-memory form and the CSV schema.

One row is one landmark (a star for UVISI, a coastline site for GOES) seen by one imager at one time:
its absolute error (NAV datum, the measured position minus the catalogue/map-predicted position), the
quality-metric factors of eq. 3-1, and optionally the relative error (FFR datum) of the same landmark
between the previous frame of the same imager and this one, by image-to-image correlation.

CSV schema ``uvisi-inr-landmarks/1``
------------------------------------
Plain comma-separated text, one header line, one row per measurement; lines starting with ``#`` are
comments (the writer puts ``# schema: uvisi-inr-landmarks/1`` first). Column order is free; names are
case-sensitive. Empty numeric cells are NaN ("not measured").

==================  ========  =========  =====================================================================
column              required  unit       meaning
==================  ========  =========  =====================================================================
``time``            yes       s          measurement time (any epoch; seconds, float)
``landmark_id``     yes       --         landmark/star identifier (text, e.g. ``HIP 32349`` or ``42``)
``imager``          yes       --         imager/channel name (text, e.g. ``WFOV_VIS``, ``VIS``, ``IR2``)
``ew_err_urad``     yes       urad       absolute error, east-west / column direction (empty = none)
``ns_err_urad``     yes       urad       absolute error, north-south / row direction (empty = none)
``qm``              one of    [0, 1]     quality metric of eq. 3-1 as recorded (overrides the factors)
``qmf_<name>``      these     [0, 1]     one column per QM factor of eq. 3-1 (1 = best), e.g. ``qmf_fit``,
                                         ``qmf_isolation``, ``qmf_contrast``; exponents gamma by ``<name>``
``contamination``   no        [0, 1]     contaminated (cloudy / neighbour-star) fraction of the neighbourhood;
                                         default 0
``rel_ew_urad``     no        urad       relative error R_{n,n-1}, EW: shift of this landmark's neighbourhood
                                         from the previous frame of this imager to this one (same sign
                                         convention as the absolute error, so R ~ A_n - A_{n-1})
``rel_ns_urad``     no        urad       relative error, NS
``rho``             no        [-1, 1]    normalised peak of the image-to-image correlation surface
``rel_dt_s``        no        s          time to the previous frame the relative error refers to
                                         (default: time since the previous row of this landmark+imager)
``kf_veto``         no        0/1        a veto decision recorded by the producing system; when present it is
                                         used instead of running the Kalman filter (gold still overrides)
any other column    no        float      carried through unchanged in ``extra`` (e.g. ``truth_invalid``)
==================  ========  =========  =====================================================================

Errors name the offending column and the file line (the header is line 1 after comments).
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["SCHEMA", "MeasurementTable", "read_csv", "write_csv", "REQUIRED_COLUMNS"]

SCHEMA = "uvisi-inr-landmarks/1"
REQUIRED_COLUMNS = ("time", "landmark_id", "imager", "ew_err_urad", "ns_err_urad")
_OPTIONAL_FLOAT = ("qm", "contamination", "rel_ew_urad", "rel_ns_urad", "rho", "rel_dt_s", "kf_veto")


def _f8(a, n):
    return np.full(n, np.nan) if a is None else np.asarray(a, dtype=np.float64).reshape(n)


@dataclass
class MeasurementTable:
    """Landmark measurements as float64 / text arrays, N rows.

    Attributes
    ----------
    time : (N,) float64, s
    landmark_id, imager : (N,) str arrays
    abs_err : (N, 2) float64, urad, columns (EW, NS); NaN = no absolute measurement
    qm_factors : dict name -> (N,) float64 in [0, 1] (eq. 3-1 factors)
    qm : (N,) float64 or None -- a recorded QM; NaN entries fall back to the factors
    contamination : (N,) float64 fraction in [0, 1]
    rel_err : (N, 2) float64, urad (EW, NS), NaN = no relative measurement
    rho : (N,) float64, normalised correlation peak (NaN = none)
    rel_dt : (N,) float64, s (NaN = time since the previous row of the same landmark and imager)
    kf_veto : (N,) float64 0/1 or None (recorded veto decisions)
    extra : dict name -> (N,) float64, carried through
    """
    time: np.ndarray
    landmark_id: np.ndarray
    imager: np.ndarray
    abs_err: np.ndarray
    qm_factors: dict = field(default_factory=dict)
    qm: np.ndarray | None = None
    contamination: np.ndarray | None = None
    rel_err: np.ndarray | None = None
    rho: np.ndarray | None = None
    rel_dt: np.ndarray | None = None
    kf_veto: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        self.time = np.asarray(self.time, dtype=np.float64).reshape(-1)
        n = self.time.size
        self.landmark_id = np.asarray(self.landmark_id).astype(str).reshape(n)
        self.imager = np.asarray(self.imager).astype(str).reshape(n) if np.ndim(self.imager) else \
            np.full(n, str(self.imager))
        self.abs_err = np.asarray(self.abs_err, dtype=np.float64).reshape(n, 2)
        self.qm_factors = {k: _f8(v, n) for k, v in self.qm_factors.items()}
        self.qm = None if self.qm is None else _f8(self.qm, n)
        self.contamination = np.zeros(n) if self.contamination is None else _f8(self.contamination, n)
        self.rel_err = np.full((n, 2), np.nan) if self.rel_err is None else \
            np.asarray(self.rel_err, dtype=np.float64).reshape(n, 2)
        self.rho = _f8(self.rho, n)
        self.rel_dt = _f8(self.rel_dt, n)
        self.kf_veto = None if self.kf_veto is None else _f8(self.kf_veto, n)
        self.extra = {k: _f8(v, n) for k, v in self.extra.items()}
        if not np.all(np.isfinite(self.time)):
            raise ValueError("measurement table: 'time' must be finite on every row")
        for name, a in list(self.qm_factors.items()) + [("qm", self.qm), ("contamination", self.contamination)]:
            if a is None:
                continue
            bad = np.flatnonzero(np.isfinite(a) & ((a < 0) | (a > 1)))
            if bad.size:
                raise ValueError(f"measurement table: column {_qcol(name)!r} must lie in [0, 1]; "
                                 f"row {bad[0]} has {a[bad[0]]!r}")
        if self.qm is None and not self.qm_factors:
            raise ValueError("measurement table: needs a 'qm' column or at least one 'qmf_<name>' factor")

    def __len__(self) -> int:
        return self.time.size

    def subset(self, idx) -> "MeasurementTable":
        """Rows ``idx`` (index array or boolean mask) as a new table."""
        take = lambda a: None if a is None else a[idx]   # noqa: E731
        return MeasurementTable(
            time=self.time[idx], landmark_id=self.landmark_id[idx], imager=self.imager[idx],
            abs_err=self.abs_err[idx], qm_factors={k: v[idx] for k, v in self.qm_factors.items()},
            qm=take(self.qm), contamination=self.contamination[idx], rel_err=self.rel_err[idx],
            rho=self.rho[idx], rel_dt=self.rel_dt[idx], kf_veto=take(self.kf_veto),
            extra={k: v[idx] for k, v in self.extra.items()})

    @staticmethod
    def concatenate(tables) -> "MeasurementTable":
        tables = list(tables)
        cat = lambda get: np.concatenate([get(t) for t in tables])   # noqa: E731
        keys = set().union(*[t.qm_factors for t in tables])
        ekeys = set().union(*[t.extra for t in tables])
        n = lambda t: np.full(len(t), np.nan)   # noqa: E731
        any_qm = any(t.qm is not None for t in tables)
        any_veto = any(t.kf_veto is not None for t in tables)
        return MeasurementTable(
            time=cat(lambda t: t.time), landmark_id=cat(lambda t: t.landmark_id),
            imager=cat(lambda t: t.imager), abs_err=cat(lambda t: t.abs_err),
            qm_factors={k: cat(lambda t: t.qm_factors.get(k, n(t))) for k in sorted(keys)},
            qm=cat(lambda t: t.qm if t.qm is not None else n(t)) if any_qm else None,
            contamination=cat(lambda t: t.contamination), rel_err=cat(lambda t: t.rel_err),
            rho=cat(lambda t: t.rho), rel_dt=cat(lambda t: t.rel_dt),
            kf_veto=cat(lambda t: t.kf_veto if t.kf_veto is not None else n(t)) if any_veto else None,
            extra={k: cat(lambda t: t.extra.get(k, n(t))) for k in sorted(ekeys)})


def _qcol(name):
    return name if name in ("qm", "contamination") else f"qmf_{name}"


def _columns(table: MeasurementTable) -> list[tuple[str, np.ndarray]]:
    cols = [("ew_err_urad", table.abs_err[:, 0]), ("ns_err_urad", table.abs_err[:, 1])]
    if table.qm is not None:
        cols.append(("qm", table.qm))
    cols += [(f"qmf_{k}", v) for k, v in table.qm_factors.items()]
    cols += [("contamination", table.contamination),
             ("rel_ew_urad", table.rel_err[:, 0]), ("rel_ns_urad", table.rel_err[:, 1]),
             ("rho", table.rho), ("rel_dt_s", table.rel_dt)]
    if table.kf_veto is not None:
        cols.append(("kf_veto", table.kf_veto))
    cols += list(table.extra.items())
    return cols


def _fmt(v: float) -> str:
    return "" if not math.isfinite(v) else repr(float(v))   # repr round-trips float64 exactly


def write_csv(table: MeasurementTable, path) -> Path:
    """Write ``table`` in schema ``uvisi-inr-landmarks/1``; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    cols = _columns(table)
    with open(path, "w", newline="") as fh:
        fh.write(f"# schema: {SCHEMA}\n")
        w = csv.writer(fh)
        w.writerow(["time", "landmark_id", "imager"] + [c for c, _ in cols])
        for i in range(len(table)):
            w.writerow([repr(float(table.time[i])), table.landmark_id[i], table.imager[i]]
                       + [_fmt(a[i]) for _, a in cols])
    return path


def read_csv(path) -> MeasurementTable:
    """Read a CSV table in schema ``uvisi-inr-landmarks/1`` (see the module doc).

    Raises ``FileNotFoundError`` for a missing file and ``ValueError`` naming the column (and file line)
    for a missing required column, a non-numeric or non-finite cell (``nan``, ``inf``: an absent value
    is an empty cell) or a factor outside [0, 1].
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such landmark CSV: {path}")
    if path.is_dir():
        raise ValueError(f"{path}: is a folder, not a landmark CSV file")
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            lines = [(i + 1, ln) for i, ln in enumerate(fh.read().splitlines())]
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a text CSV file (byte {exc.start} is not UTF-8 text)") \
            from None
    body = [(no, ln) for no, ln in lines if ln.strip() and not ln.lstrip().startswith("#")]
    if not body:
        raise ValueError(f"{path}: no header line")
    rows = list(csv.reader([ln for _, ln in body]))
    linenos = [no for no, _ in body]
    header = [h.strip() for h in rows[0]]
    for c in REQUIRED_COLUMNS:
        if c not in header:
            raise ValueError(f"{path}: missing required column {c!r} (header has {', '.join(header)})")
    dup = {h for h in header if header.count(h) > 1}
    if dup:
        raise ValueError(f"{path}: duplicate column {sorted(dup)[0]!r}")
    has_factors = any(h.startswith("qmf_") for h in header)
    if "qm" not in header and not has_factors:
        raise ValueError(f"{path}: missing column 'qm' (or at least one 'qmf_<name>' quality-factor column)")
    data = rows[1:]
    n = len(data)
    col = {h: j for j, h in enumerate(header)}
    for r, row in enumerate(data):
        if len(row) != len(header):
            raise ValueError(f"{path}: line {linenos[r + 1]}: {len(row)} cells, header has {len(header)}")

    def num(name, required=False):
        j = col[name]
        out = np.empty(n)
        for r, row in enumerate(data):
            s = row[j].strip()
            if s == "":
                if required:
                    raise ValueError(f"{path}: line {linenos[r + 1]}: column {name!r} is empty")
                out[r] = np.nan
                continue
            try:
                out[r] = float(s)
            except ValueError:
                raise ValueError(f"{path}: line {linenos[r + 1]}: column {name!r}: {s!r} is not a number") \
                    from None
            if not math.isfinite(out[r]):
                raise ValueError(f"{path}: line {linenos[r + 1]}: column {name!r}: {s!r} is not a finite "
                                 f"number (leave the cell empty for no measurement)")
        return out

    def text(name):
        j = col[name]
        out = [row[j].strip() for row in data]
        for r, s in enumerate(out):
            if s == "":
                raise ValueError(f"{path}: line {linenos[r + 1]}: column {name!r} is empty")
        return np.array(out, dtype=str) if n else np.zeros(0, dtype="U1")

    opt = {c: num(c) if c in col else None for c in _OPTIONAL_FLOAT}
    known = set(REQUIRED_COLUMNS) | set(_OPTIONAL_FLOAT)
    factors = {h[4:]: num(h) for h in header if h.startswith("qmf_")}
    extra = {h: num(h) for h in header if h not in known and not h.startswith("qmf_")}
    rel = None
    if opt["rel_ew_urad"] is not None or opt["rel_ns_urad"] is not None:
        rel = np.column_stack([opt["rel_ew_urad"] if opt["rel_ew_urad"] is not None else np.full(n, np.nan),
                               opt["rel_ns_urad"] if opt["rel_ns_urad"] is not None else np.full(n, np.nan)])
    try:
        return MeasurementTable(
            time=num("time", required=True), landmark_id=text("landmark_id"), imager=text("imager"),
            abs_err=np.column_stack([num("ew_err_urad"), num("ns_err_urad")]), qm_factors=factors,
            qm=opt["qm"], contamination=opt["contamination"], rel_err=rel, rho=opt["rho"],
            rel_dt=opt["rel_dt_s"], kf_veto=opt["kf_veto"], extra=extra)
    except ValueError as exc:        # row index -> file line
        msg = str(exc)
        m = re.search(r"row (\d+) has", msg)
        if m:
            msg = msg.replace(f"row {m.group(1)} has", f"line {linenos[int(m.group(1)) + 1]} has")
        raise ValueError(msg if msg.startswith(f"{path}: ") else f"{path}: {msg}") from None
