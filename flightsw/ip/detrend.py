"""IP step 3: detrenders (high-pass, second-order polynomial surface, none).

The MSX paper ("Detrending"): "The high-pass filter detrender generates an estimate of the background
by convolving the 64x64 pixel region with a low-pass 7x7 pixel normalized Gaussian filter kernel. This
background is subtracted from the original subimage ... The alternative detrending algorithm yields an
estimate of the background by fitting a two-dimensional second-order polynomial surface to the data,
which is then subtracted from the original."

High-pass detrender (:func:`detrend_highpass`)
----------------------------------------------
The 7x7 normalised Gaussian is separable, ``K = t t^T`` with 1-D taps ``t`` (Q1.15 words, all >= 0,
``sum t = 32768`` exactly; :func:`flightsw.ip.filters.gaussian_taps_q15`), so the DSP runs a row pass
and a column pass: 14 instead of 49 MACs per pixel. Edges replicate (SciPy ``mode="nearest"``).

1. Block headroom: ``SB = EXPADJ`` over the window (one cycle a pixel) gives ``g`` = the fewest
   redundant sign bits of any pixel, capped at 8 (``g = 3`` for 12-bit pixels).
2. Row pass into the intermediate ``y`` in **Q(16-g).g** (g fractional bits, Q13.3 for 12-bit data):
   ``MR = 2**(14-g) * 1`` (a rounding tap) ``+ sum_j x[r, c+j-3] * t[j]`` (fractional MACs), then the
   shifter extracts ``y = MR >> (16 - g)`` (SR = LSHIFT MR0, SR = SR OR ASHIFT MR1): round half up at
   ``2**-(g+1)``. Because the taps are non-negative and sum to 1, ``|y| <= max|x| * 2**g < 2**15``: no
   overflow is possible, so no SAT is needed.
3. Column pass back to **Q16.0**: ``MR = 2**(14+g)`` (rounding tap ``0x4000 * 2**g``) ``+ sum_i
   y[r+i-3, c] * t[i]``, ``lp = MR >> (16 + g)`` (round half up at 1/2), then ``AR = x - lp`` with
   AR_SAT (the only place a full-range signed input can overflow 16 bits).

Error bound (derived): the row pass is exact up to its rounding, ``|y - y_exact| <= 2**-(g+1)`` (in
input units), which the column pass carries with gain ``sum t = 1``; the column rounding adds 1/2. So
``|lp - lp_exact(quantised taps)| <= 1/2 + 2**-(g+1)`` (0.5625 for 12-bit data) and the detrended
output, ``x - lp``, has the same bound. Against the ideal Gaussian (``scipy.ndimage.gaussian_filter``
with ``truncate = 3 / sigma``) add ``max|x| * sum|t_q t_q^T / 2**30 - T T^T|`` (tap quantisation,
``tests/ip_reference.py``).

Cycles per pixel: EXPADJ 1; row pass 1 rounding tap + 7 MAC + 2 shifts + 1 store + 1 pointer
modify = 12; column pass 1 + 7 + 2 + 1 subtract + 1 store + 1 modify = 13; i.e. 26 a pixel, plus
replicating 3 border columns (row pass) and 3 border rows (column pass): 6h + 6w words, and per-row
loop overhead 3 per pass. See :func:`highpass_cycles`.

Polynomial detrender (:func:`detrend_polynomial`)
-------------------------------------------------
Least squares fit of ``a0 + a1 u + a2 v + a3 u^2 + a4 uv + a5 v^2``. On the fixed window grid the
same surface is spanned by the *orthogonal* basis (doubled, centred integer coordinates
``U = 2c - (w-1)``, ``V = 2r - (h-1)``)::

    B0 = 1, B1 = U, B2 = V, B3 = 3U^2 - (w^2-1), B4 = U V, B5 = 3V^2 - (h^2-1)

whose normal matrix ``B^T B`` is constant *and diagonal* (``sum_c U = sum_c U^3 = sum_c B3 = 0``), so
the fit is ``a_k = M_k / N_k`` with only the six image moments ``M_k = sum x B_k`` computed per frame
and ``N_k = sum B_k^2`` precomputed on the ground for the window size. Identical to the monomial
``numpy.linalg.lstsq`` fit (tested).

* Tables: ``B'_k = B_k * 2**j_k`` (int16 words in PM), ``j_k`` chosen so ``2**14 <= max|B'_k| <
  2**15`` (every table fits 16 bits for windows up to 128).
* Block shift: ``s = max(0, bitlen(max|x|) - 12)`` from EXPADJ; the moments use ``x >> s`` (so
  12-bit data, s = 0, are untouched).
* Moments ``M_k = sum (x>>s) B_k``: one MAC per pixel and term, the row's MR added into a 48-bit memory
  accumulator each row (a row of <= 128 products of <= 2**31 never leaves 40 bits): exact integers.
* Coefficients in **Q1.31** double words: ``c_k = round_half_up(M_k * R_k / 2**(P_k + j_k - 31))``
  with ``R_k = round(2**P_k / N_k)`` the 32-bit normalised reciprocal (``2**30 <= R_k < 2**31``), a
  multiprecision multiply on the DSP; ``c_k`` saturates to 32 bits. ``c_k / 2**31 = a'_k = a_k /
  2**j_k`` and ``|a'_k| <= 2.25 * 2**12 / 2**14 < 1`` (the orthogonal projection bound
  ``|a_k| max|B_k| <= max|x| sum|B_k| max|B_k| / sum B_k^2 <= 2.25 max|x|``).
* Surface per pixel, double-precision MACs: ``MR = sum_k lo(c_k) * B'_k`` (US, 6 MACs), ``MR >>= 16``
  (MR0 = MR1, MR1 = MR2), ``MR += sum_k hi(c_k) * B'_k`` (SS, 6 MACs), (RND), IF MV SAT MR:
  ``MR1 = round(surface)`` in units of ``2**s``; ``out = x - (MR1 << s)`` with AR_SAT.

Error bound (s = 0): the reciprocal and Q1.31 roundings contribute ``< 6 * 2**15 * 2**-30`` counts,
the ``>> 16`` truncation ``< 2**-16``, the RND 1/2: ``|out - (x - surface_lstsq)| <= 1/2 + 2**-12``.

Cycles per pixel: EXPADJ 1, shift 1, 6 moment MACs; surface 6 + 2 + 6 + RND/SAT 2 + shift 1 +
subtract 1 + store 1 = 19; per row 6 x 4 (accumulate MR into memory, clear) + 3; per frame 6
coefficient multiprecision multiply-rounds of 40 cycles + 20. See :func:`polynomial_cycles`.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit

from flightsw.arith.adsp2100 import block_bitlen
from flightsw.ip.filters import gaussian_taps_q15
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["detrend_highpass", "detrend_polynomial", "detrend_none", "highpass_cycles",
           "highpass_k", "polynomial_k", "polynomial_coefficients_k", "check_taps", "default_taps",
           "polynomial_cycles", "lowpass_q15", "polynomial_basis",
           "DEFAULT_HIGHPASS_SIGMA", "G_MAX", "STRIP"]

DEFAULT_HIGHPASS_SIGMA = 1.5
G_MAX = 8          # cap of the block headroom used by the high-pass intermediate


# ---------------------------------------------------------------------------------------------
# high-pass
# ---------------------------------------------------------------------------------------------

@callee_kernel
def _headroom(img, gmax):
    """EXPADJ over the block: fewest redundant sign bits of any word, capped at ``gmax``.

    ``img``: int16 [h, w]; ``gmax``: int. Returns ``g = min(15 - bitlen(max|x|), gmax)``.

    Cases
    -----
    twelve-bit : 12-bit data (-4096 .. 4095) -> 3.
    full-scale : a word of 15 significant bits (32767 or -32768) -> 0.
    cap : small data (bitlen <= 15 - gmax, all zeros included) -> ``gmax``.
    """
    return min(15 - block_bitlen(img), gmax)


@callee_kernel
def _lowpass_k(img, taps, g):
    """Separable low-pass: row pass to Q(16-g).g, column pass to Q16.0 (see module docstring).

    Host speed-up: with 7 mirror-equal taps (every Gaussian the sequences make) the two pixels
    sharing a tap are added before the multiply and each output word is one expression of the
    seven (the sum held in a register, not in the output array tap by tap): exact, as integer
    addition is associative and no partial sum exceeds the proven bound. A row at a time goes
    through a replicate-padded buffer of its own.

    ``img``: int16 [h, w] (Q16.0); ``taps``: int16 [n] Q1.15, >= 0, sum 32768; ``g``: the block
    headroom (0 .. 8). Returns ``(lp int32 [h, w], shift)``: the background is ``lp >> shift``
    (Q16.0).

    Cases
    -----
    symmetric : 7 mirror-equal taps -> the paired-add path; ``|lp - exact| <= 1/2 + 2**-(g+1)``.
    asymmetric : other taps -> one MAC per tap, the same bound.
    edges : border pixels use replicated edge words (rows and columns, SciPy ``"nearest"``).
    """
    h, w = img.shape
    n = taps.shape[0]
    p = n // 2
    t = np.empty(n, np.int32)
    sym = n == 7
    for j in range(n):
        t[j] = np.int32(taps[j])
    for j in range(p):
        if t[j] != t[n - 1 - j]:
            sym = False
    z = np.int32(0)
    t0, t1, t2, t3 = (t[0], t[1], t[2], t[3]) if sym else (z, z, z, z)
    # row pass: y = (sum x*t + 2**(14-g)) >> (15-g)     Q(16-g).g
    y = np.empty((h + 2 * p, w), np.int32)
    x = np.empty(w + 2 * p, np.int32)                  # the row, p border columns replicated
    rb = np.int32(1 << (14 - g))
    sh = np.int32(15 - g)
    for r in range(h):
        src = img[r]
        for c in range(p):
            x[c] = src[0]
            x[w + p + c] = src[w - 1]
        for c in range(w):
            x[p + c] = src[c]
        dst = y[r + p]
        if sym:
            for c in range(w):
                dst[c] = (rb + (x[c] + x[c + 6]) * t0 + (x[c + 1] + x[c + 5]) * t1
                          + (x[c + 2] + x[c + 4]) * t2 + x[c + 3] * t3) >> sh
        else:
            for c in range(w):
                dst[c] = rb
            for j in range(n):
                tj = t[j]
                for c in range(w):
                    dst[c] += x[c + j] * tj
            for c in range(w):
                dst[c] = dst[c] >> sh          # SR0: |y| < 2**15 by the convexity bound, no wrap
    for r in range(p):                     # replicate the border rows of the intermediate
        for c in range(w):                 # (word by word: a row-slice copy compiles numba's
            y[r, c] = y[p, c]              # shape-mismatch message, seconds of a first run)
            y[h + p + r, c] = y[h + p - 1, c]
    # column pass: lp = (sum y*t + 2**(14+g)) >> (15+g)     Q16.0
    lp = np.empty((h, w), np.int32)
    cb = np.int32(1 << (14 + g))
    for r in range(h):
        dst = lp[r]
        if sym:
            a0, a1, a2, a3 = y[r], y[r + 1], y[r + 2], y[r + 3]
            a4, a5, a6 = y[r + 4], y[r + 5], y[r + 6]
            for c in range(w):
                dst[c] = (cb + (a0[c] + a6[c]) * t0 + (a1[c] + a5[c]) * t1
                          + (a2[c] + a4[c]) * t2 + a3[c] * t3)
        else:
            for c in range(w):
                dst[c] = cb
            for i in range(n):
                ti = t[i]
                a = y[r + i]
                for c in range(w):
                    dst[c] += a[c] * ti
    return lp, np.int32(15 + g)


#: rows of a strip of :func:`highpass_k` (a flight window is one strip)
STRIP = 64


@callee_kernel
def highpass_k(img, taps, gmax):
    """The high-pass detrender on an int16 [h, w] window (Q16.0) with 7 Q1.15 ``taps``; the block
    headroom is capped at ``gmax``. Returns int16 [h, w] (Q16.0, AR_SAT).

    Host speed-up: a frame of more than :data:`STRIP` rows goes through the low pass a strip of
    ``STRIP`` rows at a time, each with the ``n // 2`` frame rows above and below it (its row pass
    sees the same words; its replicated border rows lie outside the rows kept), so that the two
    int32 intermediates stay in cache; the headroom ``g`` is the whole frame's.

    Cases
    -----
    typical : ``x - lowpass(x)`` within ``1/2 + 2**-(g+1)`` of the float64 correlation.
    saturate : full-range signed input -> ``x - lp`` beyond 16 bits saturates to 32767 / -32768.
    headroom-cap : small data -> ``g = gmax``, the same bound with ``2**-(gmax+1)``.
    strips : more than ``STRIP`` rows (a last strip of any height) -> the same words as one pass.
    """
    g = _headroom(img, gmax)
    h, w = img.shape
    p = taps.shape[0] // 2
    out = np.empty((h, w), np.int16)
    for r0 in range(0, h, STRIP):
        r1 = min(h, r0 + STRIP)
        a, b = max(0, r0 - p), min(h, r1 + p)            # the strip and its neighbouring rows
        lp, sh2 = _lowpass_k(img[a:b], taps, g)
        for r in range(r0, r1):
            x = img[r]
            al = lp[r - a]
            o = out[r]
            for c in range(w):
                d = np.int32(x[c]) - (al[c] >> sh2)         # AR = x - lp (AR_SAT)
                d = min(d, np.int32(32767))
                d = max(d, np.int32(-32768))
                o[c] = np.int16(d)
    return out


def lowpass_q15(img, taps):
    """The high-pass detrender's background estimate (Q16.0 int32 array), for tests and figures."""
    img = np.ascontiguousarray(img, np.int16)
    g = _headroom(img, G_MAX)
    lp, sh = _lowpass_k(img, np.asarray(taps, np.int16), g)
    return lp >> sh


