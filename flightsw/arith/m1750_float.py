"""MIL-STD-1750A 32-bit and 48-bit floating point, bit-exact to the standard's register-transfer
descriptions (RTL), callable from Python (validated) and from ``@njit`` code (not validated).

Formats (MIL-STD-1750A section 4.1.5 / 4.1.6; bit 0 is the MSB of a word)
--------------------------------------------------------------------------
32-bit float, two words ``w0 w1``::

    w0 = | S | mantissa bits 1..15 |          (mantissa MS 16 bits, bit 0 = sign)
    w1 = | mantissa bits 16..23 | exponent |  (8 more mantissa bits, 8-bit 2's complement exponent)

48-bit extended float, three words ``w0 w1 w2``: ``w0 w1`` as above (mantissa bits 0..23 and the
exponent) and ``w2`` = mantissa bits 24..39.

The mantissa ``M`` is a 2's complement fraction (24 or 40 bits, ``W = 23`` or ``39`` fraction bits),
the value is ``M / 2**W * 2**E``, ``E`` in -128..127. Normalised: the sign bit differs from the next
bit (``M`` in 400000..7FFFFF or 800000..BFFFFF for 24 bits); the only zero is all-zero words.

**Packed words** (the public contract): a 32-bit float is the int ``(w0 << 16) | w1`` in
``0..2**32-1``, a 48-bit float is ``(w0 << 32) | (w1 << 16) | w2`` in ``0..2**48-1``. Equivalently
``p32 = (M24 & 0xFFFFFF) << 8 | (E & 0xFF)`` and ``p48 = ((M40 >> 16) & 0xFFFFFF) << 24 |
(E & 0xFF) << 16 | (M40 & 0xFFFF)``. A 32-bit float is the 48-bit float with the same ``w0 w1`` and
``w2 = 0`` (:func:`to48` / :func:`to32`; ``to32`` drops ``w2``, i.e. truncates toward minus infinity).

Operations and the RTL sections they follow
-------------------------------------------
======================  ================  ==========================================
function                1750A             standard section
======================  ================  ==========================================
``fa32 / fa48``         FA / EFA          5.60 / 5.61
``fs32 / fs48``         FS / EFS          5.68 / 5.69
``fm32 / fm48``         FM / EFM          5.74 / 5.75
``fd32 / fd48``         FD / EFD          5.79 / 5.80
``fabs32``              FABS              5.62 (``fabs48``: no EFABS exists, analogue)
``fneg32``              FNEG              5.70 (``fneg48``: no EFNEG exists, = 0 EFS x)
``fix32 / fix48``       FIX / EFIX        5.85 / 5.87
``flt32 / flt48``       FLT / EFLT        5.86 / 5.88
``fc32 / fc48``         FC / EFC          5.94 / 5.95
======================  ================  ==========================================

Every arithmetic op returns ``(result, flags)``: ``flags`` is a bitmask of the pending-interrupt
(PI) register bits the instruction sets, with the standard's bit numbering (bit 0 = MSB of PI, level
L = ``0x8000 >> L``) so it can be OR-ed into an emulated PI register:
:data:`FLAG_FLOAT_OVERFLOW` (level 3), :data:`FLAG_FIXED_OVERFLOW` (level 4),
:data:`FLAG_FLOAT_UNDERFLOW` (level 6). ``fc32/fc48`` return only the comparison (-1, 0, 1): FC
never interrupts.

Decisions (where the RTL is silent, ambiguous or [UNCERTAIN] in docs/processors.md)
-----------------------------------------------------------------------------
* **FA/FS have no guard bits** (docs/processors.md B marks real-chip guard bits [UNCERTAIN]): following
  the RTL of 5.60/5.61/5.68/5.69 literally, the mantissa with the smaller exponent is shifted right
  arithmetic (bits shifted out are lost, i.e. truncated toward minus infinity) *before* the add.
  The result is therefore never above the exact sum and is below it by less than one unit of the
  *larger operand's* last place, ``2**(max(Ea, Eo) - W)``; after a cancellation the normalising
  left shift brings in zeros, so measured in the result's own ulp the error can exceed 1.
  (``DECISION_FA_GUARD_BITS = False``.)
* **FS negates the subtrahend before aligning it** (``DECISION_FS_NEGATE_FIRST = True``). The RTL
  of 5.68/5.69 writes "MO shifted right arithmetic n; MA <- MA - MO": read literally, bits shifted
  out of a positive subtrahend are truncated *before* it is subtracted, which rounds the difference
  toward plus infinity (e.g. ``1.0 - (0.5 + 2**-23)`` would give ``0.5``), contradicting 4.1.8
  ("all floating point results shall be truncated toward negative infinity"). We follow 4.1.8:
  ``a FS b`` is ``a FA (-b)`` with ``-b`` formed exactly (one extra bit) and then aligned, so FS
  obeys the same bound as FA. Results differ from the literal RTL only when ``EA > EO`` and bits
  of ``MO`` are shifted out.
* FM/FD: the exponent overflow/underflow checks on ``n = EA +/- EO`` happen *before* the mantissa
  operation, exactly as in the RTL (so e.g. ``0.5*2**64 * 0.5*2**64`` overflows although
  ``0.5*2**127`` would be representable). Result mantissas are the exact product/quotient truncated
  toward minus infinity (FM keeps the full double-length product before truncation, 5.74/5.75).
* FD: "shift right if ``|MQ| >= 1.0``" is read as "if the quotient does not fit the 2's complement
  mantissa" (``MQ`` outside ``[-1, 1)``), so an exact quotient of -1.0 stays ``-1.0 * 2**n``; the one
  quotient that is exactly -0.5 (``0.5 / -1.0``) is normalised to ``-1.0 * 2**(n-1)`` (the RTL has
  no normalise step; 4.1.5 requires normalised results), and underflows if ``n - 1 < -128``.
* FIX/EFIX on overflow (exponent > 0F / 1F): the standard leaves RA unchanged; the functions return
  0 with :data:`FLAG_FIXED_OVERFLOW` set and the caller keeps its old register value.
* Integer operands of FLT/FIX are 16/32-bit *bit patterns* (``0..0xFFFF``, ``0..0xFFFFFFFF``), as in
  :mod:`flightsw.arith.adsp2100`; ``to_signed16``/``to_signed32`` convert.

Encoding/decoding (ground side, exact; host float allowed)
----------------------------------------------------------
``encode32(x, rounding="floor")`` / ``encode48``: the largest representable value ``<= x`` (or the
nearest, ties to even, with ``rounding="nearest"``). Out of range: **clamped to the standard's
results** -- above the largest magnitude, the overflow result ``7FFFFF/7F`` (positive) or
``800000/7F`` (negative); magnitudes too small for a normalised number (exponent below -128 after
rounding) give floating zero, the underflow result. NaN or infinite ``x`` -> ``ValueError``.
``decode32/decode48`` are exact (every 1750A value is a Python float).

Speed: all op kernels are integer-only ``@njit(**KERNEL)`` functions on int64 packed words.
"""
from __future__ import annotations

import math
from fractions import Fraction
from numbers import Integral, Real

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.cpython.unsafe.numbers import leading_zeros
from numba.extending import intrinsic, overload

from flightsw.budget import PACE1750A, Processor, m1750_cycles
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = [
    "FLAG_FLOAT_OVERFLOW", "FLAG_FIXED_OVERFLOW", "FLAG_FLOAT_UNDERFLOW", "FLAG_DOMAIN",
    "encode32", "encode48", "decode32", "decode48", "encode32_array", "encode48_array",
    "decode32_array", "decode48_array", "is_normalized32", "is_normalized48",
    "fa32", "fs32", "fm32", "fd32", "fa48", "fs48", "fm48", "fd48", "madd48",
    "flt32", "fix32", "flt48", "fix48", "fabs32", "fneg32", "fabs48", "fneg48", "fc32", "fc48",
    "to48", "to32", "unpack32", "unpack48", "pack32", "pack48",
    "to_signed16", "to_signed32", "encode_k", "decode32_k", "decode48_k", "is_normalized32_k",
    "is_normalized48_k",
    "OP_MIX", "op_mix", "op_cycles", "CYCLES",
    "MAX32", "MIN32", "MAX48", "MIN48", "ONE32", "ONE48", "HALF32", "HALF48", "ZERO",
]

DECISION_FA_GUARD_BITS = False
DECISION_FS_NEGATE_FIRST = True

