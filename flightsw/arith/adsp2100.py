"""ADSP-2100 data path, bit-exact: MAC, ALU, shifter, divide primitives, and the MAC array kernels.

Registers travel as their bit patterns: 16-bit words as ints ``0..0xFFFF``, the 40-bit MAC result
register MR (= MR2:MR1:MR0) as an int ``0..2**40-1``, the shifter result SR (= SR1:SR0) as an int
``0..2**32-1``. Sources are ``shared/reference/processors.md`` section A (the 1995 ADSP-2100 Family
User's Manual [A1], MAME's ``2100ops.hxx`` [A2], and the adsp-2100_sv research notes [A3]).

Decisions where sources conflict (each follows the manual, as processors.md asks):

* **Fractional mode is always on** (the 2100 has no integer-multiply mode): the 32-bit product is
  sign-extended to 40 bits *then* shifted left one bit. Hence ``0x8000 * 0x8000 (SS)`` gives
  ``00_8000_0000`` with MV = 1 (MAME, shifting inside 32 bits, gives ``FF_8000_0000``, MV = 0).
  ``DECISION_8000_SQUARED = "manual"``.
* **RND midpoint test on the full sum** for ``MR = MR +/- X*Y (RND)``: the unrounded 40-bit result's
  low 16 bits are compared with 0x8000 (MAME compares only the product's low word).
  ``DECISION_RND_MIDPOINT = "full_sum"``. Rounding is unbiased (round half to even): add 0x8000, and
  if the unrounded low word was exactly 0x8000 clear bit 16. MR0 keeps ``old + 0x8000`` (Example 1
  of [A1]).
* Unsigned operands (SU/US/UU) form the true product, which the multiplier then *treats as signed*
  32 bits (processors.md: "the product is treated as signed"): a UU product with bit 31 set comes
  out negative, as on the hardware and in MAME.

Every scalar primitive is a plain Python function that validates its operands (``ValueError`` naming
the bad value) and, through ``numba.extending.overload``, is also callable under the same name from
``@njit`` code (no validation on that path). All cost one instruction cycle (:data:`CYCLES`).
"""
from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import overload

from flightsw.budget import ADSP_COSTS

DECISION_8000_SQUARED = "manual"
DECISION_RND_MIDPOINT = "full_sum"

#: instruction cycles of each primitive (every ADSP-2100 instruction is one cycle, processors.md A)
CYCLES = {"mac": ADSP_COSTS["mac"], "sat_mr": ADSP_COSTS["sat"], "rnd_mr": ADSP_COSTS["rnd"],
          "alu_add": ADSP_COSTS["alu"], "alu_sub": ADSP_COSTS["alu"], "ashift": ADSP_COSTS["shift"],
          "lshift": ADSP_COSTS["shift"], "norm": ADSP_COSTS["shift"], "exp": ADSP_COSTS["shift"],
          "expadj": ADSP_COSTS["shift"], "divs": ADSP_COSTS["divs"], "divq": ADSP_COSTS["divq"],
          "divide": ADSP_COSTS["divide16"]}

MASK16 = 0xFFFF
MASK32 = 0xFFFFFFFF
MASK40 = (1 << 40) - 1
MR_SAT_POS = 0x007FFFFFFF   # IF MV SAT MR, positive overflow (MR2 MSB = 0)
MR_SAT_NEG = 0xFF80000000   # negative overflow (MR2 MSB = 1)

OP_SET, OP_ADD, OP_SUB = 0, 1, 2     # MR = X*Y ; MR = MR + X*Y ; MR = MR - X*Y
_OPS = {"=": OP_SET, "+": OP_ADD, "-": OP_SUB}
_SIGNS = {"ss": (True, True), "su": (True, False), "us": (False, True), "uu": (False, False)}


# --------------------------------------------------------------------------------------------
# validation helpers (Python side only)
# --------------------------------------------------------------------------------------------
def _word(name, v):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not 0 <= v <= MASK16:
        raise ValueError(f"{name}={v!r} is not a 16-bit word (an int in 0..0xFFFF)")
    return int(v)


