"""IP step 5: adaptive threshold ``T = mean + alpha * std`` and the onboard alpha logic.

The MSX paper ("Thresholding"): "Pixels that pass the threshold are either set to a constant value
(binarized) or left pristine (clipped), whereas those that do not are set to zero ... Onboard logic
exists that increases alpha if the number of candidates detected becomes too large (approaches 100)
or decreases alpha if the tracking processor does not lock on track with any of the available
candidates (useful for dim objects)."

Everything runs on the ADSP-2100 in integer arithmetic (no float, no 1750A):

1. Block shift ``s = max(0, bitlen(max|x|) - 12)`` (EXPADJ pass) so that ``|x >> s| <= 4096``; 12-bit
   and detrended 12-bit data have ``s = 0``.
2. One pass: ``S1 = sum (x >> s)`` (double-precision ALU add), ``S2 = sum (x >> s)**2`` (MAC;
   ``2 * S2 <= 2 * 16384 * 4096**2 = 2**39`` read as an unsigned 40-bit MR: windows up to 128x128).
3. Statistics with ``n = h*w`` (multiprecision integer routines, exact):
   mean ``m4 = round_half_up(16 * S1 / n)``                                   # Q.4 (1/16 count)
   variance ``v8 = round_half_up(256 * (n*S2 - S1**2) / n**2)``                # Q.8
   std ``d4 = isqrt(v8)`` = floor(sqrt(v8))                                    # Q.4
   The square root is an **integer square root on the DSP**: the restoring bit-pair method, 16
   iterations of (trial = root | bit; compare; conditional subtract and set; shift) on the 32-bit
   radicand, 6 cycles an iteration + 4: 100 cycles.
4. ``T4 = (m4 + round_half_up(alpha_q12 * d4 / 4096)) << s``                   # Q.4, alpha Q4.12
5. Pass ``x`` when ``16 * x > T4`` (strictly above the threshold): binarise -> 1, clip -> ``x``;
   otherwise 0.

Error bound against float64 ``T = mean + alpha * std`` (population std, ``numpy.std``), s = 0:
``|m4/16 - mean| <= 1/32``; ``|v8/256 - var| <= 1/512``, so ``sqrt(v8)`` is within
``1/(512 * std)`` of std (tiny for std >= 1) and the floor loses ``< 1/16``: ``d4/16`` is in
``(std - 1/16 - eps, std]``; then ``alpha * d4`` is rounded to 1/16 with alpha exactly ``alpha_q12 /
4096``. Hence ``|T4/16 - T| <= 1/32 + alpha * (1/16 + eps) + 1/32`` (checked in ``tests/ip_reference.py``).

Cycles: EXPADJ 1 + shift 1 + MAC 1 + double add 2 per pixel (stats), compare/select/store 4 per pixel,
3 per row and pass, + 250 for the divisions (2 x 32/16 multiprecision divides), the multiprecision
``n*S2 - S1**2``, the 100-cycle isqrt and the alpha multiply. See :func:`threshold_cycles`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flightsw.arith.adsp2100 import block_bitlen
from flightsw.budget import m1750_cycles
from flightsw.numba_cache import callee_kernel

__all__ = ["threshold", "threshold_stats", "threshold_cycles", "isqrt32", "threshold_words",
           "AlphaController", "alpha_to_q12", "ALPHA_MIN", "ALPHA_MAX", "BINARIZE", "CLIP",
           "ISQRT_CYCLES", "ALPHA_LOGIC_CYCLES", "alpha_next_k", "NEAR_COUNT", "ALPHA_LOGIC"]

ALPHA_MIN = 0.0
ALPHA_MAX = 32767 / 4096          # Q4.12 word range (7.99975)
BINARIZE, CLIP = 0, 1
NEAR_COUNT = 90                   # blobs at which the alpha logic raises alpha (ASSUMED: "approaches 100")
#: the alpha logic's default floor and ceiling (ASSUMED: the paper gives neither)
DEFAULT_FLOOR, DEFAULT_CEILING = 1.0, 7.0


def alpha_bounds(alpha: float, alpha_min: float | None = None) -> tuple[float, float]:
    """The range ``(floor, ceiling)`` the alpha logic keeps a sequence's alpha in: the floor is
    the threshold step's ``alpha_min`` when it sets one, else ``min(alpha, 1.0)``; the ceiling is
    ``max(alpha, 7.0)``. One definition for the sequence's validation, the alpha logic and
    ``docs/formats.md``: every alpha of the word range 0 .. 7.99975 runs (a sequence starting
    below the default floor or above the default ceiling is not stopped by them)."""
    floor = min(alpha, DEFAULT_FLOOR) if alpha_min is None else alpha_min
    return floor, max(alpha, DEFAULT_CEILING)
ISQRT_CYCLES = 16 * 6 + 4


def alpha_to_q12(alpha):
    """Host alpha -> Q4.12 word (round half up); ``ValueError`` outside 0 .. 7.99975."""
    a = float(alpha)
    if not (ALPHA_MIN <= a <= ALPHA_MAX):
        raise ValueError(f"alpha={alpha!r} out of range {ALPHA_MIN} .. {ALPHA_MAX:.5f} (Q4.12)")
    return int(np.floor(a * 4096 + 0.5))


@callee_kernel
def isqrt32(v):
    """floor(sqrt(v)) for 0 <= v < 2**32: the DSP's restoring bit-pair square root (16 steps).

    ``v``: int, 0 .. 2**32 - 1 (the Q.8 variance word). Returns int64 ``floor(sqrt(v))`` (0 .. 65535).

    Cases
    -----
    zero : ``v == 0`` -> 0 (the start bit shifts down to 0, no iteration subtracts).
    perfect-square : ``v = r**2`` -> exactly ``r`` (remainder 0).
    between-squares : ``r**2 < v < (r + 1)**2`` -> ``r`` (floor, never rounded up).
    top : ``v = 2**32 - 1`` -> 65535 (the largest radicand, start bit 2**30 kept).
    """
    root = np.int64(0)
    rem = np.int64(v)
    bit = np.int64(1) << 30
    while bit > rem and bit > 0:
        bit >>= 2
    while bit != 0:
        if rem >= root + bit:
            rem -= root + bit
            root = (root >> 1) + bit
        else:
            root >>= 1
        bit >>= 2
    return root


@callee_kernel
def _stats_k(img):
    """Block shift and the two sums of the threshold pass.

    ``img``: int16 [h, w] (Q16.0). Returns ``(s, S1, S2)``: ``s = max(0, bitlen(max|x|) - 12)``,
    ``S1 = sum(x >> s)``, ``S2 = sum((x >> s)**2)`` (int64, exact; ``>>`` arithmetic, floor).

    Cases
    -----
    no-shift : data within 12 bits signed (-4096 .. 4095) -> ``s = 0``, sums of the raw words.
    block-shift : wider data -> ``s = bitlen - 12`` (full-scale int16 -> 3) and ``|x >> s| <= 4096``.
    negative : negative words shift towards -inf (-32768 >> 3 = -4096) and square positive.
    """
    f = img.ravel()
    s = max(0, block_bitlen(img) - 12)
    s1 = np.int64(0)
    s2 = np.int64(0)
    if s == 0:
        for i in range(f.size):
            x = np.int64(f[i])
            s1 += x
            s2 += x * x
    else:
        for i in range(f.size):
            x = np.int64(f[i]) >> s
            s1 += x
            s2 += x * x
    return s, s1, s2


@callee_kernel
def _rhu_div(a, b):
    """round_half_up(a / b) for b > 0 (floor division, exact integers).

    ``a``: int64 (any sign), ``b``: int64 > 0. Returns int64 ``floor((2a + b) / 2b)``.

    Cases
    -----
    exact : ``b`` divides ``a`` -> ``a / b``.
    tie-up : a quotient exactly halfway rounds towards +inf (5/2 -> 3, -5/2 -> -2).
    nearest : otherwise the nearest integer (7/3 -> 2, -7/3 -> -2, 8/3 -> 3).
    """
    return (2 * a + b) // (2 * b)


@callee_kernel
def threshold_words(s1, s2, n, s, alpha_q12):
    """Threshold words from a window's sums (steps 3 and 4 of the module docstring).

    ``s1 = sum(x >> s)``, ``s2 = sum((x >> s)**2)`` (int64, exact), ``n``: the window's pixel count
    (int64, 1 .. 16384), ``s``: its block shift (int64 >= 0), ``alpha_q12``: int, Q4.12 (0 ..
    32767). Returns int64 ``(T4, m4, d4)``: threshold Q.4 (in unshifted counts), mean Q.4 and std
    Q.4 of ``x >> s``. Public so that a ground tool that gets the sums another way (the full-frame
    union of windows, :mod:`hil_harness.detect.union`) applies the flight's own formula.

    Cases
    -----
    typical : ``m4 = rhu(16 S1 / n)``, ``d4 = isqrt(rhu(256 (n S2 - S1**2) / n**2))``,
        ``T4 = (m4 + rhu(alpha d4 / 4096)) << s``.
    alpha-zero : ``alpha_q12 == 0`` -> ``T4 = m4 << s`` (the mean).
    constant : ``n S2 == S1**2`` (a constant window) -> ``d4 = 0`` and ``T4 = 16 c << s``.
    max-spread : half the words -4096, half 4095 (the widest 12-bit spread) -> ``v8 = 4293918784``,
        below the clamp at ``2**32 - 1`` (the clamp never binds for int16 input).
    block-shift : ``s > 0`` -> ``T4`` is the shifted threshold ``<< s``.
    """
    m4 = _rhu_div(16 * s1, n)                                  # Q.4
    num = n * s2 - s1 * s1                                      # >= 0, exact (< 2**53)
    v8 = _rhu_div(256 * num, n * n)                             # Q.8
    if v8 > 0xFFFFFFFF:
        v8 = np.int64(0xFFFFFFFF)
    d4 = isqrt32(v8)                                            # Q.4
    t4 = (m4 + _rhu_div(np.int64(alpha_q12) * d4, np.int64(4096))) << s  # Q.4
    return t4, m4, d4


@callee_kernel
def _threshold_value(img, alpha_q12):
    """Threshold words of a window: its block shift and sums (:func:`_stats_k`), then
    :func:`threshold_words`.

    ``img``: int16 [h, w], h*w <= 16384; ``alpha_q12``: int, Q4.12 (0 .. 32767). Returns int64
    ``(T4, m4, d4, s)``: threshold Q.4 (in unshifted counts), mean Q.4 and std Q.4 of ``x >> s``,
    block shift ``s``.

    Cases
    -----
    typical : the words of :func:`threshold_words` on the window's sums.
    alpha-zero : ``alpha_q12 == 0`` -> ``T4 = m4 << s`` (the mean).
    constant : a constant window -> ``d4 = 0`` and ``T4 = 16 c``.
    max-spread : half the words -4096, half 4095 (the widest 12-bit spread) -> ``v8 = 4293918784``,
        below the clamp at ``2**32 - 1`` (the clamp never binds for int16 input).
    block-shift : full-scale data -> ``T4`` is the shifted threshold ``<< s``.
    """
    s, s1, s2 = _stats_k(img)
    n = np.int64(img.shape[0] * img.shape[1])
    t4, m4, d4 = threshold_words(s1, s2, n, np.int64(s), alpha_q12)
    return t4, m4, d4, s


@callee_kernel
def _apply_k(img, t4, mode):
    """Apply the threshold: pass ``x`` where ``16 x > T4`` (strictly).

    ``img``: int16 [h, w]; ``t4``: int, Q.4; ``mode``: 0 binarise, otherwise clip. Returns int16
    [h, w].

    Cases
    -----
    binarize : ``mode == 0`` -> 1 where ``16 x > T4``, else 0.
    clip : ``mode != 0`` -> ``x`` where ``16 x > T4``, else 0.
    equal-fails : ``16 x == T4`` does not pass (0).
    negative : negative words pass when above a negative threshold (clip keeps them negative).
    """
    h, w = img.shape
    out = np.empty((h, w), np.int16)
    f = img.ravel()
    o = out.ravel()
    t = np.int64(t4)
    if mode == 0:
        for i in range(f.size):
            o[i] = np.int16(np.int64(f[i]) * 16 > t)
    else:
        for i in range(f.size):
            o[i] = f[i] if np.int64(f[i]) * 16 > t else np.int16(0)
    return out


@callee_kernel
def threshold_k(img, alpha_q12, mode):
    """The threshold step in one compiled call.

    ``img``: int16 [h, w], h*w <= 16384 (Q16.0); ``alpha_q12``: int, Q4.12; ``mode``: 0 binarise,
    1 clip. Returns ``(out int16 [h, w], T4, m4, d4, s)`` (int64 words as :func:`_threshold_value`).

    Cases
    -----
    binarize : ``mode == 0`` -> a 0/1 image of the pixels strictly above the threshold.
    clip : ``mode == 1`` -> the passing pixels keep their words, the rest 0.
    constant : a constant window (std 0, ``16 x == T4`` everywhere) -> all 0.
    """
    t4, m4, d4, s = _threshold_value(img, alpha_q12)
    return _apply_k(img, t4, mode), t4, m4, d4, s


def threshold_stats(img, alpha):
    """``(T4, m4, d4, s)``: threshold, mean, std in Q.4 (1/16 count) and the block shift."""
    img = np.ascontiguousarray(img, np.int16)
    t4, m4, d4, s = _threshold_value(img, alpha_to_q12(alpha))
    return int(t4), int(m4), int(d4), int(s)


def threshold(img, alpha, mode="binarize", ledger=None, stage="threshold", alpha_q12=None):
    """Adaptive threshold of the subimage.

    Parameters
    ----------
    img : ndarray (h, w) int16 (Q16.0), at most 128x128 pixels
    alpha : float in 0 .. 7.99975 (quantised to Q4.12), ignored when ``alpha_q12`` is given
    mode : "binarize" (passing pixels -> 1) or "clip" (passing pixels keep their value)

    Returns
    -------
    (out int16 ndarray, T4) — the thresholded image and the threshold in Q.4 counts.
    """
    img = np.ascontiguousarray(img, np.int16)
    if img.size > 16384:
        raise ValueError(f"threshold: window {img.shape} exceeds 128x128 (the MR sum-of-squares bound)")
    if mode not in ("binarize", "clip"):
        raise ValueError(f"mode={mode!r} must be 'binarize' or 'clip'")
    aq = alpha_to_q12(alpha) if alpha_q12 is None else int(alpha_q12)
    out, t4, _, _, _ = threshold_k(img, aq, BINARIZE if mode == "binarize" else CLIP)
    if ledger is not None:
        ledger.charge("dsp", stage, threshold_cycles(*img.shape))
    return out, int(t4)


def threshold_cycles(h, w):
    """ADSP-2100 cycles of the threshold step on an h x w window."""
    return int(h * w * (5 + 4) + 2 * 3 * h + 250)


#: 1750A clocks of one alpha-logic update: 4 compares and 4 conditional jumps (the locked count's
#: compare and jump included), one add and one store
ALPHA_LOGIC_CYCLES = m1750_cycles({"C": 4, "JC": 4, "A": 1, "ST": 1})


#: The alpha logic's constants, one record (:meth:`AlphaController.logic`), the 1750A's words as
#: :func:`alpha_next_k` reads them by field. Alpha words are Q4.12 (alpha = word / 4096), counts
#: are blob counts (integers).
ALPHA_LOGIC = np.dtype([
    ("near_count", np.int64),    # blobs at which alpha rises (1..100; the paper's "approaches 100")
    ("step_up", np.int64),       # Q4.12, added when the count reaches near_count
    ("step_down", np.int64),     # Q4.12, taken off without lock (and on a locked sparse frame)
    ("alpha_min", np.int64),     # Q4.12, the floor (the sequence's alpha_min, ASSUMED 1.0 default)
    ("alpha_max", np.int64),     # Q4.12, the ceiling
    ("sparse_floor", np.int64),  # Q4.12, the floor on an unlocked frame under sparse_count blobs
    ("sparse_count", np.int64),  # blobs; 0 (default): the sparse floor never applies
    ("locked_floor", np.int64),  # Q4.12, the floor on a locked frame under locked_count blobs
    ("locked_count", np.int64),  # blobs; 0 (default): the locked floor never applies
])


@callee_kernel
def alpha_next_k(q12, count, locked, logic):
    """The alpha logic's next Q4.12 word (1750A integer code).

    ``q12``: alpha in force (Q4.12 word); ``count``: candidates detected this frame; ``locked``:
    the TP's lock; ``logic``: :data:`ALPHA_LOGIC` [1] (:meth:`AlphaController.logic`). Returns
    int.

    Cases
    -----
    too-many : ``count >= near`` -> ``min(q12 + up, max)`` (wins over no lock and over lock).
    no-lock : fewer and not locked -> ``max(q12 - down, min)``.
    no-lock-sparse : fewer than the sparse count and not locked -> ``max(q12 - down, sparse
        floor)`` (a sparse count of 0, the default, never applies).
    below-floor : not sparse, not locked and already below ``min`` (a sparse or locked frame
        took it there) -> ``q12`` unchanged (held, not pulled back up).
    locked-floor : fewer than the locked count and locked -> ``max(q12 - down, min(locked
        floor, q12))`` (steps down to the locked floor; already below it: unchanged).
    locked : locked, not fewer than the locked count (0, the default, never applies) -> ``q12``
        unchanged.
    """
    g = logic[0]
    if count >= g.near_count:
        return min(q12 + g.step_up, g.alpha_max)
    if not locked:
        if count < g.sparse_count:
            return max(q12 - g.step_down, g.sparse_floor)
        return max(q12 - g.step_down, min(g.alpha_min, q12))
    if count < g.locked_count:
        return max(q12 - g.step_down, min(g.locked_floor, q12))
    return q12


@dataclass
class AlphaController:
    """The onboard alpha logic (1750A integer code), alpha held as a Q4.12 word.

    ``update(candidate_count, tp_locked)``: when the number of candidates detected reaches
    ``near_count`` (approaching the 100 the paper names) alpha rises by ``step_up``; otherwise, when
    the track processor reports no lock, it falls by ``step_down`` (dim objects); always within
    ``alpha_min .. alpha_max``. Too many candidates wins over no lock (the message cannot carry them
    anyway). Parameters are host floats quantised to Q4.12 once at construction. ``alpha_min`` 1.0
    is assumed (the paper gives no floor); a sequence may set its own (threshold step
    ``alpha_min``, :func:`flightsw.ip.processor.alpha_controller_for`).

    ``alpha_min_sparse`` / ``sparse_blobs``: without lock, on a frame with fewer than
    ``sparse_blobs`` blobs, alpha may fall below ``alpha_min`` as far as ``alpha_min_sparse`` (and
    stays there until the count rule raises it or a sparse frame lowers it further). Both are
    ASSUMED (the paper gives no floor): a bright star in the window lifts ``mean + alpha * std``
    over a faint object while few blobs pass, where a window whose std is the noise's passes many.
    The default ``sparse_blobs = 0`` never applies.

    ``alpha_min_locked`` / ``locked_blobs``: while the TP holds lock, on a frame with fewer than
    ``locked_blobs`` blobs, alpha steps down by ``step_down`` towards ``alpha_min_locked`` (default
    ``alpha_min``), never pulled up when already below it. Both are ASSUMED (the paper lowers
    alpha only without lock): after lock a faint target often has a single compacted pixel above
    the threshold, so its centroid is that pixel's centre wherever in the pixel the target lies (a
    dead zone up to ~0.3 processed px) and the closed loop's track error sits there; a lower
    threshold while locked lets the neighbouring pixels pass, and the record's centroid prior (the
    TP's prediction) keeps the target ranked first among the extra noise blobs. The default
    ``locked_blobs = 0`` never applies.

    Each update charges the 1750A ``ip1750`` for 4 compares, 4 conditional jumps, one add and one
    store (:data:`ALPHA_LOGIC_CYCLES`).
    """

    alpha: float = 3.0
    alpha_min: float = 1.0
    alpha_max: float = 7.0
    step_up: float = 0.5
    step_down: float = 0.25
    near_count: int = NEAR_COUNT
    alpha_min_sparse: float | None = None       # host float; its Q4.12 word is _sparse
    sparse_blobs: int = 0
    alpha_min_locked: float | None = None       # host float; its Q4.12 word is _locked
    locked_blobs: int = 0
    q12: int = field(init=False)                # alpha in force, Q4.12 word

    def __post_init__(self):
        self._min = alpha_to_q12(self.alpha_min)
        self._max = alpha_to_q12(self.alpha_max)
        if self._min > self._max:
            raise ValueError(f"alpha_min={self.alpha_min} > alpha_max={self.alpha_max}")
        self._up = alpha_to_q12(self.step_up)
        self._down = alpha_to_q12(self.step_down)
        if self._up <= 0 or self._down <= 0:
            raise ValueError("step_up and step_down must be > 0")
        if not isinstance(self.near_count, (int, np.integer)) or not 1 <= self.near_count <= 100:
            raise ValueError(f"near_count={self.near_count!r} must be an int in 1..100")
        self._sparse = self._extra_floor("alpha_min_sparse", "sparse_blobs")     # Q4.12
        self._locked = self._extra_floor("alpha_min_locked", "locked_blobs")     # Q4.12
        q = alpha_to_q12(self.alpha)
        if not self._min <= q <= self._max:
            raise ValueError(f"alpha={self.alpha} outside alpha_min..alpha_max")
        self.q12 = q

    def _extra_floor(self, floor_name: str, count_name: str) -> int:
        """A floor below ``alpha_min`` and its blob count, checked -> the floor's Q4.12 word
        (``alpha_min``'s when the floor is None)."""
        floor = getattr(self, floor_name)
        floor = self.alpha_min if floor is None else floor
        q = alpha_to_q12(floor)
        if q > self._min:
            raise ValueError(f"{floor_name}={floor} > alpha_min={self.alpha_min}")
        count = getattr(self, count_name)
        if not isinstance(count, (int, np.integer)) or not 0 <= count < self.near_count:
            raise ValueError(f"{count_name}={count!r} must be an int in 0..{self.near_count - 1}")
        return q

    @property
    def value(self) -> float:
        """Current alpha (host float view of the Q4.12 word)."""
        return self.q12 / 4096

    def logic(self) -> np.ndarray:
        """The logic's constants as :func:`alpha_next_k` takes them: :data:`ALPHA_LOGIC` [1]."""
        out = np.zeros(1, ALPHA_LOGIC)
        out[0] = (self.near_count, self._up, self._down, self._min, self._max, self._sparse,
                  self.sparse_blobs, self._locked, self.locked_blobs)
        return out

    def words(self) -> np.ndarray:
        """:meth:`logic`'s fields as int64 [9], in :data:`ALPHA_LOGIC`'s order (a view for
        reports and tests; the kernels take the record)."""
        return np.array(self.logic()[0].tolist(), np.int64)

    def set_q12(self, q12: int) -> int:
        """Put the Q4.12 word ``q12`` in force (the compiled step's update); returns it."""
        self.q12 = int(q12)
        self.alpha = self.q12 / 4096
        return self.q12

    def update(self, candidate_count: int, tp_locked: bool, ledger=None) -> int:
        """Apply the logic after a frame (:func:`alpha_next_k`); returns the new Q4.12 alpha
        word."""
        q = alpha_next_k(np.int64(self.q12), np.int64(candidate_count), bool(tp_locked),
                         self.logic())
        if ledger is not None:
            ledger.charge("ip1750", "alpha_logic", ALPHA_LOGIC_CYCLES)
        return self.set_q12(q)