#: PI register bits (MIL-STD-1750A: bit 0 = MSB, interrupt level L -> mask 0x8000 >> L)
FLAG_FLOAT_OVERFLOW = 0x8000 >> 3    # level 3, floating point overflow
FLAG_FIXED_OVERFLOW = 0x8000 >> 4    # level 4, fixed point overflow
FLAG_FLOAT_UNDERFLOW = 0x8000 >> 6   # level 6, floating point underflow
#: software flag (not a PI bit) raised by the math library for arguments outside its domain
FLAG_DOMAIN = 0x10000

MASK32 = (1 << 32) - 1
MASK48 = (1 << 48) - 1

# special packed values
MAX32 = 0x7FFFFF7F            # 0.9999998 * 2**127, also the positive overflow result
MIN32 = 0x8000007F            # -1.0 * 2**127, the negative overflow result
MAX48 = 0x7FFFFF7FFFFF
MIN48 = 0x8000007F0000
ONE32 = 0x40000001
ONE48 = 0x400000010000
HALF32 = 0x40000000
HALF48 = 0x400000000000
ZERO = 0


# ================================================================================================
# unpack / pack / normalise (small kernels LLVM inlines, W = fraction bits: 23 or 39)
# ================================================================================================
@callee_kernel
def unpack32(p):
    """Packed 32-bit float -> (signed 24-bit mantissa, signed exponent).

    Cases
    -----
    positive : sign bit 0: mantissa 0..7FFFFF as is (0x40000001 -> (0x400000, 1)).
    negative-mantissa : sign bit 1: the 24-bit field read as 2's complement (0x80000000 ->
        (-2**23, 0)).
    negative-exponent : exponent byte 80..FF read as -128..-1 (0x40000080 -> (0x400000, -128)).
    zero : floating zero 0 -> (0, 0).
    """
    m = ((p >> 8) & 0xFFFFFF) ^ 0x800000
    e = (p & 0xFF) ^ 0x80
    return m - 0x800000, e - 0x80


@callee_kernel
def unpack48(p):
    """Packed 48-bit float -> (signed 40-bit mantissa, signed exponent).

    Cases
    -----
    positive : sign bit 0: the 40-bit mantissa (w0 w1 high byte, w2) as is.
    negative-mantissa : sign bit 1: the 40-bit field read as 2's complement (0x800000000000 ->
        (-2**39, 0)).
    negative-exponent : exponent byte 80..FF read as -128..-1.
    zero : floating zero 0 -> (0, 0).
    """
    m = ((((p >> 24) & 0xFFFFFF) << 16) | (p & 0xFFFF)) ^ 0x8000000000
    e = ((p >> 16) & 0xFF) ^ 0x80
    return m - 0x8000000000, e - 0x80


@callee_kernel
def pack32(m, e):
    """(signed 24-bit mantissa, exponent) -> packed 32-bit float (no checks).

    Cases
    -----
    positive : mantissa and exponent fields written as is ((0x400000, 1) -> 0x40000001).
    negative : a negative mantissa or exponent is written as its 24-/8-bit 2's complement
        ((-2**23, -128) -> 0x80000080).
    """
    return ((m & 0xFFFFFF) << 8) | (e & 0xFF)


@callee_kernel
def pack48(m, e):
    """(signed 40-bit mantissa, exponent) -> packed 48-bit float (no checks).

    Cases
    -----
    positive : mantissa bits 39..16 into w0 w1, the exponent byte, bits 15..0 into w2.
    negative : a negative mantissa or exponent is written as its 40-/8-bit 2's complement
        ((-2**39, -128) -> 0x800000800000).
    """
    return (((m >> 16) & 0xFFFFFF) << 24) | ((e & 0xFF) << 16) | (m & 0xFFFF)


@callee_kernel
def unpack_w(p, W):
    """:func:`unpack32` (W = 23) or :func:`unpack48` (W = 39) of packed word ``p``.

    Cases
    -----
    w23 : W = 23: the 32-bit layout (:func:`unpack32`).
    w39 : any other W (39): the 48-bit layout (:func:`unpack48`).
    """
    if W == 23:
        return unpack32(p)
    return unpack48(p)


@callee_kernel
def pack_w(m, e, W):
    """:func:`pack32` (W = 23) or :func:`pack48` (W = 39) of ``(m, e)`` (no checks).

    Cases
    -----
    w23 : W = 23: the 32-bit layout (:func:`pack32`).
    w39 : any other W (39): the 48-bit layout (:func:`pack48`).
    """
    if W == 23:
        return pack32(m, e)
    return pack48(m, e)


@callee_kernel
def norm_shift(m, W):
    """Left shift that normalises a non-zero signed mantissa of W fraction bits (redundant sign
    bits). Negative powers of two normalise to -1.0 (e.g. -0.5 -> -1.0 with one shift). ``m`` must
    be non-zero (every caller tests ``m == 0`` first). W is not limited to 23/39: FM normalises its
    double-length product with W = 46.

    Cases
    -----
    normalised : already normalised (0.5 <= m < 1 or -1 <= m < -0.5) -> 0.
    positive : 0 < m < 0.5 -> the shift that brings the leading 1 to bit W-1 (0.25 -> 1).
    negative : -0.5 < m < 0 -> the shift that brings the leading 0 to bit W-1 (-0.375 -> 1).
    minus-power-of-two : -2**-k -> k, i.e. normalised to -1.0 (-0.5 -> 1, -0.25 -> 2).
    """
    return leading_zeros(m ^ (m >> 63)) - (64 - W)


@callee_kernel
def overflow_word(neg, W):
    """Standard overflow result word: 7FFF..FF/7F if the result is positive, 8000..00/7F if
    negative.

    Cases
    -----
    positive-32 : W = 23, not neg -> MAX32 0x7FFFFF7F.
    negative-32 : W = 23, neg -> MIN32 0x8000007F.
    positive-48 : W = 39, not neg -> MAX48 0x7FFFFF7FFFFF.
    negative-48 : W = 39, neg -> MIN48 0x8000007F0000.
    """
    if W == 23:
        return MIN32 if neg else MAX32
    return MIN48 if neg else MAX48


@callee_kernel
def _overflow(neg, W):
    """Standard overflow result and its PI flag.

    Cases
    -----
    positive : not neg -> (7FFF..FF/7F, FLAG_FLOAT_OVERFLOW).
    negative : neg -> (8000..00/7F, FLAG_FLOAT_OVERFLOW).
    """
    return overflow_word(neg, W), FLAG_FLOAT_OVERFLOW


@callee_kernel
def _finish(m, e, W):
    """Normalise (m, e) (m fits W+1 bits), apply underflow/overflow, pack -> (p, flags).

    Cases
    -----
    zero : m == 0 -> (0, 0), floating zero whatever e.
    normalised : m already normalised, e in range -> packed (m, e), flags 0.
    normalise-shift : m not normalised -> shifted left (exponent decremented) until it is;
        -0.5 becomes -1.0 * 2**(e-1).
    underflow : the exponent after the shift is below -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    overflow : e above 127 -> the overflow word of m's sign + FLAG_FLOAT_OVERFLOW (no caller
        passes such an e: the add core and FLT stop at 127; kept for the standard's rule).
    """
    if m == 0:
        return 0, 0
    s = norm_shift(m, W)
    m = m << s
    e = e - s
    if e < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    if e > 127:
        return _overflow(m < 0, W)
    return pack_w(m, e, W), 0


