"""The uplink form of a processing sequence: 16-bit words with a CRC.

The MSX paper: the toolbox routines "can be selected and sequenced ... via uplink command before a
tracking event". This is that command's image, in the style of the record uplink
(:mod:`flightsw.records`): a header, one tagged entry per step, a CRC. The ground-side ``name`` and
``description`` are not uplinked. A rank step that names its own record file cannot be uplinked
(uplink the record, which the sequence then ranks with).

=========  ===============================================================================
word       content
=========  ===============================================================================
0          format id ``0x5351`` ("SQ")
1          length in words, header and CRC included
2          compaction factor (1, 2, 4)
3          window size (processed pixels)
4          number of steps S
...        S steps, each: ``op code << 8 | number of fields F``, then F fields, each
           ``key code << 8 | type code`` followed by its value words:

           * type 1 int: one word, two's complement (-32768..32767)
           * type 2 float: two words, a 1750A 32-bit float (nearest)
           * type 3 bool: one word, 0 or 1
           * type 4 enumeration: one word, the value's code (:data:`ENUMS`)
           * type 5 vector of Q1.15 words: a count word n (1..63), then n words
           * type 6 square matrix of Q1.15 words: a side word n (3..63, odd), then n*n words,
             row by row
last       CRC-16/CCITT-FALSE over every preceding word (:func:`flightsw.messages.crc16_ccitt`)
=========  ===============================================================================

Op codes (:data:`OP_CODES`): filter 1, filter_fft 2, detrend 3, threshold 4, colour 5, label 6,
features 7, rank 8. Key codes (:data:`KEYS`): kernel 1, size 2, sigma 3, coefficients 4, tile 5,
method 6, taps 7, alpha 8, mode 9, diagonal 10, intensity_centroid 11, max_candidates 12,
alpha_min 13, alpha_min_sparse 14, sparse_blobs 15, alpha_min_locked 16, locked_blobs 17.

:func:`sequence_from_words` checks the words' format (id, length, CRC, codes, types, value ranges,
nothing left over) and then the sequence's meaning (:meth:`ProcessingSequence.from_dict`, the same
rules as a TOML file); any failure is a :class:`~flightsw.ip.sequence.SequenceError` naming the word.
"""
from __future__ import annotations

import numpy as np

from flightsw.arith.m1750 import decode32, encode32
from flightsw.ip.sequence import ProcessingSequence, SequenceError
from flightsw.messages import crc16_ccitt

__all__ = ["SEQUENCE_FORMAT_ID", "OP_CODES", "KEYS", "ENUMS", "sequence_to_words",
           "sequence_from_words"]

SEQUENCE_FORMAT_ID = 0x5351
OP_CODES = {"filter": 1, "filter_fft": 2, "detrend": 3, "threshold": 4, "colour": 5, "label": 6,
            "features": 7, "rank": 8}
T_INT, T_FLOAT, T_BOOL, T_ENUM, T_VECTOR, T_MATRIX = 1, 2, 3, 4, 5, 6
#: key name -> (code, type code)
KEYS = {"kernel": (1, T_ENUM), "size": (2, T_INT), "sigma": (3, T_FLOAT),
        "coefficients": (4, T_MATRIX), "tile": (5, T_INT), "method": (6, T_ENUM),
        "taps": (7, T_VECTOR), "alpha": (8, T_FLOAT), "mode": (9, T_ENUM),
        "diagonal": (10, T_BOOL), "intensity_centroid": (11, T_BOOL),
        "max_candidates": (12, T_INT), "alpha_min": (13, T_FLOAT),
        "alpha_min_sparse": (14, T_FLOAT), "sparse_blobs": (15, T_INT),
        "alpha_min_locked": (16, T_FLOAT), "locked_blobs": (17, T_INT)}
#: enumeration key -> its values in code order (code = index + 1)
ENUMS = {"kernel": ("smooth", "matched", "custom", "gaussian"),
         "method": ("highpass", "polynomial", "none"),
         "mode": ("binarize", "clip")}