def check_taps(taps):
    """7 low-pass taps as int16 Q1.15 words (>= 0, sum exactly 32768); ValueError otherwise."""
    t = np.asarray(taps)
    if t.ndim != 1 or t.shape[0] != 7:
        raise ValueError(f"low-pass taps: need 7 Q1.15 words, got shape {t.shape}")
    if t.min() < 0 or t.max() > 32767 or int(t.sum()) != 32768:
        raise ValueError("low-pass taps: must be Q1.15 words >= 0 summing to exactly 32768 (1.0)")
    return t.astype(np.int16)


def detrend_highpass(img, taps=None, ledger=None, stage="detrend_highpass"):
    """High-pass detrend: ``x - lowpass7x7(x)`` (separable normalised Gaussian, replicate edges).

    Parameters
    ----------
    img : ndarray (h, w) int16 words (Q16.0)
    taps : 7 Q1.15 words >= 0 with sum 32768; default ``gaussian_taps_q15(1.5)``
    ledger : Ledger, optional — charged :func:`highpass_cycles` under ``("dsp", stage)``

    Returns ndarray (h, w) int16 (Q16.0, saturated).
    """
    taps = default_taps() if taps is None else check_taps(taps)
    img = np.ascontiguousarray(img, np.int16)
    out = highpass_k(img, taps, G_MAX)
    if ledger is not None:
        ledger.charge("dsp", stage, highpass_cycles(*img.shape))
    return out