# ================================================================================================
# FA / FS (5.60, 5.61, 5.68, 5.69)
# ================================================================================================
@callee_kernel
def _add_core(a, b, W, subtract):
    """FA/FS on packed words of W fraction bits -> (p, flags) (see the module docstring: no guard
    bits, FS negates the subtrahend exactly before aligning it).

    Cases
    -----
    a-zero : MA = 0 -> EA <- EO, no shift: the result is b (or -b for FS), normalised.
    b-zero : MO = 0 (and MA != 0) -> no shift: the result is a.
    align-b : EA > EO -> MO shifted right arithmetic EA - EO bits, the bits shifted out are lost
        (a negative b then lowers the sum by up to one unit of a's last place).
    align-a : EA < EO -> MA shifted right arithmetic, EA <- EO.
    far-operand : exponent difference over 63 -> shift capped at 63: the smaller operand becomes 0
        (positive) or -1 unit (negative) of the larger operand's last place.
    mantissa-overflow : the sum leaves [-1, 1) -> shifted right 1, exponent + 1 (0.75 + 0.75 =
        0.75 * 2).
    overflow : mantissa overflow at exponent 127 -> overflow word of the sum's sign +
        FLAG_FLOAT_OVERFLOW.
    cancel-zero : the mantissas cancel exactly -> (0, 0).
    cancel-normalise : partial cancellation -> normalised by a left shift (zeros shifted in).
    underflow : normalising takes the exponent below -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    subtract-negate-first : FS: MO negated exactly before it is aligned, so a - b is truncated
        toward minus infinity (1.0 - (0.5 + 2**-23) = 0.5 - 2**-22, not the literal RTL's 0.5).
    subtract-minus-one : FS of -1.0 * 2**e: the negation +1.0 needs the extra bit of the wide
        register and is renormalised (0 - (-1.0) = 0.5 * 2**1).
    """
    ma, ea = unpack_w(a, W)
    mo, eo = unpack_w(b, W)
    if subtract:                     # negate first (exact, wide register): see DECISION_FS_*
        mo = -mo
    n = ea - eo
    if ma == 0:                      # EA <- E0, if MA = 0 (no shifts)
        ea = eo
    elif mo != 0:
        # n > 0: MO >>= n; n < 0: MA >>= -n, EA <- E0 (arithmetic shifts; bits shifted out are
        # lost). Written branch-free (min/max -> conditional moves): n is data dependent.
        so = min(max(n, 0), 63)
        sa = min(max(-n, 0), 63)
        mo = mo >> so
        ma = ma >> sa
        ea = max(ea, eo)
    s = ma + mo
    top = 1 << W
    if s >= top or s < -top:         # OVM: shift right 1, restore sign, EA <- EA + 1
        s = s >> 1
        ea += 1
        if ea > 127:
            return _overflow(s < 0, W)
    return _finish(s, ea, W)


@njit(**KERNEL)
def _fa32_k(a, b):
    """FA (5.60): packed 32-bit ``a + b`` -> (p, flags).

    Cases
    -----
    typical : :func:`_add_core` with W = 23 (its cases), no subtraction.
    """
    return _add_core(a, b, 23, False)


@njit(**KERNEL)
def _fs32_k(a, b):
    """FS (5.68): packed 32-bit ``a - b`` -> (p, flags).

    Cases
    -----
    typical : :func:`_add_core` with W = 23 (its cases), subtrahend negated first.
    """
    return _add_core(a, b, 23, True)


@njit(**KERNEL)
def _fa48_k(a, b):
    """EFA (5.61): packed 48-bit ``a + b`` -> (p, flags).

    Cases
    -----
    typical : :func:`_add_core` with W = 39 (its cases), no subtraction.
    """
    return _add_core(a, b, 39, False)


@njit(**KERNEL)
def _fs48_k(a, b):
    """EFS (5.69): packed 48-bit ``a - b`` -> (p, flags).

    Cases
    -----
    typical : :func:`_add_core` with W = 39 (its cases), subtrahend negated first.
    """
    return _add_core(a, b, 39, True)


# ================================================================================================
# FM (5.74, 5.75)
# ================================================================================================
@callee_kernel
def _mul_exp_checks(ma, mo, n, W):
    """Pre-multiply RTL checks on n = EA + EO. Returns (done, p, flags).

    Cases
    -----
    overflow : n > 127 -> (True, overflow word of the product's sign, FLAG_FLOAT_OVERFLOW).
    underflow : n < -128 -> (True, 0, FLAG_FLOAT_UNDERFLOW).
    in-range : -128 <= n <= 127 -> (False, 0, 0): the multiply goes on.
    """
    if n > 127:
        p, f = _overflow((ma < 0) != (mo < 0), W)
        return True, p, f
    if n < -128:
        return True, 0, FLAG_FLOAT_UNDERFLOW
    return False, 0, 0


@njit(**KERNEL)
def _fm32_k(a, b):
    """FM (5.74): packed 32-bit ``a * b`` -> (p, flags); exact double-length product, normalised,
    truncated toward minus infinity.

    Cases
    -----
    zero-operand : either mantissa 0 -> (0, 0), before any exponent check.
    exp-overflow : EA + EO > 127 -> overflow word of the product's sign + FLAG_FLOAT_OVERFLOW
        (even when the normalised product would fit: 0.5*2**64 * 0.5*2**64).
    exp-underflow : EA + EO < -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    minus-one-squared : (-1.0)(-1.0) -> 0.5 * 2**(n+1).
    minus-one-squared-overflow : (-1.0)(-1.0) with n = 127 -> (MAX32, FLAG_FLOAT_OVERFLOW).
    no-shift : |product| >= 0.5 -> mantissa taken as is (truncated).
    one-shift : |product| < 0.5 -> one left shift, exponent - 1.
    negative-floor : an inexact negative product is truncated toward minus infinity.
    minus-half : a product of exactly -0.5 is normalised to -1.0 * 2**(n-1).
    norm-underflow : the normalising shift takes the exponent below -128 ->
        (0, FLAG_FLOAT_UNDERFLOW).
    """
    ma, ea = unpack32(a)
    mo, eo = unpack32(b)
    if ma == 0 or mo == 0:
        return 0, 0
    n = ea + eo
    done, p, f = _mul_exp_checks(ma, mo, n, 23)
    if done:
        return p, f
    P = ma * mo                       # exact, value P / 2**46
    if P == (1 << 46):                # (-1.0)(-1.0): MP = 8000..00 -> 4000 00, n + 1
        n += 1
        if n > 127:
            return MAX32, FLAG_FLOAT_OVERFLOW
        return pack32(0x400000, n), 0
    s = norm_shift(P, 46)            # normalise the double-length product, then truncate
    n -= s
    if n < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    return pack32((P << s) >> 23, n), 0


@callee_kernel
def prod80(A, B):
    """A * B for 0 <= A, B <= 2**39 as (H, L) with A * B = H * 2**40 + L, 0 <= L < 2**40: the
    80-bit product from 20-bit limbs (no intermediate exceeds 63 bits). Branch-free, so the lane
    form of EFM uses it too.

    Cases
    -----
    zero : A or B = 0 -> (0, 0).
    typical : any operands in range -> the exact split of the 80-bit product.
    max : A = B = 2**39 -> (2**38, 0), the largest product.
    carry : the low limbs' sum reaches 2**40 and carries into H.
    """
    M20 = (np.int64(1) << 20) - 1
    a1 = A >> 20
    a0 = A & M20
    b1 = B >> 20
    b0 = B & M20
    mid = a1 * b0 + a0 * b1
    low = ((mid & M20) << 20) + a0 * b0
    return a1 * b1 + (mid >> 20) + (low >> 40), low & ((np.int64(1) << 40) - 1)


@intrinsic
def _prod_shr38(typingctx, a, b):
    """``floor(a * b / 2**38)`` of two int64 (the exact 128-bit product, shifted right arithmetic,
    truncated to 64 bits): one 64x64 -> 128-bit multiply. For EFM's mantissas (|a|, |b| <= 2**39,
    not both -2**39) the result lies in (-2**40, 2**40)."""
    def codegen(context, builder, signature, args):
        i128 = ir.IntType(128)
        p = builder.mul(builder.sext(args[0], i128), builder.sext(args[1], i128))
        return builder.trunc(builder.ashr(p, ir.Constant(i128, 38)), ir.IntType(64))
    return types.int64(types.int64, types.int64), codegen


@callee_kernel
def _mul48_core(a, b):
    """EFM's body, compiled into :func:`_fm48_k` and :func:`madd48` (its cases are
    :func:`_fm48_k`'s).

    The signed product ``P = MA * MO`` (value ``P / 2**78``) is taken floor-divided by 2**38 in
    one 128-bit multiply (:func:`_prod_shr38`): flooring the signed value is EFM's truncation
    toward minus infinity. ``m = floor(P / 2**38)`` outside [-2**39, 2**39) means ``|product| >=
    0.5`` (``> 0.5`` when negative), already normalised: ``floor(P / 2**39) = m >> 1``; otherwise
    one normalising shift is already in ``m`` (exactly -0.5 gives ``m = -2**39``, i.e. -1.0 at
    exponent n - 1). The same words as the magnitude-and-sticky-bit form on 80-bit limbs
    (:func:`prod80`, kept for the lane form) -- tests/arith/test_m1750.py checks them against exact
    integer arithmetic.

    Cases
    -----
    typical : the normalised product truncated toward minus infinity with EFM's flags.
    """
    ma, ea = unpack48(a)
    mo, eo = unpack48(b)
    if ma == 0 or mo == 0:
        return 0, 0
    n = ea + eo
    done, p, f = _mul_exp_checks(ma, mo, n, 39)
    if done:
        return p, f
    if ma == -(1 << 39) and mo == -(1 << 39):  # (-1.0)(-1.0)
        n += 1
        if n > 127:
            return MAX48, FLAG_FLOAT_OVERFLOW
        return pack48(1 << 38, n), 0
    m = _prod_shr38(ma, mo)
    if m >= (1 << 39) or m < -(1 << 39):       # normalised as is: floor(P / 2**39)
        m = m >> 1
    else:                                        # one left shift: floor(P / 2**38)
        n -= 1
    if n < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    return pack48(m, n), 0


