"""Messages between the flight subsystems.

Conventions shared by every message (``shared/DESIGN.md``):

* Quaternions are scalar-first ``(w, x, y, z)`` and rotate body-frame vectors into the inertial (ECI,
  J2000) frame: ``v_eci = R(q) @ v_body``.
* The body frame has the UVISI boresight along +X; an imager pixel ``(row, col)`` (pixel centres at
  ``+0.5``) maps to the imager-frame direction ``(1, x, y)`` normalised, with
  ``x = (col - 128.0) * scale_col`` and ``y = (row - 122.0) * scale_row`` (gnomonic, tangent-plane
  radians per pixel): the paper's measurement unit vector ``(~1, e1, e2)``.
* Positions in metres, velocities in m/s, angles in radians, times in seconds.

Codecs: each message has one encoder (``to_words``: field checks, then one jitted kernel) and one
decoder (``from_words``: one jitted kernel checks every rule, a second fills the fields). A decoder
refuses anything its encoder would not write -- wrong id, length, count or CRC, unknown codes,
compaction 0, undefined status or flag bits, non-zero reserved or absent words, a 1750A float that
is not normalised -- with :class:`MessageError` (a ``ValueError``) naming the word and the field, so
``from_words(w).to_words()`` equals ``w`` for every accepted ``w``. :class:`Feedback` has no words
of its own: it rides in the track command (flags word 8, words 21-24, object type in word 6).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from flightsw.arith.m1750_float import (decode32_k, decode48_k, encode_k, is_normalized32_k,
                                        is_normalized48_k)
from flightsw.numba_cache import KERNEL, callee_kernel


@dataclass
class AttitudeData:
    """What the MSX attitude processor hands the track processor each frame.

    Attributes
    ----------
    t : float
        Time tag, s since the event epoch.
    q_body_to_eci : ndarray (4,) float64
        Attitude quaternion, scalar first, body -> ECI (as known on board, i.e. with knowledge error).
    rate_body : ndarray (3,) float64
        Body angular rate in body axes, rad/s.
    r_eci : ndarray (3,) float64
        Spacecraft position, m (ECI).
    v_eci : ndarray (3,) float64
        Spacecraft velocity, m/s (ECI).
    valid : bool
        False when the attitude processor has no data for this frame (a gap); the TP coasts.
    """

    t: float
    q_body_to_eci: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    rate_body: np.ndarray = field(default_factory=lambda: np.zeros(3))
    r_eci: np.ndarray = field(default_factory=lambda: np.zeros(3))
    v_eci: np.ndarray = field(default_factory=lambda: np.zeros(3))
    valid: bool = True


# ================================================================================================
# IP <-> TP messages: the candidate message (IP -> TP) and the feedback (TP -> IP)
# ================================================================================================
#: The twelve features of the MSX paper's boxed equations, in Table 1's order (the order of every
#: record, feature array and message in this package).
FEATURE_NAMES = ("size", "col", "row", "orientation", "eccentricity", "semimajor", "semiminor",
                 "sigma_ratio", "total_brightness", "avg_brightness", "max_brightness",
                 "brightness_ratio")
N_FEATURES = len(FEATURE_NAMES)
MAX_CANDIDATES = 23          # "Up to 23 candidates ... are reported to the MSX TP" (MSX paper)

#: imager id <-> 4-bit code in the message header ("real" = an image from outside the simulator)
IMAGER_CODES = {"wfov_vis": 0, "nfov_vis": 1, "wfov_uv": 2, "nfov_uv": 3, "real": 15}
_IMAGER_BY_CODE = {v: k for k, v in IMAGER_CODES.items()}

#: one reported candidate, as it travels (every float is a 1750A 32-bit value, decoded exactly)
CANDIDATE_DTYPE = np.dtype([("label", np.int64), ("distance", np.float64), ("gof", np.float64)]
                           + [(n, np.float64) for n in FEATURE_NAMES])

CANDIDATE_MSG_ID = 0x4950    # "IP"
CANDIDATE_HEADER_WORDS = 15
CANDIDATE_WORDS = 1 + 2 * (2 + N_FEATURES)   # label, distance, gof, 12 features = 29 words


def _crc_table() -> np.ndarray:
    t = np.zeros(256, np.uint16)
    for b in range(256):
        c = b << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
        t[b] = c
    t.setflags(write=False)     # read-only, as numba types a global array in a kernel: Python's
    return t                    # calls and the kernels' share one compiled specialisation


_CRC_TABLE = _crc_table()


@njit(**KERNEL)
def _crc_range(w, n, table):
    """Table-driven CRC-16/CCITT-FALSE of the first ``n`` 16-bit words of ``w`` (MSB first).

    ``w`` int64 or uint16 [>= n] words 0..0xFFFF; ``table`` uint16 [256] (poly 0x1021) -> int.

    Cases
    -----
    typical : equals CRC-16/CCITT-FALSE (init 0xFFFF, no reflection) of the words' big-endian bytes.
    prefix : only the first ``n`` words count (the encoders' trailing CRC word is excluded).
    empty : ``n == 0`` -> the initial value 0xFFFF.
    """
    crc = 0xFFFF
    for i in range(n):
        x = w[i]
        crc = ((crc << 8) & 0xFFFF) ^ table[((crc >> 8) ^ ((x >> 8) & 0xFF)) & 0xFF]
        crc = ((crc << 8) & 0xFFFF) ^ table[((crc >> 8) ^ (x & 0xFF)) & 0xFF]
    return crc


def crc16_ccitt(words) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0) over 16-bit words,
    each fed most significant byte first. Check value: ``crc16_ccitt_bytes(b"123456789") == 0x29B1``.
    Table driven, in one jitted call (the flight software's bus check runs every frame).

    Parameters
    ----------
    words : iterable of int, each 0..0xFFFF
    """
    w = np.asarray(words if isinstance(words, np.ndarray) else list(words))
    if w.size == 0:
        return 0xFFFF
    if w.dtype.kind not in "iu":
        if not np.all(np.equal(np.mod(w, 1), 0)):
            raise ValueError("crc16_ccitt: words must be integers")
        w = w.astype(np.int64)
    bad = (w < 0) | (w > 0xFFFF)
    if np.any(bad):
        raise ValueError(f"crc16_ccitt: word {int(w[bad][0])!r} is not a 16-bit word")
    w = np.ascontiguousarray(w, dtype=np.int64).ravel()
    return int(_crc_range(w, w.shape[0], _CRC_TABLE))


def crc16_ccitt_bytes(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of a byte string (see :func:`crc16_ccitt`), bit by bit (the reference the
    table-driven word CRC is tested against)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


# ================================================================================================
# errors and the checks every codec shares
# ================================================================================================
class MessageError(ValueError):
    """A message that cannot be encoded or decoded. ``message`` names the message ("candidate
    message", "track command"), ``word`` the index of the offending word (None when an encoder
    refuses a field value) and ``field`` the field; ``str()`` says all three and why."""

    def __init__(self, message, word, field, reason):
        where = f"{message}: " + (f"word {word} ({field})" if word is not None else str(field))
        super().__init__(f"{where}: {reason}")
        self.message, self.word, self.field, self.reason = message, word, field, reason


def _int_field(owner, name, v, lo, hi):
    """``v`` as an int in ``lo..hi`` (Python or NumPy integer, not a bool) or MessageError."""
    if type(v) is int and lo <= v <= hi:
        return v
    if isinstance(v, np.integer) and lo <= v <= hi:
        return int(v)
    raise MessageError(owner, None, name, f"{v!r} must be an int in {lo}..{hi}")


def _real_field(owner, name, v):
    """``v`` as a finite float (Python or NumPy real, not a bool) or MessageError."""
    if type(v) is float or (isinstance(v, (float, int, np.floating, np.integer))
                            and not isinstance(v, (bool, np.bool_))):
        if math.isfinite(v):
            return float(v)
    raise MessageError(owner, None, name, f"{v!r} must be a finite number")


def _word_array(owner, words) -> np.ndarray:
    """Received words as a 1-D int64 array (values not yet range-checked) or MessageError."""
    try:
        w = np.asarray(words)
    except (ValueError, TypeError, OverflowError) as exc:
        raise MessageError(owner, None, "words", f"not an array of words ({exc})") from None
    if w.ndim != 1 or w.dtype.kind not in "iu":
        raise MessageError(owner, None, "words", f"expected a 1-D integer array, got {w.dtype} "
                           f"{w.shape}")
    return w.astype(np.int64)          # uint64 above 2**63 wraps negative: the kernels refuse it


def _code_table(codes) -> np.ndarray:
    """bool[256]: which byte values are codes of ``codes`` (a name -> code dict), for kernels."""
    t = np.zeros(256, np.bool_)
    t[list(codes.values())] = True
    t.setflags(write=False)                         # as _crc_table's
    return t


_IMAGER_OK = _code_table(IMAGER_CODES)

# verdicts of the decoding kernels (with the word index they concern); 0: well formed
_BAD_WORD, _BAD_ID, _BAD_LENGTH, _BAD_CRC, _BAD_CODE, _BAD_FLOAT, _NOT_ZERO, _BAD_FLAGS, \
    _BAD_RANGE, _BAD_COUNT, _BAD_CODE2 = range(1, 12)
_REASONS = {_BAD_WORD: "not a 16-bit word (0..0xFFFF)", _BAD_ID: "wrong message id",
            _BAD_LENGTH: "length word, count and words received do not agree",
            _BAD_CRC: "bad checksum (CRC-16/CCITT over the preceding words)",
            _BAD_CODE: "unknown imager code (high byte)",
            _BAD_CODE2: "unknown code (low byte)",
            _BAD_FLOAT: "not a normalised 1750A float or floating zero",
            _NOT_ZERO: "reserved or absent value must be zero words",
            _BAD_FLAGS: "undefined bits set", _BAD_RANGE: "out of range",
            _BAD_COUNT: f"candidate count above {MAX_CANDIDATES}"}


@callee_kernel
def _words_ok(w):
    """Index of the first word outside 0..0xFFFF, -1 if none (``w`` int64 [n]).

    Cases
    -----
    all-words : every value in 0..0xFFFF (both ends included) -> -1.
    negative : a negative value -> its index (the first bad one).
    too-large : a value above 0xFFFF -> its index.
    """
    for i in range(w.shape[0]):
        if w[i] < 0 or w[i] > 0xFFFF:
            return i
    return -1


@callee_kernel
def _f32_at(w, i):
    """Words ``i``, ``i + 1`` of ``w`` (int64, 16-bit values) -> the packed 32-bit 1750A float.

    Cases
    -----
    typical : ``(w[i] << 16) | w[i + 1]`` (mantissa high word first, as MIL-STD-1750A 4.1.5).
    """
    return (w[i] << 16) | w[i + 1]


@callee_kernel
def _f48_at(w, i):
    """Words ``i`` .. ``i + 2`` of ``w`` (int64, 16-bit values) -> the packed 48-bit 1750A float.

    Cases
    -----
    typical : ``(w[i] << 32) | (w[i + 1] << 16) | w[i + 2]`` (the standard's 48-bit word order).
    """
    return (w[i] << 32) | (w[i + 1] << 16) | w[i + 2]


# ================================================================================================
# the candidate message codec (one jitted encoder, one jitted checker + filler)
# ================================================================================================
@callee_kernel
def _cand_encode_k(head, t, alpha, iv, fv, out, table):
    """Candidate message words into ``out`` (uint16): ``head`` int64[15] header words (3-5 and
    11-12 are filled here from the time tag ``t`` and ``alpha``, finite float64), ``iv``/``fv``
    int64/float64 views (k, 15) of the candidates. Returns -1 when written, else the candidate
    index of a label outside 0..0xFFFF (``k + i``: of candidate ``i``'s non-finite value).

    Cases
    -----
    header : words 3-5 the time tag (48-bit, nearest), 11-12 alpha (32-bit, nearest), the rest as
        given.
    candidates : per candidate its label word then 14 values as 32-bit floats (two words each).
    crc : the last word is the CRC of all the words before it.
    no-candidates : ``k == 0`` -> the 15 header words and the CRC.
    bad-label : a label outside 0..0xFFFF -> its candidate index, nothing written.
    non-finite : a NaN or infinite value in candidate i -> ``k + i``, nothing written.
    """
    p = encode_k(t, 39, True)
    head[3], head[4], head[5] = (p >> 32) & 0xFFFF, (p >> 16) & 0xFFFF, p & 0xFFFF
    p = encode_k(alpha, 23, True)
    head[11], head[12] = (p >> 16) & 0xFFFF, p & 0xFFFF
    k = iv.shape[0]
    for i in range(k):
        if iv[i, 0] < 0 or iv[i, 0] > 0xFFFF:
            return i
        for j in range(1, 15):
            if not math.isfinite(fv[i, j]):
                return k + i
    n = 0
    for i in range(15):
        out[n] = head[i]
        n += 1
    for i in range(k):
        out[n] = iv[i, 0]
        n += 1
        for j in range(1, 15):
            p = encode_k(fv[i, j], 23, True)
            out[n] = (p >> 16) & 0xFFFF
            out[n + 1] = p & 0xFFFF
            n += 2
    out[n] = _crc_range(out, n, table)
    return -1


@njit(**KERNEL)
def _cand_check_k(w, table, imager_ok):
    """Every rule of the candidate message on int64 words ``w`` -> (verdict, word index, time tag,
    alpha); verdict 0 when the message is well formed (:data:`_REASONS` otherwise).

    Rules in this order; the first that fails gives the verdict and the word it names.

    Cases
    -----
    well-formed : verdict 0 with the decoded time tag and alpha.
    bad-word : a value outside 0..0xFFFF -> ``_BAD_WORD`` at its index.
    short : fewer than 16 words -> ``_BAD_LENGTH`` at word 1 (word 0 when at most one word).
    bad-id : word 0 not 0x4950 -> ``_BAD_ID``.
    bad-count : count (word 14) above 23 -> ``_BAD_COUNT``.
    bad-length : length word, count and words received disagree -> ``_BAD_LENGTH`` at word 1.
    bad-crc : last word not the CRC of the others -> ``_BAD_CRC`` at the last word.
    bad-imager : unknown imager code (word 6 high byte) -> ``_BAD_CODE``.
    compaction-zero : compaction (word 6 low byte) 0 -> ``_BAD_RANGE``.
    bad-time-tag : words 3-5 not a normalised 48-bit float or zero -> ``_BAD_FLOAT`` at 3.
    bad-alpha : words 11-12 not normalised -> ``_BAD_FLOAT`` at 11.
    bad-candidate-float : a candidate value not normalised -> ``_BAD_FLOAT`` at its first word.
    """
    n = w.shape[0]
    bad = _words_ok(w)
    if bad >= 0:
        return _BAD_WORD, bad, 0.0, 0.0
    if n < 16:
        return _BAD_LENGTH, 1 if n > 1 else 0, 0.0, 0.0
    if w[0] != 0x4950:
        return _BAD_ID, 0, 0.0, 0.0
    k = w[14]
    if k > 23:
        return _BAD_COUNT, 14, 0.0, 0.0
    if w[1] != 15 + 29 * k + 1 or n != w[1]:
        return _BAD_LENGTH, 1, 0.0, 0.0
    if _crc_range(w, n - 1, table) != w[n - 1]:
        return _BAD_CRC, n - 1, 0.0, 0.0
    if not imager_ok[w[6] >> 8]:
        return _BAD_CODE, 6, 0.0, 0.0
    if (w[6] & 0xFF) == 0:
        return _BAD_RANGE, 6, 0.0, 0.0
    if not is_normalized48_k(_f48_at(w, np.int64(3))):
        return _BAD_FLOAT, 3, 0.0, 0.0
    if not is_normalized32_k(_f32_at(w, np.int64(11))):
        return _BAD_FLOAT, 11, 0.0, 0.0
    for i in range(k):
        b = 15 + 29 * i
        for j in range(14):
            if not is_normalized32_k(_f32_at(w, b + 1 + 2 * j)):
                return _BAD_FLOAT, b + 1 + 2 * j, 0.0, 0.0
    return 0, 0, decode48_k(_f48_at(w, np.int64(3))), decode32_k(_f32_at(w, np.int64(11)))


@njit(**KERNEL)
def _cand_fill_k(w, iv, fv):
    """Candidates of checked words ``w`` into the int64/float64 views (k, 15) of the array.

    Cases
    -----
    typical : per candidate the label and 14 exactly decoded 32-bit values (column 0 of ``fv``
        is the label's slot and left to ``iv``).
    """
    for i in range(iv.shape[0]):
        b = 15 + 29 * i
        iv[i, 0] = w[b]
        for j in range(14):
            fv[i, 1 + j] = decode32_k(_f32_at(w, b + 1 + 2 * j))


@callee_kernel
def candidate_words_k(head, t, alpha, iv, fv, out):
    """The candidate message's one encoder for compiled callers (:meth:`CandidateMessage.to_words`
    runs the same kernel): :func:`_cand_encode_k` with the CRC table. ``head`` int64 [15], ``t``
    and ``alpha`` finite float64, ``iv``/``fv`` int64/float64 views [k, 15] of the candidates,
    ``out`` uint16 [15 + 29 k + 1]. Returns -1 when written, else the failing candidate's code.

    Cases
    -----
    typical : the words :meth:`CandidateMessage.to_words` writes for the same fields.
    bad-label : a label outside 0..0xFFFF -> its index, as :func:`_cand_encode_k`.
    """
    return _cand_encode_k(head, t, alpha, iv, fv, out, _CRC_TABLE)


_CAND_HEAD_FIELDS = ("id", "length", "frame_count", "time_tag", "time_tag", "time_tag",
                     "imager/compaction", "window_row0", "window_col0", "window_rows",
                     "window_cols", "alpha", "alpha", "record_id", "count")
_CAND_BODY_FIELDS = ("label",) + tuple(n for n in ("distance", "gof") + FEATURE_NAMES
                                       for _ in range(2))


def _candidate_field(i: int, n: int) -> str:
    """Name of word ``i`` of an ``n``-word candidate message."""
    if i < CANDIDATE_HEADER_WORDS:
        return _CAND_HEAD_FIELDS[i]
    if i == n - 1:
        return "crc"
    j, off = divmod(i - CANDIDATE_HEADER_WORDS, CANDIDATE_WORDS)
    return f"candidate {j} {_CAND_BODY_FIELDS[off]}"


# ================================================================================================
# the track command codec
# ================================================================================================
@callee_kernel
def _group(v, lo, hi):
    """1 all finite, 0 all NaN, -1 mixed (an optional group ``v[lo:hi]`` of the track command,
    float64).

    Cases
    -----
    all-finite : every value finite -> 1.
    all-nan : every value NaN -> 0.
    mixed : finite and NaN together -> -1.
    infinite : an infinite value is neither (the group is mixed) -> -1.
    """
    nf = 0
    nn = 0
    for i in range(lo, hi):
        if math.isfinite(v[i]):
            nf += 1
        elif v[i] != v[i]:
            nn += 1
    if nf == hi - lo:
        return 1
    if nn == hi - lo:
        return 0
    return -1


#: per value of the track command's float64[17] (q_point, predicted row/col, los_eci, r_est, v_est,
#: sigma_pos, sigma_vel): its first word, its width (2: 32-bit, 3: 48-bit) and its presence flag
_TC_AT = np.array([13, 15, 17, 19, 21, 23, 25, 27, 29, 31, 34, 37, 40, 43, 46, 49, 51], np.int64)
_TC_WIDTH = np.array([2] * 9 + [3] * 6 + [2, 2], np.int64)
_TC_FLAG = np.array([0x10] * 4 + [0x02] * 5 + [0x04] * 8, np.int64)


@njit(**KERNEL)
def _track_encode_k(head, t, v, out, table):
    """Track command words into ``out`` (uint16[55]): ``head`` int64[13] (flags word without the
    presence bits; words 3-5 are the time tag ``t``, finite, encoded here), ``v`` float64[17]
    (:data:`_TC_AT` order). Returns 0 when written; 1 when a group (q_point; the prediction; the
    estimate) is partly present, 2 when the pointing quaternion's norm is off 1 by more than
    :data:`Q_NORM_TOL` (nothing useful written).

    Cases
    -----
    present-groups : each group all finite sets its presence flag (0x10 q_point, 0x02 the
        prediction, 0x04 the estimate) and its values are encoded (nearest), 48-bit for r, v.
    absent-groups : a group all NaN leaves its flag clear and its words zero.
    reserved-and-crc : word 53 zero, word 54 the CRC of words 0-53.
    partial-group : a group partly finite -> 1.
    non-unit-quaternion : a present q_point whose norm is off 1 by more than ``Q_NORM_TOL`` -> 2.
    """
    gp = _group(v, np.int64(0), np.int64(4))
    gr = _group(v, np.int64(4), np.int64(9))
    ge = _group(v, np.int64(9), np.int64(17))
    if gp < 0 or gr < 0 or ge < 0:
        return 1
    if gp and abs(math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]) - 1.0) \
            > Q_NORM_TOL:
        return 2
    for i in range(13):
        out[i] = head[i]
    p = encode_k(t, 39, True)
    out[3], out[4], out[5] = (p >> 32) & 0xFFFF, (p >> 16) & 0xFFFF, p & 0xFFFF
    flags = head[8] | (0x02 if gr else 0) | (0x04 if ge else 0) | (0x10 if gp else 0)
    out[8] = flags
    for i in range(17):
        a = _TC_AT[i]
        present = (flags & _TC_FLAG[i]) != 0
        if _TC_WIDTH[i] == 3:
            p = encode_k(v[i], 39, True) if present else 0
            out[a] = (p >> 32) & 0xFFFF
            out[a + 1] = (p >> 16) & 0xFFFF
            out[a + 2] = p & 0xFFFF
        else:
            p = encode_k(v[i], 23, True) if present else 0
            out[a] = (p >> 16) & 0xFFFF
            out[a + 1] = p & 0xFFFF
    out[53] = 0
    out[54] = _crc_range(out, np.int64(54), table)
    return 0


