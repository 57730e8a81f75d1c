"""IP steps 2 and 4, the slow path: linear filters larger than 7x7 through a fixed-point 2-D FFT.

The MSX paper ("Linear filtering"): "Larger convolution kernels are applied via software frequency
domain filtering, although throughput concerns limit the use of this option." This module is that
option as the ADSP-2100 would run it: radix-2 decimation-in-time FFTs on Q1.15 complex words with
**block floating point** (the ADSP-2100 applications-handbook scheme), overlap-save tiles, a
pointwise product with the kernel's spectrum, the inverse FFT, and one rounding to the output words.
The result is the same correlation as :func:`flightsw.ip.filters.correlate_q15` (replicate edges,
kernel not flipped, Q16.0 out), within the error bound derived below.

Data path (per frame, window ``h x w`` of Q16.0 words, odd ``k x k`` kernel of Q1.15 words)
-----------------------------------------------------------------------------------------
1. **DC removal** (exact): ``m = round_half_up(mean(window))``; the FFTs transform ``x - m`` and the
   constant comes back at the end as ``m * sum(k)`` (correlating a constant with replicate edges gives
   the constant times the kernel sum). This keeps the background level out of the FFT's dynamic range
   (the DC bin of a 12-bit frame would otherwise set the block exponent for every other bin). ``m = 0``
   when ``x - m`` would not fit 16 bits.
2. **Overlap-save tiles** of ``T x T`` complex words (``T`` in {16, 32}; 64 only off the flight
   board, see memory below): tile ``(i, j)`` holds the replicate-padded window from row ``i V``, column
   ``j V`` (``V = T - k + 1`` valid outputs a side, zeros past the padded window) and yields the
   ``V x V`` outputs whose kernel footprint lies inside the tile, so the circular correlation equals
   the linear one there.
3. **Forward 2-D FFT**, row-column: rows (only the tile rows that hold data), then columns; each 1-D
   FFT is radix-2 DIT (bit-reversed addressing on the loads, natural-order results).
4. **Product** with the kernel spectrum ``Kq`` (conjugate of the kernel's DFT: correlation), then
   5. the **inverse 2-D FFT** (conjugate twiddles, unnormalised) over the columns and only the ``V``
   valid rows.
6. **Output**: ``out = RND/SAT((Y * 2**(D + 15) + m * sum(k)) / 2**15)`` with ``D`` the accumulated
   block exponent minus ``log2(T*T)`` (the inverse transform's ``1/T**2``): a single round-half-even
   (the MR's ``(RND)``) and saturation to 16 bits.

Arithmetic of one butterfly (integers, ``c, s`` the Q1.15 twiddle words of ``W = (c - j s)/2**15``)
---------------------------------------------------------------------------------------------------
Block floating point: every stage starts with the block's largest magnitude (EXPADJ over the
previous stage's outputs, ``SB``) and shifts its inputs right by ``sh = max(0, bitlen - 13)`` bits
(``ASHIFT``, floor) so that every input component is in ``[-2**13, 2**13)``; then::

    t_r = RND((b_r c + b_i s) / 2**15)      t_i = RND((b_i c - b_r s) / 2**15)      (2 MACs each)
    a'  = a + t,  b' = a - t                                                          (ALU)

with ``RND`` the MR's round half to even. ``|t| <= sqrt(2) 2**13 + 1/2`` and ``|a +- t| < 19 780``:
no stage can overflow, so no saturation is needed. The product step shifts so that ``|X| < 2**14``
(``bitlen <= 14``) and rounds ``P = RND(X * Kq / 2**15)``; ``|Kq| <= 32767`` (complex magnitude) keeps
``|P| < 2**14.5``. The kernel spectrum is ground-computed once per uplinked kernel (float64 DFT,
rounded to Q1.15 words with its own exponent ``e_k`` so that ``max |Kq| <= 32767``) and held in PM.
The shifts are the *block exponent*; ``D = (sum of all shifts) + e_k - 2 log2 T``.

Error bound (derived; :func:`fft_correlate` returns it per tile)
----------------------------------------------------------------
Compare with the exact correlation of the same Q1.15 taps (``scipy.ndimage.correlate(x, k/2**15,
mode="nearest")``). Let ``E`` bound the L2 norm (over the tile's complex array, in the current
stage's units) of the difference between the fixed-point array and the exact transform carried with
the same shifts. The input ``x - m`` is exact (``E = 0``). A butterfly stage over ``n`` complex
elements with input bit length ``bl`` and shift ``sh``:

* the exact radix-2 stage is ``sqrt(2)`` times an orthogonal map: carried error ``sqrt(2) E / 2**sh``;
* the floor of the input shift: ``|f| <= 1 - 2**-sh`` per component: ``sqrt(2) (1 - 2**-sh) sqrt(2n)``;
* the twiddle words: ``delta_w = max |Wq - W|`` (from the table, about ``2**-15.5``) on inputs of
  magnitude ``<= 2**(bl-sh)`` per component: ``sqrt(2) delta_w 2**(bl-sh) sqrt(n)``;
* the RND of ``t`` (``<= 1/2`` per component, each ``t`` used twice): ``sqrt(n / 2)``.

The product step (shift ``sh``): ``(E / 2**sh + (1 - 2**-sh) sqrt(2n)) max|Kq| / 2**15 +
2**(bl-sh) sqrt(2n) delta_K / 2**15 + sqrt(2n) / 2`` with ``delta_K = max |Kq - K_exact|`` (``<=
2**-1/2``). After the inverse passes the output pixels are the real parts of the first ``V x V``
elements, so **every output pixel** is within ``B = E 2**D + 1/2`` of the exact correlation (the
last 1/2: the final RND) and their RMS within ``E 2**D / sqrt(V_r V_c) + 1/2`` (L2 over the pixels
<= L2 over the array). Saturated pixels excepted. ``B`` depends only on the block exponents (the
shifts and the data's L2 norms), which is what the scaling predicts. It is a worst case (about 60
counts for 12-bit frames in 32x32 tiles: the L2-to-max step alone gives away a factor T); the
statistical model (independent rounding errors: variance 1/12 per RND, the floor's second moment per
shift, gains 2 per stage and ``mean |Kq|^2 / 2**30`` through the product, the energy spread evenly
over the ``T^2`` elements, half of it in the real parts) predicts the RMS error, returned as
``rms_predicted``: 0.29 counts for 12-bit star-field frames, where the final RND dominates and
the maximum error is ~0.6 counts; up to ~2 counts RMS (16 maximum) for uniform 12-bit noise under a
zero-mean 11x11 filter in 16x16 tiles, where many stages must shift. The tests hold every pixel to the
rigorous bound and the measured RMS to at most 1.25 x the prediction (it stays within 0.45 - 1.05 x).

Cycles (ADSP-2100, charged to ``"dsp"``; [ASSUMED] composition: the flight assembly is not public)
----------------------------------------------------------------------------------------------
* butterfly: 4 input shifts + 4 MACs + 4 ALU + 4 EXPADJ on the outputs = 16 (loads/stores and the PM
  twiddle fetch ride in the multifunction instructions);
* per FFT stage: 4 a group (twiddle pointer, DO set-up, pointer modifies) and 14 a stage (DO set-up,
  read SB, form SE, reset SB); 10 per FFT (bit-reverse addressing set-up);
* tile fill 2 per element (re = x - m, im = 0, bit-reversed store) + 3 a row; product 8 per element
  (4 MACs, 2 shifts, 2 EXPADJ); output 5 per pixel (shift, MAC of ``m sum k``, RND, SAT, store) + 3
  a row; per frame: the mean, ``h w + 50``.

On a 64x64 window the frequency path never beats the spatial one with the tiles the DSP memory
allows (9x9: 1.65 M cycles, 0.20 s at 8.192 MHz, against 0.34 M spatially; 15x15: 2.80 M against
0.93 M); with 64x64 tiles (ground only) it breaks even near 29x29 (31x31: 3.2 M against 3.9 M).
Hence the paper's "throughput concerns limit the use of this option".

Memory: the tile buffer is ``2 T**2`` words of DM (2048 at T = 32) beside the window and the output
(4096 each at 64x64); the kernel spectrum ``2 T**2`` words and the twiddles live in PM. T = 64 would
need 8192 DM words for the tile alone, which with window and output fills the 16K DM: allowed only
on request (ground runs), not chosen automatically.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numba import njit

from flightsw.arith.adsp2100 import bitlen
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["FFT_TILES", "FLIGHT_TILES", "MAX_FFT_KERNEL", "FFTKernel", "fft_kernel",
           "fft_correlate", "fft_filter_cycles", "fft_cycles_1d", "twiddles_q15",
           "gaussian_kernel_q15", "choose_tile", "fft_dm_words"]

FFT_TILES = (16, 32, 64)
FLIGHT_TILES = (16, 32)          # tile buffers that fit the DSP data memory beside a 64x64 window
MAX_FFT_KERNEL = 63

BUTTERFLY_CYCLES = 16
GROUP_CYCLES = 4
STAGE_CYCLES = 14
FFT_SETUP_CYCLES = 10
FILL_CYCLES = 2
PRODUCT_CYCLES = 8
OUTPUT_CYCLES = 5
ROW_CYCLES = 3


# ------------------------------------------------------------------------------------------------
# tables and the kernel spectrum (ground side: float64 allowed, results are Q1.15 words)
# ------------------------------------------------------------------------------------------------
@lru_cache(maxsize=None)
def twiddles_q15(T):
    """Q1.15 twiddle words of a T-point FFT: ``c[m] = round(2**15 cos(2 pi m / T))``, ``s[m] =
    round(2**15 sin(2 pi m / T))`` for ``m < T/2``, clipped to 32767 (cos 0 = 1 and sin pi/2 = 1 are
    not representable); and ``delta_w = max |(c - j s)/2**15 - exp(-2 pi j m / T)|``."""
    m = np.arange(T // 2)
    ang = 2 * np.pi * m / T
    c = np.clip(np.round(32768 * np.cos(ang)), -32768, 32767).astype(np.int64)
    s = np.clip(np.round(32768 * np.sin(ang)), -32768, 32767).astype(np.int64)
    dw = float(np.abs((c - 1j * s) / 32768 - np.exp(-1j * ang)).max())
    return c, s, dw


@lru_cache(maxsize=None)
def bitrev(T):
    n = T.bit_length() - 1
    return np.array([int(format(i, f"0{n}b")[::-1], 2) for i in range(T)], np.int64)


def gaussian_kernel_q15(size, sigma):
    """Normalised 2-D Gaussian ``exp(-r^2 / 2 sigma^2) / sum`` of any odd size, Q1.15 words with the sum
    forced to exactly 32768 through the centre tap (the low-pass for kernels past 7x7)."""
    if not isinstance(size, (int, np.integer)) or size < 3 or size % 2 == 0:
        raise ValueError(f"size={size!r} must be an odd int >= 3")
    p = size // 2
    y, x = np.mgrid[-p:p + 1, -p:p + 1]
    g = np.exp(-(x * x + y * y) / (2.0 * float(sigma) ** 2))
    q = np.round(g / g.sum() * 32768).astype(np.int64)
    q[p, p] += 32768 - q.sum()
    if q.max() > 32767:
        raise ValueError(f"sigma={sigma!r} too small for a Q1.15 kernel (centre tap >= 1.0)")
    return q.astype(np.int16)


@dataclass(frozen=True)
class FFTKernel:
    """A kernel prepared for the frequency path (what the ground uplinks besides the taps).

    Attributes
    ----------
    taps : int16 [k, k] Q1.15 words
    tile : FFT size T
    kr, ki : int64 [T, T] the spectrum words ``Kq`` (real, imaginary), transposed (the product runs
        on the column-pass layout)
    ek : int, the spectrum's exponent (``K_exact = Kq * 2**(ek - 15)``)
    kmax : float, ``max |Kq|`` (complex magnitude, <= 32767)
    k2mean : float, ``mean |Kq|**2`` (the statistical error model's gain)
    dk : float, ``max |Kq - K_exact 2**(15 - ek)|`` in words
    ksum : int, ``sum(taps)``
    """

    taps: np.ndarray = field(repr=False)
    tile: int
    kr: np.ndarray = field(repr=False)
    ki: np.ndarray = field(repr=False)
    ek: int
    kmax: float
    k2mean: float
    dk: float
    ksum: int

    @property
    def size(self):
        return int(self.taps.shape[0])


#: An FFT filter's constants, one record (:func:`fft_spec`) :func:`fft_correlate_k` reads by
#: field: the :class:`FFTKernel`'s words and the ground's error model (float64: the bound is a
#: ground product, not a flight word).
FFT_SPEC = np.dtype([
    ("tile", np.int64),      # T, the FFT size (16, 32 or 64)
    ("size", np.int64),      # k, the odd kernel size
    ("ek", np.int64),        # the spectrum's exponent: K_exact = Kq * 2**(ek - 15)
    ("ksum", np.int64),      # sum of the taps (Q1.15 words)
    ("use_mean", np.int64),  # 1: remove the window's DC level first (step 1)
    ("kmax", np.float64),    # max |Kq|, words (error model)
    ("k2mean", np.float64),  # mean |Kq|**2, words**2 (error model)
    ("dk", np.float64),      # max |Kq - K_exact 2**(15 - ek)|, words (error model)
    ("dw", np.float64),      # the twiddle table's error, words (error model)
])

#: One tile's block exponents (:func:`fft_correlate_k`), bits: the result is the tile's
#: correlation times ``2**D``.
TILE_INFO = np.dtype([
    ("forward_shifts", np.int64),   # the forward row and column passes' shifts
    ("product_shift", np.int64),    # the shift before the product with the spectrum
    ("inverse_shifts", np.int64),   # the inverse passes' shifts
    ("D", np.int64),                # the tile's total exponent
])


def fft_spec(kern: "FFTKernel", dw: float, use_mean: bool = True) -> np.ndarray:
    """:data:`FFT_SPEC` [1] of a prepared kernel, the twiddle table's error ``dw`` and the DC
    removal's switch."""
    out = np.zeros(1, FFT_SPEC)
    out[0] = (kern.tile, kern.size, kern.ek, kern.ksum, bool(use_mean), kern.kmax, kern.k2mean,
              kern.dk, dw)
    return out


def fft_kernel(taps, tile):
    """Prepare ``taps`` (odd k x k Q1.15 words) for T = ``tile``: the conjugate DFT of the kernel
    zero-padded to T x T (correlation), quantised to Q1.15 words with the smallest exponent ``ek``
    (>= -15) that keeps every word's complex magnitude <= 32767."""
    taps = np.asarray(taps)
    k = taps.shape[0]
    if tile not in FFT_TILES:
        raise ValueError(f"tile={tile!r} must be one of {FFT_TILES}")
    if k >= tile:
        raise ValueError(f"a {k}x{k} kernel needs an FFT tile larger than {tile}")
    return _fft_kernel_cached(taps.astype(np.int16).tobytes(), k, int(tile))


@lru_cache(maxsize=64)
def _fft_kernel_cached(raw, k, T):
    taps = np.frombuffer(raw, np.int16).reshape(k, k).copy()
    kp = np.zeros((T, T))
    kp[:k, :k] = taps / 32768.0
    K = np.conj(np.fft.fft2(kp))              # correlation: X * conj(DFT(k))
    mag = np.abs(K).max()
    ek = -15
    while True:
        scale = 2.0 ** (15 - ek)
        kr = np.round(K.real * scale)
        ki = np.round(K.imag * scale)
        if np.hypot(kr, ki).max() <= 32767 and np.abs(kr).max() <= 32767 \
                and np.abs(ki).max() <= 32767:
            break
        ek += 1
    dk = float(np.abs((kr + 1j * ki) - K * scale).max()) if mag > 0 else 0.0
    return FFTKernel(taps, T, np.ascontiguousarray(kr.T.astype(np.int64)),
                     np.ascontiguousarray(ki.T.astype(np.int64)), int(ek),
                     float(np.hypot(kr, ki).max()), float((kr * kr + ki * ki).mean()), dk,
                     int(taps.astype(np.int64).sum()))


# ------------------------------------------------------------------------------------------------
# cycles
# ------------------------------------------------------------------------------------------------
def fft_cycles_1d(T):
    """ADSP-2100 cycles of one T-point radix-2 DIT FFT with block floating point (module docstring)."""
    n = T.bit_length() - 1
    return int(BUTTERFLY_CYCLES * (T // 2) * n + GROUP_CYCLES * (T - 1) + STAGE_CYCLES * n
               + FFT_SETUP_CYCLES)


def _tile_grid(h, w, k, T):
    V = T - k + 1
    return V, -(-h // V), -(-w // V)


def fft_filter_cycles(h, w, k, tile):
    """ADSP-2100 cycles of the frequency-domain k x k filter on an h x w window with T = ``tile``."""
    T = int(tile)
    V, nti, ntj = _tile_grid(h, w, k, T)
    f1 = fft_cycles_1d(T)
    M = h + k - 1                       # rows of the replicate-padded window
    total = h * w + 50                  # the mean (DC removal)
    for i in range(nti):
        rows_data = min(T, M - i * V)   # tile rows that hold data (the rest stay zero)
        vr = min(V, h - i * V)
        for j in range(ntj):
            vc = min(V, w - j * V)
            total += T * T * FILL_CYCLES + ROW_CYCLES * T
            total += f1 * (rows_data + T)                 # forward: rows with data, all columns
            total += T * T * PRODUCT_CYCLES
            total += f1 * (T + vr)                        # inverse: all columns, valid rows
            total += vr * vc * OUTPUT_CYCLES + ROW_CYCLES * vr
    return int(total)


def choose_tile(h, w, k, tiles=FLIGHT_TILES):
    """The tile size of ``tiles`` with the fewest cycles for this window and kernel (None: none fits)."""
    best = None
    for T in tiles:
        if T - k + 1 < 1:
            continue
        c = fft_filter_cycles(h, w, k, T)
        if best is None or c < best[1]:
            best = (T, c)
    return None if best is None else best[0]


def fft_dm_words(h, w, tile):
    """DSP data-memory words of the frequency path: window + output + the complex tile buffer."""
    return int(2 * h * w + 2 * tile * tile)


# ------------------------------------------------------------------------------------------------
# the fixed-point kernels
# ------------------------------------------------------------------------------------------------
@callee_kernel
def _rnd15(a):
    """MR (RND) read from MR1 for MR = 2a: round half to even of a / 2**15.

    ``a``: int64 sum of Q.15 products. Returns int64.

    Cases
    -----
    round-nearest : ``a / 2**15`` to the nearest integer, either sign.
    tie-even : ``a & 0x7FFF == 0x4000`` -> the even neighbour (0.5 -> 0, 1.5 -> 2, -0.5 -> 0,
        -1.5 -> -2).
    """
    q = (a + 0x4000) >> 15
    if (a & 0x7FFF) == 0x4000:
        q &= ~np.int64(1)
    return q


@callee_kernel
def _row_pass(re, im, nv, spec, tables, inverse, state, log):
    """Radix-2 DIT FFT along axis 1 of rows 0..nv-1 (stage by stage over the whole block, one block
    exponent). ``state`` = (bl, E, Vv): ``bl`` the bit length of the block's largest magnitude on
    entry, ``E`` the L2 error bound, ``Vv`` the statistical error energy (module docstring).
    Returns (bl, E, Vv, shifts) after the pass; ``log`` [nstages, 3] receives (n, bl, sh) per
    stage.

    ``re``, ``im``: int64 [T, T] rows of complex words, transformed in place (natural order out);
    ``spec``: :data:`FFT_SPEC` [1] (its ``tile`` T and ``dw``, the twiddle table's error);
    ``tables`` = (``brev`` int64 [T] bit-reversal table, ``twc``, ``tws`` int64 [T/2] Q1.15
    twiddle words). The result times ``2**shifts`` is the DFT.

    Cases
    -----
    forward : ``inverse`` false -> ``numpy.fft.fft`` of each row within the L2 bound ``E``.
    inverse : ``inverse`` true (conjugate twiddles) -> ``T * numpy.fft.ifft`` within ``E``.
    no-shift : every stage's inputs within 13 bits -> no shift, ``shifts == 0``.
    block-shift : wider inputs -> each stage shifts by ``bitlen - 13`` (``log`` records it).
    partial-rows : ``nv < T`` -> rows ``nv..`` untouched.
    """
    sp = spec[0]
    T, dw = sp.tile, sp.dw
    brev, twc, tws = tables
    bl, E, Vv = state
    tmp_r = np.empty(T, np.int64)
    tmp_i = np.empty(T, np.int64)
    for r in range(nv):
        xr = re[r]
        xi = im[r]
        for c in range(T):
            tmp_r[c] = xr[brev[c]]
            tmp_i[c] = xi[brev[c]]
        for c in range(T):
            xr[c] = tmp_r[c]
            xi[c] = tmp_i[c]
    nst = 0
    L = 2
    shifts = 0
    sq2 = math.sqrt(2.0)
    while L <= T:
        half = L >> 1
        stride = T // L
        sh = max(0, bl - 13)
        orv = np.int64(0)
        bsq = 0.0
        for r in range(nv):
            xr = re[r]
            xi = im[r]
            for g in range(0, T, L):
                for j in range(half):
                    c = twc[j * stride]
                    s = tws[j * stride]
                    if inverse:
                        s = -s
                    a = g + j
                    b = a + half
                    ar = xr[a] >> sh
                    ai = xi[a] >> sh
                    br = xr[b] >> sh
                    bi = xi[b] >> sh
                    bsq += float(br * br + bi * bi)
                    tr = _rnd15(br * c + bi * s)
                    ti = _rnd15(bi * c - br * s)
                    o1 = ar + tr
                    o2 = ai + ti
                    o3 = ar - tr
                    o4 = ai - ti
                    xr[a] = o1
                    xi[a] = o2
                    xr[b] = o3
                    xi[b] = o4
                    orv |= (o1 ^ (o1 >> 63)) | (o2 ^ (o2 >> 63)) | (o3 ^ (o3 >> 63)) \
                        | (o4 ^ (o4 >> 63))
        n = nv * T
        fl = 1.0 - 2.0 ** (-sh)
        E = sq2 * (E / 2.0 ** sh + fl * math.sqrt(2.0 * n)) \
            + sq2 * dw * math.sqrt(bsq) + math.sqrt(n / 2.0)
        Vv = 2.0 * (Vv / 4.0 ** sh + 2.0 * n * _floor_m2(sh)) + 2.0 * dw * dw * bsq + n / 6.0
        log[nst, 0] = n
        log[nst, 1] = bl
        log[nst, 2] = sh
        nst += 1
        shifts += sh
        bl = bitlen(orv)
        L <<= 1
    return bl, E, Vv, shifts


@callee_kernel
def _floor_m2(sh):
    """Second moment of the floor error of ``>> sh`` on uniformly distributed low bits.

    ``sh``: int >= 0. Returns float ``(d - 1)(2d - 1) / (6 d**2)``, ``d = 2**sh`` (in output LSBs).

    Cases
    -----
    no-shift : ``sh == 0`` -> 0.
    typical : the mean of ``(k / d)**2`` over the ``d`` equally likely low-bit patterns.
    """
    d = 2.0 ** sh
    return (d - 1.0) * (2.0 * d - 1.0) / (6.0 * d * d)


@callee_kernel
def _block_bitlen(re, im, nv, T):
    """Bit length (``x`` or ``~x``) of the largest word in rows ``0..nv-1`` of ``re`` and ``im``
    (int64 [T, T]): the tile's block exponent on entry.

    Cases
    -----
    typical : the largest positive or negative (``~x``) word of either array decides.
    zero : all words 0 or -1 -> 0.
    rows-beyond-nv : rows ``nv..`` are not looked at.
    """
    orv = np.int64(0)
    for r in range(nv):
        for c in range(T):
            a = re[r, c]
            b = im[r, c]
            orv |= (a ^ (a >> 63)) | (b ^ (b >> 63))
    return bitlen(orv)


@callee_kernel
def _transpose(a, T):
    """Transposed copy of an int64 [T, T] array (the row-column FFT's corner turn).

    Cases
    -----
    typical : ``out[c, r] = a[r, c]``.
    """
    out = np.empty((T, T), np.int64)
    for r in range(T):
        for c in range(T):
            out[c, r] = a[r, c]
    return out


@callee_kernel
def _dc_mean(img, use_mean):
    """The DC level the frequency path removes from an int16 [h, w] window: ``m = round_half_up(
    mean)`` when ``use_mean``, else 0; 0 too when some ``x - m`` would not fit 16 bits.

    Cases
    -----
    dc-removal : ``use_mean`` and every ``x - m`` fits -> the mean rounded half up.
    no-dc : ``use_mean`` false -> 0.
    dc-does-not-fit : some ``x - m`` outside -32768..32767 -> 0.
    """
    h, w = img.shape
    s = np.int64(0)
    mx = np.int64(-32768)
    mn = np.int64(32767)
    for r in range(h):
        for c in range(w):
            v = np.int64(img[r, c])
            s += v
            mx = max(mx, v)
            mn = min(mn, v)
    n = np.int64(h * w)
    m = (2 * s + n) // (2 * n) if use_mean else np.int64(0)
    if mx - m > 32767 or mn - m < -32768:
        m = np.int64(0)
    return m


@callee_kernel
def _store_tile(re, vr, vc, D, mk, out, r0, c0):
    """One tile's output: ``out[r0 + u, c0 + v]`` = one RND/SAT of ``(Y 2**(D+15) + m sum k) /
    2**15`` for the valid ``vr x vc`` corner of the inverse transform ``re`` (int64 [T, T]);
    ``mk = m sum(k)``.

    Cases
    -----
    saturate : results beyond 16 bits -> 32767 / -32768.
    tie-even : a result exactly halfway rounds to even.
    fine-exponent : ``D + 15 < 0`` -> ``mk`` is shifted left to the sum's scale instead.
    """
    up = D + 15
    cext = 0 if up >= 0 else -up
    sh_up = up + cext
    q = 15 + cext
    half = np.int64(1) << (q - 1)
    lowmask = (np.int64(1) << q) - 1
    for u in range(vr):
        for v in range(vc):
            num = (re[u, v] << sh_up) + (mk << cext)
            o = (num + half) >> q
            if (num & lowmask) == half:
                o &= ~np.int64(1)
            o = min(max(o, -32768), 32767)
            out[r0 + u, c0 + v] = np.int16(o)


@njit(**KERNEL)
def fft_correlate_k(img, spec, kr, ki, brev, twc, tws):
    """The whole frequency path on an int16 window (module docstring). Returns (out int16 [h, w],
    bounds float64 [nti, ntj], rms float64 [nti, ntj] (the predicted RMS), info
    :data:`TILE_INFO` [nti, ntj], m (the DC level removed)).

    ``img``: int16 [h, w] (Q16.0); ``spec``: :data:`FFT_SPEC` [1], the kernel's constants and the
    DC removal's switch; ``kr``, ``ki``: int64 [T, T] the spectrum words (:class:`FFTKernel`);
    ``brev``: int64 [T] bit reversal; ``twc``, ``tws``: int64 [T/2] Q1.15 twiddle words.

    Cases
    -----
    typical : every pixel within its tile's bound of ``scipy.ndimage.correlate(mode="nearest")``.
    tiles : several overlap-save tiles, the last row/column of tiles partly valid, tile rows past
        the padded window zero.
    dc-removal : ``m = round_half_up(mean)`` removed before and ``m sum(k)`` added after; a constant
        window comes out exact.
    no-dc : ``use_mean`` false -> ``m = 0`` (still within its larger bound).
    dc-does-not-fit : ``x - m`` outside 16 bits -> ``m = 0``.
    saturate : outputs beyond 16 bits -> 32767 / -32768.
    tie-even : an output exactly halfway rounds to even.
    fine-exponent : ``D + 15 < 0`` (a kernel of tiny taps) -> ``m sum(k)`` is shifted left to the
        sum's scale instead; still within the bound.
    """
    sp = spec[0]
    T, kk, ek, ksum = sp.tile, sp.size, sp.ek, sp.ksum
    kmax, k2mean, dk = sp.kmax, sp.k2mean, sp.dk
    use_mean = sp.use_mean != 0
    tables = (brev, twc, tws)
    h, w = img.shape
    p = kk // 2
    V = T - kk + 1
    nti = (h + V - 1) // V
    ntj = (w + V - 1) // V
    M_r = h + 2 * p
    M_c = w + 2 * p
    m = _dc_mean(img, use_mean)
    logT = 0
    while (1 << logT) < T:
        logT += 1
    log = np.zeros((logT, 3), np.int64)
    out = np.empty((h, w), np.int16)
    bounds = np.zeros((nti, ntj))
    rmsp = np.zeros((nti, ntj))
    info = np.zeros((nti, ntj), TILE_INFO)
    re = np.zeros((T, T), np.int64)
    im = np.zeros((T, T), np.int64)
    mk = m * ksum
    for ti in range(nti):
        for tj in range(ntj):
            # ---- fill: replicate-padded window rows ti*V.., cols tj*V.., x - m, zeros past it ----
            rows_data = min(T, M_r - ti * V)
            for u in range(T):
                for v in range(T):
                    re[u, v] = 0
                    im[u, v] = 0
            for u in range(rows_data):
                rr = min(max(ti * V + u - p, 0), h - 1)
                for v in range(T):
                    cc = tj * V + v
                    if cc >= M_c:
                        break
                    cc = min(max(cc - p, 0), w - 1)
                    re[u, v] = np.int64(img[rr, cc]) - m
            # ---- forward FFT: rows with data, then all columns ----
            bl = _block_bitlen(re, im, rows_data, T)
            E = 0.0
            Vv = 0.0
            bl, E, Vv, sf1 = _row_pass(re, im, rows_data, spec, tables, False, (bl, E, Vv), log)
            re = _transpose(re, T)
            im = _transpose(im, T)
            bl, E, Vv, sf2 = _row_pass(re, im, T, spec, tables, False, (bl, E, Vv), log)
            # ---- product with the kernel spectrum (column-pass layout: kr, ki transposed) ----
            shm = max(0, bl - 14)
            orv = np.int64(0)
            xsq = 0.0
            for u in range(T):
                for v in range(T):
                    xr = re[u, v] >> shm
                    xi = im[u, v] >> shm
                    xsq += float(xr * xr + xi * xi)
                    a = kr[u, v]
                    b = ki[u, v]
                    pr = _rnd15(xr * a - xi * b)
                    pi = _rnd15(xr * b + xi * a)
                    re[u, v] = pr
                    im[u, v] = pi
                    orv |= (pr ^ (pr >> 63)) | (pi ^ (pi >> 63))
            nn = T * T
            E = (E / 2.0 ** shm + (1.0 - 2.0 ** (-shm)) * math.sqrt(2.0 * nn)) * kmax / 32768.0 \
                + math.sqrt(xsq) * dk / 32768.0 + 0.5 * math.sqrt(2.0 * nn)
            Vv = (Vv / 4.0 ** shm + 2.0 * nn * _floor_m2(shm)) * k2mean / 2.0 ** 30 \
                + xsq * dk * dk / 2.0 ** 30 + 2.0 * nn / 12.0
            bl = bitlen(orv)
            # ---- inverse FFT: all columns, then the valid rows ----
            vr = min(V, h - ti * V)
            vc = min(V, w - tj * V)
            bl, E, Vv, si1 = _row_pass(re, im, T, spec, tables, True, (bl, E, Vv), log)
            re = _transpose(re, T)
            im = _transpose(im, T)
            bl, E, Vv, si2 = _row_pass(re, im, vr, spec, tables, True, (bl, E, Vv), log)
            D = sf1 + sf2 + shm + ek + si1 + si2 - 2 * logT
            _store_tile(re, vr, vc, D, mk, out, ti * V, tj * V)
            bounds[ti, tj] = E * 2.0 ** D + 0.5
            rmsp[ti, tj] = math.sqrt(Vv * 4.0 ** D / (2.0 * T * T) + 1.0 / 12.0)
            ti_info = info[ti, tj]
            ti_info.forward_shifts = sf1 + sf2
            ti_info.product_shift = shm
            ti_info.inverse_shifts = si1 + si2
            ti_info.D = D
    return out, bounds, rmsp, info, m


def fft_correlate(img, taps, tile=None, ledger=None, stage=None, return_info=False,
                  remove_mean=True):
    """Frequency-domain correlation of a 16-bit window with an odd k x k Q1.15 kernel (replicate
    edges): the paper's slow path for kernels larger than 7x7 (any odd size 3..63 on request).

    Parameters
    ----------
    img : ndarray (h, w) int16 words (Q16.0)
    taps : ndarray (k, k) Q1.15 words, k odd, or an :class:`FFTKernel`
    tile : FFT size T (16, 32 or 64); default: the cheaper of 16 and 32 (:func:`choose_tile`)
    ledger : Ledger, optional -- charged :func:`fft_filter_cycles` under ``("dsp", stage or
        "filter_fft{k}x{k}")``
    return_info : also return a dict with the per-tile error ``bounds`` (every output pixel of tile
        ``(i, j)`` is within ``bounds[i, j]`` of the exact correlation), the per-tile ``rms_bounds``
        (L2 form), the block exponents, ``D``, the tile size, the mean removed and the cycles
    remove_mean : the DC removal of step 1 (on by default; off only to show its effect)

    Returns
    -------
    ndarray (h, w) int16 (Q16.0), and the info dict with ``return_info``
    """
    from flightsw.ip.filters import as_words
    img = as_words(img)
    if isinstance(taps, FFTKernel):
        kern = taps
    else:
        t = np.asarray(taps)
        if t.ndim != 2 or t.shape[0] != t.shape[1] or t.shape[0] % 2 == 0 \
                or not 3 <= t.shape[0] <= MAX_FFT_KERNEL:
            raise ValueError(f"kernel shape {t.shape} must be square with an odd size "
                             f"3..{MAX_FFT_KERNEL}")
        if not np.issubdtype(t.dtype, np.integer) or t.min() < -32768 or t.max() > 32767:
            raise ValueError("kernel: coefficients must be integer Q1.15 words -32768..32767")
        k = t.shape[0]
        h, w = img.shape
        if tile is None:
            tile = choose_tile(h, w, k) or choose_tile(h, w, k, FFT_TILES)
            if tile is None:
                raise ValueError(f"no FFT tile fits a {k}x{k} kernel")
        kern = fft_kernel(t, int(tile))
    T = kern.tile
    k = kern.size
    c, s, dw = twiddles_q15(T)
    out, bounds, rmsp, info, m = fft_correlate_k(img, fft_spec(kern, dw, remove_mean), kern.kr,
                                                  kern.ki, bitrev(T), c, s)
    h, w = img.shape
    cyc = fft_filter_cycles(h, w, k, T)
    if ledger is not None:
        ledger.charge("dsp", stage or f"filter_fft{k}x{k}", cyc)
    if not return_info:
        return out
    V, nti, ntj = _tile_grid(h, w, k, T)
    npx = np.array([[min(V, h - i * V) * min(V, w - j * V) for j in range(ntj)]
                    for i in range(nti)], np.float64)
    rms = (bounds - 0.5) / np.sqrt(npx) + 0.5
    return out, {"bounds": bounds, "bound": float(bounds.max()), "rms_bounds": rms,
                 "rms_predicted": rmsp,
                 "tile": T, "valid": V, "forward_shifts": info["forward_shifts"],
                 "product_shift": info["product_shift"], "inverse_shifts": info["inverse_shifts"],
                 "D": info["D"], "mean": int(m),
                 "ek": kern.ek, "cycles": cyc}