_OP_BY_CODE = {v: k for k, v in OP_CODES.items()}
_KEY_BY_CODE = {v[0]: k for k, v in KEYS.items()}
_HEADER = 5
_MAX_VECTOR = 63


def _value_words(key: str, value, where: str) -> list[int]:
    code, typ = KEYS[key]
    head = [(code << 8) | typ]
    if typ == T_INT:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                or not -32768 <= int(value) <= 32767:
            raise SequenceError(f"{where}: {key} = {value!r} is not a 16-bit integer", field=key)
        return head + [int(value) & 0xFFFF]
    if typ == T_FLOAT:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not np.isfinite(value):
            raise SequenceError(f"{where}: {key} = {value!r} is not a finite number", field=key)
        p = encode32(float(value), rounding="nearest")
        return head + [(p >> 16) & 0xFFFF, p & 0xFFFF]
    if typ == T_BOOL:
        if not isinstance(value, (bool, np.bool_)):
            raise SequenceError(f"{where}: {key} = {value!r} is not a boolean", field=key)
        return head + [int(bool(value))]
    if typ == T_ENUM:
        if value not in ENUMS[key]:
            raise SequenceError(f"{where}: {key} = {value!r} not one of {ENUMS[key]}", field=key)
        return head + [ENUMS[key].index(value) + 1]
    a = np.asarray(value)
    if a.dtype == object or not np.issubdtype(a.dtype, np.integer) or \
            (a.size and (a.min() < -32768 or a.max() > 32767)):
        raise SequenceError(f"{where}: {key} must be Q1.15 words", field=key)
    if typ == T_VECTOR:
        if a.ndim != 1 or not 1 <= a.size <= _MAX_VECTOR:
            raise SequenceError(f"{where}: {key} must hold 1..{_MAX_VECTOR} words", field=key)
        return head + [a.size] + [int(x) & 0xFFFF for x in a]
    if a.ndim != 2 or a.shape[0] != a.shape[1] or not 3 <= a.shape[0] <= _MAX_VECTOR:
        raise SequenceError(f"{where}: {key} must be a square matrix of side 3..{_MAX_VECTOR}",
                            field=key)
    return head + [a.shape[0]] + [int(x) & 0xFFFF for x in a.ravel()]


def sequence_to_words(sequence: ProcessingSequence) -> np.ndarray:
    """The uplink image of a sequence: uint16 [n] words (module docstring)."""
    d = sequence.to_dict()
    words = [SEQUENCE_FORMAT_ID, 0, int(d["preprocess"]["compaction"]),
             int(d["preprocess"]["window"]), len(d["steps"])]
    for i, step in enumerate(d["steps"]):
        where = f"step {i} {step.get('op')!r}"
        fields = {k: v for k, v in step.items() if k != "op"}
        if "record" in fields:
            raise SequenceError(f"{where}: a rank step naming its own record cannot be uplinked; "
                                f"uplink the record", step=i, field="record")
        unknown = sorted(set(fields) - set(KEYS))
        if unknown:
            raise SequenceError(f"{where}: field {unknown[0]!r} has no uplink code", step=i,
                                field=unknown[0])
        words.append((OP_CODES[step["op"]] << 8) | len(fields))
        for key, value in fields.items():
            words += _value_words(key, value, where)
    words[1] = len(words) + 1
    words.append(crc16_ccitt(np.asarray(words, np.uint16)))
    return np.asarray(words, np.uint16)


class _Reader:
    """Walks the words, each read naming its index in any error."""

    def __init__(self, w: np.ndarray):
        self.w, self.i = w, 0

    def take(self, what: str) -> int:
        if self.i >= len(self.w) - 1:               # the last word is the CRC
            raise SequenceError(f"word {self.i}: the words end inside {what}")
        v = int(self.w[self.i])
        self.i += 1
        return v

    def fail(self, what: str, back: int = 1):
        raise SequenceError(f"word {self.i - back}: {what}")


def _signed(v: int) -> int:
    return v - 0x10000 if v & 0x8000 else v