@njit(**KERNEL)
def _fm48_k(a, b):
    """EFM (5.75): packed 48-bit ``a * b`` -> (p, flags); the exact 80-bit product (one 128-bit
    multiply, :func:`_mul48_core`) normalised and truncated toward minus infinity.

    Cases
    -----
    zero-operand : either mantissa 0 -> (0, 0), before any exponent check.
    exp-overflow : EA + EO > 127 -> overflow word of the product's sign + FLAG_FLOAT_OVERFLOW.
    exp-underflow : EA + EO < -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    minus-one-squared : (-1.0)(-1.0) -> 0.5 * 2**(n+1).
    minus-one-squared-overflow : (-1.0)(-1.0) with n = 127 -> (MAX48, FLAG_FLOAT_OVERFLOW).
    positive-no-shift : positive product >= 0.5 -> floor(|P| / 2**39).
    positive-shift : positive product < 0.5 -> floor(|P| / 2**38), exponent - 1.
    negative-no-shift : negative product, |P| > 0.5 -> -ceil(|P| / 2**39) (floor of the signed
        value).
    negative-shift : negative product, |P| < 0.5 -> -ceil(|P| / 2**38), exponent - 1.
    minus-half : a product of exactly -0.5 -> -1.0 * 2**(n-1).
    norm-underflow : the normalising shift takes the exponent below -128 ->
        (0, FLAG_FLOAT_UNDERFLOW).
    """
    return _mul48_core(a, b)


@callee_kernel
def madd48(acc, a, b):
    """EFM then EFA, ``acc + a * b`` -> (p, flags): exactly ``fa48(acc, fm48(a, b))`` (two
    truncations, the flags of both OR'ed), compiled into its caller (no call) -- for the
    multiply-accumulate loops of the track processor's covariance and RK4 (compiled code only, no
    argument checks; 13 call sites, the TP's cold compile did not grow).

    Cases
    -----
    typical : ``fa48(acc, fm48(a, b))``, flags OR'ed.
    flags : an EFM overflow or underflow flag is kept even when the EFA raises none.
    """
    p, f = _mul48_core(a, b)
    s, g = _add_core(acc, p, 39, False)
    return s, f | g


# ================================================================================================
# FD (5.79, 5.80)
# ================================================================================================
@callee_kernel
def _quotient_floor(A, B, W):
    """(floor(A * 2**(W+1) / B), remainder != 0) for 0 < A, B <= 2**W, W = 23 or 39.

    W = 23: one int64 division (the dividend is below 2**48). W = 39: the dividend needs 80 bits, so
    instead of a three-step long division the quotient comes from one IEEE float64 division:
    ``q = float(A) / float(B)`` is correctly rounded (both operands exact in float64), so
    ``q * 2**40`` (an exact scaling) is within ``2**41 * 2**-53 = 2**-12`` of the true quotient
    and its truncation is ``N - 1``, ``N`` or ``N + 1``; one exact comparison of the remainder
    ``A * 2**40 - Q * B`` fixes it. The remainder is computed modulo 2**64 (int64 wrap-around)
    and is exact because its true value lies in (-B, 2B). Measured on this host: 10 ns latency
    instead of 17 for the long division. Equal to Python's exact integer division on 400,000
    operand pairs per width, random and adversarial (tests/arith/test_m1750.py).

    The estimate is never one too low: at this scale every integer is a float64 grid point, so the
    correctly rounded ``q * 2**40`` of a true quotient ``X >= N`` is ``>= N``; the ``r >= B``
    fix-up is a guard that no operand pair reaches.

    Cases
    -----
    w23 : W = 23: exact int64 floor division, sticky = remainder != 0.
    w39-estimate-exact : W = 39, the float64 estimate is already the floor: no fix-up.
    w39-estimate-high : W = 39, the estimate is one too high (remainder < 0: the true quotient
        is just below an integer and rounds up to it) -> Q - 1.
    exact-quotient : B divides A * 2**(W+1) -> sticky False.
    """
    if W == 23:
        num = A << 24
        Q = num // B
        return Q, (num - Q * B) != 0
    Q = np.int64(float(A) / float(B) * (1 << 40))
    r = (A << 40) - Q * B
    if r < 0:
        Q -= 1
        r += B
    elif r >= B:
        Q += 1
        r -= B
    return Q, r != 0


@callee_kernel
def _div_core(a, b, W):
    """FD/EFD on packed words of W fraction bits -> (p, flags); the quotient truncated toward minus
    infinity (see the module docstring for the reading of "|MQ| >= 1.0").

    Cases
    -----
    divide-by-zero : MO = 0 -> overflow word of the dividend's sign + FLAG_FLOAT_OVERFLOW
        (0 / 0 -> 7FF..F/7F).
    exp-overflow : EA - EO > 127 -> overflow word of the quotient's sign + FLAG_FLOAT_OVERFLOW.
    exp-underflow : EA - EO < -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    zero-dividend : MA = 0 (divisor non-zero) -> (0, 0) whatever the exponents.
    no-shift : |quotient| < 1 -> packed at exponent EA - EO.
    quotient-shift : quotient outside [-1, 1) -> shifted right 1, exponent + 1 (0.75 / 0.5).
    shift-overflow : that shift at exponent 127 -> overflow word + FLAG_FLOAT_OVERFLOW.
    minus-one : an exact quotient of -1.0 stays -1.0 * 2**n (no shift).
    minus-half : an exact quotient of -0.5 is normalised to -1.0 * 2**(n-1).
    minus-half-underflow : that normalisation at n = -128 -> (0, FLAG_FLOAT_UNDERFLOW).
    negative-floor : an inexact negative quotient is truncated toward minus infinity
        (-1/3 -> the word just below -1/3).
    """
    ma, ea = unpack_w(a, W)
    mo, eo = unpack_w(b, W)
    n = ea - eo
    if ma == 0:
        n = 0
    if mo == 0:                                   # divide by zero -> overflow, sign MA0 vs MO0
        return _overflow(ma < 0, W)
    if n > 127:
        return _overflow((ma < 0) != (mo < 0), W)
    if n < -128:
        return 0, FLAG_FLOAT_UNDERFLOW
    if ma == 0:
        return 0, 0
    neg = (ma < 0) != (mo < 0)
    A = -ma if ma < 0 else ma
    B = -mo if mo < 0 else mo
    # Qmag = floor(|q| * 2**(W+1)), sticky = inexact; |q| = A / B in [0.5, 2]
    Qmag, sticky = _quotient_floor(A, B, W)
    if neg:   # floor(q * 2**W) = -ceil(|q| * 2**W)
        Q = -((Qmag >> 1) + (1 if ((Qmag & 1) != 0 or sticky) else 0))
    else:
        Q = Qmag >> 1
    top = 1 << W
    if Q >= top or Q < -top:                      # quotient does not fit the mantissa
        Q = Q >> 1
        n += 1
        if n > 127:
            return _overflow(Q < 0, W)
    if Q == -(1 << (W - 1)):                      # exactly -0.5: normalise
        Q = -top
        n -= 1
        if n < -128:
            return 0, FLAG_FLOAT_UNDERFLOW
    return pack_w(Q, n, W), 0


@njit(**KERNEL)
def _fd32_k(a, b):
    """FD (5.79): packed 32-bit ``a / b`` -> (p, flags).

    Cases
    -----
    typical : :func:`_div_core` with W = 23 (its cases).
    """
    return _div_core(a, b, 23)


@njit(**KERNEL)
def _fd48_k(a, b):
    """EFD (5.80): packed 48-bit ``a / b`` -> (p, flags).

    Cases
    -----
    typical : :func:`_div_core` with W = 39 (its cases).
    """
    return _div_core(a, b, 39)