def _mr(v):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not 0 <= v <= MASK40:
        raise ValueError(f"mr={v!r} is not a 40-bit MR pattern (an int in 0..2**40-1)")
    return int(v)


def _count(name, v, lo, hi):
    if not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
        raise ValueError(f"{name}={v!r} is not an int in {lo}..{hi}")
    return int(v)


def _flag(name, v):
    if v not in (0, 1, True, False):
        raise ValueError(f"{name}={v!r} is not a flag (0 or 1)")
    return int(v)


# --------------------------------------------------------------------------------------------
# kernels
# --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def s16(w):
    """Sign-extend a 16-bit pattern to a Python/numba int."""
    w = w & 0xFFFF
    return w - 0x10000 if w & 0x8000 else w


@njit(cache=True, inline="always")
def s40(mr):
    """Sign-extend a 40-bit MR pattern."""
    mr = mr & 0xFFFFFFFFFF
    return mr - 0x10000000000 if mr & 0x8000000000 else mr


@njit(cache=True, inline="always")
def mv_of(mr):
    """MV condition: MR bits 39..31 not all equal (the value does not fit 32-bit MR1:MR0)."""
    top = (mr >> 31) & 0x1FF
    return 1 if (top != 0 and top != 0x1FF) else 0


@njit(cache=True, inline="always")
def product40(x, y, x_signed, y_signed):
    """The multiplier's contribution to MR: 16x16 product, taken as signed 32 bits, sign-extended to
    40 bits and shifted left one bit (fractional mode). Returns the signed value (no masking)."""
    xv = s16(x) if x_signed else (x & 0xFFFF)
    yv = s16(y) if y_signed else (y & 0xFFFF)
    p = (xv * yv) & 0xFFFFFFFF
    if p & 0x80000000:
        p -= 0x100000000
    return p << 1


@njit(cache=True, inline="always")
def rnd40(res, lo_unrounded):
    """Unbiased rounding at the MR0/MR1 boundary of a 40-bit value (both as patterns)."""
    res = (res + 0x8000) & 0xFFFFFFFFFF
    if lo_unrounded == 0x8000:
        res &= ~0x10000 & 0xFFFFFFFFFF
    return res


@njit(cache=True)
def _mac_k(mr, x, y, op, x_signed, y_signed, rnd):
    p = product40(x, y, x_signed, y_signed)
    if op == 0:
        res = p
    elif op == 1:
        res = mr + p
    else:
        res = mr - p
    res &= 0xFFFFFFFFFF
    if rnd:
        res = rnd40(res, res & 0xFFFF)
    return res, mv_of(res)


@njit(cache=True)
def _sat_mr_k(mr):
    if mv_of(mr):
        return 0xFF80000000 if (mr >> 39) & 1 else 0x007FFFFFFF
    return mr


@njit(cache=True)
def _rnd_mr_k(mr):
    return rnd40(mr, mr & 0xFFFF)


@njit(cache=True)
def _alu_add_k(x, y, ar_sat):
    r = x + y
    ac = (r >> 16) & 1
    r &= 0xFFFF
    av = 1 if ((x ^ r) & (y ^ r) & 0x8000) else 0
    if ar_sat and av:
        r = 0x8000 if ac else 0x7FFF
    return r, ac, av


@njit(cache=True)
def _alu_sub_k(x, y, ar_sat):
    r = x + ((~y) & 0xFFFF) + 1
    ac = (r >> 16) & 1          # carry = NOT borrow
    r &= 0xFFFF
    av = 1 if ((x ^ y) & (x ^ r) & 0x8000) else 0
    if ar_sat and av:
        r = 0x8000 if ac else 0x7FFF
    return r, ac, av


@njit(cache=True)
def _ashift_k(x, se, hi):
    xv = s16(x) << 16 if hi else s16(x)
    if se > 0:
        res = (xv << se) if se < 32 else 0
    else:
        res = (xv >> -se) if se > -32 else (xv >> 31)
    return res & 0xFFFFFFFF


