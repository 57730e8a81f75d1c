"""MIL-STD-1750A 16/32-bit integer arithmetic with the standard's overflow rules.

Registers travel as bit patterns: 16-bit words as ints ``0..0xFFFF``, 32-bit double words
``(RA << 16) | RA+1`` as ints ``0..0xFFFFFFFF`` (as :mod:`flightsw.arith.adsp2100`); use
:func:`~flightsw.arith.m1750_float.to_signed16` / ``to_signed32`` for the signed values. Every
function returns its result(s) and ``flags``, the PI bits set (:data:`FLAG_FIXED_OVERFLOW`, level 4).

Rules (sections 4.1.3, 4.1.4, 4.1.9 and the RTL of 5.55-5.78):

* Overflow keeps the low 16 / 32 bits of the exact result and sets the fixed-overflow flag.
* ``add16/sub16/add32/sub32`` (A, S, DA, DS; 5.55, 5.63, 5.59, 5.67): overflow when the operands
  have the same (add) / opposite (subtract) signs and the result's sign differs from the first.
* ``neg16/neg32/abs16/abs32`` (NEG, DNEG, ABS, DABS; 5.65, 5.66, 5.57, 5.58): 8000 / 8000 0000 is
  returned unchanged with overflow.
* ``mul16`` (MS, 5.71): 16-bit product, overflow unless the product fits 16 bits (never when an
  operand is 0). ``mul16x32`` (M, 5.72): exact 32-bit product, never overflows (8000 * 8000 =
  4000 0000). ``mul32`` (DM, 5.73): 32x32, keeps the low 32 bits, overflow unless it fits.
* ``div16`` (DV, 5.76): 16/16 -> (quotient, remainder), truncation toward zero, remainder with the
  dividend's sign; overflow for 8000/FFFF (quotient 8000, the low 16 bits of +32768, remainder 0).
  ``div32_16`` (D, 5.77): 32/16 -> (quotient, remainder); overflow if the quotient does not fit 16
  bits (low 16 bits kept). ``div32`` (DD, 5.78): 32/32 -> quotient; overflow for 8000 0000 /
  FFFF FFFF. Division by zero: fixed overflow and all-zero results (4.1.4).
"""
from __future__ import annotations

from numbers import Integral

import numpy as np
from numba import njit
from numba.extending import overload

