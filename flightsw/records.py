"""A priori feature records (MSX paper, "Candidate ranking" and Table 1): validation, the
human-readable TOML form and the uplink form (16-bit words).

A record gives, for each of the twelve features (:data:`flightsw.messages.FEATURE_NAMES`, Table 1's
order), the expected mean ``m_i``, standard deviation ``sigma_i``, weight ``w_i`` and the lower/upper
coarse-quantisation thresholds, plus the GOF rejection threshold (a probability: candidates whose GOF
is below it are not reported) and the coarse-quantisation flag. Every number is held as the nearest
1750A 32-bit float (what the uplink carries and the flight code computes with), so both forms
round-trip exactly.

TOML form (``flightsw/data/record_*.toml``)::

    [record]
    name = "aurora"           # ground-side name (not uplinked)
    id = 1                    # record id, 0..65535
    version = 1               # 0..65535
    object_type = "aurora"    # generic | star | satellite | aurora | plume
    gof_threshold = 0.0       # 0 <= p <= 1
    quantize = false          # the coarse-quantisation flag

    [feature.size]            # one table per feature, all twelve
    mean = 600.0
    sigma = 100.0             # > 0
    weight = 1.0              # >= 0; n = number of non-zero weights (>= 1)
    lower = 100.0             # lower < upper, lower + upper > 0
    upper = 1000.0

Uplink form: 129 16-bit words (:func:`Record.to_words`)

=======  ======================================================================
word     content
=======  ======================================================================
0        format id 0x5245 ("RE")
1        length in words, 129
2        record id
3        version
4        object type code << 8 | flags (bit 0: quantize)
5        number of features, 12
6, 7     GOF threshold, 1750A 32-bit float (w0, w1)
8..127   per feature (Table 1 order) 10 words: mean, sigma, weight, lower, upper,
         each a 1750A 32-bit float (w0, w1)
128      CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, MSB first, no final xor;
         check value 0x29B1 for "123456789") over words 0..127
=======  ======================================================================

Validation (both directions): sigma <= 0, negative weight, lower >= upper, lower + upper <= 0, no
non-zero weight, a non-finite or out-of-range value, a missing or unknown feature, a wrong word count
or bad CRC raise :class:`RecordError` (a ``ValueError``) naming the field. :class:`RecordStore`
keeps the records in force: a rejected uplink leaves the record in force unchanged.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from flightsw.arith.m1750 import decode32, encode32
from flightsw.messages import FEATURE_NAMES, N_FEATURES, crc16_ccitt

__all__ = ["Record", "RecordStore", "RecordError", "load_record", "shipped_records", "OBJECT_TYPES",
           "RECORD_WORDS", "RECORD_FORMAT_ID", "COLUMNS"]

OBJECT_TYPES = {"generic": 0, "star": 1, "satellite": 2, "aurora": 3, "plume": 4}
_TYPE_BY_CODE = {v: k for k, v in OBJECT_TYPES.items()}
COLUMNS = ("mean", "sigma", "weight", "lower", "upper")
RECORD_FORMAT_ID = 0x5245
RECORD_HEADER_WORDS = 8
RECORD_WORDS = RECORD_HEADER_WORDS + 2 * len(COLUMNS) * N_FEATURES + 1   # 129
_F32_MAX = 0.9999998 * 2.0 ** 127


class RecordError(ValueError):
    """An invalid record (TOML form, uplink words or field values) or an unreadable record file;
    the message names the file or field. Every loader and decoder of this module raises only
    this."""


def _q32(where: str, v) -> float:
    """Value -> nearest 1750A 32-bit float (as a Python float); ValueError naming ``where``."""
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise RecordError(f"{where} = {v!r} is not a number")
    v = float(v)
    if not math.isfinite(v) or abs(v) > _F32_MAX:
        raise RecordError(f"{where} = {v!r} is not a finite 1750A float")
    return decode32(encode32(v, rounding="nearest"))


def _comment_text(line: str) -> str:
    """A line as TOML allows it in a comment: control characters (other than tab) written as
    ``\\xNN``."""
    return "".join(ch if ch == "\t" or (" " <= ch and ch != "\x7f") else f"\\x{ord(ch):02x}"
                   for ch in line)


def _short(v: float) -> str:
    """Shortest decimal that encodes (nearest) to the same 1750A word, TOML float syntax."""
    target = encode32(v, rounding="nearest")
    for p in range(1, 18):
        s = repr(float(f"{v:.{p}g}"))
        if encode32(float(s), rounding="nearest") == target:
            break
    else:  # pragma: no cover - 17 digits always suffice
        s = repr(v)
    if not any(ch in s for ch in ".en"):
        s += ".0"
    return s


@dataclass(frozen=True)
class Record:
    """One a priori feature record.

    Attributes
    ----------
    name : str
        Ground-side name (not part of the uplink).
    record_id, version : int
        0..65535.
    object_type : str
        A key of :data:`OBJECT_TYPES`.
    mean, sigma, weight, lower, upper : tuple of 12 float
        Per feature (Table 1 order); units of :mod:`flightsw.ip.features` at the reference scale
        (centroids in full-resolution imager pixels). Stored as exact 1750A 32-bit values.
    gof_threshold : float
        Candidates with GOF below it are rejected (0 rejects none).
    quantize : bool
        The coarse-quantisation flag.
    description : str
        Free text (the TOML comment block is not kept; this is).
    """

    name: str
    record_id: int
    version: int
    object_type: str
    mean: tuple
    sigma: tuple
    weight: tuple
    lower: tuple
    upper: tuple
    gof_threshold: float = 0.0
    quantize: bool = False
    description: str = field(default="", compare=False)

    def __post_init__(self):
        who = f"record {self.name!r}"
        for key in ("record_id", "version"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= 0xFFFF:
                raise RecordError(f"{who}: {key} = {v!r} must be an int in 0..65535")
        if not isinstance(self.object_type, str) or self.object_type not in OBJECT_TYPES:
            raise RecordError(f"{who}: object_type = {self.object_type!r} must be one of "
                             f"{sorted(OBJECT_TYPES)}")
        if self.quantize not in (True, False):
            raise RecordError(f"{who}: quantize = {self.quantize!r} must be a bool")
        object.__setattr__(self, "quantize", bool(self.quantize))
        for col in COLUMNS:
            vals = getattr(self, col)
            try:
                vals = tuple(vals)
            except TypeError:
                raise RecordError(f"{who}: {col} must be a sequence of {N_FEATURES} "
                                  f"numbers") from None
            if len(vals) != N_FEATURES:
                raise RecordError(f"{who}: {col} has {len(vals)} values, expected {N_FEATURES} "
                                 f"(one per feature {FEATURE_NAMES})")
            object.__setattr__(self, col, tuple(_q32(f"{who}: feature {FEATURE_NAMES[i]!r} {col}", v)
                                                for i, v in enumerate(vals)))
        g = _q32(f"{who}: gof_threshold", self.gof_threshold)
        if not 0.0 <= g <= 1.0:
            raise RecordError(f"{who}: gof_threshold = {g!r} must be a probability in [0, 1]")
        object.__setattr__(self, "gof_threshold", g)
        for i, fname in enumerate(FEATURE_NAMES):
            where = f"{who}: feature {fname!r}"
            if self.sigma[i] <= 0.0:
                raise RecordError(f"{where} sigma = {self.sigma[i]!r} must be > 0")
            if self.weight[i] < 0.0:
                raise RecordError(f"{where} weight = {self.weight[i]!r} must be >= 0")
            if self.lower[i] >= self.upper[i]:
                raise RecordError(f"{where} lower = {self.lower[i]!r} must be < upper = "
                                 f"{self.upper[i]!r}")
            if self.lower[i] + self.upper[i] <= 0.0:
                raise RecordError(f"{where} lower + upper = {self.lower[i] + self.upper[i]!r} must "
                                 f"be > 0 (the quantisation midpoint)")
        if self.n_weighted == 0:
            raise RecordError(f"{who}: weight is zero for every feature (n = 0 degrees of freedom)")

    # ---- derived ----
    @property
    def n_weighted(self) -> int:
        """n, the number of non-zero weights (the chi-square degrees of freedom)."""
        return sum(1 for w in self.weight if w != 0.0)

    @property
    def object_code(self) -> int:
        return OBJECT_TYPES[self.object_type]

    def table(self) -> np.ndarray:
        """float64 [12, 5]: columns mean, sigma, weight, lower, upper."""
        return np.array([getattr(self, c) for c in COLUMNS], np.float64).T

    def words32(self) -> np.ndarray:
        """Packed 1750A 32-bit words int64 [5, 12] (rows mean, sigma, weight, lower, upper): what
        the flight kernels compute with."""
        return np.array([[encode32(v) for v in getattr(self, c)] for c in COLUMNS], np.int64)

    def replace(self, **changes) -> "Record":
        from dataclasses import replace
        return replace(self, **changes)

    # ---- uplink words ----
    def to_words(self) -> np.ndarray:
        """The uplink image: uint16 [129] (layout in the module docstring)."""
        w = [RECORD_FORMAT_ID, RECORD_WORDS, self.record_id, self.version,
             (self.object_code << 8) | int(self.quantize), N_FEATURES]
        g = encode32(self.gof_threshold)
        w += [g >> 16, g & 0xFFFF]
        for i in range(N_FEATURES):
            for col in COLUMNS:
                p = encode32(getattr(self, col)[i])
                w += [p >> 16, p & 0xFFFF]
        w.append(crc16_ccitt(w))
        return np.array(w, np.uint16)

    @classmethod
    def from_words(cls, words, name: str | None = None) -> "Record":
        """Decode and validate an uplink image; :class:`RecordError` names the bad field."""
        try:
            a = np.asarray(words)
        except (ValueError, TypeError, OverflowError) as exc:
            raise RecordError(f"record words: not an array of words ({exc})") from None
        if a.ndim != 1:
            raise RecordError(f"record words: expected a 1-D array, got shape {a.shape}")
        if a.size != RECORD_WORDS:
            raise RecordError(f"record words: length {a.size}, expected {RECORD_WORDS}")
        if not np.issubdtype(a.dtype, np.integer) or a.min() < 0 or a.max() > 0xFFFF:
            raise RecordError("record words: every word must be an integer 0..0xFFFF")
        w = [int(x) for x in a]
        crc = crc16_ccitt(w[:-1])
        if crc != w[-1]:
            raise RecordError(f"record words: bad CRC (CRC-16/CCITT 0x{crc:04X} computed, "
                             f"0x{w[-1]:04X} in word {RECORD_WORDS - 1})")
        if w[0] != RECORD_FORMAT_ID:
            raise RecordError(f"record words: format id 0x{w[0]:04X}, expected "
                              f"0x{RECORD_FORMAT_ID:04X}")
        if w[1] != RECORD_WORDS:
            raise RecordError(f"record words: length word {w[1]}, expected {RECORD_WORDS}")
        if w[5] != N_FEATURES:
            raise RecordError(f"record words: feature count {w[5]}, expected {N_FEATURES}")
        code = w[4] >> 8
        if code not in _TYPE_BY_CODE:
            raise RecordError(f"record words: object type code {code} unknown")
        if w[4] & 0xFE:
            raise RecordError(f"record words: flags word 0x{w[4] & 0xFF:02X} has undefined bits "
                              f"set")

        def f32(i, where):
            p = (w[i] << 16) | w[i + 1]
            try:
                return decode32(p)
            except ValueError:
                raise RecordError(f"record words: {where} (words {i}, {i + 1}) is not a normalised "
                                 f"1750A float") from None

        cols = {c: [] for c in COLUMNS}
        k = RECORD_HEADER_WORDS
        for fname in FEATURE_NAMES:
            for col in COLUMNS:
                cols[col].append(f32(k, f"feature {fname!r} {col}"))
                k += 2
        rid = w[2]
        if name is None:
            name = next((r.name for r in _shipped_cache().values() if r.record_id == rid),
                        f"record-{rid}")
        return cls(name=name, record_id=rid, version=w[3], object_type=_TYPE_BY_CODE[code],
                   gof_threshold=f32(6, "gof_threshold"), quantize=bool(w[4] & 1), **cols)

    # ---- TOML ----
    @classmethod
    def from_toml(cls, text: str, source: str = "<string>") -> "Record":
        """Parse and validate the TOML form (module docstring)."""
        if not isinstance(text, str):
            raise RecordError(f"{source}: TOML text must be a str, got {type(text).__name__}")
        try:
            doc = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise RecordError(f"{source}: not valid TOML: {exc}") from None
        head = doc.get("record")
        if not isinstance(head, dict):
            raise RecordError(f"{source}: missing [record] table")
        feats = doc.get("feature")
        if not isinstance(feats, dict):
            raise RecordError(f"{source}: missing [feature.<name>] tables")
        unknown = sorted(set(feats) - set(FEATURE_NAMES))
        if unknown:
            raise RecordError(f"{source}: unknown feature(s) {unknown}; expected {FEATURE_NAMES}")
        missing = [f for f in FEATURE_NAMES if f not in feats]
        if missing:
            raise RecordError(f"{source}: wrong length: feature table(s) {missing} missing "
                             f"({len(feats)} of {N_FEATURES} given)")
        for key in ("name", "id", "version", "object_type"):
            if key not in head:
                raise RecordError(f"{source}: [record] {key} missing")
        extra = sorted(set(head) - {"name", "id", "version", "object_type", "gof_threshold",
                                    "quantize", "description"})
        if extra:
            raise RecordError(f"{source}: [record] unknown key(s) {extra}")
        cols = {c: [] for c in COLUMNS}
        for fname in FEATURE_NAMES:
            t = feats[fname]
            if not isinstance(t, dict):
                raise RecordError(f"{source}: feature.{fname} must be a table")
            bad = sorted(set(t) - set(COLUMNS))
            if bad:
                raise RecordError(f"{source}: feature.{fname}: unknown key(s) {bad}")
            for col in COLUMNS:
                if col not in t:
                    raise RecordError(f"{source}: feature.{fname}.{col} missing")
                cols[col].append(t[col])
        return cls(name=str(head["name"]), record_id=head["id"], version=head["version"],
                   object_type=head["object_type"], gof_threshold=head.get("gof_threshold", 0.0),
                   quantize=head.get("quantize", False),
                   description=str(head.get("description", "")), **cols)

    def to_toml(self, comment: str = "") -> str:
        """The TOML form, written by a TOML library (``tomli_w``: any name or description, quotes
        and backslashes included, reads back as given); numbers as the shortest decimals of their
        1750A values; ``comment`` as ``#`` lines first."""
        import tomli_w
        head = {"name": self.name, "id": int(self.record_id), "version": int(self.version),
                "object_type": self.object_type, "gof_threshold": float(_short(self.gof_threshold)),
                "quantize": bool(self.quantize)}
        if self.description:
            head["description"] = self.description
        doc = {"record": head, "feature": {
            fname: {col: float(_short(getattr(self, col)[i])) for col in COLUMNS}
            for i, fname in enumerate(FEATURE_NAMES)}}
        lines = [f"# {_comment_text(ln)}".rstrip() for ln in comment.splitlines()] if comment else []
        return "".join(f"{ln}\n" for ln in lines) + tomli_w.dumps(doc)


