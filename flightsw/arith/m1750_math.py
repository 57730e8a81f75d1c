"""Flight math library written only in MIL-STD-1750A floating-point operations.

Every routine takes and returns packed 1750A floats (see :mod:`flightsw.arith.m1750_float`) and
returns ``(result, flags)``. Values are computed only with the emulated instructions (``fa32``,
``fm32``, ``fd32``, ``fix32``, ``flt32`` ... and their 48-bit forms) plus integer/logical word
operations a 1750A program does with its integer instructions (reading or replacing the 8-bit
exponent field, zeroing ``w2``, sign tests, table indexing). No host floating point is used.

``flags`` reports the *result*: :data:`FLAG_FLOAT_OVERFLOW` / :data:`FLAG_FLOAT_UNDERFLOW` when the
result overflows / underflows (with the standard's overflow result / zero), :data:`FLAG_DOMAIN` for
arguments outside the domain. Underflows of intermediate terms (e.g. ``z**k`` of a tiny argument
flushing to zero) are absorbed, as a flight library that masks those interrupts would.

Algorithms (W = 23 for 32-bit, 39 for 48-bit; polynomial coefficients are near-minimax fits rounded
to the format, stored as packed words):

* ``sqrt``: ``x = g * 4**k`` with ``g`` in [0.25, 1) by editing the exponent; linear seed, then
  Heron steps ``y = (y + g / y) * 0.5`` (2 for 32-bit, 3 for 48-bit); exponent + k.
* ``exp``: ``n = round(x / ln2)`` (FM, FA +-0.5, FIX), ``r = x - n*ln2`` in 48-bit with a 2-part
  ``ln2`` whose first part makes ``n * C1`` and the subtraction exact (the FA has no guard bits);
  ``exp(r) = 1 + r + r**2 P(r)``; exponent + n (overflow/underflow per the standard).
* ``ln``: ``x = f * 2**E``, ``f`` in [sqrt(1/2), sqrt(2)); ``f - 1`` exact (``(f - 0.5) - 0.5`` when
  ``f < 1``); ``s = (f-1)/(f+1)``; ``ln f = s (2 + s**2 P(s**2))``; ``+ E*ln2_hi + E*ln2_lo``.
* ``sin``/``cos``: ``n = round(x * 2/pi)``, ``r = x - n*pi/2`` in 48-bit with a 3-part ``pi/2``
  (23, 23, 40 bits; ``n * C1`` exact), quadrant ``n mod 4``; ``sin r = r + r z P(z)``,
  ``cos r = 1 + z (-1/2 + z Q(z))``, ``z = r*r``. Domain: exponent <= 15, the range FIX needs
  (``|x| < 2**15``, and ``-2**15 = -1.0 * 2**15`` itself); beyond: ``(0, FLAG_DOMAIN)``.
* ``atan2``: ``t = min/max`` of ``|y|, |x|``; ``k = round(8t)``, ``u = (t - k/8)/(1 + t k/8)``,
  ``atan t = atan(k/8) + u + u z P(z)``; octant/quadrant fix-ups with ``pi/2 - a``, ``pi - a``, FNEG.
  ``atan2(0, 0) = 0``.

Accuracy: measured against numpy float64 on dense samples of the decoded inputs (the tests assert
these bounds; ``ulp`` = one unit in the last place of the exact result in the same format,
``2**(floor(log2|v|) - W)``):

=================  ==============================  =========================================
routine            domain sampled                  max error (measured -> stated bound)
=================  ==============================  =========================================
sqrt32 / sqrt48    (0, 2**127)                     1.0 / 1.0 ulp        -> 1.5 ulp
exp32              [-88.7, 88]                     2.5 ulp              -> 3 ulp
ln32               (0, 2**127), dense near 1       3.5 ulp              -> 4 ulp
sin32 / cos32      |x| < 2**15 (and -2**15)        2.86 * 2**-23 abs    -> 3.5 * 2**-23 (4.2e-7)
sin48 / cos48      |x| < 2**15 (and -2**15)        3.43 * 2**-39 abs    -> 4 * 2**-39 (7.3e-12)
atan2_32           all quadrants, |r| 2**-20..2**20  6.4 ulp            -> 8 ulp
atan2_48           all quadrants, |r| 2**-20..2**20  4.7 ulp            -> 6 ulp
=================  ==============================  =========================================

The atan2 figures are dominated by ``t`` just above 1/16 where ``atan(1/8) + atan(u)`` cancels to
just below 1/16 (result ulp half the operands' ulp, and FA has no guard bits); elsewhere it is
within 3 ulp. sin/cos errors are absolute (relative error is meaningless at the zeros).

(The stated bounds are in :data:`MAX_ERROR`.)

Cycle costs: :data:`MATH_OP_MIX` gives each routine's worst-path operation mix in
:mod:`flightsw.budget` keys; ``op_cycles(name)`` and :data:`MATH_CYCLES` turn it into PACE1750A
clocks (module constants ``CYC_SQRT32`` ... are plain ints usable inside ``@njit`` code).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import overload

from flightsw.arith.m1750_float import (
    FLAG_DOMAIN, FLAG_FLOAT_OVERFLOW, FLAG_FLOAT_UNDERFLOW, MAX32, MAX48, MIN32, MIN48, ONE32, ONE48,
    HALF32, HALF48, OP_MIX, check32, check48, overload_impl1, overload_impl2, fa32, fa48, fabs32,
    fabs48, fc32, fc48, fd32, fd48, fix32, fix48, flt32, flt48, fm32, fm48, fneg32, fneg48, fs32,
    fs48, m1750_cycles,
    to32, to48, unpack32, unpack48,
)
from flightsw.arith.m1750_lanes import (
    fa32_lanes, fabs32_lanes, fc32_v, fd32_lanes, fd32_pos_lanes, fix32_lanes, fm32_lanes,
    fneg32_lanes, fs32_lanes, scale32_v,
)
from flightsw.budget import PACE1750A, Processor
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["sqrt32", "sqrt48", "exp32", "ln32", "sin32", "cos32", "sin48", "cos48",
           "atan2_32", "atan2_48", "sqrt32_lanes", "atan2_32_lanes", "MATH_OP_MIX", "MATH_CYCLES",
           "MAX_ERROR", "math_cycles"]

# ------------------------------------------------------------------------------------------------
# constants (packed words; generated from exact rationals / float64 fits, rounded to nearest)
# ------------------------------------------------------------------------------------------------
MHALF32, MHALF48 = 0x800000ff, 0x800000ff0000
TWO32, TWO48 = 0x40000002, 0x400000020000
EIGHT32, EIGHT48 = 0x40000004, 0x400000040000
LOG2E32 = 0x5c551e01
TWO_OVER_PI32, TWO_OVER_PI48 = 0x517cc200, 0x517cc100b727
PIO2_32, PI32 = 0x6487ed01, 0x6487ed02
PIO2_48, PI48 = 0x6487ed015111, 0x6487ed025111
# pi/2 = C1 + C2 + C3: C1, C2 with 23 significant bits (n*C exact for |n| < 2**15), C3 40 bits
PIO2_C1_48, PIO2_C2_48, PIO2_C3_48 = 0x6487ed010000, 0x5110b4e90000, 0x611a62d16331
# ln2 = C1 + C2 (C1 28 bits: n*C1 exact for |n| < 2**9)
LN2_C1_48, LN2_C2_48 = 0x58b90b00f800, 0x7d1cf7e39abd
# ln2 = HI + LO for ln32 (HI 16 bits: E*HI exact)
LN2_HI32, LN2_LO32 = 0x58b90000, 0x5fdf47ed
SQRTHALF_M32 = 0x5a827a          # smallest 24-bit mantissa >= sqrt(1/2) * 2**23

K8_32 = (0x00000000, 0x400000fe, 0x400000ff, 0x600000ff, 0x40000000, 0x50000000, 0x60000000,
         0x70000000, 0x40000001)                                  # k/8, k = 0..8
K8_48 = (0x000000000000, 0x400000fe0000, 0x400000ff0000, 0x600000ff0000, 0x400000000000,
         0x500000000000, 0x600000000000, 0x700000000000, 0x400000010000)
ATANK_32 = (0x00000000, 0x7f56eafd, 0x7d6dd8fe, 0x5bd865ff, 0x76b19cff, 0x47802f00, 0x525e3f00,
            0x5c029f00, 0x6487ed00)                               # atan(k/8)
ATANK_48 = (0x000000000000, 0x7f56eafd6ab1, 0x7d6dd7fee4b2, 0x5bd865ff0793, 0x76b19cff1587,
            0x47802e00af7c, 0x525e3e008c9a, 0x5c029f0015e1, 0x6487ed005111)

SQRT_INIT32 = (0x591f21ff, 0x569af000)                 # c0 + c1 g on [0.25, 1]
SQRT32_STEPS = 2                                       # Heron steps (3 for 48-bit)
SQRT_INIT48 = (0x591f21ff6d07, 0x569af0002129)
# P(z) coefficients, lowest degree first
SIN32 = (0xaaaaabfe, 0x444442fa, 0x97fc67f4, 0x5b23f5ee)
SIN48 = (0xaaaaaafeaaab, 0x444444fa4444, 0x97f97ff49816, 0x5c778eee5359, 0x946747e7ee6c,
         0x581311e0b600, 0xaa7071d80000)
COS32 = (0x555555fc, 0xa4fa52f7, 0x6803eef1, 0xb706e5eb)
COS48 = (0x555555fc5555, 0xa4fa4ff7a4fb, 0x680680f16bbf, 0xb606baeb9426, 0x47c423e4e958,
         0x90a525dcc800, 0x514d69d8a000)
ATAN32 = (0xaaaabcff, 0x65fd14fe)
ATAN48 = (0xaaaaaaffaaab, 0x666666fe676c, 0xb6db6bfe5517, 0x71cb2bfdd93b, 0xa2211efdbd8f)
LN32 = (0x55555500, 0x6666a1ff, 0x490d8aff, 0x78d791fe)
EXP32 = (0x40000000, 0x555555fe, 0x555555fc, 0x444424fa, 0x5b069ef7, 0x6868eaf4, 0x674c95f1)


# ------------------------------------------------------------------------------------------------
# word-level helpers (1750A integer/logical instructions on the exponent field)
# ------------------------------------------------------------------------------------------------
@callee_kernel
def _set_exp32(p, e):
    """Replace the exponent byte of packed 32-bit float ``p`` (int) with ``e`` (int, -128..127); the
    mantissa bits are kept (a 1750A integer/logical edit, no float operation, no checks).

    Cases
    -----
    replace : returns ``p`` with its low byte replaced by ``e & 0xFF`` (negative ``e`` written as
        its 8-bit two's complement), the 24 mantissa bits unchanged.
    """
    return (p & 0xFFFFFF00) | (e & 0xFF)


@callee_kernel
def _set_exp48(p, e):
    """Replace the exponent byte (bits 16..23) of packed 48-bit float ``p`` (int) with ``e`` (int,
    -128..127); the 40 mantissa bits (``w0``, the high byte of ``w1``, ``w2``) are kept. No checks.

    Cases
    -----
    replace : returns ``p`` with bits 16..23 replaced by ``e & 0xFF``, ``w0``, the mantissa byte of
        ``w1`` and ``w2`` unchanged.
    """
    return (p & 0xFFFFFF00FFFF) | ((e & 0xFF) << 16)


@callee_kernel
def _scale32(p, k):
    """p * 2**k by exponent edit, with the standard's overflow/underflow results.

    Cases
    -----
    zero : floating zero returns ``(0, 0)`` whatever ``k``.
    in-range : new exponent in -128..127 (both ends included): the exponent edited, the mantissa
        kept (exactly ``p * 2**k``), flags 0.
    overflow-positive : new exponent above 127, positive mantissa: ``(MAX32, FLAG_FLOAT_OVERFLOW)``.
    overflow-negative : new exponent above 127, negative mantissa: ``(MIN32, FLAG_FLOAT_OVERFLOW)``.
    underflow : new exponent below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    m, e = unpack32(p)
    if m == 0:
        return 0, 0
    e += k
    if e > 127:
        return (MIN32 if m < 0 else MAX32), FLAG_FLOAT_OVERFLOW
    if e < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    return _set_exp32(p, e), 0


@callee_kernel
def _scale48(p, k):
    """``p * 2**k`` for a packed 48-bit float ``p`` by exponent edit, with the standard's
    overflow/underflow results -> ``(word, flags)`` (the 48-bit form of :func:`_scale32`).

    Cases
    -----
    zero : floating zero returns ``(0, 0)`` whatever ``k``.
    in-range : new exponent in -128..127 (both ends included): exactly ``p * 2**k``, all 40 mantissa
        bits kept, flags 0.
    overflow-positive : new exponent above 127, positive mantissa: ``(MAX48, FLAG_FLOAT_OVERFLOW)``.
    overflow-negative : new exponent above 127, negative mantissa: ``(MIN48, FLAG_FLOAT_OVERFLOW)``.
    underflow : new exponent below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    m, e = unpack48(p)
    if m == 0:
        return 0, 0
    e += k
    if e > 127:
        return (MIN48 if m < 0 else MAX48), FLAG_FLOAT_OVERFLOW
    if e < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    return _set_exp48(p, e), 0


@callee_kernel
def _s16(w):
    """The low 16 bits of ``w`` (int) read as a two's complement integer, -32768..32767.

    Cases
    -----
    non-negative : bit 15 clear: the pattern's value (0..32767).
    negative : bit 15 set: the pattern minus 65536 (0xFFFF -> -1, 0x8000 -> -32768).
    """
    return ((w & 0xFFFF) ^ 0x8000) - 0x8000


@callee_kernel
def _s32(w):
    """The low 32 bits of ``w`` (int) read as a two's complement integer.

    Cases
    -----
    non-negative : bit 31 clear: the pattern's value.
    negative : bit 31 set: the pattern minus 2**32 (0xFFFFFFFF -> -1).
    """
    return ((w & 0xFFFFFFFF) ^ 0x80000000) - 0x80000000


# ================================================================================================
# sqrt
# ================================================================================================
@callee_kernel
def _sqrt32_k(x):
    """sqrt of a packed 32-bit float ``x`` -> ``(word, flags)``: ``x = g * 4**k`` with ``g`` in
    [0.25, 1) by exponent edit, linear seed, 2 Heron steps in FD/FA/FM, exponent + ``k``.

    Cases
    -----
    zero : ``x = 0`` returns ``(0, 0)``.
    negative : ``x < 0`` returns ``(0, FLAG_DOMAIN)``.
    even-exponent : ``x = f * 2**e``, ``e`` even: ``g = f`` in [0.5, 1), result exponent + ``e/2``;
        within 1.5 ulp of sqrt(x) (9 -> 3 exactly).
    odd-exponent : ``e`` odd: ``g = f/2`` in [0.25, 0.5), result exponent + ``(e+1)/2``; within
        1.5 ulp (4 = 0.5 * 2**3 -> 2 exactly).
    range-ends : the smallest (``0.5 * 2**-128``) and largest (``MAX32``) magnitudes: ``k`` stays
        in -64..64, so the result never overflows or underflows; within 1.5 ulp, flags 0.
    """
    m, e = unpack32(x)
    if m == 0:
        return 0, 0
    if m < 0:
        return 0, FLAG_DOMAIN
    if e & 1:                                   # x = (f/2) * 2**(e+1)
        g = _set_exp32(x, -1)
        k = (e + 1) >> 1
    else:
        g = _set_exp32(x, 0)
        k = e >> 1
    y, _ = fm32(g, SQRT_INIT32[1])
    y, _ = fa32(y, SQRT_INIT32[0])
    for _i in range(SQRT32_STEPS):
        q, _ = fd32(g, y)
        y, _ = fa32(y, q)
        y, _ = fm32(y, HALF32)
    return _scale32(y, k)


@callee_kernel
def sqrt32_lanes(xs, out):
    """sqrt32 of every word of ``xs`` int64 [K] into ``out`` int64 [K]; returns the OR of the flags.

    The same instructions as :func:`sqrt32` for each element, each applied to all elements at once
    in its branch-free lane form (:mod:`flightsw.arith.m1750_lanes`: SIMD on the host; the Heron
    division, whose operands are positive, in FD's positive-operand form ``fd32_pos``, the same
    words); the zero and domain cases are selected at the end.

    Parameters
    ----------
    xs : int64 [K]
        Packed 32-bit floats (normalised or zero).
    out : int64 [K]
        Receives the packed square roots.

    Returns
    -------
    int
        The OR of every lane's flags (``FLAG_DOMAIN`` if any lane is negative).

    Cases
    -----
    empty : ``K = 0``: nothing written, returns 0.
    zero : a zero lane gives 0.
    negative : a negative lane gives 0 and ``FLAG_DOMAIN`` in the returned OR.
    even-exponent : lanes with an even exponent: within 1.5 ulp of sqrt (exact squares exact).
    odd-exponent : lanes with an odd exponent: within 1.5 ulp.
    mixed-block : zero, negative and positive lanes in one call: each lane as alone, flags OR-ed.
    """
    K = xs.size
    buf = np.empty((4, K), np.int64)             # g, k, y, z (q is out; no op writes its input)
    g, k, y, z = buf[0], buf[1], buf[2], buf[3]
    for i in range(K):
        x = xs[i]
        m, e = unpack32(x)
        odd = (e & 1) != 0                       # x = (f/2) * 2**(e+1): g in [0.25, 0.5)
        # (x <= 0 lanes, selected away at the end, divide 1/2 instead: fd32_pos needs g > 0)
        g[i] = _set_exp32(x, -1 if odd else 0) if m > 0 else HALF32
        k[i] = (e + 1) >> 1 if odd else e >> 1
    fm32_lanes(g, np.int64(SQRT_INIT32[1]), z)
    fa32_lanes(z, np.int64(SQRT_INIT32[0]), y)
    for _j in range(SQRT32_STEPS):
        fd32_pos_lanes(g, y, out)                # g in [1/4, 1), y near 1: both positive
        fa32_lanes(y, out, z)
        fm32_lanes(z, np.int64(HALF32), y)
    flags = 0
    for i in range(K):
        m, _ = unpack32(xs[i])
        r, f = scale32_v(y[i], k[i])
        out[i] = 0 if m <= 0 else r
        flags |= (FLAG_DOMAIN if m < 0 else 0) if m <= 0 else f
    return flags


@callee_kernel
def _sqrt48_k(x):
    """sqrt of a packed 48-bit float ``x`` -> ``(word, flags)``; as :func:`_sqrt32_k` in EFD/EFA/EFM
    with 3 Heron steps.

    Cases
    -----
    zero : ``x = 0`` returns ``(0, 0)``.
    negative : ``x < 0`` returns ``(0, FLAG_DOMAIN)``.
    even-exponent : ``x = f * 2**e``, ``e`` even: ``g = f``, result exponent + ``e/2``; within 1.5
        ulp (48-bit ulp; 9 -> 3 exactly).
    odd-exponent : ``e`` odd: ``g = f/2``, result exponent + ``(e+1)/2``; within 1.5 ulp.
    range-ends : ``0.5 * 2**-128`` and values near ``2**127``: no overflow or underflow, within 1.5
        ulp, flags 0.
    """
    m, e = unpack48(x)
    if m == 0:
        return 0, 0
    if m < 0:
        return 0, FLAG_DOMAIN
    if e & 1:
        g = _set_exp48(x, -1)
        k = (e + 1) >> 1
    else:
        g = _set_exp48(x, 0)
        k = e >> 1
    y, _ = fm48(g, SQRT_INIT48[1])
    y, _ = fa48(y, SQRT_INIT48[0])
    for _i in range(3):
        q, _ = fd48(g, y)
        y, _ = fa48(y, q)
        y, _ = fm48(y, HALF48)
    return _scale48(y, k)


# ================================================================================================
# exp, ln (32-bit)
# ================================================================================================
@callee_kernel
def _exp32_k(x):
    """``e**x`` of a packed 32-bit float ``x`` -> ``(word, flags)``: ``n = round(x / ln2)``, ``r = x
    - n ln2`` in 48-bit with a 2-part ln2, ``1 + r + r**2 P(r)``, exponent + ``n``.

    Cases
    -----
    zero : ``exp(0)`` returns ``(ONE32, 0)`` exactly.
    saturate-high : ``x >= 256`` (exponent above 8): ``(MAX32, FLAG_FLOAT_OVERFLOW)`` at once.
    saturate-low : ``x <= -256``: ``(0, FLAG_FLOAT_UNDERFLOW)`` at once.
    overflow : ``~88.03 < x < 256``: the final exponent edit overflows: ``(MAX32,
        FLAG_FLOAT_OVERFLOW)``.
    underflow : ``-256 < x < ~-89.41``: the final exponent edit underflows: ``(0,
        FLAG_FLOAT_UNDERFLOW)``.
    positive : ``0 < x <= 88``: ``n`` from ``x log2(e) + 0.5`` truncated by FIX (halves away from
        zero); within 3 ulp, flags 0.
    negative : ``-88.7 <= x < 0``: ``n`` from ``x log2(e) - 0.5`` truncated toward zero (``n <=
        0``); within 3 ulp, flags 0.
    tiny : ``|x| <= 1e-3``: ``n = 0``, ``r = x``; ``1 + x`` within 3 ulp.
    """
    m, e = unpack32(x)
    if m == 0:
        return ONE32, 0
    if e > 8:                                   # |x| >= 256
        if m > 0:
            return MAX32, FLAG_FLOAT_OVERFLOW
        return 0, FLAG_FLOAT_UNDERFLOW
    t, _ = fm32(x, LOG2E32)
    t, _ = fa32(t, HALF32 if m > 0 else MHALF32)
    nw, _ = fix32(t)
    n = _s16(nw)
    nf, _ = flt32(nw)
    nf48 = to48(nf)
    a, _ = fm48(nf48, LN2_C1_48)
    r48, _ = fs48(to48(x), a)
    b, _ = fm48(nf48, LN2_C2_48)
    r48, _ = fs48(r48, b)
    r = to32(r48)
    q = EXP32[6]
    for i in range(5, -1, -1):
        q, _ = fm32(q, r)
        q, _ = fa32(q, EXP32[i])
    z, _ = fm32(r, r)
    w, _ = fm32(z, q)
    s, _ = fa32(r, w)
    p, _ = fa32(ONE32, s)
    return _scale32(p, n)


@callee_kernel
def _ln32_k(x):
    """Natural log of a packed 32-bit float ``x`` -> ``(word, flags)``: ``x = f * 2**E`` with ``f``
    in [sqrt(1/2), sqrt(2)), ``s = (f-1)/(f+1)``, ``ln f = s (2 + s**2 P(s**2))``, plus ``E ln2``
    (two parts) combined in 48-bit.

    Cases
    -----
    non-positive : ``x = 0`` or ``x < 0``: ``(MIN32, FLAG_DOMAIN)``.
    one : ``ln 1 = 0`` exactly (floating zero), flags 0.
    low-mantissa : mantissa below ``sqrt(1/2)`` (``f`` in [0.5, 0.7071)): ``f`` doubled to [1, sqrt
        2) and ``E - 1``; within 4 ulp.
    high-mantissa : ``f`` in [0.7071, 1): ``f - 1`` formed exactly as ``(f - 0.5) - 0.5``; within 4
        ulp.
    near-one : ``|x - 1| <= 1e-3`` and the ranges [1.41, 2), [0.5, 0.71) where ``E ln2`` and ``ln
        f`` cancel (summed in 48-bit, no guard bits lost): within 4 ulp of the small result.
    range-ends : ``0.5 * 2**-128`` and ``1.7e38``: within 4 ulp, flags 0 (the result never
        overflows).
    """
    m, e = unpack32(x)
    if m <= 0:
        return MIN32, FLAG_DOMAIN
    if m < SQRTHALF_M32:                        # f in [0.5, sqrt(1/2)) -> 2f in [1, sqrt 2)
        f = _set_exp32(x, 1)
        E = e - 1
        d, _ = fs32(f, ONE32)                   # exact: same exponent
    else:
        f = _set_exp32(x, 0)
        E = e
        d, _ = fs32(f, HALF32)                  # exact
        d, _ = fs32(d, HALF32)                  # exact: all on the 2**-23 grid
    den, _ = fa32(f, ONE32)
    s, _ = fd32(d, den)
    z, _ = fm32(s, s)
    q = LN32[3]
    for i in range(2, -1, -1):
        q, _ = fm32(q, z)
        q, _ = fa32(q, LN32[i])
    w, _ = fm32(z, q)
    w, _ = fa32(w, TWO32)
    lnf, _ = fm32(s, w)
    ef, _ = flt32(E & 0xFFFF)
    hi, _ = fm32(ef, LN2_HI32)                  # exact
    lo, _ = fm32(ef, LN2_LO32)
    # E*ln2 + ln f cancels for x in [1.41, 2) and [0.5, 0.71): combine in 48-bit (no guard bits)
    t, _ = fa48(to48(lo), to48(lnf))
    r, _ = fa48(to48(hi), t)
    return to32(r), 0


# ================================================================================================
# sin, cos
# ================================================================================================
@callee_kernel
def _reduce_n(x48):
    """n = round(x * 2/pi) (48-bit FM, FA +-0.5, EFIX) -> (n signed, n as 48-bit float).

    Cases
    -----
    positive : ``x >= 0``: ``n = trunc(x 2/pi + 0.5)``, halves rounded away from zero, ``n >= 0``.
    negative : ``x < 0``: ``n = trunc(x 2/pi - 0.5)`` (EFIX truncates toward zero), ``n <= 0``.
    """
    t, _ = fm48(x48, TWO_OVER_PI48)
    m, _ = unpack48(t)
    t, _ = fa48(t, HALF48 if m >= 0 else MHALF48)
    nw, _ = fix48(t)
    nf, _ = flt48(nw)
    return _s32(nw), nf


@callee_kernel
def _reduce48(x):
    """r = x - n*pi/2 in 48-bit, exact up to the C2/C3 terms. x is a 48-bit float, |x| < 2**15.

    Returns ``(n, r)``: ``n`` signed int (the quadrant count), ``r`` packed 48-bit float.

    Cases
    -----
    first-octant : ``|x| < pi/4`` (``n = 0``): ``r = x`` exactly (head, tail and zero products add
        back without loss).
    reduce : ``pi/4 <= |x| < 2**15``: ``r = x - n pi/2`` with ``n C1``, ``n C2`` and the head
        subtraction exact; ``|r| <= ~pi/4`` and within ``2**-37`` of the exact ``x - n pi/2``.
    negative : ``x < 0``: ``n <= 0``, ``r`` within the same ``2**-37``.
    """
    n, nf = _reduce_n(x)
    xhi = x & 0xFFFFFFFF0000                    # 24-bit head (zero w2): floor, same exponent
    xlo, _ = fs48(x, xhi)                       # exact tail
    a, _ = fm48(nf, PIO2_C1_48)                 # exact
    r, _ = fs48(xhi, a)                         # exact (no bits shifted out)
    b, _ = fm48(nf, PIO2_C2_48)                 # exact
    r, _ = fs48(r, b)
    r, _ = fa48(r, xlo)
    c, _ = fm48(nf, PIO2_C3_48)
    r, _ = fs48(r, c)
    return n, r


@callee_kernel
def _sin_poly32(r):
    """``sin r`` of a packed 32-bit float ``r``, ``|r| <= ~pi/4``: ``r + r z P(z)``, ``z = r*r``
    (FM/FA).

    Cases
    -----
    typical : ``|r| <= ~pi/4``: within 3.5 * 2**-23 absolute of sin r.
    tiny : ``r*r`` underflows (``|r| < ~2**-65``): the term flushes to zero (flag absorbed) and
        ``r`` is returned unchanged.
    """
    z, _ = fm32(r, r)
    q = SIN32[3]
    for i in range(2, -1, -1):
        q, _ = fm32(q, z)
        q, _ = fa32(q, SIN32[i])
    w, _ = fm32(z, q)
    w, _ = fm32(r, w)
    s, _ = fa32(r, w)
    return s


@callee_kernel
def _cos_poly32(r):
    """``cos r`` of a packed 32-bit float ``r``, ``|r| <= ~pi/4``: ``1 + z (-1/2 + z Q(z))``, ``z =
    r*r``.

    Cases
    -----
    typical : ``|r| <= ~pi/4``: within 3.5 * 2**-23 absolute of cos r.
    tiny : ``r*r`` underflows (``|r| < ~2**-65``): returns ``ONE32`` exactly.
    """
    z, _ = fm32(r, r)
    q = COS32[3]
    for i in range(2, -1, -1):
        q, _ = fm32(q, z)
        q, _ = fa32(q, COS32[i])
    w, _ = fm32(z, q)
    w, _ = fa32(w, MHALF32)
    w, _ = fm32(z, w)
    c, _ = fa32(ONE32, w)
    return c


@callee_kernel
def _sin_poly48(r):
    """``sin r`` of a packed 48-bit float ``r``, ``|r| <= ~pi/4`` (degree-6 ``P``, EFM/EFA).

    Cases
    -----
    typical : ``|r| <= ~pi/4``: within 4 * 2**-39 absolute of sin r.
    tiny : ``r*r`` underflows (``|r| < ~2**-65``): returns ``r`` unchanged.
    """
    z, _ = fm48(r, r)
    q = SIN48[6]
    for i in range(5, -1, -1):
        q, _ = fm48(q, z)
        q, _ = fa48(q, SIN48[i])
    w, _ = fm48(z, q)
    w, _ = fm48(r, w)
    s, _ = fa48(r, w)
    return s


@callee_kernel
def _cos_poly48(r):
    """``cos r`` of a packed 48-bit float ``r``, ``|r| <= ~pi/4`` (degree-6 ``Q``, EFM/EFA).

    Cases
    -----
    typical : ``|r| <= ~pi/4``: within 4 * 2**-39 absolute of cos r.
    tiny : ``r*r`` underflows (``|r| < ~2**-65``): returns ``ONE48`` exactly.
    """
    z, _ = fm48(r, r)
    q = COS48[6]
    for i in range(5, -1, -1):
        q, _ = fm48(q, z)
        q, _ = fa48(q, COS48[i])
    w, _ = fm48(z, q)
    w, _ = fa48(w, MHALF48)
    w, _ = fm48(z, w)
    c, _ = fa48(ONE48, w)
    return c


@callee_kernel
def _trig32(x, quad_shift):
    """``sin x`` (``quad_shift = 0``) or ``cos x`` (``quad_shift = 1``, ``cos x = sin(x + pi/2)``)
    of a packed 32-bit float ``x`` -> ``(word, flags)``: 48-bit reduction, quadrant
    ``q = (n + quad_shift) & 3``, 32-bit polynomial.

    Cases
    -----
    zero : ``x = 0``: sin ``(0, 0)``, cos ``(ONE32, 0)``.
    domain : exponent above 15 (``|x| >= 2**15`` except ``-2**15``): ``(0, FLAG_DOMAIN)``.
    domain-edge : exponent 15 (``2**14 <= |x| < 2**15``, e.g. 32767, and ``-2**15 = -1.0 * 2**15``)
        is reduced and evaluated normally.
    quadrant-0 : ``q = 0``: the sin polynomial of ``r``.
    quadrant-1 : ``q = 1``: the cos polynomial of ``r``.
    quadrant-2 : ``q = 2``: the sin polynomial, negated (FNEG).
    quadrant-3 : ``q = 3``: the cos polynomial, negated (FNEG).
    negative : ``x < 0``: ``n < 0`` and ``q`` is ``n`` mod 4 (two's complement ``& 3``).
    """
    m, e = unpack32(x)
    if m == 0:
        return (0 if quad_shift == 0 else ONE32), 0
    if e > 15:
        return 0, FLAG_DOMAIN
    n, r48 = _reduce48(to48(x))
    r = to32(r48)
    q = (n + quad_shift) & 3
    v = _sin_poly32(r) if (q & 1) == 0 else _cos_poly32(r)
    if q >= 2:
        v, _ = fneg32(v)
    return v, 0


@callee_kernel
def _trig48(x, quad_shift):
    """``sin x`` / ``cos x`` (``quad_shift`` 0 / 1) of a packed 48-bit float ``x`` -> ``(word,
    flags)``, as :func:`_trig32` with the 48-bit polynomials.

    Cases
    -----
    zero : ``x = 0``: sin ``(0, 0)``, cos ``(ONE48, 0)``.
    domain : exponent above 15 (``|x| >= 2**15`` except ``-2**15``): ``(0, FLAG_DOMAIN)``.
    domain-edge : exponent 15 (``2**14 <= |x| < 2**15`` and ``-2**15``) is reduced and evaluated
        normally.
    quadrant-0 : ``q = 0``: sin polynomial.
    quadrant-1 : ``q = 1``: cos polynomial.
    quadrant-2 : ``q = 2``: sin polynomial negated.
    quadrant-3 : ``q = 3``: cos polynomial negated.
    negative : ``x < 0``: ``q`` is ``n`` mod 4.
    """
    m, e = unpack48(x)
    if m == 0:
        return (0 if quad_shift == 0 else ONE48), 0
    if e > 15:
        return 0, FLAG_DOMAIN
    n, r = _reduce48(x)
    q = (n + quad_shift) & 3
    v = _sin_poly48(r) if (q & 1) == 0 else _cos_poly48(r)
    if q >= 2:
        v, _ = fneg48(v)
    return v, 0


@callee_kernel
def _sin32_k(x):
    """``sin x`` of a packed 32-bit float -> ``(word, flags)`` (:func:`_trig32`, shift 0).

    Cases
    -----
    zero : ``sin 0 = (0, 0)``.
    domain : exponent above 15 (``|x| >= 2**15`` except ``-2**15``): ``(0, FLAG_DOMAIN)``.
    typical : ``0 < |x| < 2**15``: within 3.5 * 2**-23 absolute, flags 0.
    """
    return _trig32(x, 0)


@callee_kernel
def _cos32_k(x):
    """``cos x`` of a packed 32-bit float -> ``(word, flags)`` (:func:`_trig32`, shift 1).

    Cases
    -----
    zero : ``cos 0 = (ONE32, 0)``.
    domain : exponent above 15 (``|x| >= 2**15`` except ``-2**15``): ``(0, FLAG_DOMAIN)``.
    typical : ``0 < |x| < 2**15``: within 3.5 * 2**-23 absolute, flags 0.
    """
    return _trig32(x, 1)


@callee_kernel
def _sin48_k(x):
    """``sin x`` of a packed 48-bit float -> ``(word, flags)`` (:func:`_trig48`, shift 0).

    Cases
    -----
    zero : ``sin 0 = (0, 0)``.
    domain : exponent above 15 (``|x| >= 2**15`` except ``-2**15``): ``(0, FLAG_DOMAIN)``.
    typical : ``0 < |x| < 2**15``: within 4 * 2**-39 absolute, flags 0.
    """
    return _trig48(x, 0)


@callee_kernel
def _cos48_k(x):
    """``cos x`` of a packed 48-bit float -> ``(word, flags)`` (:func:`_trig48`, shift 1).

    Cases
    -----
    zero : ``cos 0 = (ONE48, 0)``.
    domain : exponent above 15 (``|x| >= 2**15`` except ``-2**15``): ``(0, FLAG_DOMAIN)``.
    typical : ``0 < |x| < 2**15``: within 4 * 2**-39 absolute, flags 0.
    """
    return _trig48(x, 1)


# ================================================================================================
# atan2
# ================================================================================================
@njit(**KERNEL)
def _atan2_32_k(y, x):
    """``atan2(y, x)`` of packed 32-bit floats -> ``(word, 0)`` in [-pi, pi]: ``t = min/max`` of
    ``|y|, |x|``, ``k = round(8t)``, ``atan t = atan(k/8) + atan(u)``, octant/quadrant fix-ups.
    Flags are always 0.

    Cases
    -----
    origin : ``atan2(0, 0) = (0, 0)``.
    positive-x-axis : ``y = 0``, ``x > 0``: 0.
    negative-x-axis : ``y = 0``, ``x < 0``: ``PI32`` (pi rounded to nearest; there is no -0, so
        never -pi).
    y-axis : ``x = 0``, ``y != 0``: ``PIO2_32`` or its FNEG.
    first-octant : ``|y| < |x|``: ``t = |y|/|x|``, no fix-up; within 8 ulp.
    swap : ``|y| > |x|``: ``t = |x|/|y|`` and ``a = pi/2 - a``; within 8 ulp.
    diagonal : ``|y| = |x|`` (FC equal, no swap): ``k = 8``, ``u = 0``, ``a`` is the table's atan(1)
        word, pi/4 rounded to nearest (0x6487ED00), before the fix-ups.
    negative-x : ``x < 0``: ``a = pi - a``; within 8 ulp.
    negative-y : ``y < 0``: ``a`` negated (FNEG); within 8 ulp.
    ratio-underflow : ``min/max`` below the smallest float (FD underflow, flag absorbed): ``t = 0``,
        so the result is exactly 0, pi/2 (``PIO2_32``), pi or their negations.
    """
    my, _ = unpack32(y)
    mx, _ = unpack32(x)
    if my == 0 and mx == 0:
        return 0, 0
    ay, _ = fabs32(y)
    ax, _ = fabs32(x)
    swap = fc32(ay, ax) > 0
    if swap:
        t, _ = fd32(ax, ay)
    else:
        t, _ = fd32(ay, ax)
    k8, _ = fm32(t, EIGHT32)
    k8, _ = fa32(k8, HALF32)
    kw, _ = fix32(k8)
    k = kw & 0xF
    c = K8_32[k]
    num, _ = fs32(t, c)
    den, _ = fm32(t, c)
    den, _ = fa32(den, ONE32)
    u, _ = fd32(num, den)
    z, _ = fm32(u, u)
    q, _ = fm32(ATAN32[1], z)
    q, _ = fa32(q, ATAN32[0])
    w, _ = fm32(z, q)
    w, _ = fm32(u, w)
    a, _ = fa32(u, w)
    a, _ = fa32(ATANK_32[k], a)
    if swap:
        a, _ = fs32(PIO2_32, a)
    if mx < 0:
        a, _ = fs32(PI32, a)
    if my < 0:
        a, _ = fneg32(a)
    return a, 0


_K8_32 = np.array(K8_32 + (0,) * 7, np.int64)           # k = 0..15 (fix & 0xF): no bounds check
_ATANK_32 = np.array(ATANK_32 + (0,) * 7, np.int64)


@callee_kernel
def atan2_32_lanes(ys, xs, out):
    """atan2_32 of every pair (ys[i], xs[i]) into ``out`` int64 [K]; returns the OR of the flags
    (always 0: atan2 raises none). The same instructions as :func:`atan2_32` per element, each
    applied to all elements at once in its lane form (see :func:`sqrt32_lanes`); the octant
    choices are computed for every element and selected, ``atan2(0, 0) = 0`` at the end.

    Parameters
    ----------
    ys, xs : int64 [K]
        Packed 32-bit floats (normalised or zero).
    out : int64 [K]
        Receives the packed angles in [-pi, pi].

    Returns
    -------
    int
        Always 0.

    Cases
    -----
    empty : ``K = 0``: nothing written, returns 0.
    origin : a ``(0, 0)`` lane gives 0 (its division is done as 0/1 so the block keeps the positive
        division form).
    axes : ``y = 0`` lanes give 0 or ``PI32``; ``x = 0`` lanes ``PIO2_32`` or its FNEG.
    octants : lanes in every octant (swap, ``x < 0``, ``y < 0`` selected per lane): within 8 ulp of
        atan2; diagonal lanes exactly the atan(1) word (or its fix-ups).
    ratio-underflow : ``min/max`` below the smallest float: ``t = 0``, exactly 0 or pi/2.
    """
    K = ys.size
    buf = np.empty((10, K), np.int64)
    ay, ax, t, c, ak, num, den, u, z, swap = (buf[0], buf[1], buf[2], buf[3], buf[4], buf[5],
                                              buf[6], buf[7], buf[8], buf[9])
    fabs32_lanes(ys, ay)
    fabs32_lanes(xs, ax)
    for i in range(K):
        sw = fc32_v(ay[i], ax[i]) > 0
        num[i] = ax[i] if sw else ay[i]
        # atan2(0, 0) lanes divide 0 by 1 instead of by 0 (their result is selected away at the
        # end), so that a block holding one takes fd32_lanes' positive form like the others
        both0 = ((ay[i] & 0xFFFFFF00) == 0) & ((ax[i] & 0xFFFFFF00) == 0)
        den[i] = ONE32 if both0 else (ay[i] if sw else ax[i])
        swap[i] = sw
    fd32_lanes(num, den, t)
    fm32_lanes(t, np.int64(EIGHT32), u)
    fa32_lanes(u, np.int64(HALF32), c)
    fix32_lanes(c, z)
    for i in range(K):
        kk = z[i] & 0xF
        c[i] = _K8_32[kk]
        ak[i] = _ATANK_32[kk]
    fs32_lanes(t, c, num)
    fm32_lanes(t, c, ay)
    fa32_lanes(ay, np.int64(ONE32), den)
    fd32_lanes(num, den, u)
    fm32_lanes(u, u, z)
    fm32_lanes(np.int64(ATAN32[1]), z, c)
    fa32_lanes(c, np.int64(ATAN32[0]), ax)
    fm32_lanes(z, ax, num)
    fm32_lanes(u, num, t)
    fa32_lanes(u, t, ay)
    fa32_lanes(ak, ay, den)                      # a = atan(k/8) + u + u z P(z)
    fs32_lanes(np.int64(PIO2_32), den, num)
    for i in range(K):
        den[i] = num[i] if swap[i] != 0 else den[i]
    fs32_lanes(np.int64(PI32), den, num)
    for i in range(K):
        den[i] = num[i] if (xs[i] & 0x80000000) != 0 else den[i]   # sign of the mantissa of x
    fneg32_lanes(den, num)
    for i in range(K):
        a = num[i] if (ys[i] & 0x80000000) != 0 else den[i]
        out[i] = 0 if ((ys[i] & 0xFFFFFF00) == 0) & ((xs[i] & 0xFFFFFF00) == 0) else a
    return 0


@callee_kernel
def _atan2_48_k(y, x):
    """``atan2(y, x)`` of packed 48-bit floats -> ``(word, 0)`` in [-pi, pi], as :func:`_atan2_32_k`
    with a degree-4 ``P``. Flags are always 0.

    Cases
    -----
    origin : ``atan2(0, 0) = (0, 0)``.
    positive-x-axis : ``y = 0``, ``x > 0``: 0.
    negative-x-axis : ``y = 0``, ``x < 0``: ``PI48`` (pi rounded to nearest; never -pi).
    y-axis : ``x = 0``, ``y != 0``: ``PIO2_48`` or its negation.
    first-octant : ``|y| < |x|``: no fix-up; within 6 ulp.
    swap : ``|y| > |x|``: ``a = pi/2 - a``; within 6 ulp.
    diagonal : ``|y| = |x|``: ``a`` is the table's atan(1) word (pi/4 rounded to nearest) before
        the fix-ups.
    negative-x : ``x < 0``: ``a = pi - a``; within 6 ulp.
    negative-y : ``y < 0``: ``a`` negated; within 6 ulp.
    ratio-underflow : ``min/max`` underflows: ``t = 0``, result exactly 0, pi/2, pi or a negation.
    """
    my, _ = unpack48(y)
    mx, _ = unpack48(x)
    if my == 0 and mx == 0:
        return 0, 0
    ay, _ = fabs48(y)
    ax, _ = fabs48(x)
    swap = fc48(ay, ax) > 0
    if swap:
        t, _ = fd48(ax, ay)
    else:
        t, _ = fd48(ay, ax)
    k8, _ = fm48(t, EIGHT48)
    k8, _ = fa48(k8, HALF48)
    kw, _ = fix48(k8)
    k = kw & 0xF
    c = K8_48[k]
    num, _ = fs48(t, c)
    den, _ = fm48(t, c)
    den, _ = fa48(den, ONE48)
    u, _ = fd48(num, den)
    z, _ = fm48(u, u)
    q = ATAN48[4]
    for i in range(3, -1, -1):
        q, _ = fm48(q, z)
        q, _ = fa48(q, ATAN48[i])
    w, _ = fm48(z, q)
    w, _ = fm48(u, w)
    a, _ = fa48(u, w)
    a, _ = fa48(ATANK_48[k], a)
    if swap:
        a, _ = fs48(PIO2_48, a)
    if mx < 0:
        a, _ = fs48(PI48, a)
    if my < 0:
        a, _ = fneg48(a)
    return a, 0


# ================================================================================================
# public wrappers + overloads
# ================================================================================================
def _pub1(name, kern, check, doc):
    def fn(x):
        r, f = kern(check(f"{name}: x", x))
        return int(r), int(f)
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = doc
    overload(fn, jit_options=KERNEL)(overload_impl1(kern))
    return fn


def _pub2(name, kern, check, doc):
    def fn(y, x):
        r, f = kern(check(f"{name}: y", y), check(f"{name}: x", x))
        return int(r), int(f)
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = doc
    overload(fn, jit_options=KERNEL)(overload_impl2(kern))
    return fn


sqrt32 = _pub1("sqrt32", _sqrt32_k, check32,
               "``sqrt32(x) -> (sqrt(x), flags)``, packed 32-bit floats. x < 0 -> (0, FLAG_DOMAIN). "
               "Max error 1.5 ulp (see MAX_ERROR).")
sqrt48 = _pub1("sqrt48", _sqrt48_k, check48,
               "``sqrt48(x) -> (sqrt(x), flags)``, packed 48-bit floats. x < 0 -> (0, FLAG_DOMAIN). "
               "Max error 1.5 ulp.")
exp32 = _pub1("exp32", _exp32_k, check32,
              "``exp32(x) -> (e**x, flags)``; overflow (x > ~88.03, e**x >= 2**127) -> (7FFFFF7F, "
              "FLAG_FLOAT_OVERFLOW), underflow (x < ~-89.41, e**x < 2**-129) -> (0, "
              "FLAG_FLOAT_UNDERFLOW). "
              "Max error 3 ulp.")
ln32 = _pub1("ln32", _ln32_k, check32,
             "``ln32(x) -> (ln x, flags)``; x <= 0 -> (8000007F, FLAG_DOMAIN). Max error 4 ulp.")
sin32 = _pub1("sin32", _sin32_k, check32,
              "``sin32(x) -> (sin x, flags)``, |x| < 2**15 else (0, FLAG_DOMAIN). "
              "Max absolute error 3.5 * 2**-23.")
cos32 = _pub1("cos32", _cos32_k, check32,
              "``cos32(x) -> (cos x, flags)``, |x| < 2**15 else (0, FLAG_DOMAIN). "
              "Max absolute error 3.5 * 2**-23.")
sin48 = _pub1("sin48", _sin48_k, check48,
              "``sin48(x) -> (sin x, flags)``, |x| < 2**15 else (0, FLAG_DOMAIN). "
              "Max absolute error 4 * 2**-39.")
cos48 = _pub1("cos48", _cos48_k, check48,
              "``cos48(x) -> (cos x, flags)``, |x| < 2**15 else (0, FLAG_DOMAIN). "
              "Max absolute error 4 * 2**-39.")
atan2_32 = _pub2("atan2_32", _atan2_32_k, check32,
                 "``atan2_32(y, x) -> (atan2(y, x), flags)`` in [-pi, pi]; atan2(0, 0) = 0. "
                 "Max error 8 ulp.")
atan2_48 = _pub2("atan2_48", _atan2_48_k, check48,
                 "``atan2_48(y, x) -> (atan2(y, x), flags)`` in [-pi, pi]. Max error 6 ulp.")


# ================================================================================================
# cycle costs
# ================================================================================================
def _mix(*parts):
    out = {}
    for p in parts:
        for k, v in p.items():
            out[k] = out.get(k, 0) + v
    return out


#: integer/logical work of one exponent-field edit or sign test + branch ([ASSUMED] mix)
_EXP_EDIT = {"SHIFT": 1, "AR": 2}
_TEST = {"LR": 1, "JC": 1}
_CALL = {"SJS": 1, "URS": 1}

_REDUCE48 = {"EFM": 4, "EFA": 2, "EFS": 4, "EFIX": 1, "EFLT": 1}   # incl. +-0.5 and the xlo split
_SIN48P = {"EFM": 9, "EFA": 7}
_COS48P = {"EFM": 9, "EFA": 8}
_SIN32P = {"FM": 6, "FA": 4}
_COS32P = {"FM": 6, "FA": 5}

#: worst-path operation mix of each math routine (flightsw.budget keys); the float-instruction
#: counts are checked against instrumented runs of the kernels in tests/arith/test_m1750_math.py.
MATH_OP_MIX = {
    "sqrt32": _mix({"FM": 3, "FA": 3, "FD": 2}, _EXP_EDIT, _EXP_EDIT, _TEST, _TEST, _CALL),
    "sqrt48": _mix({"EFM": 4, "EFA": 4, "EFD": 3}, _EXP_EDIT, _EXP_EDIT, _TEST, _TEST, _CALL),
    "exp32": _mix({"FM": 9, "FA": 9, "FIX": 1, "FLT": 1, "EFM": 2, "EFS": 2, "DL": 1},
                  _EXP_EDIT, _TEST, _TEST, _CALL),
    "ln32": _mix({"FM": 8, "FA": 5, "FS": 2, "FD": 1, "FLT": 1, "EFA": 2, "DL": 3}, _EXP_EDIT,
                 _TEST, _TEST, _CALL),
    "sin32": _mix(_REDUCE48, _COS32P, {"FNEG": 1, "DL": 2}, _TEST, _TEST, _TEST, _CALL),
    "cos32": _mix(_REDUCE48, _COS32P, {"FNEG": 1, "DL": 2}, _TEST, _TEST, _TEST, _CALL),
    "sin48": _mix(_REDUCE48, _COS48P, {"EFS": 1}, _TEST, _TEST, _TEST, _CALL),
    "cos48": _mix(_REDUCE48, _COS48P, {"EFS": 1}, _TEST, _TEST, _TEST, _CALL),
    "atan2_32": _mix({"FABS": 2, "FC": 1, "FD": 2, "FM": 6, "FA": 5, "FS": 3, "FIX": 1,
                      "FNEG": 1}, _TEST, _TEST, _TEST, _TEST, _CALL),
    # fabs48 = sign test + EFS (no EFABS), fneg48 = EFS from zero
    "atan2_48": _mix({"L": 2, "JC": 2, "EFS": 2 + 3 + 1, "EFC": 1, "EFD": 2, "EFM": 9,
                      "EFA": 8, "EFIX": 1}, _TEST, _TEST, _TEST, _TEST, _CALL),
}

#: float-instruction part of each mix (what the tests count by instrumenting the kernels)
FLOAT_KEYS = ("FA", "FS", "FM", "FD", "FIX", "FLT", "FABS", "FNEG", "FC",
              "EFA", "EFS", "EFM", "EFD", "EFIX", "EFLT", "EFC")


def math_cycles(name: str, processor: Processor = PACE1750A) -> int:
    """Clocks of one call of math routine ``name`` (worst path) on ``processor``."""
    try:
        mix = MATH_OP_MIX[name]
    except KeyError:
        raise KeyError(f"no operation mix for {name!r}; known: {sorted(MATH_OP_MIX)}") from None
    return m1750_cycles(mix, processor)


MATH_CYCLES = {k: math_cycles(k) for k in MATH_OP_MIX}
OP_MIX.update(MATH_OP_MIX)       # op_mix()/op_cycles() of m1750_float know the math routines too
CYC_SQRT32, CYC_SQRT48 = MATH_CYCLES["sqrt32"], MATH_CYCLES["sqrt48"]
CYC_EXP32, CYC_LN32 = MATH_CYCLES["exp32"], MATH_CYCLES["ln32"]
CYC_SIN32, CYC_COS32 = MATH_CYCLES["sin32"], MATH_CYCLES["cos32"]
CYC_SIN48, CYC_COS48 = MATH_CYCLES["sin48"], MATH_CYCLES["cos48"]
CYC_ATAN2_32, CYC_ATAN2_48 = MATH_CYCLES["atan2_32"], MATH_CYCLES["atan2_48"]

#: stated max errors, ``(kind, bound)``: kind "ulp" (units in the last place of the exact result,
#: same format) or "abs" (absolute); asserted by tests/arith/test_m1750_math.py
MAX_ERROR = {
    "sqrt32": ("ulp", 1.5), "sqrt48": ("ulp", 1.5), "exp32": ("ulp", 3.0), "ln32": ("ulp", 4.0),
    "sin32": ("abs", 3.5 * 2.0 ** -23), "cos32": ("abs", 3.5 * 2.0 ** -23),
    "sin48": ("abs", 4.0 * 2.0 ** -39), "cos48": ("abs", 4.0 * 2.0 ** -39),
    "atan2_32": ("ulp", 8.0), "atan2_48": ("ulp", 6.0),
}