@njit(cache=True)
def _lshift_k(x, se, hi):
    xv = (x & 0xFFFF) << 16 if hi else (x & 0xFFFF)
    if se > 0:
        res = (xv << se) if se < 32 else 0
    else:
        res = (xv >> -se) if se > -32 else 0
    return res & 0xFFFFFFFF


@njit(cache=True)
def _norm_k(x, se, hi, ac):
    if hi:
        xv = s16(x) << 16
        if se > 0:
            # right shift recovering an ALU overflow: the carry re-enters at the MSB (NORM HI)
            u = ((xv & 0xFFFFFFFF) >> 1) | (ac << 31)
            if u & 0x80000000:
                u -= 0x100000000
            res = u >> (se - 1)
        else:
            res = (xv << -se) if se > -32 else 0
    else:
        xv = x & 0xFFFF
        if se > 0:
            res = (xv >> se) if se < 32 else 0
        else:
            res = (xv << -se) if se > -32 else 0
    return res & 0xFFFFFFFF


@njit(cache=True)
def _redundant_sign_bits(x):
    xv = s16(x) << 16
    n = 0
    if xv < 0:
        while (xv & 0x40000000) != 0 and n < 15:
            n += 1
            xv <<= 1
    else:
        xv |= 0x8000
        while (xv & 0x40000000) == 0 and n < 15:
            n += 1
            xv <<= 1
    return n


@njit(cache=True)
def _exp_hi_k(x, hix, av):
    ss = 1 if x & 0x8000 else 0
    if hix and av:
        # the value overflowed into the carry: one right shift (NORM HI) brings it back
        return 1, 1 - ss
    return -_redundant_sign_bits(x), ss


@njit(cache=True)
def _exp_lo_k(x, se, ss):
    if se != -15:
        return se
    n = 15
    x &= 0xFFFF
    if ss:
        while (x & 0x8000) != 0 and n < 31:
            n += 1
            x = (x << 1) & 0xFFFF
    else:
        v = (x << 1) | 1
        while (v & 0x10000) == 0 and n < 31:
            n += 1
            v <<= 1
    return -n


@njit(cache=True)
def _expadj_k(x, sb):
    e = -_redundant_sign_bits(x)
    return e if e > sb else sb


@njit(cache=True)
def _divs_k(af, ay0, x):
    t = (x ^ af) & 0xFFFF
    aq = (t >> 15) & 1
    af_new = ((af << 1) | (ay0 >> 15)) & 0xFFFF
    ay0_new = ((ay0 << 1) | aq) & 0xFFFF
    return af_new, ay0_new, aq


@njit(cache=True)
def _divq_k(af, ay0, x, aq):
    res = (af + x) if aq else (af - x)
    t = res ^ x
    aq_new = (t >> 15) & 1
    af_new = ((res << 1) | (ay0 >> 15)) & 0xFFFF
    ay0_new = ((ay0 << 1) | ((~t >> 15) & 1)) & 0xFFFF
    return af_new, ay0_new, aq_new


@njit(cache=True)
def _divide_signed_k(hi, lo, divisor):
    af, ay0, aq = _divs_k(hi, lo, divisor)
    for _ in range(15):
        af, ay0, aq = _divq_k(af, ay0, divisor, aq)
    return ay0, af


@njit(cache=True)
def _divide_unsigned_k(hi, lo, divisor):
    af, ay0, aq = hi & 0xFFFF, lo & 0xFFFF, 0
    for _ in range(16):
        af, ay0, aq = _divq_k(af, ay0, divisor, aq)
    return ay0, af