# ================================================================================================
# FABS (5.62), FNEG (5.70)
# ================================================================================================
@callee_kernel
def _fabs_core(a, W):
    """FABS on a packed word of W fraction bits -> (p, flags).

    Cases
    -----
    non-negative : MA >= 0 (zero included) -> a unchanged, flags 0.
    negative : MA < 0 -> (-MA, E).
    minus-one : -1.0 * 2**e -> 0.5 * 2**(e+1).
    overflow : -1.0 * 2**127 -> (7FF..F/7F, FLAG_FLOAT_OVERFLOW).
    """
    m, e = unpack_w(a, W)
    if m >= 0:
        return a, 0
    if m == -(1 << W):               # -1.0 * 2**e -> 0.5 * 2**(e+1)
        e += 1
        if e > 127:
            return _overflow(False, W)
        return pack_w(1 << (W - 1), e, W), 0
    return pack_w(-m, e, W), 0


@callee_kernel
def _fneg_core(a, W):
    """FNEG on a packed word of W fraction bits -> (p, flags).

    Cases
    -----
    zero : 0 -> (0, 0).
    typical : any other mantissa -> (-MA, E).
    minus-one : -1.0 * 2**e -> 0.5 * 2**(e+1).
    minus-one-overflow : -1.0 * 2**127 -> (7FF..F/7F, FLAG_FLOAT_OVERFLOW).
    half : 0.5 * 2**e -> -1.0 * 2**(e-1).
    half-underflow : 0.5 * 2**-128 -> (0, FLAG_FLOAT_UNDERFLOW).
    """
    m, e = unpack_w(a, W)
    if m == 0:
        return 0, 0
    if m == -(1 << W):               # -1.0 * 2**e -> 0.5 * 2**(e+1)
        if e == 127:
            return _overflow(False, W)
        return pack_w(1 << (W - 1), e + 1, W), 0
    if m == (1 << (W - 1)):          # 0.5 * 2**e -> -1.0 * 2**(e-1)
        if e == -128:
            return 0, FLAG_FLOAT_UNDERFLOW
        return pack_w(-(1 << W), e - 1, W), 0
    return pack_w(-m, e, W), 0


@njit(**KERNEL)
def _fabs32_k(a):
    """FABS (5.62): packed 32-bit ``|a|`` -> (p, flags).

    Cases
    -----
    typical : :func:`_fabs_core` with W = 23 (its cases).
    """
    return _fabs_core(a, 23)


@njit(**KERNEL)
def _fabs48_k(a):
    """48-bit analogue of FABS: packed 48-bit ``|a|`` -> (p, flags).

    Cases
    -----
    typical : :func:`_fabs_core` with W = 39 (its cases).
    """
    return _fabs_core(a, 39)


@njit(**KERNEL)
def _fneg32_k(a):
    """FNEG (5.70): packed 32-bit ``-a`` -> (p, flags).

    Cases
    -----
    typical : :func:`_fneg_core` with W = 23 (its cases).
    """
    return _fneg_core(a, 23)


@njit(**KERNEL)
def _fneg48_k(a):
    """48-bit negate (``0 EFS a``): packed 48-bit ``-a`` -> (p, flags).

    Cases
    -----
    typical : :func:`_fneg_core` with W = 39 (its cases).
    """
    return _fneg_core(a, 39)


# ================================================================================================
# FIX / EFIX (5.85, 5.87), FLT / EFLT (5.86, 5.88)
# ================================================================================================
@njit(**KERNEL)
def _fix32_k(a):
    """FIX (5.85): packed 32-bit float -> (16-bit integer pattern, flags), truncated toward zero.

    Cases
    -----
    overflow : exponent > 15 -> (0, FLAG_FIXED_OVERFLOW) (the hardware leaves RA unchanged).
    positive : truncated toward zero (32767.99 -> 32767).
    negative : truncated toward zero, not toward minus infinity (-1.5 -> -1 = 0xFFFF).
    minus-32768 : -1.0 * 2**15 -> 0x8000, no flag.
    tiny : exponent below -40 -> shift capped at 63 -> 0 (either sign).
    zero : 0 -> (0, 0).
    """
    m, e = unpack32(a)
    if e > 15:
        return 0, FLAG_FIXED_OVERFLOW
    s = 23 - e
    if s > 63:
        s = 63
    r = (m >> s) if m >= 0 else -((-m) >> s)      # truncate toward zero
    return r & 0xFFFF, 0


@njit(**KERNEL)
def _fix48_k(a):
    """EFIX (5.87): packed 48-bit float -> (32-bit integer pattern, flags), truncated toward zero.

    Cases
    -----
    overflow : exponent > 31 -> (0, FLAG_FIXED_OVERFLOW).
    positive : truncated toward zero (2**31 - 0.5 -> 0x7FFFFFFF).
    negative : truncated toward zero (-123456.9 -> -123456).
    minus-2-31 : -1.0 * 2**31 -> 0x80000000, no flag.
    tiny : exponent below -24 -> shift capped at 63 -> 0 (either sign).
    zero : 0 -> (0, 0).
    """
    m, e = unpack48(a)
    if e > 31:
        return 0, FLAG_FIXED_OVERFLOW
    s = 39 - e
    if s > 63:
        s = 63
    r = (m >> s) if m >= 0 else -((-m) >> s)
    return r & 0xFFFFFFFF, 0


@njit(**KERNEL)
def _flt32_k(i):
    """FLT (5.86): 16-bit integer pattern -> (packed 32-bit float, 0), exact.

    Cases
    -----
    zero : 0 -> (0, 0).
    positive : 1..32767 -> normalised from exponent 15 (1 -> 0x40000001).
    negative : 0x8000..0xFFFF read as -32768..-1 (0x8000 -> -1.0 * 2**15 = 0x8000000F).
    """
    v = ((i & 0xFFFF) ^ 0x8000) - 0x8000
    if v == 0:
        return 0, 0
    return _finish(v << 8, 15, 23)


@njit(**KERNEL)
def _flt48_k(i):
    """EFLT (5.88): 32-bit integer pattern -> (packed 48-bit float, 0), exact.

    Cases
    -----
    zero : 0 -> (0, 0).
    positive : 1..2**31-1 -> normalised from exponent 31.
    negative : 0x80000000.. read as 2's complement (0x80000000 -> -1.0 * 2**31 = 0x8000001F0000).
    """
    v = ((i & 0xFFFFFFFF) ^ 0x80000000) - 0x80000000
    if v == 0:
        return 0, 0
    return _finish(v << 8, 31, 39)


# ================================================================================================
# FC / EFC (5.94, 5.95)
# ================================================================================================
@callee_kernel
def _fc_core(a, b, W):
    """FC/EFC on packed words of W fraction bits -> -1 (a < b), 0 (a = b), 1 (a > b).

    Cases
    -----
    sign-differs : different signs (zero counted as its own sign) -> ordered by sign.
    both-zero : both floating zero -> 0.
    exponent-differs : same sign, different exponents -> larger exponent is larger in magnitude,
        reversed for negatives.
    mantissa-differs : same sign and exponent -> ordered by mantissa.
    equal : same words -> 0.
    """
    ma, ea = unpack_w(a, W)
    mo, eo = unpack_w(b, W)
    sa = -1 if ma < 0 else (1 if ma > 0 else 0)
    so = -1 if mo < 0 else (1 if mo > 0 else 0)
    if sa != so:
        return 1 if sa > so else -1
    if sa == 0:
        return 0
    if ea != eo:   # same sign, normalised: larger exponent -> larger magnitude
        c = 1 if ea > eo else -1
        return c if sa > 0 else -c
    if ma == mo:
        return 0
    return 1 if ma > mo else -1


@njit(**KERNEL)
def _fc32_k(a, b):
    """FC (5.94): compare packed 32-bit floats -> -1, 0, 1.

    Cases
    -----
    typical : :func:`_fc_core` with W = 23 (its cases).
    """
    return _fc_core(a, b, 23)


@njit(**KERNEL)
def _fc48_k(a, b):
    """EFC (5.95): compare packed 48-bit floats -> -1, 0, 1.

    Cases
    -----
    typical : :func:`_fc_core` with W = 39 (its cases).
    """
    return _fc_core(a, b, 39)


@callee_kernel
def to48(p):
    """32-bit float -> the same value as a 48-bit float (``w2 = 0``); exact.

    Cases
    -----
    typical : ``w0 w1`` kept, ``w2 = 0``: the same value (0x40000001 -> 0x400000010000).
    """
    return (p & 0xFFFFFFFF) << 16


@callee_kernel
def to32(p):
    """48-bit float -> 32-bit float by dropping ``w2``: the 40-bit 2's complement mantissa is cut to
    24 bits, i.e. truncated toward minus infinity; the cut of a normalised mantissa is normalised.

    Cases
    -----
    exact : ``w2 = 0`` -> the same value.
    truncate-positive : positive with ``w2 != 0`` -> the next 32-bit value below (toward zero).
    truncate-negative : negative with ``w2 != 0`` -> the next 32-bit value below (away from
        zero).
    """
    return (p >> 16) & 0xFFFFFFFF


