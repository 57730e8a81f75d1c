"""Messages between the flight subsystems.

Conventions shared by every message (``shared/DESIGN.md``):

* Quaternions are scalar-first ``(w, x, y, z)`` and rotate body-frame vectors into the inertial (ECI,
  J2000) frame: ``v_eci = R(q) @ v_body``.
* The body frame has the UVISI boresight along +X; an imager pixel ``(row, col)`` (pixel centres at
  ``+0.5``) maps to the imager-frame direction ``(1, x, y)`` normalised, with
  ``x = (col - 128.0) * scale_col`` and ``y = (row - 122.0) * scale_row`` (gnomonic, tangent-plane
  radians per pixel): the paper's measurement unit vector ``(~1, e1, e2)``.
* Positions in metres, velocities in m/s, angles in radians, times in seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit


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
    return t


_CRC_TABLE = _crc_table()


@njit(cache=True)
def _crc_range(w, n, table):
    """Table-driven CRC-16/CCITT-FALSE of the first ``n`` 16-bit words of ``w`` (MSB first)."""
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


# -- jitted codec kernels (fast paths of the to_words / from_words methods; anything unusual falls
#    back to the plain implementations, which validate and raise) ----------------------------------
from flightsw.arith.m1750_float import _dec32_k, _dec48_k, _enc_k, _norm48_k  # noqa: E402


def _is_int_in(v, lo, hi) -> bool:
    return (not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, np.integer))
            and lo <= v <= hi)


def _require_int_in(name, v, lo, hi) -> None:
    """ValueError unless ``v`` is an int (not a bool) in ``lo..hi``."""
    if not _is_int_in(v, lo, hi):
        raise ValueError(f"{name}={v!r} must be an int in {lo}..{hi}")


_REALS = (float, int, np.floating, np.integer)


@njit(cache=True)
def _cand_encode_k(head, iv, fv, out, table):
    """Candidate message words into ``out`` (uint16): ``head`` int64[15] header words, ``iv``/``fv``
    int64/float64 views (k, 15) of the candidates. 1: a label out of range, 2: a non-finite value
    (nothing useful written), 0: done."""
    k = iv.shape[0]
    for i in range(k):
        if iv[i, 0] < 0 or iv[i, 0] > 0xFFFF:
            return 1
    for i in range(k):
        for j in range(1, 15):
            if not math.isfinite(fv[i, j]):
                return 2
    n = 0
    for i in range(15):
        out[n] = head[i]
        n += 1
    for i in range(k):
        out[n] = iv[i, 0]
        n += 1
        for j in range(1, 15):
            p = _enc_k(fv[i, j], 23, True)
            out[n] = (p >> 16) & 0xFFFF
            out[n + 1] = p & 0xFFFF
            n += 2
    crc = _crc_range(out, n, table)
    out[n] = crc
    return 0


@njit(cache=True)
def _cand_decode_k(w, table):
    """Checks of :meth:`CandidateMessage.from_words` on int64 words ``w``: (status, k, time tag,
    alpha); status 0 when the message is well formed (else the plain decoder reports it)."""
    n = w.shape[0]
    for i in range(n):
        if w[i] < 0 or w[i] > 0xFFFF:
            return 1, 0, 0.0, 0.0
    k = w[14]
    if w[0] != 0x4950 or k > 23 or w[1] != 15 + 29 * k + 1 or n != 15 + 29 * k + 1:
        return 2, 0, 0.0, 0.0
    if _crc_range(w, n - 1, table) != w[n - 1]:
        return 3, 0, 0.0, 0.0
    pt = (w[3] << 32) | (w[4] << 16) | w[5]
    if not _norm48_k(pt):
        return 4, 0, 0.0, 0.0
    return 0, k, _dec48_k(pt), _dec32_k((w[11] << 16) | w[12])


@njit(cache=True)
def _cand_fill_k(w, iv, fv):
    for i in range(iv.shape[0]):
        b = 15 + 29 * i
        iv[i, 0] = w[b]
        for j in range(14):
            fv[i, 1 + j] = _dec32_k((w[b + 1 + 2 * j] << 16) | w[b + 2 + 2 * j])


@njit(cache=True)
def _group(v, lo, hi):
    """1 all finite, 0 all NaN, -1 mixed (TrackCommand._present)."""
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


@njit(cache=True)
def _track_encode_k(head, v, out, table):
    """Track command words into ``out`` (uint16[55]): ``head`` int64[13] (flags word without the
    presence bits), ``v`` float64[17] = q_point, predicted row/col, los_eci, r_est, v_est, sigma_pos,
    sigma_vel. False when a group is partly present (the plain encoder reports it)."""
    gp = _group(v, 0, 4)
    gr = _group(v, 4, 9)
    ge = _group(v, 9, 17)
    if gp < 0 or gr < 0 or ge < 0:
        return False
    for i in range(13):
        out[i] = head[i]
    out[8] = head[8] | (0x02 if gr else 0) | (0x04 if ge else 0) | (0x10 if gp else 0)
    n = 13
    for i in range(17):
        present = gp if i < 4 else (gr if i < 9 else ge)
        if 9 <= i < 15:
            p = _enc_k(v[i], 39, True) if present else 0
            out[n] = (p >> 32) & 0xFFFF
            out[n + 1] = (p >> 16) & 0xFFFF
            out[n + 2] = p & 0xFFFF
            n += 3
        else:
            p = _enc_k(v[i], 23, True) if present else 0
            out[n] = (p >> 16) & 0xFFFF
            out[n + 1] = p & 0xFFFF
            n += 2
    out[53] = 0
    out[54] = _crc_range(out, 54, table)
    return True


@njit(cache=True)
def _track_decode_k(w, v, table):
    """Checks and values of :meth:`TrackCommand.from_words` (int64[55] words): fills ``v`` (as in
    :func:`_track_encode_k`, NaN when absent); returns (status, time tag), status 0 when well formed."""
    for i in range(55):
        if w[i] < 0 or w[i] > 0xFFFF:
            return 1, 0.0
    if w[0] != 0x5450 or w[1] != 55:
        return 2, 0.0
    if _crc_range(w, 54, table) != w[54]:
        return 3, 0.0
    pt = (w[3] << 32) | (w[4] << 16) | w[5]
    if not _norm48_k(pt):
        return 4, 0.0
    flags = w[8]
    n = 13
    for i in range(17):
        if i < 4:
            present = flags & 0x10
        elif i < 9:
            present = flags & 0x02
        else:
            present = flags & 0x04
        if 9 <= i < 15:
            p = (w[n] << 32) | (w[n + 1] << 16) | w[n + 2]
            n += 3
            if present:
                if not _norm48_k(p):
                    return 5, 0.0
                v[i] = _dec48_k(p)
            else:
                v[i] = np.nan
        else:
            p = (w[n] << 16) | w[n + 1]
            n += 2
            v[i] = _dec32_k(p) if present else np.nan
    return 0, _dec48_k(pt)


def _f32_words(x: float) -> tuple[int, int]:
    from flightsw.arith.m1750 import encode32
    p = encode32(float(x), rounding="nearest")
    return p >> 16, p & 0xFFFF


def _f32_value(w0: int, w1: int) -> float:
    from flightsw.arith.m1750 import decode32
    return decode32((w0 << 16) | w1)


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

    @property
    def has_prediction(self) -> bool:
        return bool(np.isfinite(self.predicted_row) and np.isfinite(self.predicted_col))


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

    def _check(self):
        def rng(name, v, lo, hi):
            _require_int_in(f"CandidateMessage.{name}", v, lo, hi)
        rng("frame_count", self.frame_count, 0, 0xFFFF)
        rng("compaction", self.compaction, 1, 255)
        rng("window_row0", self.window_row0, -32768, 32767)
        rng("window_col0", self.window_col0, -32768, 32767)
        rng("window_rows", self.window_rows, 0, 0xFFFF)
        rng("window_cols", self.window_cols, 0, 0xFFFF)
        rng("record_id", self.record_id, 0, 0xFFFF)
        if self.imager not in IMAGER_CODES:
            raise ValueError(f"CandidateMessage.imager={self.imager!r} is not one of {sorted(IMAGER_CODES)}")
        c = np.asarray(self.candidates)
        if c.dtype != CANDIDATE_DTYPE:
            raise ValueError(f"CandidateMessage.candidates has dtype {c.dtype}, expected CANDIDATE_DTYPE")
        if len(c) > MAX_CANDIDATES:
            raise ValueError(f"CandidateMessage.candidates has {len(c)} entries, at most {MAX_CANDIDATES}")
        if np.any((c["label"] < 0) | (c["label"] > 0xFFFF)):
            raise ValueError("CandidateMessage.candidates label must be 0..65535")
        if not (np.isfinite(self.time_tag) and np.isfinite(self.alpha)):
            raise ValueError("CandidateMessage.time_tag and alpha must be finite")

    def _fast_ok(self) -> bool:
        """The cheap checks of :meth:`_check` that the jitted encoder does not repeat."""
        c = self.candidates
        return (_is_int_in(self.frame_count, 0, 0xFFFF) and _is_int_in(self.compaction, 1, 255)
                and _is_int_in(self.window_row0, -32768, 32767)
                and _is_int_in(self.window_col0, -32768, 32767)
                and _is_int_in(self.window_rows, 0, 0xFFFF) and _is_int_in(self.window_cols, 0, 0xFFFF)
                and _is_int_in(self.record_id, 0, 0xFFFF) and self.imager in IMAGER_CODES
                and type(c) is np.ndarray and c.dtype == CANDIDATE_DTYPE and c.ndim == 1
                and len(c) <= MAX_CANDIDATES and isinstance(self.time_tag, _REALS)
                and isinstance(self.alpha, _REALS)
                and math.isfinite(self.time_tag) and math.isfinite(self.alpha))

    def to_words(self) -> np.ndarray:
        """Encode as 16-bit words (layout in the class docstring) -> uint16 array."""
        if self._fast_ok():
            c = np.ascontiguousarray(self.candidates)
            k = len(c)
            t = _enc_k(float(self.time_tag), 39, True)
            a = _enc_k(float(np.float64(self.alpha)), 23, True)
            head = np.array([CANDIDATE_MSG_ID, CANDIDATE_HEADER_WORDS + CANDIDATE_WORDS * k + 1,
                             self.frame_count, (t >> 32) & 0xFFFF, (t >> 16) & 0xFFFF, t & 0xFFFF,
                             (IMAGER_CODES[self.imager] << 8) | self.compaction,
                             self.window_row0 & 0xFFFF, self.window_col0 & 0xFFFF, self.window_rows,
                             self.window_cols, (a >> 16) & 0xFFFF, a & 0xFFFF, self.record_id, k],
                            np.int64)
            out = np.empty(CANDIDATE_HEADER_WORDS + CANDIDATE_WORDS * k + 1, np.uint16)
            if k:
                iv = c.view(np.int64).reshape(k, 15)
                fv = c.view(np.float64).reshape(k, 15)
            else:
                iv = np.zeros((0, 15), np.int64)
                fv = np.zeros((0, 15), np.float64)
            if _cand_encode_k(head, iv, fv, out, _CRC_TABLE) == 0:
                return out
        return self._to_words_plain()

    def _to_words_plain(self) -> np.ndarray:
        from flightsw.arith.m1750 import encode32_array, encode48
        self._check()
        c = self.candidates
        k = len(c)
        t = encode48(float(self.time_tag), rounding="nearest")
        a = encode32_array(np.array([self.alpha], np.float64), rounding="nearest")[0]
        head = [CANDIDATE_MSG_ID, CANDIDATE_HEADER_WORDS + CANDIDATE_WORDS * k + 1, self.frame_count,
                (t >> 32) & 0xFFFF, (t >> 16) & 0xFFFF, t & 0xFFFF,
                (IMAGER_CODES[self.imager] << 8) | self.compaction,
                self.window_row0 & 0xFFFF, self.window_col0 & 0xFFFF, self.window_rows,
                self.window_cols, (int(a) >> 16) & 0xFFFF, int(a) & 0xFFFF, self.record_id, k]
        body = np.zeros((k, CANDIDATE_WORDS), np.int64)
        if k:
            vals = np.stack([c["distance"], c["gof"]] + [c[n] for n in FEATURE_NAMES], axis=1)
            if not np.all(np.isfinite(vals)):
                raise ValueError("CandidateMessage.candidates hold a non-finite value")
            p = encode32_array(vals, rounding="nearest")
            body[:, 0] = c["label"]
            body[:, 1::2] = (p >> 16) & 0xFFFF
            body[:, 2::2] = p & 0xFFFF
        words = np.concatenate([np.array(head, np.int64), body.ravel()])
        return np.append(words, crc16_ccitt(words)).astype(np.uint16)

    @classmethod
    def from_words(cls, words) -> "CandidateMessage":
        """Decode :meth:`to_words` output; a wrong id, length or checksum -> ``ValueError``."""
        w = np.asarray(words)
        if w.ndim == 1 and w.size >= CANDIDATE_HEADER_WORDS + 1 and w.dtype.kind in "iu":
            wi = w.astype(np.int64)
            st, k, t, alpha = _cand_decode_k(wi, _CRC_TABLE)
            if st == 0 and (wi[6] >> 8) in _IMAGER_BY_CODE:
                h = wi[:CANDIDATE_HEADER_WORDS].tolist()
                cand = np.zeros(k, CANDIDATE_DTYPE)
                if k:
                    _cand_fill_k(wi, cand.view(np.int64).reshape(k, 15),
                                 cand.view(np.float64).reshape(k, 15))
                s16 = lambda v: v - 0x10000 if v & 0x8000 else v  # noqa: E731
                return cls(frame_count=h[2], time_tag=t, imager=_IMAGER_BY_CODE[h[6] >> 8],
                           compaction=h[6] & 0xFF, window_row0=s16(h[7]), window_col0=s16(h[8]),
                           window_rows=h[9], window_cols=h[10], alpha=alpha, record_id=h[13],
                           candidates=cand)
        return cls._from_words_plain(w)

    @classmethod
    def _from_words_plain(cls, words) -> "CandidateMessage":
        w = np.asarray(words)
        if w.ndim != 1 or w.size < CANDIDATE_HEADER_WORDS + 1:
            raise ValueError(f"candidate message: {w.size} words, need at least "
                             f"{CANDIDATE_HEADER_WORDS + 1}")
        if not np.issubdtype(w.dtype, np.integer) or w.min() < 0 or w.max() > 0xFFFF:
            raise ValueError("candidate message: words must be integers 0..0xFFFF")
        w = [int(x) for x in w]
        if w[0] != CANDIDATE_MSG_ID:
            raise ValueError(f"candidate message: id word 0x{w[0]:04X}, expected 0x{CANDIDATE_MSG_ID:04X}")
        k = w[14]
        n = CANDIDATE_HEADER_WORDS + CANDIDATE_WORDS * k + 1
        if k > MAX_CANDIDATES or w[1] != n or len(w) != n:
            raise ValueError(f"candidate message: length word {w[1]}, candidate count {k} and "
                             f"{len(w)} words received do not agree (expected {n})")
        crc = crc16_ccitt(w[:-1])
        if crc != w[-1]:
            raise ValueError(f"candidate message: bad checksum (CRC-16/CCITT 0x{crc:04X} computed, "
                             f"0x{w[-1]:04X} received)")
        from flightsw.arith.m1750 import decode32_array, decode48
        code = w[6] >> 8
        if code not in _IMAGER_BY_CODE:
            raise ValueError(f"candidate message: unknown imager code {code}")
        s16 = lambda v: v - 0x10000 if v & 0x8000 else v  # noqa: E731
        cand = np.zeros(k, CANDIDATE_DTYPE)
        if k:
            body = np.array(w[CANDIDATE_HEADER_WORDS:-1], np.int64).reshape(k, CANDIDATE_WORDS)
            vals = decode32_array((body[:, 1::2] << 16) | body[:, 2::2])
            cand["label"] = body[:, 0]
            cand["distance"], cand["gof"] = vals[:, 0], vals[:, 1]
            for i, name in enumerate(FEATURE_NAMES):
                cand[name] = vals[:, 2 + i]
        return cls(frame_count=w[2], time_tag=decode48((w[3] << 32) | (w[4] << 16) | w[5]),
                   imager=_IMAGER_BY_CODE[code], compaction=w[6] & 0xFF, window_row0=s16(w[7]),
                   window_col0=s16(w[8]), window_rows=w[9], window_cols=w[10],
                   alpha=float(decode32_array(np.array([(w[11] << 16) | w[12]]))[0]),
                   record_id=w[13], candidates=cand)

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
TC_INTERNAL_ERROR = 0x8000       # step() caught an exception (see TrackProcessor.last_error)

TC_STATUS_NAMES = {
    TC_COASTING: "coasting", TC_BAD_MESSAGE: "bad_message", TC_FRAME_GAP: "frame_gap",
    TC_ATTITUDE_INVALID: "attitude_invalid", TC_INNOVATION_REJECTED: "innovation_rejected",
    TC_REINITIALISED: "reinitialised", TC_OBJECT_DECIDED: "object_decided",
    TC_NEW_DECISION: "new_decision", TC_EKF_RUNNING: "ekf_running",
    TC_EMPTY_MESSAGE: "empty_message", TC_OBJECT_LOST: "object_lost", TC_EKF_RESET: "ekf_reset",
    TC_ARITH_FLAG: "arith_flag", TC_NO_NOMINAL: "no_nominal", TC_INTERNAL_ERROR: "internal_error",
}

# flag-word bits of the track command (which optional values are present)
_TCF_LOCKED, _TCF_PRED, _TCF_EST, _TCF_DECIDED, _TCF_POINT, _TCF_OPP, _TCF_OBJIDX = (
    0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40)


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
        ot = "" if self.object_type == "none" else self.object_type
        return Feedback(predicted_row=float(self.predicted_row), predicted_col=float(self.predicted_col),
                        object_type=ot, locked=bool(self.locked))

    # -- codec ----------------------------------------------------------------------------------
    def _check(self):
        def rng(name, v, lo, hi):
            _require_int_in(f"TrackCommand.{name}", v, lo, hi)
        rng("frame_count", self.frame_count, 0, 0xFFFF)
        rng("status", self.status, 0, 0xFFFF)
        rng("n_star_gates", self.n_star_gates, 0, 0xFFFF)
        rng("n_object_gates", self.n_object_gates, 0, 0xFFFF)
        rng("decided_frame", self.decided_frame, -1, 0xFFFF)
        rng("object_index", self.object_index, -1, 0xFFFF)
        if self.imager not in IMAGER_CODES:
            raise ValueError(f"TrackCommand.imager={self.imager!r} is not one of {sorted(IMAGER_CODES)}")
        if self.object_type not in OBJECT_TYPE_CODES:
            raise ValueError(f"TrackCommand.object_type={self.object_type!r} is not one of "
                             f"{sorted(OBJECT_TYPE_CODES)}")
        if self.mode not in ("dedicated", "opportunity"):
            raise ValueError(f"TrackCommand.mode={self.mode!r} must be 'dedicated' or 'opportunity'")
        if not np.isfinite(self.time_tag):
            raise ValueError("TrackCommand.time_tag must be finite")
        for name, n in (("q_point", 4), ("los_eci", 3), ("r_est", 3), ("v_est", 3)):
            a = np.asarray(getattr(self, name), float)
            if a.shape != (n,):
                raise ValueError(f"TrackCommand.{name} must have shape ({n},), got {a.shape}")

    @staticmethod
    def _present(*vals) -> bool:
        """All finite -> True, all NaN -> False, anything else -> ValueError."""
        a = np.concatenate([np.atleast_1d(np.asarray(v, float)) for v in vals])
        if np.all(np.isfinite(a)):
            return True
        if np.all(np.isnan(a)):
            return False
        raise ValueError("TrackCommand: a group of values must be all finite or all NaN")

    def _fast_values(self):
        """float64[17] of the codec's values when every field is of the usual kind and valid for
        :meth:`_check`, else None (the plain encoder then validates and reports)."""
        if not (_is_int_in(self.frame_count, 0, 0xFFFF) and _is_int_in(self.status, 0, 0xFFFF)
                and _is_int_in(self.n_star_gates, 0, 0xFFFF)
                and _is_int_in(self.n_object_gates, 0, 0xFFFF)
                and _is_int_in(self.decided_frame, -1, 0xFFFF)
                and _is_int_in(self.object_index, -1, 0xFFFF)
                and self.imager in IMAGER_CODES and self.object_type in OBJECT_TYPE_CODES
                and self.mode in ("dedicated", "opportunity")
                and isinstance(self.time_tag, _REALS) and math.isfinite(self.time_tag)):
            return None
        v = np.empty(17)
        for name, lo, n in (("q_point", 0, 4), ("los_eci", 6, 3), ("r_est", 9, 3), ("v_est", 12, 3)):
            a = getattr(self, name)
            if type(a) is not np.ndarray or a.shape != (n,) or a.dtype.kind != "f":
                return None
            v[lo:lo + n] = a
        for name, i in (("predicted_row", 4), ("predicted_col", 5), ("sigma_pos", 15),
                        ("sigma_vel", 16)):
            x = getattr(self, name)
            if not isinstance(x, _REALS) or isinstance(x, (bool, np.bool_)):
                return None
            v[i] = x
        return v

    def to_words(self) -> np.ndarray:
        """Encode as 55 uint16 words (layout in the class docstring), CRC last."""
        v = self._fast_values()
        if v is not None:
            t = _enc_k(float(self.time_tag), 39, True)
            flags = ((_TCF_LOCKED if self.locked else 0) | (_TCF_DECIDED if self.decided_frame >= 0 else 0)
                     | (_TCF_OPP if self.mode == "opportunity" else 0)
                     | (_TCF_OBJIDX if self.object_index >= 0 else 0))
            head = np.array([TRACK_MSG_ID, TRACK_WORDS, int(self.frame_count), (t >> 32) & 0xFFFF,
                             (t >> 16) & 0xFFFF, t & 0xFFFF,
                             (IMAGER_CODES[self.imager] << 8) | OBJECT_TYPE_CODES[self.object_type],
                             int(self.status), flags, int(self.n_star_gates), int(self.n_object_gates),
                             max(int(self.decided_frame), 0), max(int(self.object_index), 0)], np.int64)
            out = np.empty(TRACK_WORDS, np.uint16)
            if _track_encode_k(head, v, out, _CRC_TABLE):
                return out
        return self._to_words_plain()

    def _to_words_plain(self) -> np.ndarray:
        from flightsw.arith.m1750 import encode32_array, encode48
        self._check()
        has_pt = self._present(self.q_point)
        has_pred = self._present(self.predicted_row, self.predicted_col, self.los_eci)
        has_est = self._present(self.r_est, self.v_est, self.sigma_pos, self.sigma_vel)
        flags = ((_TCF_LOCKED if self.locked else 0) | (_TCF_PRED if has_pred else 0)
                 | (_TCF_EST if has_est else 0) | (_TCF_DECIDED if self.decided_frame >= 0 else 0)
                 | (_TCF_POINT if has_pt else 0) | (_TCF_OPP if self.mode == "opportunity" else 0)
                 | (_TCF_OBJIDX if self.object_index >= 0 else 0))

        def f32(vals, present):
            v = np.atleast_1d(np.asarray(vals, float))
            p = encode32_array(v, rounding="nearest").astype(np.int64) if present \
                else np.zeros(len(v), np.int64)
            return np.stack([(p >> 16) & 0xFFFF, p & 0xFFFF], 1).ravel().tolist()

        def f48(vals, present):
            out = []
            for v in np.atleast_1d(np.asarray(vals, float)):
                p = encode48(float(v), rounding="nearest") if present else 0
                out += [(p >> 32) & 0xFFFF, (p >> 16) & 0xFFFF, p & 0xFFFF]
            return out

        t = encode48(float(self.time_tag), rounding="nearest")
        w = [TRACK_MSG_ID, TRACK_WORDS, int(self.frame_count), (t >> 32) & 0xFFFF, (t >> 16) & 0xFFFF,
             t & 0xFFFF, (IMAGER_CODES[self.imager] << 8) | OBJECT_TYPE_CODES[self.object_type],
             int(self.status), flags, int(self.n_star_gates), int(self.n_object_gates),
             max(int(self.decided_frame), 0), max(int(self.object_index), 0)]
        w += f32(self.q_point, has_pt)
        w += f32([self.predicted_row, self.predicted_col], has_pred)
        w += f32(self.los_eci, has_pred)
        w += f48(self.r_est, has_est) + f48(self.v_est, has_est)
        w += f32([self.sigma_pos, self.sigma_vel], has_est)
        w.append(0)
        assert len(w) == TRACK_WORDS - 1
        return np.array(w + [crc16_ccitt(w)], np.uint16)

    @classmethod
    def from_words(cls, words) -> "TrackCommand":
        """Decode :meth:`to_words` output; wrong id, length, checksum or codes -> ``ValueError``."""
        w = np.asarray(words)
        if w.ndim == 1 and w.size == TRACK_WORDS and w.dtype.kind in "iu":
            wi = w.astype(np.int64)
            v = np.empty(17)
            st, t = _track_decode_k(wi, v, _CRC_TABLE)
            code, otype = int(wi[6]) >> 8, int(wi[6]) & 0xFF
            if st == 0 and code in _IMAGER_BY_CODE and otype in _OBJECT_TYPE_BY_CODE:
                h = wi[:13].tolist()
                flags = h[8]
                return cls(frame_count=h[2], time_tag=t, q_point=v[0:4].copy(),
                           predicted_row=float(v[4]), predicted_col=float(v[5]),
                           imager=_IMAGER_BY_CODE[code], object_type=_OBJECT_TYPE_BY_CODE[otype],
                           locked=bool(flags & _TCF_LOCKED), status=h[7], n_star_gates=h[9],
                           n_object_gates=h[10], decided_frame=h[11] if flags & _TCF_DECIDED else -1,
                           object_index=h[12] if flags & _TCF_OBJIDX else -1,
                           mode="opportunity" if flags & _TCF_OPP else "dedicated",
                           los_eci=v[6:9].copy(), r_est=v[9:12].copy(), v_est=v[12:15].copy(),
                           sigma_pos=float(v[15]), sigma_vel=float(v[16]))
        return cls._from_words_plain(w)

    @classmethod
    def _from_words_plain(cls, words) -> "TrackCommand":
        from flightsw.arith.m1750 import decode32_array, decode48
        w = np.asarray(words)
        if w.ndim != 1 or w.size != TRACK_WORDS:
            raise ValueError(f"track command: {w.size} words, expected {TRACK_WORDS}")
        if not np.issubdtype(w.dtype, np.integer) or w.min() < 0 or w.max() > 0xFFFF:
            raise ValueError("track command: words must be integers 0..0xFFFF")
        w = [int(x) for x in w]
        if w[0] != TRACK_MSG_ID or w[1] != TRACK_WORDS:
            raise ValueError(f"track command: id 0x{w[0]:04X} / length {w[1]}, expected "
                             f"0x{TRACK_MSG_ID:04X} / {TRACK_WORDS}")
        crc = crc16_ccitt(w[:-1])
        if crc != w[-1]:
            raise ValueError(f"track command: bad checksum (CRC-16/CCITT 0x{crc:04X} computed, "
                             f"0x{w[-1]:04X} received)")
        code, otype = w[6] >> 8, w[6] & 0xFF
        if code not in _IMAGER_BY_CODE or otype not in _OBJECT_TYPE_BY_CODE:
            raise ValueError(f"track command: unknown imager code {code} or object type code {otype}")
        flags = w[8]

        def f32(i, n, present):
            if not present:
                return np.full(n, np.nan)
            a = np.array(w[i:i + 2 * n], np.int64)
            return decode32_array((a[0::2] << 16) | a[1::2])

        def f48(i, n, present):
            return np.array([decode48((w[i + 3 * k] << 32) | (w[i + 3 * k + 1] << 16) | w[i + 3 * k + 2])
                             if present else np.nan for k in range(n)])

        pred = f32(21, 2, flags & _TCF_PRED)
        sig = f32(49, 2, flags & _TCF_EST)
        return cls(frame_count=w[2], time_tag=decode48((w[3] << 32) | (w[4] << 16) | w[5]),
                   q_point=f32(13, 4, flags & _TCF_POINT), predicted_row=float(pred[0]),
                   predicted_col=float(pred[1]), imager=_IMAGER_BY_CODE[code],
                   object_type=_OBJECT_TYPE_BY_CODE[otype], locked=bool(flags & _TCF_LOCKED),
                   status=w[7], n_star_gates=w[9], n_object_gates=w[10],
                   decided_frame=w[11] if flags & _TCF_DECIDED else -1,
                   object_index=w[12] if flags & _TCF_OBJIDX else -1,
                   mode="opportunity" if flags & _TCF_OPP else "dedicated",
                   los_eci=f32(25, 3, flags & _TCF_PRED), r_est=f48(31, 3, flags & _TCF_EST),
                   v_est=f48(40, 3, flags & _TCF_EST), sigma_pos=float(sig[0]), sigma_vel=float(sig[1]))

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