# --------------------------------------------------------------------------------------------
# public scalar API (validated from Python, overloaded for @njit callers)
# --------------------------------------------------------------------------------------------
def mac(mr, x, y, op="+", signs="ss", rnd=False):
    """One MAC instruction: ``MR = X*Y``, ``MR = MR + X*Y`` or ``MR = MR - X*Y``.

    Parameters
    ----------
    mr : int
        Current MR, 40-bit pattern (ignored for ``op="="``).
    x, y : int
        16-bit words (X and Y operand registers).
    op : {"+", "-", "="}
    signs : {"ss", "su", "us", "uu"}
        Operand formats of X and Y (signed / unsigned).
    rnd : bool
        Unbiased rounding of the result at the MR0/MR1 boundary (the ``(RND)`` option; the manual's
        option is signed-signed only, we allow it with any formats).

    Returns
    -------
    (mr, mv) : (int, int)
        New MR pattern and the MV flag (MR[39:31] not all equal).

    One cycle. The product is shifted left one bit (fractional mode, always on in the 2100).
    """
    mr = _mr(mr)
    x, y = _word("x", x), _word("y", y)
    if op not in _OPS:
        raise ValueError(f"op={op!r} must be one of '+', '-', '='")
    if not isinstance(signs, str) or signs.lower() not in _SIGNS:
        raise ValueError(f"signs={signs!r} must be one of 'ss', 'su', 'us', 'uu'")
    xs, ys = _SIGNS[signs.lower()]
    res, mv = _mac_k(mr, x, y, _OPS[op], xs, ys, bool(rnd))
    return int(res), int(mv)


@overload(mac, jit_options={"cache": True})
def _mac_ov(mr, x, y, op="+", signs="ss", rnd=False):
    def impl(mr, x, y, op="+", signs="ss", rnd=False):
        o = 1 if op == "+" else (2 if op == "-" else 0)
        xs = signs[0] == "s" or signs[0] == "S"
        ys = signs[1] == "s" or signs[1] == "S"
        return _mac_k(mr, x, y, o, xs, ys, rnd)
    return impl


def sat_mr(mr):
    """``IF MV SAT MR``: saturate MR to 32 bits when it overflowed (MR[39:31] not all equal).

    Positive overflow (MR2 MSB 0) gives ``00_7FFF_FFFF``, negative gives ``FF_8000_0000``; otherwise MR
    is unchanged. One cycle."""
    return int(_sat_mr_k(_mr(mr)))


@overload(sat_mr, jit_options={"cache": True})
def _sat_mr_ov(mr):
    return lambda mr: _sat_mr_k(mr)


def rnd_mr(mr):
    """``MR = MR (RND)``: unbiased rounding of MR at the MR0/MR1 boundary (round half to even);
    MR0 keeps ``old MR0 + 0x8000``. One cycle."""
    return int(_rnd_mr_k(_mr(mr)))


@overload(rnd_mr, jit_options={"cache": True})
def _rnd_mr_ov(mr):
    return lambda mr: _rnd_mr_k(mr)


def alu_add(x, y, ar_sat=False):
    """``AR = X + Y`` on 16-bit words. Returns ``(ar, ac, av)``.

    AC is the carry out of bit 15, AV the two's-complement overflow. With AR_SAT (MSTAT bit) an
    overflowed result saturates: AV=1, AC=0 -> 0x7FFF; AV=1, AC=1 -> 0x8000. One cycle."""
    return tuple(int(v) for v in _alu_add_k(_word("x", x), _word("y", y), bool(ar_sat)))


@overload(alu_add, jit_options={"cache": True})
def _alu_add_ov(x, y, ar_sat=False):
    return lambda x, y, ar_sat=False: _alu_add_k(x, y, ar_sat)


def alu_sub(x, y, ar_sat=False):
    """``AR = X - Y`` (computed as X + NOT Y + 1; AC is the carry, i.e. NOT borrow). Returns
    ``(ar, ac, av)`` with AR_SAT as in :func:`alu_add`. One cycle."""
    return tuple(int(v) for v in _alu_sub_k(_word("x", x), _word("y", y), bool(ar_sat)))


@overload(alu_sub, jit_options={"cache": True})
def _alu_sub_ov(x, y, ar_sat=False):
    return lambda x, y, ar_sat=False: _alu_sub_k(x, y, ar_sat)


