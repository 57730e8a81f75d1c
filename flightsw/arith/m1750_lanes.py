"""Branch-free forms of the MIL-STD-1750A float instructions, for loops that run one instruction
over many independent operands (the blob-parallel feature routine, the distance terms of the
ranking): the host compiles such a loop to SIMD instructions only when its body has no branches.

Each ``xxx_v`` returns exactly what its namesake in :mod:`flightsw.arith.m1750_float` returns (the
result word and the PI flags) for every pair of normalised operands: it evaluates every case of the
standard's register-transfer description (zero operands, the exponent pre-checks, the overflow
shift, normalisation, underflow, overflow) and *selects* the result the RTL would branch to, in the
RTL's order of precedence. The scalar forms stay the reference and the faster choice for a single
dependent chain (a select costs every case, a predicted branch only one); the tests compare the
two on random and adversarial operands (``tests/arith/test_m1750_lanes.py``).

Two host details differ from the scalar forms without changing a result:

* FD's quotient comes from one float64 division for both widths (the scalar 32-bit form divides
  integers; there is no SIMD integer division): ``A * 2**24 / B`` with ``A, B <= 2**23`` is below
  ``2**25``, so the float64 rounding error (``<= 2**-29``) is smaller than the distance
  (``>= 2**-23``) of a non-integral quotient from an integer and the truncation is the exact floor;
  the 40-bit form keeps the exact remainder fix-up of ``m1750_float._quotient_floor``.
* Divisors of zero are replaced by one before the division (the result is then selected away), so
  the caller's loop can be compiled with ``error_model="numpy"`` (no division-by-zero branch).
* ``fd32_lanes`` and ``fd48_lanes`` first check whether every lane has a dividend >= 0, a divisor
  > 0 and, for a non-zero dividend, an exponent difference in -128..126; then none of the RTL's
  special cases can fire and the block runs the positive form (``fd32_pos_v``/``fd48_pos_v``: the
  quotient alone, the same words, no flags) at about a third of the cost. Any other block runs
  the full form. The feature routine's divisions (moments by the weight sum, r^2 by N^2, totals by
  N) are of the first kind.

Each function is meant to be the body of a caller's loop: a plain compiled function, which LLVM
inlines into that loop (numba's own IR-level ``inline="always"`` gave the same speed, and cost a first
run about a quarter of its compile time: ``docs/validation.md``, first run).
"""
from __future__ import annotations

import numpy as np
from numba import types
from numba.extending import overload

from flightsw.arith.m1750_float import (
    FLAG_FIXED_OVERFLOW, FLAG_FLOAT_OVERFLOW, FLAG_FLOAT_UNDERFLOW, MAX32, MAX48,
    norm_shift, overflow_word, pack_w, prod80, unpack_w, pack32, pack48, unpack32, unpack48,
)
from flightsw.numba_cache import callee_kernel

__all__ = ["fa32_v", "fs32_v", "fm32_v", "fd32_v", "fd32_pos_v", "fa48_v", "fs48_v", "fm48_v",
           "fd48_v", "fd48_pos_v", "flt48_v", "fc32_v", "fc32_key", "fabs32_v", "fneg32_v",
           "fix32_v", "scale32_v", "fa32_lanes", "fs32_lanes", "fm32_lanes", "fd32_lanes",
           "fd32_pos_lanes", "fa48_lanes", "fs48_lanes", "fm48_lanes", "fd48_lanes", "flt48_lanes",
           "fabs32_lanes", "fneg32_lanes", "fix32_lanes"]

_FOV = FLAG_FLOAT_OVERFLOW
_FUN = FLAG_FLOAT_UNDERFLOW