@njit(**KERNEL)
def _track_check_k(w, v, table, imager_ok, type_ok, status_mask):
    """Every rule of the track command on int64[55] words ``w``; fills ``v`` (NaN when absent).
    Returns (verdict, word index, time tag); verdict 0 when well formed.

    Cases
    -----
    well-formed : verdict 0, ``v`` the decoded values (NaN for absent groups).
    bad-word : a value outside 0..0xFFFF -> ``_BAD_WORD`` at its index.
    bad-id : word 0 not 0x5450 -> ``_BAD_ID``.
    bad-length : word 1 not 55 -> ``_BAD_LENGTH``.
    bad-crc : word 54 not the CRC -> ``_BAD_CRC``.
    bad-imager : unknown imager code -> ``_BAD_CODE`` at 6.
    bad-object-type : unknown object type code -> ``_BAD_CODE2`` at 6.
    status-bits : status bits outside the defined mask -> ``_BAD_FLAGS`` at 7.
    flags-bits : flag bits above 0x7F -> ``_BAD_FLAGS`` at 8.
    absent-header-word : decided frame (11) or object index (12) non-zero while its flag is
        clear -> ``_NOT_ZERO``.
    reserved-word : word 53 non-zero -> ``_NOT_ZERO``.
    bad-time-tag : time tag not a normalised 48-bit float -> ``_BAD_FLOAT`` at 3.
    absent-value : an absent group's words non-zero -> ``_NOT_ZERO`` at the value's first word.
    bad-float : a present 32-bit or 48-bit value not normalised -> ``_BAD_FLOAT`` there.
    non-unit-quaternion : a pointing quaternion whose norm is off 1 by more than
        :data:`Q_NORM_TOL` -> ``_BAD_RANGE`` at its first word (13).
    """
    bad = _words_ok(w)
    if bad >= 0:
        return _BAD_WORD, bad, 0.0
    if w[0] != 0x5450:
        return _BAD_ID, 0, 0.0
    if w[1] != 55:
        return _BAD_LENGTH, 1, 0.0
    if _crc_range(w, np.int64(54), table) != w[54]:
        return _BAD_CRC, 54, 0.0
    if not imager_ok[w[6] >> 8]:
        return _BAD_CODE, 6, 0.0
    if not type_ok[w[6] & 0xFF]:
        return _BAD_CODE2, 6, 0.0
    if w[7] & ~status_mask:
        return _BAD_FLAGS, 7, 0.0
    flags = w[8]
    if flags & ~0x7F:
        return _BAD_FLAGS, 8, 0.0
    if (flags & 0x08) == 0 and w[11] != 0:
        return _NOT_ZERO, 11, 0.0
    if (flags & 0x40) == 0 and w[12] != 0:
        return _NOT_ZERO, 12, 0.0
    if w[53] != 0:
        return _NOT_ZERO, 53, 0.0
    if not is_normalized48_k(_f48_at(w, np.int64(3))):
        return _BAD_FLOAT, 3, 0.0
    for i in range(17):
        a = _TC_AT[i]
        wide = _TC_WIDTH[i] == 3
        p = _f48_at(w, a) if wide else _f32_at(w, a)
        if (flags & _TC_FLAG[i]) == 0:
            if p != 0:
                return _NOT_ZERO, a, 0.0
            v[i] = np.nan
        elif wide:
            if not is_normalized48_k(p):
                return _BAD_FLOAT, a, 0.0
            v[i] = decode48_k(p)
        else:
            if not is_normalized32_k(p):
                return _BAD_FLOAT, a, 0.0
            v[i] = decode32_k(p)
    if flags & _TC_FLAG[0]:                 # a pointing quaternion: unit within the 1750A rounding
        n2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]
        if abs(math.sqrt(n2) - 1.0) > Q_NORM_TOL:
            return _BAD_RANGE, _TC_AT[0], 0.0
    return 0, 0, decode48_k(_f48_at(w, np.int64(3)))