def ashift(x, se, hi=True):
    """``SR = ASHIFT x BY se (HI|LO)``: arithmetic shift of a 16-bit word placed at SR[31:16] (HI) or
    SR[15:0] (LO, sign-extended), positive ``se`` = left. Off-scale counts give all sign bits (right)
    or zero (left). Returns the 32-bit SR pattern. One cycle."""
    return int(_ashift_k(_word("x", x), _count("se", se, -128, 127), bool(hi)))


@overload(ashift, jit_options={"cache": True})
def _ashift_ov(x, se, hi=True):
    return lambda x, se, hi=True: _ashift_k(x, se, hi)


def lshift(x, se, hi=True):
    """``SR = LSHIFT x BY se (HI|LO)``: logical shift, zero fill; as :func:`ashift` otherwise."""
    return int(_lshift_k(_word("x", x), _count("se", se, -128, 127), bool(hi)))


@overload(lshift, jit_options={"cache": True})
def _lshift_ov(x, se, hi=True):
    return lambda x, se, hi=True: _lshift_k(x, se, hi)


def norm(x, se, hi=True, ac=0):
    """``SR = NORM x (HI|LO)`` with shift code ``se`` as left by EXP (``se <= 0`` shifts left by
    ``-se``). ``se = +1`` after ``EXP (HIX)`` of an overflowed value shifts right one bit and fills the
    MSB from the ALU carry ``ac`` (HI only). Returns the 32-bit SR pattern. One cycle."""
    return int(_norm_k(_word("x", x), _count("se", se, -128, 127), bool(hi), _flag("ac", ac)))


@overload(norm, jit_options={"cache": True})
def _norm_ov(x, se, hi=True, ac=0):
    return lambda x, se, hi=True, ac=0: _norm_k(x, se, hi, ac)


def exp_hi(x, hix=False, av=0):
    """``SE = EXP x (HI|HIX)``: ``SE = -(redundant sign bits)``, 0..-15, and the sign SS. With HIX and
    ``av = 1`` (the ALU overflowed) SE = +1 and SS is the inverted sign. Returns ``(se, ss)``."""
    se, ss = _exp_hi_k(_word("x", x), bool(hix), _flag("av", av))
    return int(se), int(ss)


@overload(exp_hi, jit_options={"cache": True})
def _exp_hi_ov(x, hix=False, av=0):
    return lambda x, hix=False, av=0: _exp_hi_k(x, hix, av)


def exp_lo(x, se, ss):
    """``SE = EXP x (LO)`` for the low word of a double-precision value: acts only when the HI step
    gave ``se = -15``, then counts on into the low word (``-15..-31``) using the sign ``ss``."""
    return int(_exp_lo_k(_word("x", x), _count("se", se, -128, 127), _flag("ss", ss)))


@overload(exp_lo, jit_options={"cache": True})
def _exp_lo_ov(x, se, ss):
    return lambda x, se, ss: _exp_lo_k(x, se, ss)


def expadj(x, sb):
    """``SB = EXPADJ x``: block exponent; SB takes the word's exponent only if it is larger (initialise
    ``sb = -16``). Returns the new SB."""
    return int(_expadj_k(_word("x", x), _count("sb", sb, -16, 15)))


@overload(expadj, jit_options={"cache": True})
def _expadj_ov(x, sb):
    return lambda x, sb: _expadj_k(x, sb)


def divs(af, ay0, x):
    """``DIVS AF, X``: first step of signed division. Returns ``(af, ay0, aq)``."""
    return tuple(int(v) for v in _divs_k(_word("af", af), _word("ay0", ay0), _word("x", x)))


@overload(divs, jit_options={"cache": True})
def _divs_ov(af, ay0, x):
    return lambda af, ay0, x: _divs_k(af, ay0, x)


def divq(af, ay0, x, aq):
    """``DIVQ X``: one non-restoring quotient step. Returns ``(af, ay0, aq)``."""
    return tuple(int(v) for v in _divq_k(_word("af", af), _word("ay0", ay0), _word("x", x),
                                         _flag("aq", aq)))