@lru_cache(maxsize=None)
def default_taps(sigma=DEFAULT_HIGHPASS_SIGMA):
    """The 7 Q1.15 taps of the normalised Gaussian of ``sigma`` (pixels), cached."""
    return gaussian_taps_q15(sigma, 7)


def highpass_cycles(h, w, n=7):
    """ADSP-2100 cycles of the separable high-pass detrender on an h x w window."""
    p = n // 2
    expadj = h * w + 3
    row = h * w * (n + 5) + 2 * p * h + 3 * h + 10
    col = h * w * (n + 6) + 2 * p * w + 3 * h + 10
    return int(expadj + row + col)


def detrend_none(img, ledger=None, stage="detrend_none"):
    """No detrending: the image passes unchanged (0 cycles, recorded)."""
    if ledger is not None:
        ledger.charge("dsp", stage, 0)
    return np.asarray(img)


# ---------------------------------------------------------------------------------------------
# polynomial surface
# ---------------------------------------------------------------------------------------------
@lru_cache(maxsize=16)
def polynomial_basis(h, w):
    """Ground-precomputed constants for an h x w window.

    Returns ``(tables int16 [6, h, w], j int64[6], N list[int], R int64[6], P int64[6])``:
    the scaled orthogonal basis tables ``B'_k = B_k << j_k``, the exact norms ``N_k = sum B_k^2``,
    and the 32-bit normalised reciprocals ``R_k = round(2**P_k / N_k)``."""
    U = 2 * np.arange(w, dtype=np.int64) - (w - 1)
    V = 2 * np.arange(h, dtype=np.int64) - (h - 1)
    UU, VV = np.meshgrid(U, V)
    B = [np.ones((h, w), np.int64), UU, VV, 3 * UU * UU - (w * w - 1), UU * VV,
         3 * VV * VV - (h * h - 1)]
    tables = np.empty((6, h, w), np.int16)
    js, Ns, Rs, Ps = [], [], [], []
    for k, b in enumerate(B):
        m = int(np.abs(b).max())
        if m == 0:                      # degenerate axis (h or w == 1): not used by the flight sizes
            raise ValueError(f"window {h}x{w} too small for the polynomial detrender")
        j = 0
        while (m << (j + 1)) < 2 ** 15:
            j += 1
        while (m << j) >= 2 ** 15:
            j -= 1
        if j < 0:
            raise ValueError(f"window {h}x{w}: basis {k} does not fit a 16-bit table")
        tables[k] = (b << j).astype(np.int16)
        N = int((b * b).sum())
        P = 30 + N.bit_length()          # 2**30 <= 2**P / N < 2**31 (rounded)
        R = (2 ** P + N // 2) // N
        if R >= 2 ** 31:
            P -= 1
            R = (2 ** P + N // 2) // N
        js.append(j)
        Ns.append(N)
        Rs.append(R)
        Ps.append(P)
    return tables, np.array(js, np.int64), Ns, np.array(Rs, np.int64), np.array(Ps, np.int64)


@callee_kernel
def _block_shift(img):
    """Block shift of the polynomial moments: ``max(0, bitlen(max|x|) - 12)`` of int16 [h, w].

    Cases
    -----
    no-shift : 12-bit data -> 0.
    shift : full-scale data -> 3 (``|x >> 3| <= 4096``).
    """
    return max(0, block_bitlen(img) - 12)


@callee_kernel
def _moments_k(img, tables, js, s):
    """Exact moments ``M_k = sum (x >> s) * B_k`` (B_k = B'_k >> j_k, exact since B'_k = B_k << j_k).

    ``img``: int16 [h, w]; ``tables``: int16 [6, h, w]; ``js``: int64 [6]; ``s``: block shift.
    Returns int64 [6].

    Cases
    -----
    typical : the six integer moments against the orthogonal basis, exactly.
    shifted : ``s > 0`` -> the moments of ``x >> s`` (arithmetic shift, towards -inf).
    """
    h, w = img.shape
    M = np.zeros(6, np.int64)
    for r in range(h):
        for c in range(w):
            x = np.int64(img[r, c]) >> s
            for k in range(6):
                M[k] += x * (np.int64(tables[k, r, c]) >> js[k])
    return M


@callee_kernel
def _surface_sub_k(img, tables, cw, s):
    """Surface by double-precision MACs and subtraction (see module docstring).

    ``img``: int16 [h, w]; ``tables``: int16 [6, h, w]; ``cw``: int64 [6] Q1.31 coefficient words;
    ``s``: block shift. Returns int16 [h, w] ``x - (surface << s)``, AR_SAT.

    Cases
    -----
    typical : the surface rounded to the nearest count (within 1/2 + 2**-12 of the lstsq fit).
    tie-even : a surface exactly halfway (MR0 == 0x8000) rounds to even (0.5 -> 0, 1.5 -> 2,
        -1.5 -> -2).
    surface-sat : an MR beyond 32 bits -> the surface saturates to 32767 / -32768 (IF MV SAT MR).
    ar-sat : ``x - surface`` beyond 16 bits -> 32767 / -32768.
    shift : ``s > 0`` -> the surface is shifted up by ``s`` before the subtraction.
    """
    h, w = img.shape
    out = np.empty((h, w), np.int16)
    lo = np.empty(6, np.int64)
    hi = np.empty(6, np.int64)
    for k in range(6):
        lo[k] = cw[k] & 0xFFFF          # unsigned low word
        hi[k] = cw[k] >> 16             # signed high word
    for r in range(h):
        for c in range(w):
            mr = np.int64(0)
            for k in range(6):
                mr += (lo[k] * np.int64(tables[k, r, c])) << 1       # US MACs
            mr >>= 16                                                  # MR0 = MR1, MR1 = MR2
            for k in range(6):
                mr += (hi[k] * np.int64(tables[k, r, c])) << 1       # SS MACs
            # (RND), IF MV SAT MR, MR1
            m40 = mr & 0xFFFFFFFFFF
            if m40 & 0x8000000000:
                m40 -= 0x10000000000
            low = m40 & 0xFFFF
            m40 += 0x8000
            if low == 0x8000:
                m40 &= ~np.int64(0x10000)
            if m40 >= 0x80000000:
                sv = np.int64(32767)
            elif m40 < -0x80000000:
                sv = np.int64(-32768)
            else:
                sv = m40 >> 16
            d = np.int64(img[r, c]) - (sv << s)                         # AR = x - surface, AR_SAT
            out[r, c] = np.int16(min(max(d, -32768), 32767))
    return out


@callee_kernel
def polynomial_coefficients_k(M, js, rs, ps):
    """Q1.31 coefficient words ``c_k = round_half_up(M_k R_k / 2**(P_k + j_k - 31))``, saturated to
    32 bits: the DSP's multiprecision multiply-round (module docstring).

    ``M`` int64 [6] exact moments (``|M_k| < 2**40``), ``js`` int64 [6] table shifts, ``rs`` int64
    [6] reciprocals ``R_k < 2**31``, ``ps`` int64 [6] their exponents. The product needs up to 71
    bits, so it is formed as ``A 2**16 + B`` (``0 <= B < 2**16``) and rounded in two steps:
    ``floor((A 2**16 + B + half) / 2**sh) = floor((A + floor((B + half) / 2**16)) / 2**(sh - 16))``.
    Returns int64 [6].

    Cases
    -----
    round-two-step : ``sh >= 16`` (every flight window) -> the two-step round half up, exact.
    round-one-step : ``0 < sh < 16`` -> one round half up of ``A 2**16 + B``.
    left-shift : ``sh <= 0`` -> the product shifted left, no rounding.
    saturate : a result beyond 32 bits (either sign, any ``sh``) -> 2**31 - 1 / -2**31.
    zero-moment : ``M_k == 0`` -> 0, whatever the shift.
    """
    out = np.empty(6, np.int64)
    lim = np.int64(2 ** 31 - 1)
    for k in range(6):
        sh = ps[k] + js[k] - 31
        m = M[k]
        a = (m >> 16) * rs[k]                  # prod = a * 2**16 + b
        b = (m & 0xFFFF) * rs[k]
        a += b >> 16
        b &= 0xFFFF
        if sh >= 16:
            c = (a + ((b + (np.int64(1) << (sh - 1))) >> 16)) >> (sh - 16)
        elif abs(a) >= np.int64(1) << 46:      # |prod| >= 2**62: saturates at any sh < 16
            c = lim if a > 0 else -lim - 1
        elif sh > 0:
            c = ((a << 16) + b + (np.int64(1) << (sh - 1))) >> sh
        elif abs(a) >= np.int64(1) << 30:      # |prod| >= 2**46 before the left shift
            c = lim if a > 0 else -lim - 1
        else:                                  # |prod| < 2**46 + 2**16, shifted left by -sh
            p = (a << 16) + b
            if p == 0:
                c = np.int64(0)
            elif -sh < 62 and abs(p) < np.int64(1) << (62 + sh):
                c = p << (-sh)
            else:
                c = lim if p > 0 else -lim - 1
        out[k] = min(max(c, -lim - 1), lim)
    return out


@njit(**KERNEL)
def polynomial_k(img, tables, js, rs, ps):
    """The polynomial detrender on an int16 [h, w] window (Q16.0): block shift, the six moments,
    the Q1.31 coefficients and the surface subtraction. ``tables`` int16 [6, h, w] and ``js``, ``rs``,
    ``ps`` int64 [6] are :func:`polynomial_basis`'s ground constants. Returns (out int16 [h, w],
    coefficient words int64 [6], block shift s).

    Cases
    -----
    typical : ``x - lstsq surface`` within ``1/2 + 2**-12`` (12-bit data, s = 0).
    block-shift : full-scale data -> s = 3, coefficients inside 32 bits, int16 output.
    """
    s = _block_shift(img)
    M = _moments_k(img, tables, js, s)
    cw = polynomial_coefficients_k(M, js, rs, ps)
    return _surface_sub_k(img, tables, cw, s), cw, s


def detrend_polynomial(img, ledger=None, stage="detrend_polynomial", return_surface=False):
    """Second-order polynomial surface-fit detrend: ``x - LSQ surface(x)``.

    Parameters
    ----------
    img : ndarray (h, w) int16 words (Q16.0), h, w >= 3
    ledger : Ledger, optional — charged :func:`polynomial_cycles` under ``("dsp", stage)``

    Returns ndarray (h, w) int16 (Q16.0, saturated); with ``return_surface`` also the Q1.31
    coefficient words and the block shift.
    """
    img = np.ascontiguousarray(img, np.int16)
    h, w = img.shape
    if h < 3 or w < 3:
        raise ValueError(f"window {h}x{w} too small for a second-order surface (need >= 3x3)")
    tables, js, _, rs, ps = polynomial_basis(h, w)
    out, cw, s = polynomial_k(img, tables, js, rs, ps)
    if ledger is not None:
        ledger.charge("dsp", stage, polynomial_cycles(h, w))
    if return_surface:
        return out, cw, s
    return out


def polynomial_cycles(h, w):
    """ADSP-2100 cycles of the polynomial detrender on an h x w window."""
    per_pixel = 1 + 1 + 6 + 19
    return int(h * w * per_pixel + h * (6 * 4 + 3) + 6 * 40 + 20)