@callee_kernel
def _finish_v(m, e, W):
    """m1750_float._finish without branches: normalise (m, e), underflow/overflow, pack.

    Cases
    -----
    zero : ``m = 0``: ``(0, 0)`` whatever ``e``.
    normalised : ``m`` already normalised: packed as is, flags 0.
    left-shift : ``m`` has redundant sign bits (after a cancellation): shifted left, exponent
        reduced.
    negative-power : a negative power of two (-0.5) normalises to -1.0 with the exponent one lower.
    overflow : exponent above 127: the standard's overflow word of the sign,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : exponent below -128 after the shift: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    s = np.int64(norm_shift(m, W)) if m != 0 else 0
    m2 = m << s
    e2 = e - s
    p = pack_w(m2, e2, W)
    hi = e2 > 127
    lo = e2 < -128
    p = overflow_word(m2 < 0, W) if hi else p
    f = _FOV if hi else 0
    p = 0 if lo else p
    f = _FUN if lo else f
    p = 0 if m == 0 else p
    f = 0 if m == 0 else f
    return p, f


@callee_kernel
def _add_v(a, b, W, subtract):
    """FA/FS (5.60, 5.61, 5.68, 5.69; m1750_float._add_core).

    Cases
    -----
    zero-operand : one operand is zero: no alignment, the other operand's mantissa and exponent.
    align-right : exponents differ: the operand with the smaller exponent is shifted right
        arithmetic by the difference (capped at 63), bits lost.
    shifted-out : a negative operand shifted right past its last bit leaves -1 unit (floor), a
        positive one 0.
    subtract : FS: the subtrahend's mantissa is negated exactly before the alignment.
    mantissa-overflow : the sum is outside [-1, 1): shifted right 1, exponent + 1.
    cancel : the mantissas cancel: floating zero, flags 0.
    overflow : the mantissa-overflow shift takes the exponent above 127: overflow word,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : normalising the sum takes the exponent below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    ma, ea = unpack_w(a, W)
    mo, eo = unpack_w(b, W)
    if subtract:                               # a compile-time constant: not a data branch
        mo = -mo
    both = (ma != 0) & (mo != 0)               # only then are the mantissas aligned
    n = ea - eo
    so = min(max(n, 0), 63) if both else 0
    sa = min(max(-n, 0), 63) if both else 0
    e = max(ea, eo) if both else (eo if ma == 0 else ea)
    s = (ma >> sa) + (mo >> so)
    top = np.int64(1) << W
    ov = (s >= top) | (s < -top)               # OVM: shift right 1, EA + 1 (normalised after it)
    s = (s >> 1) if ov else s
    e = e + 1 if ov else e
    return _finish_v(s, e, W)


@callee_kernel
def fa32_v(a, b):
    """FA (5.60), branch-free.

    Cases
    -----
    exact : the aligned result fits the mantissa (``1 + 1 = 2`` after the mantissa-overflow shift;
        ``10 + 0.5 = 10.5``): exact, flags 0.
    truncate : bits of the operand with the smaller exponent are shifted out: the result is below
        the exact one by less than one unit of the larger operand (``1 + (-2**-40) = 1 - 2**-22``).
    zero : ``0 + x = x``; ``x + (-x)`` is floating zero; flags 0.
    overflow : the result's exponent exceeds 127: the overflow word of its sign,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : normalising after a cancellation takes the exponent below -128:
        ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    return _add_v(a, b, 23, False)


@callee_kernel
def fs32_v(a, b):
    """FS (5.68), branch-free.

    Cases
    -----
    exact : the aligned result fits the mantissa (``1 - 2 = -1``): exact, flags 0.
    truncate : bits of the operand with the smaller exponent are shifted out: the result is below
        the exact one by less than one unit of the larger operand
        (``1 - (0.5 + 2**-23) = 0.5 - 2**-22``, the subtrahend negated before it is shifted).
    zero : ``0 - x = -x``; ``x - x`` is floating zero; flags 0.
    overflow : the result's exponent exceeds 127: the overflow word of its sign,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : normalising after a cancellation takes the exponent below -128:
        ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    return _add_v(a, b, 23, True)


@callee_kernel
def fa48_v(a, b):
    """EFA (5.61), branch-free.

    Cases
    -----
    exact : the aligned result fits the mantissa (``1 + 1 = 2`` after the mantissa-overflow shift;
        ``10 + 0.5 = 10.5``): exact, flags 0.
    truncate : bits of the operand with the smaller exponent are shifted out: the result is below
        the exact one by less than one unit of the larger operand (``1 + (-2**-60) = 1 - 2**-38``).
    zero : ``0 + x = x``; ``x + (-x)`` is floating zero; flags 0.
    overflow : the result's exponent exceeds 127: the overflow word of its sign,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : normalising after a cancellation takes the exponent below -128:
        ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    return _add_v(a, b, 39, False)


@callee_kernel
def fs48_v(a, b):
    """EFS (5.69), branch-free.

    Cases
    -----
    exact : the aligned result fits the mantissa (``1 - 2 = -1``): exact, flags 0.
    truncate : bits of the operand with the smaller exponent are shifted out: the result is below
        the exact one by less than one unit of the larger operand
        (``1 - (0.5 + 2**-39) = 0.5 - 2**-38``, the subtrahend negated before it is shifted).
    zero : ``0 - x = -x``; ``x - x`` is floating zero; flags 0.
    overflow : the result's exponent exceeds 127: the overflow word of its sign,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : normalising after a cancellation takes the exponent below -128:
        ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    return _add_v(a, b, 39, True)