# ------------------------------------------------------------------------------------------------
# shipped records and files
# ------------------------------------------------------------------------------------------------
_SHIPPED: dict | None = None


def _shipped_cache() -> dict:
    global _SHIPPED
    if _SHIPPED is None:
        out = {}
        for entry in sorted(resources.files("flightsw").joinpath("data").iterdir(), key=lambda e: e.name):
            if entry.name.startswith("record_") and entry.name.endswith(".toml"):
                rec = Record.from_toml(entry.read_text(), source=entry.name)
                out[rec.name] = rec
        _SHIPPED = out
    return _SHIPPED


def shipped_records() -> dict:
    """name -> :class:`Record` of every ``flightsw/data/record_*.toml``."""
    return dict(_shipped_cache())


def load_record(name_or_path) -> Record:
    """A shipped record by name ("aurora", "star", "satellite", "plume") or a TOML file path."""
    if isinstance(name_or_path, Record):
        return name_or_path
    s = str(name_or_path)
    shipped = _shipped_cache()
    if s in shipped:
        return shipped[s]
    p = Path(s)
    if p.suffix.lower() == ".toml" or p.exists():
        if not p.exists():
            raise RecordError(f"{p}: no such record file")
        try:
            text = p.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise RecordError(f"{p}: cannot read the record file ({exc.__class__.__name__}: "
                              f"{exc})") from None
        return Record.from_toml(text, source=str(p))
    raise RecordError(f"record {s!r}: not a shipped record ({sorted(shipped)}) nor a .toml file")


