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

from dataclasses import dataclass, field

import numpy as np


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


def crc16_ccitt(words) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0) over 16-bit words,
    each fed most significant byte first. Check value: ``crc16_ccitt_bytes(b"123456789") == 0x29B1``.

    Parameters
    ----------
    words : iterable of int, each 0..0xFFFF
    """
    data = bytearray()
    for w in words:
        w = int(w)
        if not 0 <= w <= 0xFFFF:
            raise ValueError(f"crc16_ccitt: word {w!r} is not a 16-bit word")
        data += bytes((w >> 8, w & 0xFF))
    return crc16_ccitt_bytes(bytes(data))


def crc16_ccitt_bytes(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of a byte string (see :func:`crc16_ccitt`)."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


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
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ValueError(f"CandidateMessage.{name}={v!r} must be an int in {lo}..{hi}")
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

    def to_words(self) -> np.ndarray:
        """Encode as 16-bit words (layout in the class docstring) -> uint16 array."""
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