# ================================================================================================
# Python-side validation
# ================================================================================================
def _int_in(name, v, hi):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (Integral, np.integer)) or not 0 <= v <= hi:
        raise ValueError(f"{name}={v!r} is not a packed word in 0..{hi:#x}")
    return int(v)


def is_normalized32(p: int) -> bool:
    """True if ``p`` (in 0..2**32-1) is floating zero (all bits 0) or a normalised 32-bit float."""
    m = (p >> 8) & 0xFFFFFF
    if m == 0:
        return p == 0
    return ((m >> 23) ^ (m >> 22)) & 1 == 1


def is_normalized48(p: int) -> bool:
    """True if ``p`` (in 0..2**48-1) is floating zero or a normalised 48-bit float."""
    m = (((p >> 24) & 0xFFFFFF) << 16) | (p & 0xFFFF)
    if m == 0:
        return p == 0
    return ((m >> 39) ^ (m >> 38)) & 1 == 1


def check32(name, v):
    """``v`` as an int if it is a normalised packed 32-bit float or floating zero, else
    ``ValueError`` naming ``name`` and the value."""
    v = _int_in(name, v, MASK32)
    if not is_normalized32(v):
        raise ValueError(f"{name}={v:#010x} is not a normalised 1750A 32-bit float or floating zero")
    return v


def check48(name, v):
    """``v`` as an int if it is a normalised packed 48-bit float or floating zero, else
    ``ValueError`` naming ``name`` and the value."""
    v = _int_in(name, v, MASK48)
    if not is_normalized48(v):
        raise ValueError(f"{name}={v:#014x} is not a normalised 1750A 48-bit float or floating zero")
    return v


def to_signed16(w: int) -> int:
    """16-bit pattern -> signed int."""
    w = int(w) & 0xFFFF
    return w - 0x10000 if w & 0x8000 else w


def to_signed32(w: int) -> int:
    """32-bit pattern -> signed int."""
    w = int(w) & 0xFFFFFFFF
    return w - 0x100000000 if w & 0x80000000 else w


# ================================================================================================
# encode / decode (ground side)
# ================================================================================================
def _encode(x, W, rounding, name):
    if type(x) is float and (rounding == "nearest" or rounding == "floor") and math.isfinite(x):
        return int(_enc_k(x, W, rounding == "nearest"))     # fast path, same arithmetic
    if rounding not in ("floor", "nearest"):
        raise ValueError(f"rounding={rounding!r} must be 'floor' or 'nearest'")
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, (Real, np.floating, np.integer)):
        raise ValueError(f"{name}: x={x!r} is not a real number")
    if isinstance(x, (float, np.floating)):
        xf = float(x)
        if not math.isfinite(xf):
            raise ValueError(f"{name}: x={x!r} is not finite")
        if xf == 0.0:
            return 0
        f, e = math.frexp(xf)            # |f| in [0.5, 1)
        v = math.ldexp(f, W)             # exact (|v| < 2**53)
        if rounding == "floor":
            mi = math.floor(v)
        else:
            mi = round(v)                # ties to even, exact
    else:
        fr = Fraction(x)
        if fr == 0:
            return 0
        e = (abs(fr.numerator).bit_length() - abs(fr.denominator).bit_length())
        while abs(fr) >= Fraction(2) ** e:
            e += 1
        while abs(fr) < Fraction(2) ** (e - 1):
            e -= 1
        v = fr * Fraction(2) ** (W - e)
        mi = math.floor(v) if rounding == "floor" else round(v)
    # normalise the integer mantissa mi (value mi * 2**(e - W))
    top = 1 << W
    if mi >= top:                        # rounded up to 1.0
        mi >>= 1
        e += 1
    if mi == -(top >> 1):                # -0.5 (exact or rounded to) -> -1.0 * 2**(e-1)
        mi = -top
        e -= 1
    if mi == 0:
        return 0
    if e > 127:
        if W == 23:
            return MIN32 if mi < 0 else MAX32
        return MIN48 if mi < 0 else MAX48
    if e < -128:
        return 0
    return int(pack32(mi, e) if W == 23 else pack48(mi, e))


def encode32(x, rounding: str = "floor") -> int:
    """Encode a real number as a packed 32-bit 1750A float ``(w0 << 16) | w1``.

    ``rounding="floor"`` (default, like the arithmetic, 4.1.8): the largest representable value
    ``<= x``. ``"nearest"``: nearest representable value, ties to even (ground tools).
    Out of range: clamped to the standard's overflow result (``0x7FFFFF7F`` / ``0x8000007F``), and
    magnitudes below the smallest normalised number give floating zero (the underflow result; for a
    tiny *negative* x that zero is above x). NaN/inf -> ``ValueError``.
    """
    return _encode(x, 23, rounding, "encode32")


def encode48(x, rounding: str = "floor") -> int:
    """Encode a real number as a packed 48-bit 1750A float ``(w0 << 32) | (w1 << 16) | w2``.
    Same rules as :func:`encode32` (overflow clamp ``0x7FFFFF7FFFFF`` / ``0x8000007F0000``)."""
    return _encode(x, 39, rounding, "encode48")


def decode32(p) -> float:
    """Packed 32-bit 1750A float -> Python float (exact). Non-normalised words -> ``ValueError``."""
    p = check32("decode32: p", p)
    m, e = unpack32.py_func(p)
    return math.ldexp(float(m), e - 23)


def decode48(p) -> float:
    """Packed 48-bit 1750A float -> Python float (exact: 40-bit mantissas fit a double)."""
    p = check48("decode48: p", p)
    m, e = unpack48.py_func(p)
    return math.ldexp(float(m), e - 39)


@callee_kernel
def enc_mantissa(x, W, nearest):
    """Finite non-zero float64 -> normalised ``(mi, e)`` with value ``mi * 2**(e - W)`` (W = 23:
    32-bit, 39: 48-bit), floor or nearest-even rounding, before the exponent range is checked.
    The one normalisation every jitted encoder uses (:func:`_enc_k`, ``flightsw.tp.f1750.enc32``).

    A normal double is read from its bits: the 53-bit significand shifted right ``53 - W`` bits
    with the rounding done on the shifted-out bits (integer work only, about 3 ns instead of the
    frexp/ldexp/floor path's 15-35); subnormals (and W >= 53) take that float path. Inlined into
    its callers, where ``W`` and ``nearest`` are constants and their branches fold away (the
    track processor's 46 centroid conversions a frame: 0.25 us less).

    Cases
    -----
    exact : x representable in W + 1 bits -> its mantissa and exponent.
    floor : not nearest -> truncated toward minus infinity (a negative x gets the next lower
        mantissa).
    nearest : nearest -> the closer mantissa; below half a unit down, above half up.
    nearest-tie-even : exactly half a unit -> the even mantissa.
    round-up-carry : rounding up to 2**W -> halved, exponent + 1.
    minus-half : a mantissa of -0.5 (x = -2**k, or rounded to it) -> -1.0 * 2**(e-1).
    subnormal : a subnormal double (or W >= 53) -> the frexp path, the same rounding rules.
    """
    bits = np.float64(x).view(np.int64)
    be = (bits >> 52) & 0x7FF
    if be != 0 and W < 53:
        sh = 53 - W                          # significand bits shifted out
        m = (bits & 0xFFFFFFFFFFFFF) | 0x10000000000000
        q = m >> sh
        rem = m & ((np.int64(1) << sh) - 1)
        half = np.int64(1) << (sh - 1)
        if bits < 0:                         # value -m: floor rounds the magnitude up
            if nearest:
                q += 1 if (rem > half or (rem == half and (q & 1) == 1)) else 0
            else:
                q += 1 if rem != 0 else 0
            mi = -q
        else:
            if nearest:
                q += 1 if (rem > half or (rem == half and (q & 1) == 1)) else 0
            mi = q
        e = be - 1022
    else:
        f, e = math.frexp(x)
        v = math.ldexp(f, W)
        fl = math.floor(v)
        if nearest:
            d = v - fl                       # exact (|v| < 2**40)
            if d > 0.5 or (d == 0.5 and (int(fl) & 1) == 1):
                fl += 1.0
        mi = int(fl)
    top = 1 << W
    if mi >= top:
        mi >>= 1
        e += 1
    if mi == -(top >> 1):
        mi = -top
        e -= 1
    return mi, e