@callee_kernel
def _mul_pre_v(p, f, ma, mo, n, W):
    """The RTL's checks before the multiply, applied over (p, f): n overflow/underflow, then a zero
    operand (the highest precedence).

    Cases
    -----
    pass : ``n`` in -128..127 and both mantissas non-zero: ``(p, f)`` unchanged.
    exp-overflow : ``n > 127``: the overflow word of the product's sign, ``FLAG_FLOAT_OVERFLOW``.
    exp-underflow : ``n < -128``: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    zero-operand : a zero mantissa: ``(0, 0)``, over every other outcome.
    """
    p = overflow_word((ma < 0) != (mo < 0), W) if n > 127 else p
    f = _FOV if n > 127 else f
    p = 0 if n < -128 else p
    f = _FUN if n < -128 else f
    z = (ma == 0) | (mo == 0)
    p = 0 if z else p
    f = 0 if z else f
    return p, f


@callee_kernel
def fm32_v(a, b):
    """FM (5.74), branch-free (m1750_float._fm32_k).

    Cases
    -----
    typical : the exact double-length product, normalised (one left shift when its magnitude is
        below 0.5), truncated to 24 bits: exact for short mantissas (1.5 * 2.5 = 3.75).
    floor : a product with bits below the mantissa: truncated toward minus infinity (negative
        products move away from zero).
    minus-one-squared : (-1.0)(-1.0): 0.5 * 2**(n+1).
    minus-one-squared-overflow : (-1.0)(-1.0) with ``n = 127``: ``(MAX32, FLAG_FLOAT_OVERFLOW)``.
    exp-overflow : ``n = EA + EO > 127`` (checked before the multiply): overflow word of the sign.
    exp-underflow : ``n < -128``: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    norm-underflow : the normalising shift takes ``n`` below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    zero : an operand is zero: ``(0, 0)``.
    """
    ma, ea = unpack32(a)
    mo, eo = unpack32(b)
    n = ea + eo
    P = ma * mo                                # exact, value P / 2**46
    s = np.int64(norm_shift(P, 46)) if P != 0 else 0
    n2 = n - s
    p = pack32((P << s) >> 23, n2)
    f = 0
    p = 0 if n2 < -128 else p
    f = _FUN if n2 < -128 else f
    sp = P == (np.int64(1) << 46)              # (-1.0)(-1.0) -> 0.5 * 2**(n + 1)
    p = (MAX32 if n + 1 > 127 else pack32(0x400000, n + 1)) if sp else p
    f = (_FOV if n + 1 > 127 else 0) if sp else f
    return _mul_pre_v(p, f, ma, mo, n, 23)


@callee_kernel
def fm48_v(a, b):
    """EFM (5.75), branch-free (m1750_float._fm48_k: the 80-bit product from 20-bit limbs).

    Cases
    -----
    typical : positive product, normalised and truncated to 40 bits (1.5 * 2.5 = 3.75).
    negative : negative product: ``floor(-x) = -ceil(x)`` from the magnitude's dropped bits
        (sticky), so inexact negative products move away from zero.
    minus-half : the product is exactly -0.5: -1.0 * 2**(n-1).
    minus-one-squared : (-1.0)(-1.0): 0.5 * 2**(n+1).
    minus-one-squared-overflow : (-1.0)(-1.0) with ``n = 127``: ``(MAX48, FLAG_FLOAT_OVERFLOW)``.
    exp-overflow : ``n > 127`` before the multiply: overflow word of the sign.
    exp-underflow : ``n < -128``: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    norm-underflow : the normalising shift takes ``n`` below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    zero : an operand is zero: ``(0, 0)``.
    """
    ma, ea = unpack48(a)
    mo, eo = unpack48(b)
    n = ea + eo
    neg = (ma < 0) != (mo < 0)
    A = -ma if ma < 0 else ma
    B = -mo if mo < 0 else mo
    H, L = prod80(A, B)
    half = np.int64(1) << 37
    mA = (H << 1) | (L >> 39)                  # floor(|P| / 2**39), normalised as is
    mB = (H << 2) | (L >> 38)                  # floor(|P| / 2**38), one left shift
    stA = np.int64((L & ((np.int64(1) << 39) - 1)) != 0)
    stB = np.int64((L & ((np.int64(1) << 38) - 1)) != 0)
    # positive: |P| >= 2**77 keeps the exponent; negative: floor(-x) = -ceil(x), and an exact
    # -0.5 becomes -1.0 * 2**(n-1), which is the one-shift formula's value for L = 0
    big = (H > half) | ((H == half) & ((L != 0) | (not neg)))
    m = (-(mA + stA) if neg else mA) if big else (-(mB + stB) if neg else mB)
    n2 = n if big else n - 1
    p = pack48(m, n2)
    f = 0
    p = 0 if n2 < -128 else p
    f = _FUN if n2 < -128 else f
    sp = (A == (np.int64(1) << 39)) & (B == (np.int64(1) << 39))      # (-1.0)(-1.0)
    p = (MAX48 if n + 1 > 127 else pack48(np.int64(1) << 38, n + 1)) if sp else p
    f = (_FOV if n + 1 > 127 else 0) if sp else f
    return _mul_pre_v(p, f, ma, mo, n, 39)