def _read_value(r: _Reader, key: str, typ: int):
    if typ == T_INT:
        return _signed(r.take(key))
    if typ == T_FLOAT:
        hi, lo = r.take(key), r.take(key)
        try:
            return decode32((hi << 16) | lo)
        except ValueError:
            r.fail(f"{key}: not a normalised 1750A 32-bit float", 2)
    if typ == T_BOOL:
        v = r.take(key)
        if v not in (0, 1):
            r.fail(f"{key}: boolean word {v} is not 0 or 1")
        return bool(v)
    if typ == T_ENUM:
        v = r.take(key)
        if not 1 <= v <= len(ENUMS[key]):
            r.fail(f"{key}: code {v} is not one of 1..{len(ENUMS[key])}")
        return ENUMS[key][v - 1]
    n = r.take(key)
    if typ == T_VECTOR:
        if not 1 <= n <= _MAX_VECTOR:
            r.fail(f"{key}: count {n} outside 1..{_MAX_VECTOR}")
        return [_signed(r.take(key)) for _ in range(n)]
    if not 3 <= n <= _MAX_VECTOR or n % 2 == 0:
        r.fail(f"{key}: side {n} is not odd in 3..{_MAX_VECTOR}")
    flat = [_signed(r.take(key)) for _ in range(n * n)]
    return [flat[k * n:(k + 1) * n] for k in range(n)]


def _read_step(r: _Reader, index: int) -> dict:
    head = r.take(f"step {index}")
    op = _OP_BY_CODE.get(head >> 8)
    if op is None:
        r.fail(f"step {index}: op code {head >> 8} is not defined")
    step = {"op": op}
    for _ in range(head & 0xFF):
        kt = r.take(f"step {index} ({op})")
        key = _KEY_BY_CODE.get(kt >> 8)
        if key is None:
            r.fail(f"step {index} ({op}): key code {kt >> 8} is not defined")
        if KEYS[key][1] != (kt & 0xFF):
            r.fail(f"step {index} ({op}): {key} has type code {kt & 0xFF}, expected {KEYS[key][1]}")
        if key in step:
            r.fail(f"step {index} ({op}): {key} given twice")
        step[key] = _read_value(r, key, kt & 0xFF)
    return step


def sequence_from_words(words, name: str = "uplinked") -> ProcessingSequence:
    """Decode and validate an uplinked sequence (module docstring); ``name`` is the ground-side name
    given to the result. Raises :class:`SequenceError` naming the word at fault."""
    w = np.asarray(words)
    if w.ndim != 1 or w.size < _HEADER + 1:
        raise SequenceError(f"a sequence uplink needs at least {_HEADER + 1} words, got {w.size}")
    if not np.issubdtype(w.dtype, np.integer) or w.min() < 0 or w.max() > 0xFFFF:
        raise SequenceError("a sequence uplink is 16-bit words (0..65535)")
    w = w.astype(np.uint16)
    if int(w[0]) != SEQUENCE_FORMAT_ID:
        raise SequenceError(f"word 0: format id 0x{int(w[0]):04X} is not 0x{SEQUENCE_FORMAT_ID:04X}")
    if int(w[1]) != w.size:
        raise SequenceError(f"word 1: length {int(w[1])} but {w.size} words were received")
    crc = crc16_ccitt(w[:-1])
    if crc != int(w[-1]):
        raise SequenceError(f"word {w.size - 1}: CRC 0x{int(w[-1]):04X}, computed 0x{crc:04X}")
    r = _Reader(w)
    r.i = 2
    compaction, window, n_steps = r.take("header"), r.take("header"), r.take("header")
    steps = [_read_step(r, k) for k in range(n_steps)]
    if r.i != w.size - 1:
        raise SequenceError(f"word {r.i}: {w.size - 1 - r.i} word(s) after the last step")
    return ProcessingSequence.from_dict({"name": name, "preprocess": {"compaction": compaction,
                                                                      "window": window},
                                         "steps": steps})