@njit(**KERNEL)
def _enc_k(x, W, nearest):
    """One finite float64 -> packed 1750A word (W = 23: 32-bit, 39: 48-bit); exactly
    :func:`_encode_array`'s arithmetic for one element (floor or nearest-even rounding).

    Cases
    -----
    zero : x = 0.0 (either sign) -> 0.
    typical-32 : W = 23, in range -> the packed 32-bit word.
    typical-48 : W = 39, in range -> the packed 48-bit word.
    underflow : exponent below -128 -> 0 (floating zero, the underflow result).
    overflow-32 : W = 23, exponent above 127 -> MAX32 (positive) or MIN32 (negative).
    overflow-48 : W = 39, exponent above 127 -> MAX48 or MIN48.
    """
    if x == 0.0:
        return 0
    mi, e = enc_mantissa(x, W, nearest)
    if mi == 0 or e < -128:
        return 0
    if W == 23:
        if e > 127:
            return MIN32 if mi < 0 else MAX32
        return ((mi & 0xFFFFFF) << 8) | (e & 0xFF)
    if e > 127:
        return MIN48 if mi < 0 else MAX48
    return (((mi >> 16) & 0xFFFFFF) << 24) | ((e & 0xFF) << 16) | (mi & 0xFFFF)


@njit(**KERNEL)
def _enc_array_k(x, W, nearest, out):
    """Encode the flat float64 ``x`` into ``out`` (int64); False (nothing written) if any is not finite.

    Cases
    -----
    all-finite : every element encoded with :func:`_enc_k` -> True.
    non-finite : any NaN or infinity -> False, ``out`` untouched.
    empty : zero-length ``x`` -> True, nothing written.
    """
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return False
    for i in range(x.shape[0]):
        out[i] = _enc_k(x[i], W, nearest)
    return True


#: exact powers of two 2**-192 .. 2**191 (index k + 192): scaling by a table entry is one exact
#: multiplication, where math.ldexp is a libm call in jitted code
_POW2 = np.ldexp(1.0, np.arange(-192, 192))


@callee_kernel
def _dec32_k(p):
    """Packed 32-bit float -> float64 (exact: 24-bit mantissa times a power of two, no subnormals
    in the 1750A range), in jitted code.

    Cases
    -----
    zero : 0 -> 0.0.
    typical : m * 2**(e - 23) exactly.
    exponent-extremes : exponents -128 and 127 (the power-of-two table's ends in use) exact.
    """
    m, e = unpack32(p)
    return float(m) * _POW2[e + (192 - 23)]


@callee_kernel
def _dec48_k(p):
    """Packed 48-bit float -> float64 (exact), in jitted code.

    Cases
    -----
    zero : 0 -> 0.0.
    typical : m * 2**(e - 39) exactly (40-bit mantissas fit a double).
    exponent-extremes : exponents -128 and 127 exact.
    """
    m, e = unpack48(p)
    return float(m) * _POW2[e + (192 - 39)]


@callee_kernel
def _norm48_k(p):
    """:func:`is_normalized48` of a 48-bit pattern (in range).

    Cases
    -----
    zero : all bits 0 -> True.
    zero-mantissa : mantissa 0 with a non-zero exponent -> False.
    normalised : mantissa bits 0 and 1 differ (either sign) -> True.
    not-normalised : mantissa bits 0 and 1 equal -> False.
    """
    m = (((p >> 24) & 0xFFFFFF) << 16) | (p & 0xFFFF)
    if m == 0:
        return p == 0
    return ((m >> 39) ^ (m >> 38)) & 1 == 1


@callee_kernel
def _norm32_k(p):
    """:func:`is_normalized32` of a 32-bit pattern (in range).

    Cases
    -----
    zero : all bits 0 -> True.
    zero-mantissa : mantissa 0 with a non-zero exponent -> False.
    normalised : mantissa bits 0 and 1 differ (either sign) -> True.
    not-normalised : mantissa bits 0 and 1 equal -> False.
    """
    m = (p >> 8) & 0xFFFFFF
    if m == 0:
        return p == 0
    return ((m >> 23) ^ (m >> 22)) & 1 == 1


#: the scalar kernels under public names, for ``@njit`` codecs of other modules (no validation):
#: ``encode_k(x, W, nearest)`` finite float64 -> packed word (W = 23: 32-bit, 39: 48-bit),
#: ``decode32_k`` / ``decode48_k`` packed -> float64 (exact), ``is_normalized32_k/48_k`` -> bool
encode_k, decode32_k, decode48_k = _enc_k, _dec32_k, _dec48_k
is_normalized32_k, is_normalized48_k = _norm32_k, _norm48_k


@njit(**KERNEL)
def _dec_array_k(p, W, out):
    """Decode the flat packed words ``p`` (int64) into ``out`` (float64, same length), exactly.

    Cases
    -----
    w23 : W = 23: every word through :func:`_dec32_k`.
    w39 : W = 39: every word through :func:`_dec48_k`.
    empty : zero-length ``p`` -> nothing written.
    """
    for i in range(p.shape[0]):
        out[i] = _dec32_k(p[i]) if W == 23 else _dec48_k(p[i])


def _encode_array(x, W, rounding):
    x = np.asarray(x, dtype=np.float64)
    flat = np.ascontiguousarray(x).reshape(-1)
    out = np.empty(flat.shape[0], np.int64)
    if not _enc_array_k(flat, W, rounding != "floor", out):
        bad = x[~np.isfinite(x)].flat[0]
        raise ValueError(f"encode array: value {bad!r} is not finite")
    return out.reshape(x.shape)


def encode32_array(x, rounding: str = "floor") -> np.ndarray:
    """Vectorised :func:`encode32` (float64 input) -> int64 array of packed words."""
    if rounding not in ("floor", "nearest"):
        raise ValueError(f"rounding={rounding!r} must be 'floor' or 'nearest'")
    return _encode_array(x, 23, rounding)


def encode48_array(x, rounding: str = "floor") -> np.ndarray:
    """Vectorised :func:`encode48` (float64 input) -> int64 array of packed words."""
    if rounding not in ("floor", "nearest"):
        raise ValueError(f"rounding={rounding!r} must be 'floor' or 'nearest'")
    return _encode_array(x, 39, rounding)


def decode32_array(p) -> np.ndarray:
    """Vectorised :func:`decode32` (no normalisation check) -> float64 array."""
    p = np.asarray(p, dtype=np.int64)
    out = np.empty(p.shape, np.float64)
    _dec_array_k(np.ascontiguousarray(p).reshape(-1), 23, out.reshape(-1))
    return out


def decode48_array(p) -> np.ndarray:
    """Vectorised :func:`decode48` (no normalisation check) -> float64 array."""
    p = np.asarray(p, dtype=np.int64)
    out = np.empty(p.shape, np.float64)
    _dec_array_k(np.ascontiguousarray(p).reshape(-1), 39, out.reshape(-1))
    return out


# ================================================================================================
# public functions: validated Python wrappers + numba overloads (unvalidated) for @njit callers
# ================================================================================================
def _binary(name, kern, check, doc):
    def fn(a, b):
        a = check(f"{name}: a", a)
        b = check(f"{name}: b", b)
        r, f = kern(a, b)
        return int(r), int(f)
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = doc
    return fn


def _unary(name, kern, check, doc):
    def fn(a):
        a = check(f"{name}: a", a)
        r, f = kern(a)
        return int(r), int(f)
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = doc
    return fn


def _int16(name, v):
    return _int_in(name, v, 0xFFFF)


def _int32(name, v):
    return _int_in(name, v, MASK32)


_DOC_ADD = ("``{n}(a, b) -> (a {op} b, flags)``: {mn} (MIL-STD-1750A {sec}). Packed {w}-bit floats; "
            "the mantissa with the smaller exponent is shifted right arithmetic with no guard bits "
            "(RTL, see module docstring), mantissa overflow -> shift right and exponent + 1, "
            "normalise; overflow -> 7FF..F/7F or 800..0/7F + FLAG_FLOAT_OVERFLOW, underflow -> 0 + "
            "FLAG_FLOAT_UNDERFLOW.")

fa32 = _binary("fa32", _fa32_k, check32,
               _DOC_ADD.format(n="fa32", op="+", mn="FA", sec="5.60", w=32))
fs32 = _binary("fs32", _fs32_k, check32,
               _DOC_ADD.format(n="fs32", op="-", mn="FS", sec="5.68", w=32))
fa48 = _binary("fa48", _fa48_k, check48,
               _DOC_ADD.format(n="fa48", op="+", mn="EFA", sec="5.61", w=48))