_TC_VALUE_NAMES = ("q_point",) * 4 + ("predicted_row", "predicted_col") + ("los_eci",) * 3 \
    + ("r_est",) * 3 + ("v_est",) * 3 + ("sigma_pos", "sigma_vel")
_TC_HEAD_FIELDS = ("id", "length", "frame_count", "time_tag", "time_tag", "time_tag",
                   "imager/object_type", "status", "flags", "n_star_gates", "n_object_gates",
                   "decided_frame", "object_index")


def _track_field(i: int) -> str:
    """Name of word ``i`` of the track command."""
    if i < len(_TC_HEAD_FIELDS):
        return _TC_HEAD_FIELDS[i]
    if i >= 53:
        return "reserved" if i == 53 else "crc"
    j = int(np.searchsorted(_TC_AT, i, side="right")) - 1
    return _TC_VALUE_NAMES[j]


#: the feedback's values as :func:`feedback_words_k` writes them: float64 [4] predicted row, col
#: (NaN: none), object type code (:data:`OBJECT_TYPE_CODES`, "none" read as 0: no object), locked
FEEDBACK_VALUES = 4


@callee_kernel
def feedback_words_k(words, fb):
    """The IP's per-frame read of the track command: every check of :meth:`TrackCommand.from_words`
    (:func:`_track_check_k`) on ``words`` (uint16 [n]); when they pass, the feedback's values into
    ``fb`` (float64 [4], :data:`FEEDBACK_VALUES`), else ``fb`` unchanged. Returns the verdict (0
    accepted; the word and field are named by :meth:`TrackCommand.feedback_from_words`).

    Cases
    -----
    accepted : a well-formed command -> 0, ``fb`` = (row, col, type code, locked).
    object-none : object type "none" (code 1) -> type code 0, as the Feedback reads it.
    refused : any check failing (CRC, codes, flags, floats) -> its verdict, ``fb`` unchanged.
    wrong-length : not 55 words -> ``_BAD_LENGTH``, ``fb`` unchanged.
    """
    if words.shape[0] != 55:
        return _BAD_LENGTH
    w = np.empty(55, np.int64)
    for i in range(55):
        w[i] = words[i]
    v = np.empty(17)
    verdict, _, _ = _track_check_k(w, v, _CRC_TABLE, _IMAGER_OK, _TYPE_OK, _TC_STATUS_MASK)
    if verdict == 0:
        code = w[6] & 0xFF
        fb[0], fb[1] = v[4], v[5]
        fb[2] = 0.0 if code == 1 else float(code)
        fb[3] = float(w[8] & _TCF_LOCKED)
    return verdict


