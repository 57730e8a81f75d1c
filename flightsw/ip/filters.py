"""IP steps 2 and 4: linear filtering of the subimage (noise smoothing, matched filtering).

The MSX paper ("Linear filtering"): "Linear convolution filters having sizes of 3x3, 5x5, or 7x7 pixels
can be applied to the 64x64 pixel processing subimage ... Filters can be uplinked to the satellite to
replace the default filters available. Larger convolution kernels are applied via software frequency
domain filtering, although throughput concerns limit the use of this option."

Arithmetic (ADSP-2100, :func:`flightsw.arith.adsp2100.correlate_valid_q15` semantics)
-----------------------------------------------------------------------------------
``out[r, c] = MR1 of  sum_{i,j} x[r+i-p, c+j-p] * k[i, j]`` with pixels ``x`` as Q16.0 words,
coefficients ``k`` as Q1.15 words, the fractional-mode product (x2), 40-bit accumulation, unbiased
``(RND)`` on the last tap and ``IF MV SAT MR`` before the store. The output is Q16.0 (image units):
``out = round_half_even(sum x*k / 2**15)`` saturated to -32768..32767. This is a *correlation*
(kernel not flipped); the default kernels are symmetric so it is also the convolution.

Edge handling: the window is padded by ``p = k // 2`` pixels replicating the edge pixels (the DSP
copies the border words into a padded buffer: one cycle per border word), i.e. SciPy's
``mode="nearest"``. Tested against ``scipy.ndimage.correlate(..., mode="nearest")``.

Error bound against the float64 correlation with the *same* (quantised) coefficients: the sum is exact
in the 40-bit MR (<= 49 products of <= 2**31 never leave 40 bits), so the only error is the final
rounding, ``|out - exact| <= 1/2`` whenever no saturation occurs. Against the ideal real-valued
kernel ``K`` add ``max|x| * sum|k/2**15 - K|`` (coefficient quantisation, <= 2**-16 per tap).

Host fast path: the accumulation ``A = sum x*k`` (without the fractional x2) is held in int32 when
``max|x| * sum|k| < 2**31 - 2**14`` (checked per call), which vectorises 8-wide; otherwise int64. Both paths give the exact integer
``A``, so the result equals the MR bit for bit (tested against ``correlate_valid_q15``).

Cycles (charged to ``"dsp"``): border replication ``(h+2p)(w+2p) - h*w`` moves + 4, then
:func:`flightsw.arith.adsp2100.correlate_cycles` ``h*w*(k*k + 3) + 3h + 10``.

Frequency-domain path for larger kernels (sequence op ``filter_fft``):
:func:`flightsw.ip.fftfilter.fft_correlate`.
"""
from __future__ import annotations

import math

import numpy as np

from flightsw.arith.adsp2100 import correlate_cycles
from flightsw.numba_cache import callee_kernel

__all__ = ["SPATIAL_SIZES", "DEFAULT_KERNELS", "smoothing_kernel", "matched_kernel",
           "validate_kernel", "correlate_q15", "filter_cycles", "pad_cycles",
           "gaussian_taps_q15", "matched_kernel_any"]

SPATIAL_SIZES = (3, 5, 7)


# ---------------------------------------------------------------------------------------------
# default kernels (ground-side design: host floats allowed here, the result is Q1.15 words)
# ---------------------------------------------------------------------------------------------
def _binomial(n):
    row = np.array([math.comb(n - 1, i) for i in range(n)], np.int64)
    return row


