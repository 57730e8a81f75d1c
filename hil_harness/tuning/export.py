"""Export a tuned record (TOML + uplink words) and check either form before uplink.

Uplink words files (the 129-word image of :meth:`flightsw.records.Record.to_words`):

* **binary** (``.bin``, ``.uplink``, ``.dat``): 258 bytes, each 16-bit word big-endian (the 1750A's
  byte order);
* **text** (any other suffix, ``.words`` by convention): one word per line as 4 hexadecimal digits
  (``0x`` prefix optional); ``#`` starts a comment; blank lines are ignored.

:func:`check_record_file` reads a TOML record or a words file (recognised by content: TOML starts with
``[``, ``#`` comment lines or ``key =``; binary is anything that is not text) and returns a
:class:`CheckResult`: the verdict ``OK`` / ``OK with warnings`` / ``REJECTED`` and the reasons.
Rejected are: every error of :class:`~flightsw.records.Record` (wrong length, bad CRC, format id,
unknown object type, undefined flag bits, non-normalised float, sigma <= 0, negative weight,
lower >= upper, lower + upper <= 0, GOF threshold outside [0, 1], no non-zero weight), a file that
is not a whole number of words, and **units / physical range** errors (:func:`unit_problems`):
a feature mean outside what the IP can measure for that feature (or a weighted brightness
threshold above 4095), in the units of :mod:`flightsw.ip.features` at the reference scale -- size, semi-axes, eccentricity and
brightness >= 0, sigma ratio and brightness ratio in [0, 1], orientation in [0, 180] degrees,
average/maximum brightness <= 4095 (12-bit counts), centroid means inside the 244 x 256 frame.
Warnings (not rejected): brightness rows that look like 8-bit data (Table 1's, "note a"), an
orientation row that looks like radians, a weighted feature whose sigma is tiny next to its mean.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flightsw.messages import FEATURE_NAMES
from flightsw.records import RECORD_WORDS, Record
from hil_harness.fileio import temp_beside

__all__ = ["export_record", "write_words", "read_words", "record_from", "check_record_file", "check_record",
           "unit_problems", "CheckResult", "BINARY_SUFFIXES"]

BINARY_SUFFIXES = (".bin", ".uplink", ".dat")
_HEX = re.compile(r"^(0[xX])?[0-9a-fA-F]{1,4}$")

#: feature -> (min, max) physically possible value (None: unbounded), units of flightsw.ip.features
RANGES = {
    "size": (0.0, None), "col": (0.0, 256.0), "row": (0.0, 244.0), "orientation": (0.0, 180.0),
    "eccentricity": (0.0, None), "semimajor": (0.0, None), "semiminor": (0.0, None),
    "sigma_ratio": (0.0, 1.0), "total_brightness": (0.0, None), "avg_brightness": (0.0, 4095.0),
    "max_brightness": (0.0, 4095.0), "brightness_ratio": (0.0, 1.0),
}


def _atomic_write(path, data: bytes):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_beside(path, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def write_words(path, words, comment: str = "") -> Path:
    """Write uplink words (binary big-endian for .bin/.uplink/.dat, else hex text), atomically."""
    w = np.asarray(words)
    if w.ndim != 1 or not np.issubdtype(w.dtype, np.integer) or (w.size and (w.min() < 0
                                                                            or w.max() > 0xFFFF)):
        raise ValueError("write_words: expected a 1-D array of 16-bit words")
    p = Path(path)
    if p.suffix.lower() in BINARY_SUFFIXES:
        _atomic_write(p, w.astype(">u2").tobytes())
    else:
        head = "".join(f"# {ln}\n" for ln in comment.splitlines()) if comment else ""
        _atomic_write(p, (head + "".join(f"{int(x):04X}\n" for x in w)).encode())
    return p


def _is_text(data: bytes) -> bool:
    if not data:
        return True
    try:
        s = data.decode("ascii")
    except UnicodeDecodeError:
        return False
    return all(ch.isprintable() or ch in "\r\n\t" for ch in s)


def read_words(path) -> np.ndarray:
    """Read a words file (module docstring) -> int64 array; ValueError on a malformed file."""
    p = Path(path)
    data = p.read_bytes()
    if p.suffix.lower() in BINARY_SUFFIXES or not _is_text(data):
        if len(data) % 2:
            raise ValueError(f"{p}: {len(data)} bytes is not a whole number of 16-bit words")
        return np.frombuffer(data, ">u2").astype(np.int64)
    out = []
    for n, ln in enumerate(data.decode("ascii").splitlines(), start=1):
        s = ln.split("#", 1)[0].strip()
        if not s:
            continue
        for j, tok in enumerate(s.replace(",", " ").split(), start=1):
            if not _HEX.match(tok):     # the text is not quoted: the file may be anyone's
                raise ValueError(f"{p}: line {n}: item {j} ({len(tok)} characters) is not a 16-bit "
                                 f"hexadecimal word (1 to 4 hex digits, optional 0x)")
            out.append(int(tok, 16))
    return np.array(out, np.int64)


def record_from(spec) -> Record:
    """The record a ``--record`` option names: a shipped name, a record TOML, or an uplink image
    (a words file, text or binary, as scenario uplinks take; ``.words``, ``.bin``...). Errors
    name the file."""
    from flightsw.records import RecordError, load_record
    p = Path(str(spec))
    if isinstance(spec, Record) or p.suffix.lower() == ".toml" or not p.is_file():
        return load_record(spec)
    data = p.read_bytes()
    if _looks_like_toml(data):
        return load_record(p)
    try:
        return Record.from_words(read_words(p), name=p.stem)
    except RecordError as exc:
        raise ValueError(f"{p}: not a record uplink image: {exc}") from None


def export_record(record: Record, toml_path=None, words_path=None, comment: str = "") -> dict:
    """Write the TOML form and/or the uplink words (both atomically); returns the paths and CRC."""
    out = {}
    words = record.to_words()
    if toml_path is not None:
        text = record.to_toml(comment)
        if Record.from_toml(text, source=str(toml_path)) != record:     # checked before writing
            raise ValueError(f"{toml_path}: the record's TOML does not read back to the record")
        _atomic_write(toml_path, text.encode())
        out["toml"] = str(toml_path)
    if words_path is not None:
        write_words(words_path, words, f"uplink image of record {record.name!r} id "
                                       f"{record.record_id} version {record.version}: "
                                       f"{RECORD_WORDS} words, CRC 0x{int(words[-1]):04X}")
        out["words"] = str(words_path)
    out["crc"] = f"0x{int(words[-1]):04X}"
    # the written forms must read back to the same record
    if toml_path is not None:
        back = Record.from_toml(Path(toml_path).read_text(), source=str(toml_path))
        if back != record:
            raise ValueError(f"{toml_path}: TOML does not read back to the same record")
    if words_path is not None:
        back = Record.from_words(read_words(words_path), name=record.name)
        if back.to_words().tolist() != words.tolist():
            raise ValueError(f"{words_path}: words do not read back to the same record")
    return out


def unit_problems(record: Record) -> tuple[list, list]:
    """(errors, warnings): physical-range / unit checks of a valid record (module docstring)."""
    errors, warns = [], []
    for i, name in enumerate(FEATURE_NAMES):
        lo, hi = RANGES[name]
        for col in ("mean", "lower", "upper"):
            v = getattr(record, col)[i]
            # thresholds only place the sigmoid's midpoint: checked for units (12-bit brightness)
            if col != "mean" and (record.weight[i] == 0.0 or name not in ("avg_brightness",
                                                                          "max_brightness")):
                continue
            if lo is not None and v < lo - 1e-9 and col == "mean":
                errors.append(f"feature {name!r} {col} = {v:g} is below {lo:g}, impossible for "
                              f"this feature")
            if hi is not None and v > hi + 1e-9:
                unit = " (12-bit counts)" if "brightness" in name else ""
                errors.append(f"feature {name!r} {col} = {v:g} is above {hi:g}{unit}, impossible "
                              f"for this feature")
        if record.weight[i] > 0 and record.sigma[i] < 1e-6 * max(abs(record.mean[i]), 1.0):
            warns.append(f"feature {name!r}: sigma {record.sigma[i]:g} is tiny next to the mean "
                         f"{record.mean[i]:g} (the coefficient w/sigma^2 dominates the distance)")
    mx = record.mean[FEATURE_NAMES.index("max_brightness")]
    up = record.upper[FEATURE_NAMES.index("max_brightness")]
    if mx <= 255.0 and up <= 255.0:
        warns.append(f"brightness rows look like 8-bit counts (max_brightness mean {mx:g}, upper "
                     f"{up:g}); UVISI frames are 12-bit (0..4095)")
    io = FEATURE_NAMES.index("orientation")
    if record.weight[io] > 0 and record.upper[io] <= 3.2 and abs(record.mean[io]) <= 3.2:
        warns.append("orientation row looks like radians; the IP measures degrees in [0, 180)")
    return errors, warns


@dataclass
class CheckResult:
    path: str
    kind: str                       # "toml" | "words (binary)" | "words (text)"
    record: Record | None = None
    errors: list = field(default_factory=list)
    warnings: list = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.errors

    @property
    def verdict(self) -> str:
        if self.errors:
            return "REJECTED"
        return "OK with warnings" if self.warnings else "OK"

    def lines(self) -> list:
        out = [f"{self.path}: {self.verdict} ({self.kind})"]
        r = self.record
        if r is not None:
            w = r.to_words()
            out.append(f"  record {r.name!r} id {r.record_id} version {r.version}, object type "
                       f"{r.object_type}, n = {r.n_weighted}, quantize "
                       f"{'on' if r.quantize else 'off'}, GOF threshold {r.gof_threshold:.6g}, "
                       f"uplink CRC 0x{int(w[-1]):04X}")
        out += [f"  error: {e}" for e in self.errors]
        out += [f"  warning: {e}" for e in self.warnings]
        return out


def check_record(record: Record, path="<record>", kind="record") -> CheckResult:
    errs, warns = unit_problems(record)
    return CheckResult(str(path), kind, record, errs, warns)


def _looks_like_toml(data: bytes) -> bool:
    if not _is_text(data):
        return False
    for ln in data.decode("ascii", "replace").splitlines():
        s = ln.strip()
        if not s or s.startswith("#"):
            continue
        return s.startswith("[") or bool(re.match(r"^[A-Za-z_][\w.\-]*\s*=", s))
    return False


def check_record_file(path) -> CheckResult:
    """Validate a TOML record or an uplink words file (module docstring); never raises for a bad
    record (the reasons are in the result), only for a missing file."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir():
        return CheckResult(str(p), "folder", None, ["a folder, not a record file"])
    try:
        data = p.read_bytes()
    except OSError as exc:
        return CheckResult(str(p), "unreadable", None, [f"cannot read: {exc.strerror or exc}"])
    if p.suffix.lower() == ".toml" or (p.suffix.lower() not in BINARY_SUFFIXES
                                       and _looks_like_toml(data)):
        try:
            rec = Record.from_toml(data.decode("utf-8"), source=p.name)
        except UnicodeDecodeError:
            return CheckResult(str(p), "toml", None, ["not UTF-8 text"])
        except ValueError as exc:
            return CheckResult(str(p), "toml", None, [str(exc)])
        return check_record(rec, p, "toml")
    kind = "words (binary)" if (p.suffix.lower() in BINARY_SUFFIXES or not _is_text(data)) \
        else "words (text)"
    try:
        words = read_words(p)
        rec = Record.from_words(words)
    except ValueError as exc:
        return CheckResult(str(p), kind, None, [str(exc)])
    return check_record(rec, p, kind)