@dataclass
class Feedback:
    """What the track processor feeds back to the IP each frame (MSX paper, Figure 1): the
    predicted location and type of the object it tracks, and whether it holds a lock.

    Attributes
    ----------
    predicted_row, predicted_col : float
        Predicted object centroid in the imager's full-resolution pixel frame (0-based, pixel centres
        at +0.5); NaN when the TP has no prediction. The IP centres its 64x64 window there and uses
        it as the record's centroid means.
    object_type : str
        Type of the tracked object ("aurora", "satellite", "star", "plume", or "" for none).
    locked : bool
        True when the TP is locked on track (the IP's alpha logic lowers alpha when it is not).
    """

    predicted_row: float = float("nan")
    predicted_col: float = float("nan")
    object_type: str = ""
    locked: bool = False

    def __post_init__(self):
        """Checked as the IP reads it: both coordinates finite numbers or both NaN, a known object
        type, a bool lock (MessageError naming the field otherwise)."""
        owner = "feedback"
        vals = []
        for name in ("predicted_row", "predicted_col"):
            v = getattr(self, name)
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer,
                                                                     np.floating)):
                raise MessageError(owner, None, name, f"{v!r} must be a number (NaN: none)")
            v = float(v)
            if math.isinf(v):
                raise MessageError(owner, None, name, f"{v!r} must be finite (NaN: none)")
            vals.append(v)
        if math.isnan(vals[0]) != math.isnan(vals[1]):
            raise MessageError(owner, None, "predicted_row" if math.isnan(vals[0]) else
                               "predicted_col", "a prediction needs both coordinates (or neither)")
        self.predicted_row, self.predicted_col = vals
        if not isinstance(self.object_type, str) or self.object_type not in OBJECT_TYPE_CODES:
            raise MessageError(owner, None, "object_type", f"{self.object_type!r} is not one of "
                               f"{sorted(OBJECT_TYPE_CODES)}")
        if self.locked not in (True, False):
            raise MessageError(owner, None, "locked", f"{self.locked!r} must be a bool")
        self.locked = bool(self.locked)

    @property
    def has_prediction(self) -> bool:
        return not math.isnan(self.predicted_row)

    def values(self) -> np.ndarray:
        """float64 [4] as :func:`feedback_words_k` writes them (row, col, type code, locked)."""
        return np.array([self.predicted_row, self.predicted_col,
                         OBJECT_TYPE_CODES[self.object_type], self.locked], np.float64)

    @classmethod
    def from_values(cls, v) -> "Feedback":
        """The Feedback of :meth:`values` / :func:`feedback_words_k` values ``v``."""
        row, col, code, locked = v.tolist() if isinstance(v, np.ndarray) else v
        return cls(row, col, _OBJECT_TYPE_BY_CODE[int(code)], bool(locked))