def smoothing_kernel(size=3):
    """Noise-smoothing kernel: the binomial (discrete Gaussian) ``b b^T / 4**(size-1)``, exact in Q1.15
    (3x3: [1 2 1]^2/16, 5x5: [1 4 6 4 1]^2/256, 7x7: [1 6 15 20 15 6 1]^2/4096), sum = 1.0 exactly.
    Returns int16 Q1.15 words."""
    if size not in SPATIAL_SIZES:
        raise ValueError(f"size={size!r} must be one of {SPATIAL_SIZES}")
    b = _binomial(size)
    k = np.outer(b, b) * (32768 // int(b.sum()) ** 2)
    return k.astype(np.int16)    # Q1.15


def matched_kernel(size=3, sigma=1.0):
    """The paper's matched filter (Figure 3): a zero-mean circularly symmetric Gaussian, here
    ``g = exp(-r^2 / 2 sigma^2) - mean(g)`` scaled to unit L2 norm (white noise keeps its standard
    deviation), quantised to Q1.15 with the integer sum forced to exactly 0 (the residual of the
    rounding goes into the centre tap). Returns int16 Q1.15 words. Spatial sizes 3/5/7 only; the
    frequency path (:mod:`flightsw.ip.fftfilter`) takes any odd size through :func:`matched_kernel_any`."""
    if size not in SPATIAL_SIZES:
        raise ValueError(f"size={size!r} must be one of {SPATIAL_SIZES}")
    return matched_kernel_any(size, sigma)


def matched_kernel_any(size, sigma=1.0):
    """:func:`matched_kernel` for any odd ``size >= 3``."""
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 3 or size % 2 == 0:
        raise ValueError(f"size={size!r} must be an odd int >= 3")
    p = size // 2
    y, x = np.mgrid[-p:p + 1, -p:p + 1]
    g = np.exp(-(x * x + y * y) / (2.0 * sigma * sigma))
    g -= g.mean()
    g /= np.sqrt((g * g).sum())
    k = np.round(g * 32768).astype(np.int64)
    k[p, p] -= k.sum()
    if np.abs(k).max() > 32767:
        raise ValueError("matched kernel does not fit Q1.15")
    return k.astype(np.int16)    # Q1.15


def gaussian_taps_q15(sigma, size=7):
    """1-D normalised Gaussian taps (``exp(-i^2 / 2 sigma^2)`` for ``|i| <= size // 2``, the kernel
    ``scipy.ndimage.gaussian_filter1d(sigma, truncate=(size//2)/sigma)`` uses) quantised to Q1.15 with
    the sum forced to exactly 32768 (= 1.0) through the centre tap. Returns int16."""
    p = size // 2
    i = np.arange(-p, p + 1)
    t = np.exp(-0.5 * (i / float(sigma)) ** 2)
    t /= t.sum()
    q = np.round(t * 32768).astype(np.int64)
    q[p] += 32768 - q.sum()
    return q.astype(np.int16)    # Q1.15


DEFAULT_KERNELS = {"smooth": smoothing_kernel, "matched": matched_kernel}


def validate_kernel(coefficients, name="coefficients"):
    """Check an uplinked spatial kernel: square, 3/5/7, integer Q1.15 words -32768..32767.
    Returns an int16 array; ``ValueError`` naming the problem."""
    try:
        k = np.asarray(coefficients)
    except Exception as exc:  # ragged lists
        raise ValueError(f"{name}: not a rectangular array ({exc})") from None
    if k.dtype == object or k.ndim != 2:
        raise ValueError(f"{name}: must be a 2-D list of Q1.15 words, got shape {k.shape}")
    if k.shape[0] != k.shape[1] or k.shape[0] not in SPATIAL_SIZES:
        raise ValueError(f"{name}: kernel shape {k.shape[0]}x{k.shape[1]} is not 3x3, 5x5 or 7x7 "
                         "(the spatial path; larger kernels go through 'filter_fft')")
    if not np.issubdtype(k.dtype, np.integer):
        if not np.all(np.isfinite(k)) or np.any(k != np.round(k)):
            raise ValueError(f"{name}: coefficients must be integer Q1.15 words (value * 32768)")
    if k.min() < -32768 or k.max() > 32767:
        raise ValueError(f"{name}: coefficient out of the Q1.15 word range -32768..32767 "
                         f"(min {k.min()}, max {k.max()})")
    return k.astype(np.int16)


# ---------------------------------------------------------------------------------------------
# kernels
# ---------------------------------------------------------------------------------------------
@callee_kernel
def _finish(a):
    """MR1 after (RND) and IF MV SAT MR, from the exact sum ``a = sum x*k`` (MR = 2a, 40 bits).

    ``(2a + 0x8000) >> 16 == (a + 0x4000) >> 15``; the RND tie (MR0 == 0x8000, i.e. ``a & 0x7FFF ==
    0x4000``) clears bit 16 (the result's LSB); SAT of the rounded MR equals clamping MR1.

    ``a``: int64 exact sum of Q16.0 x Q1.15 products (Q.15). Returns int16 (Q16.0).

    Cases
    -----
    round-nearest : ``a / 2**15`` rounded to the nearest integer (``|err| <= 1/2``).
    tie-even : ``a & 0x7FFF == 0x4000`` (exactly half) -> the even neighbour (0.5 -> 0, 1.5 -> 2).
    sat-high : a rounded sum above 32767 -> 32767.
    sat-low : a rounded sum below -32768 -> -32768.
    """
    a = np.int64(a)
    q = (a + 0x4000) >> 15
    t = np.int64(1) if (a & 0x7FFF) == 0x4000 else np.int64(0)
    q = q & ~t
    return np.int16(min(max(q, -32768), 32767))


@callee_kernel
def pad_nearest(img, p):
    """Replicate-edge padding by ``p`` (SciPy mode="nearest"). int16 -> int16.

    ``img``: int16 [h, w], h, w >= 1; ``p``: int >= 0. Returns int16 [h + 2p, w + 2p].

    Cases
    -----
    no-pad : ``p == 0`` -> a copy.
    replicate : the border rows/columns repeat the edge pixels, corners the corner pixel
        (``numpy.pad(mode="edge")``).
    pad-wider-than-image : ``p >= h`` or ``p >= w`` (a 1x1 image) -> every word the edge word.
    """
    h, w = img.shape
    out = np.empty((h + 2 * p, w + 2 * p), np.int16)
    for r in range(h + 2 * p):
        rr = min(max(r - p, 0), h - 1)
        src = img[rr]
        dst = out[r]
        for c in range(p):
            dst[c] = src[0]
            dst[w + p + c] = src[w - 1]
        for c in range(w):
            dst[p + c] = src[c]
    return out


@callee_kernel
def _maxabs(img):
    """max |x| of an int16 array (any shape) as int32 (-32768 -> 32768).

    Cases
    -----
    typical : the largest magnitude of either sign.
    most-negative : -32768 -> 32768 (no int16 wrap).
    empty : no elements -> 0.
    """
    f = img.ravel()
    m = np.int32(0)
    for i in range(f.size):
        a = np.int32(f[i])
        a = a if a >= 0 else -a
        m = max(m, a)
    return m


@callee_kernel
def _finish32(acc, out):
    """Vectorised :func:`_finish` over a row of int32 sums (no overflow: the caller's bound).

    ``acc``: int32 [w] sums (Q.15), ``|acc| < 2**31 - 2**14``; ``out``: int16 [w] written in place
    (Q16.0).

    Cases
    -----
    round-nearest : as :func:`_finish`, ``|err| <= 1/2``.
    tie-even : exactly half -> the even neighbour.
    sat-high : above 32767 after rounding -> 32767 (reachable inside the int32 bound: 32767 x
        kernel gain ~2).
    sat-low : below -32768 -> -32768.
    """
    for n in range(acc.size):
        a = acc[n]
        q = (a + np.int32(0x4000)) >> np.int32(15)
        t = np.int32((a & np.int32(0x7FFF)) == np.int32(0x4000))
        q = q & ~t
        q = min(q, np.int32(32767))
        q = max(q, np.int32(-32768))
        out[n] = np.int16(q)


#: the most words of an image whose k x k (k > 3) sums go through one int32 image (a flight
#: window's stay in cache; a larger frame is summed one output row at a time)
SMALL_WORDS = 128 * 128


@callee_kernel
def _correlate_k32(pad, kern, h, w):
    """Correlation with int32 sums (the caller proved ``max|x| sum|k| < 2**31 - 2**14``).

    ``pad``: int16 [h + 2p, w + 2p] replicate-padded image; ``kern``: int16 [k, k] Q1.15. Returns
    int16 [h, w] (Q16.0). Host speed-up for 3x3 kernels: each output word's nine products summed
    in a register and finished at once (the same integer sum: addition is associative and no
    partial sum leaves the bound); other sizes add one tap at a time into an int32 image (up to
    :data:`SMALL_WORDS` words), or for a larger frame into an int32 row, one output row at a time
    (a whole-frame int32 image passed 25 times fell out of the cache on large frames).

    Cases
    -----
    typical : the exact sum rounded as :func:`_finish32` (``scipy.ndimage.correlate`` within 1/2).
    zero-taps : taps equal to 0 add nothing (skipped on the tap-at-a-time path).
    three : a 3x3 kernel -> the register path, the same words.
    rows : more than ``SMALL_WORDS`` words and k > 3 -> one output row at a time, the same words.
    """
    kh, kw = kern.shape
    out = np.empty((h, w), np.int16)
    if kh == 3 and kw == 3:
        k00, k01, k02 = np.int32(kern[0, 0]), np.int32(kern[0, 1]), np.int32(kern[0, 2])
        k10, k11, k12 = np.int32(kern[1, 0]), np.int32(kern[1, 1]), np.int32(kern[1, 2])
        k20, k21, k22 = np.int32(kern[2, 0]), np.int32(kern[2, 1]), np.int32(kern[2, 2])
        for r in range(h):
            a, b, d = pad[r], pad[r + 1], pad[r + 2]
            o = out[r]
            for c in range(w):
                s = (np.int32(a[c]) * k00 + np.int32(a[c + 1]) * k01 + np.int32(a[c + 2]) * k02
                     + np.int32(b[c]) * k10 + np.int32(b[c + 1]) * k11
                     + np.int32(b[c + 2]) * k12 + np.int32(d[c]) * k20
                     + np.int32(d[c + 1]) * k21 + np.int32(d[c + 2]) * k22)
                q = (s + np.int32(0x4000)) >> np.int32(15)          # as _finish32
                q = q & ~np.int32((s & np.int32(0x7FFF)) == np.int32(0x4000))
                o[c] = np.int16(max(min(q, np.int32(32767)), np.int32(-32768)))
        return out
    if h * w <= SMALL_WORDS:                   # a window: tap by tap into its int32 image
        acc2 = np.zeros((h, w), np.int32)
        for i in range(kh):
            for j in range(kw):
                kij = np.int32(kern[i, j])
                if kij == 0:
                    continue
                for r in range(h):
                    src = pad[r + i, j:j + w]
                    dst = acc2[r]
                    for c in range(w):
                        dst[c] += np.int32(src[c]) * kij
        _finish32(acc2.ravel(), out.ravel())
        return out
    acc = np.empty(w, np.int32)                # a frame: one output row's sums at a time
    for r in range(h):
        for c in range(w):
            acc[c] = 0
        for i in range(kh):
            src = pad[r + i]
            for j in range(kw):
                kij = np.int32(kern[i, j])
                if kij == 0:
                    continue
                for c in range(w):
                    acc[c] += np.int32(src[c + j]) * kij
        _finish32(acc, out[r])
    return out


@callee_kernel
def _correlate_k64(pad, kern, h, w):
    """Correlation with int64 sums (any 16-bit data and kernel).

    ``pad``: int16 [h + 2p, w + 2p] replicate-padded image; ``kern``: int16 [k, k] Q1.15. Returns
    int16 [h, w] (Q16.0).

    Cases
    -----
    typical : the exact sum rounded and saturated as :func:`_finish`.
    saturate : full-scale data with a large-gain kernel -> 32767 / -32768 where the sum leaves the
        word.
    """
    kh, kw = kern.shape
    acc = np.zeros((h, w), np.int64)
    for i in range(kh):
        for j in range(kw):
            kij = np.int64(kern[i, j])
            for r in range(h):
                src = pad[r + i, j:j + w]
                dst = acc[r]
                for c in range(w):
                    dst[c] += np.int64(src[c]) * kij
    out = np.empty((h, w), np.int16)
    a1 = acc.ravel()
    o1 = out.ravel()
    for n in range(h * w):
        o1[n] = _finish(a1[n])
    return out


INT32_LIMIT = 2 ** 31 - 2 ** 14     # a + 0x4000 must not overflow int32 in the finish


@callee_kernel
def correlate_q15_k(img, kern):
    """Correlate an int16 image with an int16 Q1.15 kernel, replicate edges, ADSP RND/SAT store.
    Chooses the int32 accumulator when ``max|x| * sum|k| < 2**31 - 2**14`` proves it exact.

    ``img``: int16 [h, w] (Q16.0); ``kern``: int16 [k, k] Q1.15, k odd. Returns int16 [h, w]
    (Q16.0), the same words on either path.

    Cases
    -----
    int32-path : the bound holds (12-bit data, unit-gain kernels) -> :func:`_correlate_k32`.
    int64-path : the bound fails (full-scale data or large kernels) -> :func:`_correlate_k64`.
    edges : border pixels see replicated edge words (SciPy ``mode="nearest"``).
    """
    kh, kw = kern.shape
    p = kh // 2
    h, w = img.shape
    pad = pad_nearest(img, p)
    sk = np.int64(0)
    for i in range(kh):
        for j in range(kw):
            sk += abs(np.int64(kern[i, j]))
    if np.int64(_maxabs(img)) * sk < INT32_LIMIT:
        return _correlate_k32(pad, kern, h, w)
    return _correlate_k64(pad, kern, h, w)


def as_words(img, name="image"):
    img = np.asarray(img)
    if img.ndim != 2:
        raise ValueError(f"{name} must be 2-D, got shape {img.shape}")
    if img.dtype != np.int16:
        if img.size and (img.min() < -32768 or img.max() > 32767):
            raise ValueError(f"{name} values do not fit 16-bit words")
        img = img.astype(np.int16)
    return np.ascontiguousarray(img)


def correlate_q15(img, kern, ledger=None, stage=None):
    """Spatial correlation of a 16-bit image with a 3x3/5x5/7x7 Q1.15 kernel (replicate edges).

    Parameters
    ----------
    img : ndarray (h, w), int16 words (Q16.0)
    kern : ndarray (k, k), int16 Q1.15 words, k in {3, 5, 7}
    ledger : flightsw.budget.Ledger, optional
        Charged :func:`filter_cycles` under ``("dsp", stage or "filter{k}x{k}")``.

    Returns
    -------
    ndarray (h, w) int16 (Q16.0)
    """
    kern = validate_kernel(kern, "kernel")
    img = as_words(img)
    out = correlate_q15_k(img, kern)
    if ledger is not None:
        k = kern.shape[0]
        ledger.charge("dsp", stage or f"filter{k}x{k}", filter_cycles(img.shape[0], img.shape[1], k))
    return out


def pad_cycles(h, w, p):
    """Cycles to build the replicate-padded buffer: one move per border word, 4 set-up."""
    return int((h + 2 * p) * (w + 2 * p) - h * w + 4) if p else 0


def filter_cycles(h, w, k):
    """ADSP-2100 cycles of a k x k spatial filter on an h x w window: padding + correlate_cycles."""
    return pad_cycles(h, w, k // 2) + correlate_cycles(h, w, k)