@overload(divq, jit_options={"cache": True})
def _divq_ov(af, ay0, x, aq):
    return lambda af, ay0, x, aq: _divq_k(af, ay0, x, aq)


def divide_signed(hi, lo, divisor):
    """Signed division ``DIVS`` + 15 ``DIVQ`` (16 cycles) of the 32-bit dividend ``hi:lo`` by a 16-bit
    divisor. Quotient format for M.N / O.P is (M-O+1).(N-P-1): a 1.31 dividend over a 1.15 divisor
    gives a 1.15 quotient (valid when ``|dividend| < |divisor|``). Some results are 1 LSB off, as on the
    chip (manual App. B). Returns ``(quotient, partial_remainder)`` words (AY0, AF)."""
    d = _word("divisor", divisor)
    if d == 0:
        raise ValueError("divisor=0: the DIVS/DIVQ sequence has no defined quotient")
    q, r = _divide_signed_k(_word("hi", hi), _word("lo", lo), d)
    return int(q), int(r)


@overload(divide_signed, jit_options={"cache": True})
def _divide_signed_ov(hi, lo, divisor):
    return lambda hi, lo, divisor: _divide_signed_k(hi, lo, divisor)


def divide_unsigned(hi, lo, divisor):
    """Unsigned division: clear AQ, 16 ``DIVQ`` (16 cycles).

    The quotient bits come out with the same scaling as the signed form (1.31 / 1.15 -> 1.15):
    ``quotient = floor((hi:lo) / (2 * divisor))``, so an integer quotient needs the dividend shifted
    left one bit first. The non-restoring steps test the partial remainder's bit 15, so the sequence
    is defined only for ``1 <= divisor <= 0x7FFF`` and ``hi < divisor``; other operands are rejected.
    Returns ``(quotient, partial_remainder)`` words (AY0, AF)."""
    d = _word("divisor", divisor)
    hi = _word("hi", hi)
    if not 1 <= d <= 0x7FFF:
        raise ValueError(f"divisor={d:#06x}: unsigned DIVQ needs 1 <= divisor <= 0x7FFF")
    if hi >= d:
        raise ValueError(f"hi={hi:#06x} >= divisor={d:#06x}: the quotient does not fit 16 bits")
    q, r = _divide_unsigned_k(hi, _word("lo", lo), d)
    return int(q), int(r)


@overload(divide_unsigned, jit_options={"cache": True})
def _divide_unsigned_ov(hi, lo, divisor):
    return lambda hi, lo, divisor: _divide_unsigned_k(hi, lo, divisor)


# --------------------------------------------------------------------------------------------
# array kernels: the multiply-accumulate loops of the image processor
# --------------------------------------------------------------------------------------------
@njit(cache=True)
def block_bitlen(img):
    """Bit length of the largest-magnitude 16-bit word of ``img`` (``x`` for x >= 0, ``~x`` for
    x < 0): the block exponent an EXPADJ pass over the block yields, as a count of significant
    bits (0..15). ``img``: integer array, any shape, values in 16-bit range."""
    f = img.ravel()
    m = np.int32(0)
    for i in range(f.size):
        a = np.int32(f[i])
        m |= a ^ (a >> np.int32(15))
    return bitlen(m)


@njit(cache=True, inline="always")
def bitlen(v):
    """Number of significant bits of a non-negative integer (0 for 0)."""
    n = 0
    while v > 0:
        n += 1
        v >>= 1
    return n


@njit(cache=True)
def finish_mr(acc, rnd, sat):
    """Store step of a MAC loop: the 40-bit accumulation ``acc`` (signed int) -> the word MR1 holds
    after ``(RND)`` on the last MAC and ``IF MV SAT MR``. Returns a signed 16-bit value."""
    mr = acc & 0xFFFFFFFFFF
    if rnd:
        mr = rnd40(mr, mr & 0xFFFF)
    if sat and mv_of(mr):
        mr = 0xFF80000000 if (mr >> 39) & 1 else 0x007FFFFFFF
    return s16((mr >> 16) & 0xFFFF)