def _feedback(row, col, object_type, locked) -> Feedback:
    """The Feedback a track command carries (the command's "none" object type is the feedback's
    "": no object)."""
    return Feedback(predicted_row=float(row), predicted_col=float(col),
                    object_type="" if object_type == "none" else object_type, locked=bool(locked))


@dataclass
class CandidateMessage:
    """The IP -> TP candidate message of one frame.

    Attributes
    ----------
    frame_count : int
        Frame counter, 0..65535 (wraps).
    time_tag : float
        Frame time tag, s; carried as a 1750A 48-bit float (encode48 nearest; decodes exactly).
    imager : str
        Imager id, a key of :data:`IMAGER_CODES`.
    compaction : int
        Compaction factor f used (1, 2, 4 in flight; 1..255 in the ground's full-frame mode).
    window_row0, window_col0 : int
        Top-left corner of the processing window in full-resolution imager pixels (-32768..32767).
    window_rows, window_cols : int
        Processing window size in processed (compacted) pixels (64 x 64 in flight).
    alpha : float
        Threshold multiplier alpha used this frame (1750A 32-bit float).
    record_id : int
        Id of the a priori record that ranked the candidates (0..65535).
    candidates : ndarray (k,) of :data:`CANDIDATE_DTYPE`, k <= 23
        Best GOF first. ``row``/``col`` are full-resolution imager pixels (0-based, pixel centres at
        +0.5), the other features normalised to the reference scale (see ``flightsw.ip.features``);
        ``label`` is the blob colour in the processed window; every float a 1750A 32-bit value.

    Word layout (:meth:`to_words`, 16-bit words)
    ------------------------------------------
    ====  =====================================================================
    word  content
    ====  =====================================================================
    0     message id 0x4950 ("IP")
    1     total length in words (15 + 29 k + 1)
    2     frame count
    3-5   time tag, 1750A 48-bit float, s
    6     imager code << 8 | compaction
    7, 8  window row0, col0 (full-res pixels, 2's complement)
    9,10  window rows, cols (processed pixels)
    11-12 alpha (1750A 32-bit float)
    13    record id
    14    candidate count k (0..23)
    ...   k candidates of 29 words: label, distance (2), gof (2), then the 12 features (2 each)
          in :data:`FEATURE_NAMES` order
    last  CRC-16/CCITT-FALSE over all preceding words (:func:`crc16_ccitt`)
    ====  =====================================================================
    """

    frame_count: int = 0
    time_tag: float = 0.0
    imager: str = "wfov_vis"
    compaction: int = 1
    window_row0: int = 0
    window_col0: int = 0
    window_rows: int = 64
    window_cols: int = 64
    alpha: float = 0.0
    record_id: int = 0
    candidates: np.ndarray = field(default_factory=lambda: np.zeros(0, CANDIDATE_DTYPE))

    @property
    def count(self) -> int:
        return int(len(self.candidates))

    def to_words(self) -> np.ndarray:
        """Encode as 16-bit words (layout in the class docstring) -> uint16 array. A field the
        format cannot carry (out of range, non-finite, unknown imager) -> :class:`MessageError`."""
        o = "CandidateMessage"
        c = self.candidates
        if type(c) is not np.ndarray or c.dtype != CANDIDATE_DTYPE or c.ndim != 1:
            raise MessageError(o, None, "candidates", "must be a 1-D array of CANDIDATE_DTYPE")
        k = len(c)
        if k > MAX_CANDIDATES:
            raise MessageError(o, None, "candidates", f"{k} entries, at most {MAX_CANDIDATES}")
        if not isinstance(self.imager, str) or self.imager not in IMAGER_CODES:
            raise MessageError(o, None, "imager", f"{self.imager!r} is not one of "
                               f"{sorted(IMAGER_CODES)}")
        n = CANDIDATE_HEADER_WORDS + CANDIDATE_WORDS * k + 1
        head = np.array([CANDIDATE_MSG_ID, n,
                         _int_field(o, "frame_count", self.frame_count, 0, 0xFFFF),
                         0, 0, 0, (IMAGER_CODES[self.imager] << 8)
                         | _int_field(o, "compaction", self.compaction, 1, 255),
                         _int_field(o, "window_row0", self.window_row0, -32768, 32767) & 0xFFFF,
                         _int_field(o, "window_col0", self.window_col0, -32768, 32767) & 0xFFFF,
                         _int_field(o, "window_rows", self.window_rows, 0, 0xFFFF),
                         _int_field(o, "window_cols", self.window_cols, 0, 0xFFFF),
                         0, 0, _int_field(o, "record_id", self.record_id, 0, 0xFFFF), k], np.int64)
        c = np.ascontiguousarray(c)
        out = np.empty(n, np.uint16)
        bad = candidate_words_k(head, _real_field(o, "time_tag", self.time_tag),
                                _real_field(o, "alpha", self.alpha),
                                c.view(np.int64).reshape(k, 15), c.view(np.float64).reshape(k, 15),
                                out)
        if bad >= 0:
            raise MessageError(o, None, f"candidates[{bad % k}]", "label must be 0..65535"
                               if bad < k else "holds a non-finite value")
        return out

    @classmethod
    def from_words(cls, words) -> "CandidateMessage":
        """Decode :meth:`to_words` output. Anything the encoder would not have written (a wrong id,
        length or checksum; an unknown imager; compaction 0; a float that is not a normalised
        1750A value) -> :class:`MessageError` naming the word and field;
        ``from_words(w).to_words()`` equals ``w`` for every ``w`` accepted."""
        o = "candidate message"
        w = _word_array(o, words)
        verdict, i, t, alpha = _cand_check_k(w, _CRC_TABLE, _IMAGER_OK)
        if verdict:
            reason = _REASONS[verdict]
            if verdict == _BAD_CRC:
                reason += f": 0x{crc16_ccitt(w[:-1]):04X} computed, 0x{int(w[-1]):04X} received"
            elif verdict == _BAD_LENGTH and len(w) > CANDIDATE_HEADER_WORDS:
                want = CANDIDATE_HEADER_WORDS + CANDIDATE_WORDS * int(w[14]) + 1
                reason += (f": length word {int(w[1])}, count {int(w[14])}, {len(w)} words "
                           f"(expected {want})")
            elif verdict == _BAD_RANGE:
                reason = "compaction 0 (must be 1..255)"
            raise MessageError(o, i, _candidate_field(i, len(w)), reason)
        k = int(w[14])
        cand = np.zeros(k, CANDIDATE_DTYPE)
        if k:
            _cand_fill_k(w, cand.view(np.int64).reshape(k, 15),
                         cand.view(np.float64).reshape(k, 15))
        h = w[:CANDIDATE_HEADER_WORDS].tolist()
        return cls(frame_count=h[2], time_tag=t, imager=_IMAGER_BY_CODE[h[6] >> 8],
                   compaction=h[6] & 0xFF, window_row0=h[7] - ((h[7] & 0x8000) << 1),
                   window_col0=h[8] - ((h[8] & 0x8000) << 1), window_rows=h[9], window_cols=h[10],
                   alpha=alpha, record_id=h[13], candidates=cand)
    def __eq__(self, other):
        if not isinstance(other, CandidateMessage):
            return NotImplemented
        head = ("frame_count", "time_tag", "imager", "compaction", "window_row0", "window_col0",
                "window_rows", "window_cols", "alpha", "record_id")
        return (all(getattr(self, h) == getattr(other, h) for h in head)
                and self.candidates.dtype == other.candidates.dtype
                and np.array_equal(self.candidates, other.candidates))