fs48 = _binary("fs48", _fs48_k, check48,
               _DOC_ADD.format(n="fs48", op="-", mn="EFS", sec="5.69", w=48))
_DOC_MUL = ("``{n}(a, b) -> (a * b, flags)``: {mn} (MIL-STD-1750A {sec}). Exponents added and "
            "checked first (> 7F overflow, < 80 underflow), exact double-length mantissa product "
            "shifted left 1, (-1.0)(-1.0) -> 0.5 * 2**(n+m+1), normalised, truncated toward minus "
            "infinity.")
fm32 = _binary("fm32", _fm32_k, check32, _DOC_MUL.format(n="fm32", mn="FM", sec="5.74"))
fm48 = _binary("fm48", _fm48_k, check48, _DOC_MUL.format(n="fm48", mn="EFM", sec="5.75"))
_DOC_DIV = ("``{n}(a, b) -> (a / b, flags)``: {mn} (MIL-STD-1750A {sec}). Exponent difference "
            "checked first; quotient truncated toward minus infinity, shifted right once if it does "
            "not fit the mantissa. Divide by zero -> overflow result + FLAG_FLOAT_OVERFLOW.")
fd32 = _binary("fd32", _fd32_k, check32, _DOC_DIV.format(n="fd32", mn="FD", sec="5.79"))
fd48 = _binary("fd48", _fd48_k, check48, _DOC_DIV.format(n="fd48", mn="EFD", sec="5.80"))
fabs32 = _unary("fabs32", _fabs32_k, check32,
                "``fabs32(a) -> (|a|, flags)``: FABS (5.62). |-1.0*2**n| = 0.5*2**(n+1); "
                "|-1.0*2**127| overflows to 7FFFFF/7F.")
fabs48 = _unary("fabs48", _fabs48_k, check48,
                "``fabs48(a) -> (|a|, flags)``: 48-bit analogue of FABS (the standard has no EFABS).")
fneg32 = _unary("fneg32", _fneg32_k, check32,
                "``fneg32(a) -> (-a, flags)``: FNEG (5.70). -(-1.0*2**n) = 0.5*2**(n+1), "
                "-(0.5*2**n) = -1.0*2**(n-1); -(-1.0*2**127) overflows, -(0.5*2**-128) underflows.")
fneg48 = _unary("fneg48", _fneg48_k, check48,
                "``fneg48(a) -> (-a, flags)``: 48-bit negate (no EFNEG exists; identical to "
                "``0 EFS a`` and to FNEG's rules).")
fix32 = _unary("fix32", _fix32_k, check32,
               "``fix32(a) -> (int16 pattern, flags)``: FIX (5.85), truncation toward zero; "
               "exponent > 0F -> (0, FLAG_FIXED_OVERFLOW) (the hardware leaves RA unchanged).")
fix48 = _unary("fix48", _fix48_k, check48,
               "``fix48(a) -> (int32 pattern, flags)``: EFIX (5.87), truncation toward zero; "
               "exponent > 1F -> (0, FLAG_FIXED_OVERFLOW).")
flt32 = _unary("flt32", _flt32_k, _int16,
               "``flt32(i) -> (float32 word, 0)``: FLT (5.86) of a 16-bit pattern ``i`` "
               "(exponent 0F, normalise). Exact.")
flt48 = _unary("flt48", _flt48_k, _int32,
               "``flt48(i) -> (float48 word, 0)``: EFLT (5.88) of a 32-bit pattern ``i`` "
               "(exponent 1F, normalise). Exact.")


def fc32(a, b) -> int:
    """``fc32(a, b) -> -1 | 0 | 1``: FC (5.94), the condition status of ``a : b`` (a < b, =, >).
    Never interrupts, so no flags are returned."""
    return int(_fc32_k(check32("fc32: a", a), check32("fc32: b", b)))


def fc48(a, b) -> int:
    """``fc48(a, b) -> -1 | 0 | 1``: EFC (5.95)."""
    return int(_fc48_k(check48("fc48: a", a), check48("fc48: b", b)))


def overload_impl2(kern):
    """numba overload typing function for a public 2-argument primitive: calls ``kern``."""
    def ov(a, b):
        def impl(a, b):
            return kern(a, b)
        return _named_after(impl, kern)
    return ov


def overload_impl1(kern):
    """numba overload typing function for a public 1-argument primitive: calls ``kern``."""
    def ov(a):
        def impl(a):
            return kern(a)
        return _named_after(impl, kern)
    return ov


def _named_after(impl, kern):
    """``impl`` renamed ``<kern's module>_<kern's name>_overload``, its own name for each kernel.

    numba names a compiled function by its module, qualified name, a counter of the process that
    compiled it and its argument types. Every ``impl`` made here would share one qualified name
    and, for one arity, one argument list (int64 words), so two processes that number their
    compilations differently can give one symbol name to the overloads of two different
    primitives. A kernel keeps such an overload out of line when it is large (the TP's frame
    kernel keeps one), and when a process loads two cached kernels that define the same symbol
    LLVM binds both to one body (numba issue 10486): wrong arithmetic. With a name per kernel, two
    definitions of one symbol are always the same code."""
    f = kern.py_func
    impl.__name__ = impl.__qualname__ = (f"{f.__module__.rsplit('.', 1)[-1]}_{f.__name__}"
                                         f"_overload")
    return impl


def _register_overloads():
    pairs2 = [(fa32, _fa32_k), (fs32, _fs32_k), (fm32, _fm32_k), (fd32, _fd32_k),
              (fa48, _fa48_k), (fs48, _fs48_k), (fm48, _fm48_k), (fd48, _fd48_k),
              (fc32, _fc32_k), (fc48, _fc48_k)]
    pairs1 = [(fabs32, _fabs32_k), (fabs48, _fabs48_k), (fneg32, _fneg32_k), (fneg48, _fneg48_k),
              (fix32, _fix32_k), (fix48, _fix48_k), (flt32, _flt32_k), (flt48, _flt48_k)]
    for pub, kern in pairs2:
        overload(pub, jit_options=KERNEL)(overload_impl2(kern))
    for pub, kern in pairs1:
        overload(pub, jit_options=KERNEL)(overload_impl1(kern))


_register_overloads()


# ================================================================================================
# cycle costs (flightsw.budget PACE1750A table; memory-operand forms)
# ================================================================================================
#: operation mix of each primitive in the keys of :data:`flightsw.budget.M1750_PACE_COSTS`.
#: Memory-operand forms (FA, FM, ...) are charged: flight code takes constants and variables from
#: memory. fabs48/fneg48 have no instruction of their own: a sign test (L, JC) and an EFS from zero.
OP_MIX = {
    "fa32": {"FA": 1}, "fs32": {"FS": 1}, "fm32": {"FM": 1}, "fd32": {"FD": 1},
    "fa48": {"EFA": 1}, "fs48": {"EFS": 1}, "fm48": {"EFM": 1}, "fd48": {"EFD": 1},
    "flt32": {"FLT": 1}, "fix32": {"FIX": 1}, "flt48": {"EFLT": 1}, "fix48": {"EFIX": 1},
    "fabs32": {"FABS": 1}, "fneg32": {"FNEG": 1},
    "fabs48": {"L": 1, "JC": 1, "EFS": 1}, "fneg48": {"EFS": 1},
    "fc32": {"FC": 1}, "fc48": {"EFC": 1},
    "to48": {"DL": 1}, "to32": {"DL": 1},
}


def op_mix(name: str) -> dict:
    """The 1750A operation mix (``{budget key: count}``) of primitive or math routine ``name``."""
    try:
        return dict(OP_MIX[name])
    except KeyError:
        raise KeyError(f"no operation mix for {name!r}; known: {sorted(OP_MIX)}") from None


def op_cycles(name: str, processor: Processor = PACE1750A) -> int:
    """Clocks of one call of ``name`` on ``processor`` (default PACE1750A, 1 wait state)."""
    return m1750_cycles(op_mix(name), processor)


#: clocks per call on the default PACE1750A, for cheap charging from @njit loops
#: (``n_fa * CYCLES["fa32"]``; module-level int constants ``CYC_FA32`` etc. are also exported).
CYCLES = {k: op_cycles(k) for k in OP_MIX}
CYC_FA32, CYC_FS32, CYC_FM32, CYC_FD32 = (CYCLES[k] for k in ("fa32", "fs32", "fm32", "fd32"))
CYC_FA48, CYC_FS48, CYC_FM48, CYC_FD48 = (CYCLES[k] for k in ("fa48", "fs48", "fm48", "fd48"))