class RecordStore:
    """The records in force on board, by record id; one of them selected for ranking.

    ``uplink(words)`` validates a new image and puts it in force (replacing the record with the
    same id); on any error it raises :class:`RecordError` and nothing changes.
    """

    def __init__(self, records=None, active: int | None = None):
        self._records: dict[int, Record] = {}
        for r in (records if records is not None else _shipped_cache().values()):
            self._records[r.record_id] = r
        if not self._records:
            raise RecordError("RecordStore needs at least one record")
        self.active_id = active if active is not None else min(self._records)
        if self.active_id not in self._records:
            raise RecordError(f"active record id {active!r} not among {sorted(self._records)}")

    @property
    def active(self) -> Record:
        return self._records[self.active_id]

    def __getitem__(self, record_id: int) -> Record:
        return self._records[record_id]

    def __contains__(self, record_id) -> bool:
        return record_id in self._records

    def ids(self) -> list:
        return sorted(self._records)

    def select(self, key) -> Record:
        """Make a record active by id or by object type; returns it."""
        if isinstance(key, str):
            for rid in sorted(self._records):
                if self._records[rid].object_type == key:
                    self.active_id = rid
                    return self._records[rid]
            raise RecordError(f"no record in force for object type {key!r}")
        if key not in self._records:
            raise RecordError(f"no record in force with id {key!r}")
        self.active_id = key
        return self._records[key]

    def uplink(self, words) -> Record:
        """Validate an uplinked record image and put it in force; errors leave the store as is."""
        rec = Record.from_words(words)          # raises before anything is changed
        self._records[rec.record_id] = rec
        return rec