# ================================================================================================
# TP -> attitude processor / IP: the track command (issue 7)
# ================================================================================================
TRACK_MSG_ID = 0x5450        # "TP"
TRACK_WORDS = 55             # fixed length, CRC included

#: object type <-> code in the track command ("" and "none": no object type)
OBJECT_TYPE_CODES = {"": 0, "none": 1, "satellite": 2, "launch": 3, "plume": 4, "aurora": 5,
                     "star": 6, "generic": 7}
_OBJECT_TYPE_BY_CODE = {v: k for k, v in OBJECT_TYPE_CODES.items()}

#: TrackCommand.status bits
TC_COASTING = 0x0001             # no observation of the tracked object was used this frame
TC_BAD_MESSAGE = 0x0002          # candidate message unusable (checksum, format, time tag, imager)
TC_FRAME_GAP = 0x0004            # frame count or time tag skipped one or more frames
TC_ATTITUDE_INVALID = 0x0008     # attitude data missing or out of range: propagated from the last
TC_INNOVATION_REJECTED = 0x0010  # an EKF scalar update fell outside the innovation gate
TC_REINITIALISED = 0x0020        # new gates (or a new opportunity track) placed on this frame
TC_OBJECT_DECIDED = 0x0040       # a verified object is held (velocity filtering decided)
TC_NEW_DECISION = 0x0080         # ... and it was decided on this frame
TC_EKF_RUNNING = 0x0100          # the 6-state EKF holds an estimate (r_est, v_est valid)
TC_EMPTY_MESSAGE = 0x0200        # the message held no candidates
TC_OBJECT_LOST = 0x0400          # the verified object's gate stayed empty: object dropped
TC_EKF_RESET = 0x0800            # EKF covariance reset after repeated rejections or a long gap
TC_ARITH_FLAG = 0x1000           # a 1750A overflow/underflow/domain flag was raised this frame
TC_NO_NOMINAL = 0x2000           # dedicated mode without a nominal trajectory: nothing to track
TC_BAD_CONTENT = 0x4000          # a well-formed message whose content is meaningless (a candidate
#                                  outside the imager, a window outside the frame or empty, a GOF
#                                  outside [0, 1], a negative or non-finite distance): refused
TC_INTERNAL_ERROR = 0x8000       # step() caught an exception (see TrackProcessor.last_error)