@njit(cache=True)
def dot_q15(x, y, rnd=True, sat=True):
    """MAC loop ``MR = sum x[i]*y[i]`` (SS, fractional mode), then RND and SAT, returning MR1.

    x, y : int16/int32/int64 arrays of signed 16-bit values. With Q1.15 operands the result is the
    Q1.15 dot product; with an integer x and a Q1.15 y it is the integer-scaled result. The 40-bit
    accumulator wraps exactly as on the chip (int64 holds every partial sum of <= 2**23 terms, and the
    final value is reduced to 40 bits). Cycles: ``len(x) + 2`` (MACs, SAT, store) plus loop set-up."""
    acc = 0
    for i in range(x.shape[0]):
        acc += (np.int64(x[i]) * np.int64(y[i])) << 1
    return finish_mr(acc, rnd, sat)


@njit(cache=True)
def correlate_valid_q15(img, kern, rnd=True, sat=True):
    """2-D correlation of a 16-bit image with a Q1.15 kernel, as the ADSP-2100 computes it.

    ``out[r, c] = MR1 of sum_{i,j} img[r+i, c+j] * kern[i, j]`` with the fractional-mode product
    (x2), 40-bit accumulation, unbiased ``(RND)`` on the last tap and ``IF MV SAT MR`` before the store.
    With an integer image and a Q1.15 kernel the output is in image units (Q16.0).

    Parameters
    ----------
    img : ndarray (H + k - 1, W + k' - 1), int16/int32/int64 signed 16-bit values
        The image, already padded by the caller (edge handling is the caller's choice).
    kern : ndarray (k, k'), int16/int32/int64 Q1.15 coefficients
    Returns
    -------
    out : ndarray (H, W) int16

    Exactness of the fast path: each fractional product is at most 2**31 in magnitude, so for fewer
    than 256 taps no partial sum leaves 40 bits (the manual's "more than 255 overflows" rule) and
    int64 accumulation equals the 40-bit MR bit for bit; beyond 255 taps the result is reduced mod
    2**40 before rounding, which is what the chip's wrap-around does too.
    """
    kh, kw = kern.shape
    h = img.shape[0] - kh + 1
    w = img.shape[1] - kw + 1
    # tap-major: each tap sweeps the whole accumulator image (rows of w lanes, SIMD on the host).
    # The same int64 products and sums as the chip's pixel-by-pixel MAC loop, added in another
    # order: exact integer addition, so the same 40-bit MR at the store. (The row-at-a-time order
    # with one accumulator row ran 17-33 us for 64x64 and 7x7 depending on where the heap put the
    # row; this one 11-17 us.)
    acc = np.zeros((h, w), np.int64)
    for i in range(kh):
        for j in range(kw):
            kij = np.int64(kern[i, j]) << 1     # fractional-mode shift folded into the tap
            for r in range(h):
                src = img[r + i, j:j + w]
                dst = acc[r]
                for c in range(w):
                    dst[c] += np.int64(src[c]) * kij
    out = np.empty((h, w), np.int16)
    for r in range(h):
        for c in range(w):
            out[r, c] = finish_mr(acc[r, c], rnd, sat)
    return out


def correlate_cycles(h, w, kh, kw=None):
    """ADSP-2100 instruction cycles of :func:`correlate_valid_q15` producing an ``h x w`` output.

    Per output pixel: ``kh*kw`` single-cycle MACs with dual data fetch (the first is ``MR = X*Y``),
    one ``IF MV SAT MR``, one store of MR1 with an address modify folded in, one address-register
    modify to step the input pointer back: ``kh*kw + 3``. Per output row: a ``DO`` set-up and two
    pointer adjustments: 3. The inner tap loop is unrolled per kernel row (<= 7 words, cache-resident
    after the first pass, so no PM-miss cycles). Set-up: 10.
    """
    kw = kh if kw is None else kw
    return int(h * w * (kh * kw + 3) + h * 3 + 10)