@callee_kernel
def _div_v(a, b, W):
    """FD/EFD (5.79, 5.80; m1750_float._div_core).

    Cases
    -----
    typical : the quotient truncated toward minus infinity (1 / 3), flags 0.
    negative : negative quotient: ``-ceil(|q|)`` at the last place (-1 / 3 rounds away from zero).
    shift : ``|MA| >= |MO|``: the quotient does not fit, shifted right once, exponent + 1.
    shift-overflow : that shift takes the exponent above 127: overflow word,
        ``FLAG_FLOAT_OVERFLOW``.
    minus-half : the quotient is exactly -0.5 (0.5 / -1.0): -1.0 * 2**(n-1).
    minus-half-underflow : the same with ``n - 1 < -128``: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    divide-by-zero : divisor zero (highest precedence): overflow word of the dividend's sign (0 / 0
        gives the positive one), ``FLAG_FLOAT_OVERFLOW``.
    zero-dividend : dividend zero, divisor not: ``(0, 0)`` whatever the exponents.
    exp-overflow : ``n = EA - EO > 127``: overflow word of the quotient's sign.
    exp-underflow : ``n < -128``: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    ma, ea = unpack_w(a, W)
    mo, eo = unpack_w(b, W)
    n = ea - eo if ma != 0 else 0
    neg = (ma < 0) != (mo < 0)
    A = -ma if ma < 0 else ma
    B = -mo if mo < 0 else mo
    Bs = B if B != 0 else 1                    # no division by zero (selected away below)
    if W == 23:
        num = A << 24
        Qm = np.int64(float(num) / float(Bs))  # the exact floor (module docstring)
        sticky = Qm * Bs != num
    else:
        Qm = np.int64(float(A) / float(Bs) * 1099511627776.0)       # 2**40
        r = (A << 40) - Qm * Bs                # exact modulo 2**64 (true value in (-B, 2B))
        lo = r < 0
        hi = r >= Bs
        Qm = Qm - 1 if lo else (Qm + 1 if hi else Qm)
        r = r + Bs if lo else (r - Bs if hi else r)
        sticky = r != 0
    Q = -((Qm >> 1) + np.int64(((Qm & 1) != 0) | sticky)) if neg else Qm >> 1
    top = np.int64(1) << W
    fit = (Q >= top) | (Q < -top)
    Q = (Q >> 1) if fit else Q
    n2 = n + 1 if fit else n
    p = pack_w(Q, n2, W)
    f = 0
    p = overflow_word(Q < 0, W) if n2 > 127 else p
    f = _FOV if n2 > 127 else f
    mh = Q == -(np.int64(1) << (W - 1))        # exactly -0.5 -> -1.0 * 2**(n-1)
    p = (0 if n2 - 1 < -128 else pack_w(-top, n2 - 1, W)) if mh else p
    f = (_FUN if n2 - 1 < -128 else 0) if mh else f
    # the RTL's checks before the division, highest precedence last
    p = 0 if ma == 0 else p
    f = 0 if ma == 0 else f
    p = 0 if n < -128 else p
    f = _FUN if n < -128 else f
    p = overflow_word(neg, W) if n > 127 else p
    f = _FOV if n > 127 else f
    p = overflow_word(ma < 0, W) if mo == 0 else p
    f = _FOV if mo == 0 else f
    return p, f


@callee_kernel
def fd32_v(a, b):
    """FD (5.79), branch-free.

    Cases
    -----
    typical : quotient truncated toward minus infinity, shifted once if it does not fit, -0.5
        normalised to -1.0 * 2**(n-1); flags 0.
    zero : zero dividend, non-zero divisor: ``(0, 0)``.
    divide-by-zero : ``(MAX32 or MIN32 by the dividend's sign, FLAG_FLOAT_OVERFLOW)``.
    overflow : exponent difference (or the quotient's shift) above 127: overflow word,
        ``FLAG_FLOAT_OVERFLOW``.
    underflow : exponent below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    return _div_v(a, b, 23)


@callee_kernel
def fd32_pos_v(a, b):
    """FD of two words with *positive* mantissas whose exponent difference is within -128..126
    (the caller guarantees it: the Heron steps of sqrt32, ``g`` in [1/4, 1) over ``y`` near 1).
    Then none of the RTL's special cases can occur (no zero, no sign, the quotient shifted once
    at most, no overflow or underflow) and FD is the truncated quotient of :func:`_div_v` alone:
    the same word, no flags, a third of the instructions.

    Cases
    -----
    below-one : dividend mantissa below the divisor's: the quotient fits, exponent ``EA - EO``
        (``1 / 3`` truncated).
    at-least-one : dividend mantissa >= the divisor's: the quotient shifted right once, exponent
        ``EA - EO + 1`` (3 / 1.5 = 2).
    """
    ma, ea = unpack32(a)
    mo, eo = unpack32(b)
    Q = np.int64(float(ma << 24) / float(mo)) >> 1     # exact floor (module docstring)
    fit = Q >= (np.int64(1) << 23)
    return pack32(Q >> 1 if fit else Q, ea - eo + 1 if fit else ea - eo)


@callee_kernel
def fd48_pos_v(a, b):
    """EFD of two words with positive mantissas whose exponent difference is within -128..126:
    :func:`_div_v`'s 40-bit quotient with its exact remainder fix-up and nothing else (as
    :func:`fd32_pos_v`); the same word, no flags.

    Cases
    -----
    below-one : dividend mantissa below the divisor's: quotient fits, exponent ``EA - EO``.
    at-least-one : dividend mantissa >= the divisor's: shifted right once, exponent ``EA - EO + 1``.
    """
    ma, ea = unpack48(a)
    mo, eo = unpack48(b)
    Qm = np.int64(float(ma) / float(mo) * 1099511627776.0)          # 2**40
    r = (ma << 40) - Qm * mo                   # exact modulo 2**64 (true value in (-B, 2B))
    Qm = Qm - 1 if r < 0 else (Qm + 1 if r >= mo else Qm)
    Q = Qm >> 1
    fit = Q >= (np.int64(1) << 39)
    return pack48(Q >> 1 if fit else Q, ea - eo + 1 if fit else ea - eo)


@callee_kernel
def _nn_domain(ma, ea, mo, eo):
    """True where FD/EFD reduces to the positive form or zero: dividend >= 0, divisor > 0, and a
    non-zero dividend's exponent difference within -128..126 (none of the RTL's checks fires).

    Cases
    -----
    positive : dividend > 0, divisor > 0, ``EA - EO`` in -128..126 (both ends included): True.
    zero-dividend : dividend 0, divisor > 0: True whatever the exponents.
    negative : a negative dividend, or a divisor <= 0: False.
    exponent-range : non-zero dividend with ``EA - EO`` outside -128..126: False.
    """
    n = ea - eo
    return (ma >= 0) & (mo > 0) & ((ma == 0) | ((n >= -128) & (n <= 126)))


@callee_kernel
def fd48_v(a, b):
    """EFD (5.80), branch-free.

    Cases
    -----
    typical : quotient truncated toward minus infinity (exact remainder fix-up of the float64
        estimate), shifted once if it does not fit, -0.5 normalised; flags 0.
    zero : zero dividend, non-zero divisor: ``(0, 0)``.
    divide-by-zero : ``(MAX48 or MIN48 by the dividend's sign, FLAG_FLOAT_OVERFLOW)``.
    overflow : exponent difference above 127: overflow word, ``FLAG_FLOAT_OVERFLOW``.
    underflow : exponent difference below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    return _div_v(a, b, 39)


@callee_kernel
def flt48_v(i):
    """EFLT (5.88) of a 32-bit pattern, branch-free.

    Cases
    -----
    zero : ``i = 0``: ``(0, 0)``.
    positive : bit 31 clear: exact, normalised from exponent 31 (1 = 0.5 * 2**1).
    negative : bit 31 set: exact (0x80000000 = -1.0 * 2**31, 0xFFFFFFFF = -1.0 * 2**0).
    """
    v = ((i & 0xFFFFFFFF) ^ 0x80000000) - 0x80000000
    return _finish_v(v << 8, 31, 39)


@callee_kernel
def fc32_v(a, b):
    """FC (5.94) -> -1, 0, 1, branch-free.

    Cases
    -----
    different-signs : the signs (-, 0, +) differ: the sign order decides.
    both-zero : both floating zero: 0.
    exponent : same sign, different exponents: the larger exponent is the larger magnitude (reversed
        for negative values).
    mantissa : same sign and exponent: the mantissas' order.
    equal : the same word: 0.
    """
    ma, ea = unpack32(a)
    mo, eo = unpack32(b)
    sa = np.int64(ma > 0) - np.int64(ma < 0)
    so = np.int64(mo > 0) - np.int64(mo < 0)
    ce = (np.int64(ea > eo) - np.int64(ea < eo)) * sa      # same sign: larger exponent, larger |x|
    cm = np.int64(ma > mo) - np.int64(ma < mo)
    same = ce if ea != eo else cm
    same = 0 if sa == 0 else same
    return (np.int64(sa > so) - np.int64(sa < so)) if sa != so else same


@callee_kernel
def fc32_key(a):
    """int64 key of a normalised 32-bit word (or zero) whose integer order is FC's order:
    ``sign(fc32_key(a) - fc32_key(b)) == fc32(a, b)``. ``|key| = (e + 128) 2**24 + |m|`` orders
    equal signs by exponent, then mantissa (a normalised value has one representation); the sign
    is the mantissa's. For sorting many words with one integer compare each (the ranking).

    Cases
    -----
    zero : floating zero: key 0.
    positive : ``(e + 128) * 2**24 + m``, above every key of a smaller positive value.
    negative : minus the magnitude's key, below 0 and reversed in order.
    order : ``sign(key(a) - key(b)) == fc32(a, b)`` for any two words.
    """
    m, e = unpack32(a)
    mag = ((e + 128) << 24) + (-m if m < 0 else m)
    return 0 if m == 0 else (-mag if m < 0 else mag)


@callee_kernel
def fabs32_v(a):
    """FABS (5.62), branch-free.

    Cases
    -----
    non-negative : zero or positive: returned unchanged.
    negative : the negation, flags 0.
    minus-one : -1.0 * 2**e: 0.5 * 2**(e+1).
    minus-one-overflow : -1.0 * 2**127: ``(MAX32, FLAG_FLOAT_OVERFLOW)``.
    """
    m, e = unpack32(a)
    mn = m == -(np.int64(1) << 23)             # -1.0 * 2**e -> 0.5 * 2**(e+1)
    p = pack32(-m, e) if m < 0 else a
    p = (MAX32 if e + 1 > 127 else pack32(np.int64(1) << 22, e + 1)) if mn else p
    f = _FOV if (mn & (e + 1 > 127)) else 0
    return p, f


@callee_kernel
def fneg32_v(a):
    """FNEG (5.70), branch-free.

    Cases
    -----
    zero : 0 -> ``(0, 0)``.
    typical : the negated mantissa, same exponent.
    minus-one : -1.0 * 2**e -> 0.5 * 2**(e+1).
    minus-one-overflow : -1.0 * 2**127: ``(MAX32, FLAG_FLOAT_OVERFLOW)``.
    half : 0.5 * 2**e -> -1.0 * 2**(e-1).
    half-underflow : 0.5 * 2**-128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    m, e = unpack32(a)
    p = pack32(-m, e)
    f = 0
    mn = m == -(np.int64(1) << 23)             # -1.0 * 2**e -> 0.5 * 2**(e+1)
    p = (MAX32 if e == 127 else pack32(np.int64(1) << 22, e + 1)) if mn else p
    f = _FOV if (mn & (e == 127)) else f
    mh = m == (np.int64(1) << 22)              # 0.5 * 2**e -> -1.0 * 2**(e-1)
    p = (0 if e == -128 else pack32(-(np.int64(1) << 23), e - 1)) if mh else p
    f = _FUN if (mh & (e == -128)) else f
    p = 0 if m == 0 else p
    return p, f


@callee_kernel
def fix32_v(a):
    """FIX (5.85) -> 16-bit pattern, branch-free (overflow: 0 and the fixed-overflow flag).

    Cases
    -----
    positive : truncated toward zero (2.75 -> 2, 32767.996 -> 32767).
    negative : truncated toward zero (-2.75 -> -2); -32768 (-1.0 * 2**15) gives 0x8000.
    overflow : exponent above 15: ``(0, FLAG_FIXED_OVERFLOW)``.
    small : magnitude below 1 (shift capped at 63): 0, also for negative values (not -1).
    """
    m, e = unpack32(a)
    s = min(max(23 - e, 0), 63)
    am = -m if m < 0 else m
    r = (m >> s) if m >= 0 else -(am >> s)     # truncate toward zero
    return (0 if e > 15 else r & 0xFFFF), (FLAG_FIXED_OVERFLOW if e > 15 else 0)


@callee_kernel
def scale32_v(p, k):
    """p * 2**k by exponent edit with the standard's overflow/underflow results, branch-free
    (m1750_math._scale32).

    Cases
    -----
    zero : floating zero: ``(0, 0)`` whatever ``k``.
    in-range : new exponent in -128..127: exponent edited, mantissa kept, flags 0.
    overflow-positive : new exponent above 127, positive: ``(MAX32, FLAG_FLOAT_OVERFLOW)``.
    overflow-negative : new exponent above 127, negative: ``(MIN32, FLAG_FLOAT_OVERFLOW)``.
    underflow : new exponent below -128: ``(0, FLAG_FLOAT_UNDERFLOW)``.
    """
    m, e = unpack32(p)
    e2 = e + k
    r = (p & 0xFFFFFF00) | (e2 & 0xFF)
    r = overflow_word(m < 0, 23) if e2 > 127 else r
    f = _FOV if e2 > 127 else 0
    r = 0 if e2 < -128 else r
    f = _FUN if e2 < -128 else f
    r = 0 if m == 0 else r
    f = 0 if m == 0 else f
    return r, f


# ================================================================================================
# array forms: one instruction over every lane (each compiled once, the loop in SIMD)
# ================================================================================================
def _el(b, i):
    """b[i] for an array operand, b itself for a scalar one (both operand kinds in one op)."""


@overload(_el, inline="always")
def _el_ov(b, i):
    if isinstance(b, types.Array):
        return lambda b, i: b[i]
    return lambda b, i: b


@callee_kernel(error_model="numpy")
def fa32_lanes(a, b, out):
    """FA of every lane, ``out[i] = fa32(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    arrays : ``a`` and ``b`` arrays: every lane gets its own result (each outcome of the instruction
        in one block), the returned flags are the OR of the lanes' flags.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fa32_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel(error_model="numpy")
def fs32_lanes(a, b, out):
    """FS of every lane, ``out[i] = fs32(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    arrays : ``a`` and ``b`` arrays: every lane gets its own result (each outcome of the instruction
        in one block), the returned flags are the OR of the lanes' flags.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fs32_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel(error_model="numpy")
def fm32_lanes(a, b, out):
    """FM of every lane, ``out[i] = fm32(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    arrays : ``a`` and ``b`` arrays: every lane gets its own result (each outcome of the instruction
        in one block), the returned flags are the OR of the lanes' flags.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fm32_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel
def _all_nn(a, b, n, W):
    """:func:`_nn_domain` holds for all ``n`` lanes of ``a / b`` (W-bit mantissas).

    Cases
    -----
    all-in : every lane in the positive domain: True.
    one-out : any lane outside it: False.
    empty : ``n = 0``: True.
    """
    ok = True
    for i in range(n):
        ma, ea = unpack_w(_el(a, i), W)
        mo, eo = unpack_w(_el(b, i), W)
        ok &= _nn_domain(ma, ea, mo, eo)
    return ok


@callee_kernel(error_model="numpy")
def fd32_lanes(a, b, out):
    """FD of every lane, ``out[i] = fd32(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    positive-block : every lane has a dividend >= 0, a divisor > 0 and (for a non-zero dividend) an
        exponent difference in -128..126: the positive form, zero dividends give 0, returns 0; the
        same words as FD/EFD.
    general-block : any lane outside that domain (a negative operand, a zero divisor, an exponent
        difference the format cannot hold): the full instruction in every lane, flags OR-ed.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    # every lane in the non-negative domain (the usual case: moments, N, sums of squares): the
    # positive form, a third of the time, the same words (tested) and no flags
    if _all_nn(a, b, out.size, 23):
        for i in range(out.size):
            x = _el(a, i)
            out[i] = 0 if unpack32(x)[0] == 0 else fd32_pos_v(x, _el(b, i))
        return 0
    fl = 0
    for i in range(out.size):
        out[i], f = fd32_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel(error_model="numpy")
def fd32_pos_lanes(a, b, out):
    """:func:`fd32_pos_v` of every lane (positive operands only, see there);
    ``a``, ``b``, ``out`` int64 [K]. No flags can arise.

    Cases
    -----
    positive : every lane ``fd32_pos_v`` (positive operands): FD's words.
    empty : ``K = 0``: nothing written.
    """
    for i in range(out.size):
        out[i] = fd32_pos_v(a[i], b[i])


@callee_kernel(error_model="numpy")
def fa48_lanes(a, b, out):
    """EFA of every lane, ``out[i] = fa48(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    arrays : ``a`` and ``b`` arrays: every lane gets its own result (each outcome of the instruction
        in one block), the returned flags are the OR of the lanes' flags.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fa48_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel(error_model="numpy")
def fs48_lanes(a, b, out):
    """EFS of every lane, ``out[i] = fs48(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    arrays : ``a`` and ``b`` arrays: every lane gets its own result (each outcome of the instruction
        in one block), the returned flags are the OR of the lanes' flags.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fs48_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel(error_model="numpy")
def fm48_lanes(a, b, out):
    """EFM of every lane, ``out[i] = fm48(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    arrays : ``a`` and ``b`` arrays: every lane gets its own result (each outcome of the instruction
        in one block), the returned flags are the OR of the lanes' flags.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fm48_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel(error_model="numpy")
def fd48_lanes(a, b, out):
    """EFD of every lane, ``out[i] = fd48(a[i], b[i])``; ``a``, ``b`` int64 [K] words (or one word
    for every lane), ``out`` int64 [K]. Returns the OR of the PI flags.

    Cases
    -----
    positive-block : every lane has a dividend >= 0, a divisor > 0 and (for a non-zero dividend) an
        exponent difference in -128..126: the positive form, zero dividends give 0, returns 0; the
        same words as FD/EFD.
    general-block : any lane outside that domain (a negative operand, a zero divisor, an exponent
        difference the format cannot hold): the full instruction in every lane, flags OR-ed.
    scalar-operand : ``a`` or ``b`` one word: used for every lane.
    empty : ``K = 0``: nothing written, returns 0.
    """
    if _all_nn(a, b, out.size, 39):            # as fd32_lanes: the positive form when it applies
        for i in range(out.size):
            x = _el(a, i)
            out[i] = 0 if unpack48(x)[0] == 0 else fd48_pos_v(x, _el(b, i))
        return 0
    fl = 0
    for i in range(out.size):
        out[i], f = fd48_v(_el(a, i), _el(b, i))
        fl |= f
    return fl


@callee_kernel
def flt48_lanes(a, out):
    """EFLT of every lane, ``out[i] = flt48(a[i])`` (int64 [K]). Returns the OR of the PI flags.

    Cases
    -----
    arrays : every lane gets its own result (each outcome of the instruction in one block), the
        returned flags are the OR of the lanes' flags.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = flt48_v(a[i])
        fl |= f
    return fl


@callee_kernel
def fabs32_lanes(a, out):
    """FABS of every lane, ``out[i] = fabs32(a[i])`` (int64 [K]). Returns the OR of the PI flags.

    Cases
    -----
    arrays : every lane gets its own result (each outcome of the instruction in one block), the
        returned flags are the OR of the lanes' flags.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fabs32_v(a[i])
        fl |= f
    return fl


@callee_kernel
def fneg32_lanes(a, out):
    """FNEG of every lane, ``out[i] = fneg32(a[i])`` (int64 [K]). Returns the OR of the PI flags.

    Cases
    -----
    arrays : every lane gets its own result (each outcome of the instruction in one block), the
        returned flags are the OR of the lanes' flags.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fneg32_v(a[i])
        fl |= f
    return fl


@callee_kernel
def fix32_lanes(a, out):
    """FIX of every lane, ``out[i] = fix32(a[i])`` (int64 [K]). Returns the OR of the PI flags.

    Cases
    -----
    arrays : every lane gets its own result (each outcome of the instruction in one block), the
        returned flags are the OR of the lanes' flags.
    empty : ``K = 0``: nothing written, returns 0.
    """
    fl = 0
    for i in range(out.size):
        out[i], f = fix32_v(a[i])
        fl |= f
    return fl