TC_STATUS_NAMES = {
    TC_COASTING: "coasting", TC_BAD_MESSAGE: "bad_message", TC_FRAME_GAP: "frame_gap",
    TC_ATTITUDE_INVALID: "attitude_invalid", TC_INNOVATION_REJECTED: "innovation_rejected",
    TC_REINITIALISED: "reinitialised", TC_OBJECT_DECIDED: "object_decided",
    TC_NEW_DECISION: "new_decision", TC_EKF_RUNNING: "ekf_running",
    TC_EMPTY_MESSAGE: "empty_message", TC_OBJECT_LOST: "object_lost", TC_EKF_RESET: "ekf_reset",
    TC_ARITH_FLAG: "arith_flag", TC_NO_NOMINAL: "no_nominal", TC_BAD_CONTENT: "bad_content",
    TC_INTERNAL_ERROR: "internal_error",
}

#: the largest |norm - 1| of a pointing quaternion the receivers accept: 2**-20, ~8 roundings of a
#: 1750A 32-bit component (the TP's normalised quaternions are within 3.1e-7 on the shipped events)
Q_NORM_TOL = 2.0 ** -20

# flag-word bits of the track command (which optional values are present)
_TCF_LOCKED, _TCF_PRED, _TCF_EST, _TCF_DECIDED, _TCF_POINT, _TCF_OPP, _TCF_OBJIDX = (
    0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40)
#: the defined status bits (0xFFFF); a numpy integer, which numba types in a kernel as in a Python
#: call (a Python int global is a literal there: a second compiled specialisation)
_TC_STATUS_MASK = np.int64(sum(TC_STATUS_NAMES))
_TYPE_OK = _code_table(OBJECT_TYPE_CODES)
_MODES = {"dedicated": 0, "opportunity": _TCF_OPP}    # mode -> its flag bit