from flightsw.arith.m1750_float import FLAG_FIXED_OVERFLOW, overload_impl1, overload_impl2
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["add16", "sub16", "add32", "sub32", "neg16", "neg32", "abs16", "abs32",
           "mul16", "mul16x32", "mul32", "div16", "div32_16", "div32", "INT_OP_MIX"]


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
    negative : bit 31 set: the pattern minus 2**32 (0xFFFFFFFF -> -1, 0x80000000 -> -2**31).
    """
    return ((w & 0xFFFFFFFF) ^ 0x80000000) - 0x80000000


@njit(**KERNEL)
def _add16_k(a, b):
    """``a + b`` of two 16-bit patterns (ints 0..0xFFFF) -> ``(pattern, flags)``: A/AR (5.55).

    Cases
    -----
    no-overflow : the exact sum fits -32768..32767: its 16-bit pattern, flags 0.
    overflow-positive : the exact sum is above 32767: its low 16 bits (a negative pattern) and
        ``FLAG_FIXED_OVERFLOW``.
    overflow-negative : the exact sum is below -32768: its low 16 bits (a non-negative pattern) and
        ``FLAG_FIXED_OVERFLOW``.
    """
    r = _s16(a) + _s16(b)
    return r & 0xFFFF, (FLAG_FIXED_OVERFLOW if (r > 32767 or r < -32768) else 0)


@njit(**KERNEL)
def _sub16_k(a, b):
    """``a - b`` of two 16-bit patterns (ints 0..0xFFFF) -> ``(pattern, flags)``: S/SR (5.63).

    Cases
    -----
    no-overflow : the exact difference fits -32768..32767: its 16-bit pattern, flags 0.
    overflow-positive : the exact difference is above 32767: its low 16 bits (a negative pattern)
        and ``FLAG_FIXED_OVERFLOW``.
    overflow-negative : the exact difference is below -32768: its low 16 bits (a non-negative
        pattern) and ``FLAG_FIXED_OVERFLOW``.
    """
    r = _s16(a) - _s16(b)
    return r & 0xFFFF, (FLAG_FIXED_OVERFLOW if (r > 32767 or r < -32768) else 0)


@njit(**KERNEL)
def _add32_k(a, b):
    """``a + b`` of two 32-bit patterns (ints 0..0xFFFFFFFF) -> ``(pattern, flags)``: DA/DAR (5.59).

    Cases
    -----
    no-overflow : the exact sum fits -2**31..2**31 - 1: its 32-bit pattern, flags 0.
    overflow-positive : the exact sum is above 2**31 - 1: its low 32 bits (a negative pattern) and
        ``FLAG_FIXED_OVERFLOW``.
    overflow-negative : the exact sum is below -2**31: its low 32 bits (a non-negative pattern) and
        ``FLAG_FIXED_OVERFLOW``.
    """
    r = _s32(a) + _s32(b)
    return r & 0xFFFFFFFF, (FLAG_FIXED_OVERFLOW if (r > 0x7FFFFFFF or r < -0x80000000) else 0)


@njit(**KERNEL)
def _sub32_k(a, b):
    """``a - b`` of two 32-bit patterns (ints 0..0xFFFFFFFF) -> ``(pattern, flags)``: DS/DSR (5.67).

    Cases
    -----
    no-overflow : the exact difference fits -2**31..2**31 - 1: its 32-bit pattern, flags 0.
    overflow-positive : the exact difference is above 2**31 - 1: its low 32 bits (a negative
        pattern) and ``FLAG_FIXED_OVERFLOW``.
    overflow-negative : the exact difference is below -2**31: its low 32 bits (a non-negative
        pattern) and ``FLAG_FIXED_OVERFLOW``.
    """
    r = _s32(a) - _s32(b)
    return r & 0xFFFFFFFF, (FLAG_FIXED_OVERFLOW if (r > 0x7FFFFFFF or r < -0x80000000) else 0)


@njit(**KERNEL)
def _neg16_k(a):
    """``-a`` of a 16-bit pattern -> ``(pattern, flags)``: NEG (5.65).

    Cases
    -----
    typical : any pattern but 0x8000: the two's complement negation (0 -> 0, 0xFFFF -> 1), flags 0.
    most-negative : 0x8000 (-32768) is returned unchanged with ``FLAG_FIXED_OVERFLOW``.
    """
    a = a & 0xFFFF
    if a == 0x8000:
        return a, FLAG_FIXED_OVERFLOW
    return (-a) & 0xFFFF, 0


@njit(**KERNEL)
def _neg32_k(a):
    """``-a`` of a 32-bit pattern -> ``(pattern, flags)``: DNEG (5.66).

    Cases
    -----
    typical : any pattern but 0x80000000: the two's complement negation (0 -> 0), flags 0.
    most-negative : 0x80000000 is returned unchanged with ``FLAG_FIXED_OVERFLOW``.
    """
    a = a & 0xFFFFFFFF
    if a == 0x80000000:
        return a, FLAG_FIXED_OVERFLOW
    return (-a) & 0xFFFFFFFF, 0


@njit(**KERNEL)
def _abs16_k(a):
    """``|a|`` of a 16-bit pattern -> ``(pattern, flags)``: ABS (5.57).

    Cases
    -----
    non-negative : bit 15 clear (0 included): returned unchanged, flags 0.
    negative : 0x8001..0xFFFF: the negation (0xFFFF -> 1), flags 0.
    most-negative : 0x8000 is returned unchanged with ``FLAG_FIXED_OVERFLOW``.
    """
    a = a & 0xFFFF
    if a == 0x8000:
        return a, FLAG_FIXED_OVERFLOW
    return (-a) & 0xFFFF if a & 0x8000 else a, 0


@njit(**KERNEL)
def _abs32_k(a):
    """``|a|`` of a 32-bit pattern -> ``(pattern, flags)``: DABS (5.58).

    Cases
    -----
    non-negative : bit 31 clear (0 included): returned unchanged, flags 0.
    negative : 0x80000001..0xFFFFFFFF: the negation, flags 0.
    most-negative : 0x80000000 is returned unchanged with ``FLAG_FIXED_OVERFLOW``.
    """
    a = a & 0xFFFFFFFF
    if a == 0x80000000:
        return a, FLAG_FIXED_OVERFLOW
    return (-a) & 0xFFFFFFFF if a & 0x80000000 else a, 0


@njit(**KERNEL)
def _mul16_k(a, b):
    """``a * b`` of two 16-bit patterns, single-precision result -> ``(low 16 bits, flags)``: MS
    (5.71).

    Cases
    -----
    fits : the product is in -32768..32767 (any product with a zero operand; 0xFF00 * 0x0080 =
        -32768): its pattern, flags 0.
    overflow : the product is outside -32768..32767 (0x8000 * 0xFFFF = +32768, 256 * 256): its low
        16 bits and ``FLAG_FIXED_OVERFLOW``.
    """
    r = _s16(a) * _s16(b)
    return r & 0xFFFF, (FLAG_FIXED_OVERFLOW if (r > 32767 or r < -32768) else 0)


@njit(**KERNEL)
def _mul16x32_k(a, b):
    """``a * b`` of two 16-bit patterns as a 32-bit pattern -> ``(pattern, 0)``: M/MR (5.72).

    Cases
    -----
    typical : the exact product as a 32-bit two's complement pattern (negative products included),
        flags 0.
    most-negative : 0x8000 * 0x8000 = 0x40000000 (+2**30) and 0x8000 * 0x7FFF: exact, never an
        overflow.
    """
    return (_s16(a) * _s16(b)) & 0xFFFFFFFF, 0


@njit(**KERNEL)
def _mul32_k(a, b):
    """``a * b`` of two 32-bit patterns -> ``(low 32 bits, flags)``: DM (5.73). The exact product
    (``|p| <= 2**62``) fits int64.

    Cases
    -----
    fits : the product is in -2**31..2**31 - 1: its pattern, flags 0.
    overflow : the product is outside (0x80000000 squared, 2**16 * 2**16, 2**16 * 2**15 = +2**31):
        its low 32 bits and ``FLAG_FIXED_OVERFLOW``.
    """
    r = _s32(a) * _s32(b)          # |r| <= 2**62: exact in int64
    return r & 0xFFFFFFFF, (FLAG_FIXED_OVERFLOW if (r > 0x7FFFFFFF or r < -0x80000000) else 0)


@callee_kernel
def _tdivmod(x, y):
    """Truncating division (toward zero), remainder with the dividend's sign.

    Cases
    -----
    same-signs : both operands positive: ``q = x // y``, remainder >= 0 (7 / 2 = 3 r 1).
    negative-dividend : ``x < 0 < y``: quotient truncated toward zero, remainder negative (-7 / 2 =
        -3 r -1).
    negative-divisor : ``y < 0 < x``: -3 r 1 for 7 / -2 (remainder keeps the dividend's sign).
    both-negative : ``x, y < 0``: -7 / -2 = 3 r -1.
    exact : the remainder is 0 (12 / 4 = 3 r 0).
    """
    ax = -x if x < 0 else x
    ay = -y if y < 0 else y
    q = ax // ay
    r = ax - q * ay
    if (x < 0) != (y < 0):
        q = -q
    if x < 0:
        r = -r
    return q, r


@njit(**KERNEL)
def _div16_k(a, b):
    """``a / b`` of two 16-bit patterns -> ``(quotient, remainder, flags)``: DV/DVR (5.76).

    Cases
    -----
    typical : ``b != 0`` and the quotient fits: truncated quotient and the remainder with the
        dividend's sign, as 16-bit patterns, flags 0.
    divide-by-zero : ``b = 0``: ``(0, 0, FLAG_FIXED_OVERFLOW)``.
    overflow : 0x8000 / 0xFFFF (+32768 does not fit): quotient 0x8000 (its low 16 bits), remainder
        0, ``FLAG_FIXED_OVERFLOW``; the only 16/16 quotient that does not fit.
    """
    y = _s16(b)
    if y == 0:
        return 0, 0, FLAG_FIXED_OVERFLOW
    q, r = _tdivmod(_s16(a), y)
    return q & 0xFFFF, r & 0xFFFF, (FLAG_FIXED_OVERFLOW if q > 32767 else 0)


@njit(**KERNEL)
def _div32_16_k(a, b):
    """``a / b`` of a 32-bit dividend pattern by a 16-bit divisor pattern -> ``(quotient16,
    remainder16, flags)``: D/DR (5.77).

    Cases
    -----
    typical : ``b != 0`` and the quotient is in -32768..32767 (both ends included): truncated
        quotient and the remainder with the dividend's sign, 16-bit patterns, flags 0.
    divide-by-zero : ``b = 0``: ``(0, 0, FLAG_FIXED_OVERFLOW)``.
    overflow-positive : quotient above 32767 (0x8000 / 1, 0x10000 / 1): its low 16 bits, the
        remainder's pattern, ``FLAG_FIXED_OVERFLOW``.
    overflow-negative : quotient below -32768 (-32769 / 1): its low 16 bits,
        ``FLAG_FIXED_OVERFLOW``.
    """
    y = _s16(b)
    if y == 0:
        return 0, 0, FLAG_FIXED_OVERFLOW
    q, r = _tdivmod(_s32(a), y)
    return q & 0xFFFF, r & 0xFFFF, (FLAG_FIXED_OVERFLOW if (q > 32767 or q < -32768) else 0)


@njit(**KERNEL)
def _div32_k(a, b):
    """``a / b`` of two 32-bit patterns -> ``(quotient32, flags)``: DD/DDR (5.78); no remainder.

    Cases
    -----
    typical : ``b != 0`` and the quotient fits: the quotient truncated toward zero, flags 0.
    divide-by-zero : ``b = 0``: ``(0, FLAG_FIXED_OVERFLOW)``.
    overflow : 0x80000000 / 0xFFFFFFFF (+2**31 does not fit): quotient 0x80000000,
        ``FLAG_FIXED_OVERFLOW``.
    """
    y = _s32(b)
    if y == 0:
        return 0, FLAG_FIXED_OVERFLOW
    q, r = _tdivmod(_s32(a), y)
    return q & 0xFFFFFFFF, (FLAG_FIXED_OVERFLOW if q > 0x7FFFFFFF else 0)


# ------------------------------------------------------------------------------------------------
def _w(name, v, hi):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (Integral, np.integer)) or not 0 <= v <= hi:
        raise ValueError(f"{name}={v!r} is not a {hi.bit_length()}-bit pattern (an int in 0..{hi:#x})")
    return int(v)


def _mk(name, kern, widths, doc):
    def fn(*args):
        if len(args) != len(widths):
            raise TypeError(f"{name} takes {len(widths)} arguments, got {len(args)}")
        vals = [_w(f"{name}: {'ab'[i]}", v, (1 << w) - 1) for i, (v, w) in enumerate(zip(args, widths))]
        return tuple(int(x) for x in kern(*vals))
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = doc
    return fn


add16 = _mk("add16", _add16_k, (16, 16), "``add16(a, b) -> (a+b, flags)``: A/AR (5.55).")
sub16 = _mk("sub16", _sub16_k, (16, 16), "``sub16(a, b) -> (a-b, flags)``: S/SR (5.63).")
add32 = _mk("add32", _add32_k, (32, 32), "``add32(a, b) -> (a+b, flags)``: DA/DAR (5.59).")
sub32 = _mk("sub32", _sub32_k, (32, 32), "``sub32(a, b) -> (a-b, flags)``: DS/DSR (5.67).")
neg16 = _mk("neg16", _neg16_k, (16,), "``neg16(a) -> (-a, flags)``: NEG (5.65).")
neg32 = _mk("neg32", _neg32_k, (32,), "``neg32(a) -> (-a, flags)``: DNEG (5.66).")
abs16 = _mk("abs16", _abs16_k, (16,), "``abs16(a) -> (|a|, flags)``: ABS (5.57).")
abs32 = _mk("abs32", _abs32_k, (32,), "``abs32(a) -> (|a|, flags)``: DABS (5.58).")
mul16 = _mk("mul16", _mul16_k, (16, 16), "``mul16(a, b) -> (low 16 bits of a*b, flags)``: MS (5.71).")
mul16x32 = _mk("mul16x32", _mul16x32_k, (16, 16),
               "``mul16x32(a, b) -> (32-bit a*b, 0)``: M/MR (5.72), never overflows.")
mul32 = _mk("mul32", _mul32_k, (32, 32), "``mul32(a, b) -> (low 32 bits of a*b, flags)``: DM (5.73).")
div16 = _mk("div16", _div16_k, (16, 16),
            "``div16(a, b) -> (quotient, remainder, flags)``: DV/DVR (5.76).")
div32_16 = _mk("div32_16", _div32_16_k, (32, 16),
               "``div32_16(a, b) -> (quotient16, remainder16, flags)``: D/DR (5.77).")
div32 = _mk("div32", _div32_k, (32, 32), "``div32(a, b) -> (quotient32, flags)``: DD/DDR (5.78).")

for _pub, _k, _n in [(add16, _add16_k, 2), (sub16, _sub16_k, 2), (add32, _add32_k, 2),
                     (sub32, _sub32_k, 2), (neg16, _neg16_k, 1), (neg32, _neg32_k, 1),
                     (abs16, _abs16_k, 1), (abs32, _abs32_k, 1), (mul16, _mul16_k, 2),
                     (mul16x32, _mul16x32_k, 2), (mul32, _mul32_k, 2), (div16, _div16_k, 2),
                     (div32_16, _div32_16_k, 2), (div32, _div32_k, 2)]:
    overload(_pub, jit_options=KERNEL)(
        overload_impl2(_k) if _n == 2 else overload_impl1(_k))

#: budget keys of each integer primitive (memory-operand forms). MS, DM, DV, D, DD, DA, DS, NEG,
#: ABS have no entry of their own in flightsw.budget: they are priced like the nearest listed
#: instruction ([ASSUMED]: MS as MR, DM as 2 MR + 2 A, DV/DD as DR, DA/DS as 2 A, NEG/ABS as AR).
INT_OP_MIX = {
    "add16": {"A": 1}, "sub16": {"S": 1}, "add32": {"A": 2}, "sub32": {"S": 2},
    "neg16": {"AR": 1}, "neg32": {"AR": 2}, "abs16": {"AR": 1}, "abs32": {"AR": 2},
    "mul16": {"MR": 1}, "mul16x32": {"MR": 1}, "mul32": {"MR": 2, "A": 2},
    "div16": {"DR": 1}, "div32_16": {"DR": 1}, "div32": {"DR": 1},
}