@dataclass(eq=False)
class TrackCommand:
    """The MSX track processor's output of one frame (MSX paper, Figure 1): the pointing command for
    the attitude processor, the predicted object location and type and the lock status for the IP,
    and the track state.

    Attributes
    ----------
    frame_count : int
        Frame count of the candidate message this command answers (0..65535).
    time_tag : float
        Time of the frame, s (1750A 48-bit float).
    q_point : ndarray (4,)
        Commanded attitude, body -> ECI, scalar first: the current attitude turned by the minimal
        rotation that puts the boresight (+X body) on the predicted target line of sight. NaN when
        the TP has nothing to point at (no target, no attitude): the attitude processor keeps its
        own command.
    predicted_row, predicted_col : float
        Predicted object centroid for the IP's next frame, full-resolution pixels of ``imager``
        (0-based, centres at +0.5); NaN when there is no prediction.
    imager : str
        The imager the prediction is in (the current message's imager).
    object_type : str
        Type of the tracked object (a key of :data:`OBJECT_TYPE_CODES`).
    locked : bool
        True when the TP holds the object and used an observation of it this frame.
    status : int
        OR of the ``TC_*`` bits (:data:`TC_STATUS_NAMES`).
    n_star_gates, n_object_gates : int
        Live star / object gates of the velocity filter (0 for targets of opportunity).
    decided_frame : int
        Frame count of the frame on which the current object was verified, -1 if none.
    object_index : int
        Index in this frame's candidate message of the candidate used as the object, -1 if none.
    mode : str
        "dedicated" (velocity filtering + EKF) or "opportunity" (alpha-beta on the best candidate).
    los_eci : ndarray (3,)
        Predicted target line of sight (ECI unit vector) at the next frame; NaN if none.
    r_est, v_est : ndarray (3,)
        EKF position (m) and velocity (m/s) estimate, ECI, at ``time_tag``; NaN if the EKF is not
        running.
    sigma_pos, sigma_vel : float
        sqrt of the trace of the EKF position / velocity covariance blocks (m, m/s); NaN if none.

    Word layout (:meth:`to_words`, 55 16-bit words)
    ------------------------------------------------
    ====== =====================================================================
    word   content
    ====== =====================================================================
    0      message id 0x5450 ("TP")
    1      length in words (55)
    2      frame count
    3-5    time tag, 1750A 48-bit float, s
    6      imager code << 8 | object type code (:data:`OBJECT_TYPE_CODES`)
    7      status bits
    8      flags: 1 locked, 2 prediction, 4 estimate, 8 decided, 0x10 pointing, 0x20 opportunity
           mode, 0x40 object index present
    9, 10  live star gates, live object gates
    11     decided frame count (0 when none)
    12     object index (0 when none)
    13-20  q_point, 4 x 1750A 32-bit float
    21-24  predicted row, col (32-bit)
    25-30  los_eci (3 x 32-bit)
    31-39  r_est (3 x 48-bit), m
    40-48  v_est (3 x 48-bit), m/s
    49-52  sigma_pos, sigma_vel (32-bit)
    53     reserved (0)
    54     CRC-16/CCITT-FALSE over words 0..53 (:func:`crc16_ccitt`)
    ====== =====================================================================
    Absent values (flag bit clear) are sent as zero words and decode to NaN / -1. Every float is a
    1750A value; ``from_words(to_words(c))`` equals ``c`` when ``c``'s floats are 1750A values (the
    TP's always are; others are rounded to nearest).
    """

    frame_count: int = 0
    time_tag: float = 0.0
    q_point: np.ndarray = field(default_factory=lambda: np.full(4, np.nan))
    predicted_row: float = float("nan")
    predicted_col: float = float("nan")
    imager: str = "wfov_vis"
    object_type: str = ""
    locked: bool = False
    status: int = 0
    n_star_gates: int = 0
    n_object_gates: int = 0
    decided_frame: int = -1
    object_index: int = -1
    mode: str = "dedicated"
    los_eci: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    r_est: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    v_est: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    sigma_pos: float = float("nan")
    sigma_vel: float = float("nan")

    # -- conveniences ---------------------------------------------------------------------------
    @property
    def decided(self) -> bool:
        """True while a verified object is held (status bit TC_OBJECT_DECIDED)."""
        return bool(self.status & TC_OBJECT_DECIDED)

    @property
    def coasting(self) -> bool:
        return bool(self.status & TC_COASTING)

    def status_names(self) -> list:
        """Names of the status bits set, in bit order."""
        return [n for b, n in sorted(TC_STATUS_NAMES.items()) if self.status & b]

    def feedback(self) -> Feedback:
        """The IP's feedback for its next frame (prediction in :attr:`imager`'s pixels)."""
        return _feedback(self.predicted_row, self.predicted_col, self.object_type, self.locked)

    # -- codec ----------------------------------------------------------------------------------
    def _values(self) -> np.ndarray:
        """float64[17] of the optional values (:data:`_TC_AT` order) or MessageError."""
        v = np.empty(17)
        for name, lo, n in (("q_point", 0, 4), ("los_eci", 6, 3), ("r_est", 9, 3), ("v_est", 12, 3)):
            a = getattr(self, name)
            if type(a) is not np.ndarray or a.dtype.kind != "f":
                try:
                    a = np.asarray(a, np.float64)
                except (TypeError, ValueError) as exc:
                    raise MessageError("TrackCommand", None, name, f"not numbers ({exc})") from None
            if a.shape != (n,):
                raise MessageError("TrackCommand", None, name, f"must have shape ({n},), got "
                                   f"{a.shape}")
            v[lo:lo + n] = a
        for name, i in (("predicted_row", 4), ("predicted_col", 5), ("sigma_pos", 15),
                        ("sigma_vel", 16)):
            x = getattr(self, name)
            if type(x) is not float and (not isinstance(x, (float, int, np.floating, np.integer))
                                         or isinstance(x, (bool, np.bool_))):
                raise MessageError("TrackCommand", None, name, f"{x!r} is not a number")
            v[i] = x
        return v

    def _head(self) -> np.ndarray:
        """int64[13]: words 0..12 without the presence flags and the time tag, or MessageError."""
        o = "TrackCommand"
        status = _int_field(o, "status", self.status, 0, 0xFFFF)
        if status & ~_TC_STATUS_MASK:
            raise MessageError(o, None, "status", f"0x{status:04X} has undefined bits "
                               f"0x{status & ~_TC_STATUS_MASK:04X}")
        for name, codes in (("imager", IMAGER_CODES), ("object_type", OBJECT_TYPE_CODES),
                            ("mode", _MODES)):
            v = getattr(self, name)
            if not isinstance(v, str) or v not in codes:
                raise MessageError(o, None, name, f"{v!r} is not one of {sorted(codes)}")
        dec = _int_field(o, "decided_frame", self.decided_frame, -1, 0xFFFF)
        obj = _int_field(o, "object_index", self.object_index, -1, 0xFFFF)
        flags = ((_TCF_LOCKED if self.locked else 0) | (_TCF_DECIDED if dec >= 0 else 0)
                 | _MODES[self.mode] | (_TCF_OBJIDX if obj >= 0 else 0))
        return np.array([TRACK_MSG_ID, TRACK_WORDS,
                         _int_field(o, "frame_count", self.frame_count, 0, 0xFFFF),
                         0, 0, 0,
                         (IMAGER_CODES[self.imager] << 8) | OBJECT_TYPE_CODES[self.object_type],
                         status, flags, _int_field(o, "n_star_gates", self.n_star_gates, 0, 0xFFFF),
                         _int_field(o, "n_object_gates", self.n_object_gates, 0, 0xFFFF),
                         max(dec, 0), max(obj, 0)], np.int64)

    def to_words(self) -> np.ndarray:
        """Encode as 55 uint16 words (layout in the class docstring), CRC last. A field the format
        cannot carry, or a group of values partly NaN -> :class:`MessageError`."""
        head = self._head()
        t = _real_field("TrackCommand", "time_tag", self.time_tag)
        out = np.empty(TRACK_WORDS, np.uint16)
        v = self._values()
        bad = _track_encode_k(head, t, v, out, _CRC_TABLE)
        if bad == 2:
            raise MessageError("TrackCommand", None, "q_point",
                               f"norm {math.sqrt(float(v[:4] @ v[:4])):.9g} is off 1 by more than "
                               f"the 1750A rounding ({Q_NORM_TOL:.2g})")
        if bad:
            raise MessageError("TrackCommand", None, "values", "a group of values (q_point; "
                               "prediction + los_eci; the estimate) must be all finite or all NaN")
        return out

    @staticmethod
    def _checked(words):
        """The words as an array and the check kernel's values and time tag, or MessageError
        naming the word and field (the one decoding of the track command, for both readers)."""
        o = "track command"
        w = _word_array(o, words)
        if w.shape[0] != TRACK_WORDS:
            raise MessageError(o, None, "length", f"{w.shape[0]} words, expected {TRACK_WORDS}")
        v = np.empty(17)
        verdict, i, t = _track_check_k(w, v, _CRC_TABLE, _IMAGER_OK, _TYPE_OK, _TC_STATUS_MASK)
        if verdict:
            reason = _REASONS[verdict]
            if verdict == _BAD_CRC:
                reason += f": 0x{crc16_ccitt(w[:-1]):04X} computed, 0x{int(w[-1]):04X} received"
            elif verdict == _BAD_CODE2:
                reason = "unknown object type code (low byte)"
            elif verdict == _BAD_RANGE:
                reason = (f"pointing quaternion's norm off 1 by more than the 1750A rounding "
                          f"({Q_NORM_TOL:.2g})")
            raise MessageError(o, i, _track_field(i), reason)
        return w, v, t

    @classmethod
    def feedback_from_words(cls, words) -> Feedback:
        """The IP's feedback (:meth:`feedback`) read straight from the words, with every check of
        :meth:`from_words` and without building the whole command (the IP's per-frame read)."""
        w, v, _ = cls._checked(words)
        return _feedback(v[4], v[5], _OBJECT_TYPE_BY_CODE[int(w[6]) & 0xFF],
                         int(w[8]) & _TCF_LOCKED)

    @classmethod
    def from_words(cls, words) -> "TrackCommand":
        """Decode :meth:`to_words` output. Anything the encoder would not have written (a wrong id,
        length or checksum; unknown codes; undefined status or flag bits; non-zero reserved or
        absent words; a float that is not a normalised 1750A value) -> :class:`MessageError`
        naming the word and field; ``from_words(w).to_words()`` equals ``w`` when accepted."""
        w, v, t = cls._checked(words)
        h = w[:13].tolist()
        flags = h[8]
        return cls(frame_count=h[2], time_tag=t, q_point=v[0:4].copy(),
                   predicted_row=float(v[4]), predicted_col=float(v[5]),
                   imager=_IMAGER_BY_CODE[h[6] >> 8], object_type=_OBJECT_TYPE_BY_CODE[h[6] & 0xFF],
                   locked=bool(flags & _TCF_LOCKED), status=h[7], n_star_gates=h[9],
                   n_object_gates=h[10], decided_frame=h[11] if flags & _TCF_DECIDED else -1,
                   object_index=h[12] if flags & _TCF_OBJIDX else -1,
                   mode="opportunity" if flags & _TCF_OPP else "dedicated",
                   los_eci=v[6:9].copy(), r_est=v[9:12].copy(), v_est=v[12:15].copy(),
                   sigma_pos=float(v[15]), sigma_vel=float(v[16]))

    def __eq__(self, other):
        if not isinstance(other, TrackCommand):
            return NotImplemented
        for name in ("frame_count", "time_tag", "imager", "object_type", "locked", "status",
                     "n_star_gates", "n_object_gates", "decided_frame", "object_index", "mode"):
            if getattr(self, name) != getattr(other, name):
                return False
        for name in ("q_point", "predicted_row", "predicted_col", "los_eci", "r_est", "v_est",
                     "sigma_pos", "sigma_vel"):
            if not np.array_equal(np.asarray(getattr(self, name), float),
                                  np.asarray(getattr(other, name), float), equal_nan=True):
                return False
        return True
