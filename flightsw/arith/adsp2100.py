"""ADSP-2100 data path, bit-exact: MAC, ALU, shifter, divide primitives, and the MAC array kernels.

Registers travel as their bit patterns: 16-bit words as ints ``0..0xFFFF``, the 40-bit MAC result
register MR (= MR2:MR1:MR0) as an int ``0..2**40-1``, the shifter result SR (= SR1:SR0) as an int
``0..2**32-1``. Sources are ``docs/processors.md`` section A (the 1995 ADSP-2100 Family
User's Manual [A1], MAME's ``2100ops.hxx`` [A2], and the adsp-2100_sv research notes [A3]).

Decisions where sources conflict (each follows the manual, as docs/processors.md asks):

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
  32 bits (docs/processors.md: "the product is treated as signed"): a UU product with bit 31 set comes
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
from flightsw.numba_cache import KERNEL, callee_kernel

DECISION_8000_SQUARED = "manual"
DECISION_RND_MIDPOINT = "full_sum"

#: instruction cycles of each primitive (every ADSP-2100 instruction is one cycle, docs/processors.md A)
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
@callee_kernel
def s16(w):
    """Sign-extend a 16-bit pattern to a Python/numba int.

    Cases
    -----
    positive : 0..0x7FFF -> 0..32767.
    negative : 0x8000..0xFFFF -> -32768..-1.
    wide-input : bits above 15 are ignored (0x1FFFF -> -1).
    """
    w = w & 0xFFFF
    return w - 0x10000 if w & 0x8000 else w


@callee_kernel
def s40(mr):
    """Sign-extend a 40-bit MR pattern.

    Cases
    -----
    positive : MR2 MSB 0 -> 0..2**39-1.
    negative : MR2 MSB 1 -> -2**39..-1.
    wide-input : bits above 39 are ignored.
    """
    mr = mr & 0xFFFFFFFFFF
    return mr - 0x10000000000 if mr & 0x8000000000 else mr


@callee_kernel
def mv_of(mr):
    """MV condition: MR bits 39..31 not all equal (the value does not fit 32-bit MR1:MR0).

    Cases
    -----
    fits : bits 39..31 all 0 or all 1 (-1.0 <= MR < 1.0 in 1.31) -> 0.
    overflow-positive : a positive MR of 2**31 or more -> 1.
    overflow-negative : a negative MR below -2**31 -> 1.
    """
    top = (mr >> 31) & 0x1FF
    return 1 if (top != 0 and top != 0x1FF) else 0


@callee_kernel
def product40(x, y, x_signed, y_signed):
    """The multiplier's contribution to MR: 16x16 product, taken as signed 32 bits, sign-extended to
    40 bits and shifted left one bit (fractional mode). Returns the signed value (no masking).

    Cases
    -----
    signed : SS: the signed product times 2 (0x4000 * 0x4000 -> 2**29, 0.25 in 1.31).
    mixed : SU/US: the signed operand times the unsigned one, times 2.
    unsigned-as-signed : UU: the true product with bit 31 set is read as negative 32 bits
        (0xFFFF * 0xFFFF -> (0xFFFE0001 - 2**32) * 2).
    minus-one-squared : SS 0x8000 * 0x8000 -> +2**31 (+1.0, which does not fit 1.31: the caller's
        MV is set; the manual's reading, not MAME's).
    """
    xv = s16(x) if x_signed else (x & 0xFFFF)
    yv = s16(y) if y_signed else (y & 0xFFFF)
    p = (xv * yv) & 0xFFFFFFFF
    if p & 0x80000000:
        p -= 0x100000000
    return p << 1


@callee_kernel
def rnd40(res, lo_unrounded):
    """Unbiased rounding at the MR0/MR1 boundary of a 40-bit value (both as patterns): add 0x8000; if
    the unrounded low word ``lo_unrounded`` was exactly 0x8000, clear bit 16. MR0 keeps
    ``old + 0x8000``.

    Cases
    -----
    below-half : low word < 0x8000 -> MR1 unchanged.
    above-half : low word > 0x8000 -> MR1 + 1 (carrying into MR2).
    tie-even : low word = 0x8000 -> MR1 rounded to even (1.5 -> 2, 2.5 -> 2).
    wrap-40 : the sum leaves 40 bits -> reduced mod 2**40 (7F_FFFF_8001 -> 80_0000_0001, which
        reads negative; FF_FFFF_8000 -> 0).
    """
    res = (res + 0x8000) & 0xFFFFFFFFFF
    if lo_unrounded == 0x8000:
        res &= ~0x10000 & 0xFFFFFFFFFF
    return res


@njit(**KERNEL)
def _mac_k(mr, x, y, op, x_signed, y_signed, rnd):
    """One MAC instruction on patterns -> (new MR pattern, MV); see :func:`mac`.

    Cases
    -----
    set : op 0, ``MR = X*Y``: the old MR is ignored.
    add : op 1, ``MR = MR + X*Y``.
    sub : op 2, ``MR = MR - X*Y``.
    mv : the result does not fit 1.31 (MR[39:31] not all equal) -> MV = 1, MR not saturated.
    wrap-40 : the accumulation leaves 40 bits (over 255 products of +1.0) -> reduced mod 2**40.
    rnd-tie-full-sum : ``(RND)``: the midpoint test is on the full sum's low word (MR 0x4000 plus
        product 0x4000 -> exactly 0x8000 -> rounds to even), not on the product's.
    """
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


@njit(**KERNEL)
def _sat_mr_k(mr):
    """``IF MV SAT MR`` on a 40-bit pattern -> the new MR pattern.

    Cases
    -----
    no-mv : MR fits 1.31 -> unchanged.
    positive : MV and MR2 MSB 0 -> 00_7FFF_FFFF.
    negative : MV and MR2 MSB 1 -> FF_8000_0000.
    """
    if mv_of(mr):
        return 0xFF80000000 if (mr >> 39) & 1 else 0x007FFFFFFF
    return mr


@njit(**KERNEL)
def _rnd_mr_k(mr):
    """``MR = MR (RND)`` on a 40-bit pattern: :func:`rnd40` with MR's own low word.

    Cases
    -----
    round : low word not 0x8000 -> MR1 rounded to nearest, MR0 = old + 0x8000.
    tie-even : low word 0x8000 -> MR1 rounded to even.
    """
    return rnd40(mr, mr & 0xFFFF)


@njit(**KERNEL)
def _alu_add_k(x, y, ar_sat):
    """``AR = X + Y`` on 16-bit patterns -> (AR, AC, AV); see :func:`alu_add`.

    Cases
    -----
    no-overflow : the signed sum fits -> AR = sum, AV = 0.
    carry : the unsigned sum exceeds 0xFFFF -> AC = 1 (0xFFFF + 1 -> 0, AC 1, AV 0).
    overflow-positive : two positives give a negative AR -> AV = 1, AR wrapped.
    overflow-negative : two negatives give a positive AR -> AV = 1, AC = 1, AR wrapped.
    sat-positive : AR_SAT, AV = 1, AC = 0 -> 0x7FFF.
    sat-negative : AR_SAT, AV = 1, AC = 1 -> 0x8000.
    sat-no-overflow : AR_SAT without overflow -> AR is the plain sum.
    """
    r = x + y
    ac = (r >> 16) & 1
    r &= 0xFFFF
    av = 1 if ((x ^ r) & (y ^ r) & 0x8000) else 0
    if ar_sat and av:
        r = 0x8000 if ac else 0x7FFF
    return r, ac, av


@njit(**KERNEL)
def _alu_sub_k(x, y, ar_sat):
    """``AR = X - Y`` (X + NOT Y + 1) on 16-bit patterns -> (AR, AC, AV); see :func:`alu_sub`.

    Cases
    -----
    no-overflow : the signed difference fits -> AR = difference, AV = 0.
    borrow : X < Y as unsigned -> AC = 0 (AC is NOT borrow); X >= Y -> AC = 1.
    overflow-positive : positive minus negative gives a negative AR -> AV = 1.
    overflow-negative : negative minus positive gives a positive AR -> AV = 1.
    sat-positive : AR_SAT, AV = 1, AC = 0 -> 0x7FFF.
    sat-negative : AR_SAT, AV = 1, AC = 1 -> 0x8000.
    """
    r = x + ((~y) & 0xFFFF) + 1
    ac = (r >> 16) & 1          # carry = NOT borrow
    r &= 0xFFFF
    av = 1 if ((x ^ y) & (x ^ r) & 0x8000) else 0
    if ar_sat and av:
        r = 0x8000 if ac else 0x7FFF
    return r, ac, av


@njit(**KERNEL)
def _ashift_k(x, se, hi):
    """``SR = ASHIFT x BY se (HI|LO)`` -> the 32-bit SR pattern; see :func:`ashift`.

    Cases
    -----
    hi : HI: the word placed at SR[31:16] before the shift.
    lo : LO: the word sign-extended into SR[15:0] before the shift.
    left : 0 < se < 32 -> shifted left, bits above 31 lost.
    right : -32 < se < 0 -> shifted right, sign bits shifted in.
    zero-count : se = 0 -> the placed word.
    left-off-scale : se >= 32 -> 0.
    right-off-scale : se <= -32 -> all sign bits (0 or 0xFFFFFFFF).
    """
    xv = s16(x) << 16 if hi else s16(x)
    if se > 0:
        res = (xv << se) if se < 32 else 0
    else:
        res = (xv >> -se) if se > -32 else (xv >> 31)
    return res & 0xFFFFFFFF


@njit(**KERNEL)
def _lshift_k(x, se, hi):
    """``SR = LSHIFT x BY se (HI|LO)`` -> the 32-bit SR pattern; see :func:`lshift`.

    Cases
    -----
    hi : HI: the word placed at SR[31:16] before the shift.
    lo : LO: the word zero-extended into SR[15:0] (no sign extension).
    left : 0 < se < 32 -> shifted left, bits above 31 lost.
    right : -32 < se < 0 -> shifted right, zeros shifted in.
    left-off-scale : se >= 32 -> 0.
    right-off-scale : se <= -32 -> 0.
    """
    xv = (x & 0xFFFF) << 16 if hi else (x & 0xFFFF)
    if se > 0:
        res = (xv << se) if se < 32 else 0
    else:
        res = (xv >> -se) if se > -32 else 0
    return res & 0xFFFFFFFF


@njit(**KERNEL)
def _norm_k(x, se, hi, ac):
    """``SR = NORM x (HI|LO)`` with shift code ``se`` (left by ``-se``) -> the 32-bit SR pattern; see
    :func:`norm`.

    Cases
    -----
    hi-left : HI, se <= 0 -> the word at SR[31:16] shifted left by -se.
    hi-carry-right : HI, se > 0 (after EXP HIX of an overflow) -> shifted right, the ALU carry AC
        enters at the MSB (se = 1: AR 0xE000 with AC 0 -> 0x7000).
    hi-off-scale : HI, se <= -32 -> 0.
    lo-left : LO, se <= 0 -> the zero-extended word shifted left by -se.
    lo-right : LO, se > 0 -> the word shifted right logically.
    lo-off-scale : LO, |se| >= 32 -> 0.
    """
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


@callee_kernel
def _redundant_sign_bits(x):
    """Redundant sign bits of a 16-bit word (bits after the sign equal to it), 0..15.

    Cases
    -----
    positive : 0 < x -> the leading zeros after the sign bit (0x0010 -> 10).
    negative : x < 0 -> the leading ones after the sign bit (0xFF00 -> 7).
    normalised : 0x4000..0x7FFF, 0x8000..0xBFFF -> 0.
    all-sign : 0 or 0xFFFF -> 15 (the count stops at 15).
    """
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


@njit(**KERNEL)
def _exp_hi_k(x, hix, av):
    """``SE = EXP x (HI|HIX)`` -> (SE, SS); see :func:`exp_hi`.

    Cases
    -----
    typical : SE = -(redundant sign bits) in 0..-15, SS = the sign bit.
    all-sign : 0 or 0xFFFF -> SE = -15.
    hix-overflow : HIX with AV = 1 -> SE = +1 and SS = the inverted sign bit.
    hix-no-overflow : HIX with AV = 0 -> as HI.
    """
    ss = 1 if x & 0x8000 else 0
    if hix and av:
        # the value overflowed into the carry: one right shift (NORM HI) brings it back
        return 1, 1 - ss
    return -_redundant_sign_bits(x), ss


@njit(**KERNEL)
def _exp_lo_k(x, se, ss):
    """``SE = EXP x (LO)`` for the low word of a double-precision value -> the new SE; see
    :func:`exp_lo`.

    Cases
    -----
    hi-decided : se != -15 (the high word had a significant bit) -> se unchanged.
    positive-continue : se = -15, SS = 0 -> counts the low word's leading zeros on (-15..-31).
    negative-continue : se = -15, SS = 1 -> counts the low word's leading ones on (-15..-31).
    all-sign : a low word of sign bits only (0 with SS 0, 0xFFFF with SS 1) -> -31.
    """
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


@njit(**KERNEL)
def _expadj_k(x, sb):
    """``SB = EXPADJ x`` -> the new SB; see :func:`expadj`.

    Cases
    -----
    larger : the word's exponent (-redundant sign bits) above SB -> taken.
    not-larger : the word's exponent <= SB -> SB kept.
    initial : SB = -16 (the initial value) -> any word's exponent is taken.
    """
    e = -_redundant_sign_bits(x)
    return e if e > sb else sb


@callee_kernel
def _divs_k(af, ay0, x):
    """``DIVS AF, X`` -> (AF, AY0, AQ): AQ = sign(AF) XOR sign(X), AF:AY0 shifted left one bit with AQ
    entering AY0.

    Cases
    -----
    same-sign : dividend and divisor signs equal -> AQ = 0.
    different-sign : signs differ -> AQ = 1.
    """
    t = (x ^ af) & 0xFFFF
    aq = (t >> 15) & 1
    af_new = ((af << 1) | (ay0 >> 15)) & 0xFFFF
    ay0_new = ((ay0 << 1) | aq) & 0xFFFF
    return af_new, ay0_new, aq


@callee_kernel
def _divq_k(af, ay0, x, aq):
    """``DIVQ X`` -> (AF, AY0, AQ): one non-restoring step; the new quotient bit (NOT AQ) enters AY0.

    Cases
    -----
    subtract : AQ = 0 -> AF - X.
    add : AQ = 1 -> AF + X.
    """
    res = (af + x) if aq else (af - x)
    t = res ^ x
    aq_new = (t >> 15) & 1
    af_new = ((res << 1) | (ay0 >> 15)) & 0xFFFF
    ay0_new = ((ay0 << 1) | ((~t >> 15) & 1)) & 0xFFFF
    return af_new, ay0_new, aq_new


@njit(**KERNEL)
def _divide_signed_k(hi, lo, divisor):
    """DIVS + 15 DIVQ of ``hi:lo`` by ``divisor`` (patterns) -> (quotient AY0, partial remainder AF);
    see :func:`divide_signed`.

    Cases
    -----
    positive : dividend and divisor positive -> the 1.15 quotient within one LSB.
    negative-dividend : negative dividend, positive divisor -> negative quotient within one LSB.
    negative-divisor : positive dividend, negative divisor -> negative quotient within one LSB.
    both-negative : both negative -> positive quotient within one LSB.
    """
    af, ay0, aq = _divs_k(hi, lo, divisor)
    for _ in range(15):
        af, ay0, aq = _divq_k(af, ay0, divisor, aq)
    return ay0, af


@njit(**KERNEL)
def _divide_unsigned_k(hi, lo, divisor):
    """Cleared AQ + 16 DIVQ of ``hi:lo`` by ``divisor`` -> (quotient AY0, partial remainder AF); see
    :func:`divide_unsigned` (``1 <= divisor <= 0x7FFF``, ``hi < divisor``).

    Cases
    -----
    typical : quotient = floor((hi:lo) / (2 * divisor)).
    zero-dividend : 0 -> quotient 0.
    max-quotient : hi:lo = divisor * 2**16 - 1 -> the largest quotient, 0x7FFF.
    """
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


@overload(mac, jit_options=KERNEL)
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


@overload(sat_mr, jit_options=KERNEL)
def _sat_mr_ov(mr):
    return lambda mr: _sat_mr_k(mr)


def rnd_mr(mr):
    """``MR = MR (RND)``: unbiased rounding of MR at the MR0/MR1 boundary (round half to even);
    MR0 keeps ``old MR0 + 0x8000``. One cycle."""
    return int(_rnd_mr_k(_mr(mr)))


@overload(rnd_mr, jit_options=KERNEL)
def _rnd_mr_ov(mr):
    return lambda mr: _rnd_mr_k(mr)


def alu_add(x, y, ar_sat=False):
    """``AR = X + Y`` on 16-bit words. Returns ``(ar, ac, av)``.

    AC is the carry out of bit 15, AV the two's-complement overflow. With AR_SAT (MSTAT bit) an
    overflowed result saturates: AV=1, AC=0 -> 0x7FFF; AV=1, AC=1 -> 0x8000. One cycle."""
    return tuple(int(v) for v in _alu_add_k(_word("x", x), _word("y", y), bool(ar_sat)))


@overload(alu_add, jit_options=KERNEL)
def _alu_add_ov(x, y, ar_sat=False):
    return lambda x, y, ar_sat=False: _alu_add_k(x, y, ar_sat)


def alu_sub(x, y, ar_sat=False):
    """``AR = X - Y`` (computed as X + NOT Y + 1; AC is the carry, i.e. NOT borrow). Returns
    ``(ar, ac, av)`` with AR_SAT as in :func:`alu_add`. One cycle."""
    return tuple(int(v) for v in _alu_sub_k(_word("x", x), _word("y", y), bool(ar_sat)))


@overload(alu_sub, jit_options=KERNEL)
def _alu_sub_ov(x, y, ar_sat=False):
    return lambda x, y, ar_sat=False: _alu_sub_k(x, y, ar_sat)


def ashift(x, se, hi=True):
    """``SR = ASHIFT x BY se (HI|LO)``: arithmetic shift of a 16-bit word placed at SR[31:16] (HI) or
    SR[15:0] (LO, sign-extended), positive ``se`` = left. Off-scale counts give all sign bits (right)
    or zero (left). Returns the 32-bit SR pattern. One cycle."""
    return int(_ashift_k(_word("x", x), _count("se", se, -128, 127), bool(hi)))


@overload(ashift, jit_options=KERNEL)
def _ashift_ov(x, se, hi=True):
    return lambda x, se, hi=True: _ashift_k(x, se, hi)


def lshift(x, se, hi=True):
    """``SR = LSHIFT x BY se (HI|LO)``: logical shift, zero fill; as :func:`ashift` otherwise."""
    return int(_lshift_k(_word("x", x), _count("se", se, -128, 127), bool(hi)))


@overload(lshift, jit_options=KERNEL)
def _lshift_ov(x, se, hi=True):
    return lambda x, se, hi=True: _lshift_k(x, se, hi)


def norm(x, se, hi=True, ac=0):
    """``SR = NORM x (HI|LO)`` with shift code ``se`` as left by EXP (``se <= 0`` shifts left by
    ``-se``). ``se = +1`` after ``EXP (HIX)`` of an overflowed value shifts right one bit and fills the
    MSB from the ALU carry ``ac`` (HI only). Returns the 32-bit SR pattern. One cycle."""
    return int(_norm_k(_word("x", x), _count("se", se, -128, 127), bool(hi), _flag("ac", ac)))


@overload(norm, jit_options=KERNEL)
def _norm_ov(x, se, hi=True, ac=0):
    return lambda x, se, hi=True, ac=0: _norm_k(x, se, hi, ac)


def exp_hi(x, hix=False, av=0):
    """``SE = EXP x (HI|HIX)``: ``SE = -(redundant sign bits)``, 0..-15, and the sign SS. With HIX and
    ``av = 1`` (the ALU overflowed) SE = +1 and SS is the inverted sign. Returns ``(se, ss)``."""
    se, ss = _exp_hi_k(_word("x", x), bool(hix), _flag("av", av))
    return int(se), int(ss)


@overload(exp_hi, jit_options=KERNEL)
def _exp_hi_ov(x, hix=False, av=0):
    return lambda x, hix=False, av=0: _exp_hi_k(x, hix, av)


def exp_lo(x, se, ss):
    """``SE = EXP x (LO)`` for the low word of a double-precision value: acts only when the HI step
    gave ``se = -15``, then counts on into the low word (``-15..-31``) using the sign ``ss``."""
    return int(_exp_lo_k(_word("x", x), _count("se", se, -128, 127), _flag("ss", ss)))


@overload(exp_lo, jit_options=KERNEL)
def _exp_lo_ov(x, se, ss):
    return lambda x, se, ss: _exp_lo_k(x, se, ss)


def expadj(x, sb):
    """``SB = EXPADJ x``: block exponent; SB takes the word's exponent only if it is larger (initialise
    ``sb = -16``). Returns the new SB."""
    return int(_expadj_k(_word("x", x), _count("sb", sb, -16, 15)))


@overload(expadj, jit_options=KERNEL)
def _expadj_ov(x, sb):
    return lambda x, sb: _expadj_k(x, sb)


def divs(af, ay0, x):
    """``DIVS AF, X``: first step of signed division. Returns ``(af, ay0, aq)``."""
    return tuple(int(v) for v in _divs_k(_word("af", af), _word("ay0", ay0), _word("x", x)))


@overload(divs, jit_options=KERNEL)
def _divs_ov(af, ay0, x):
    return lambda af, ay0, x: _divs_k(af, ay0, x)


def divq(af, ay0, x, aq):
    """``DIVQ X``: one non-restoring quotient step. Returns ``(af, ay0, aq)``."""
    return tuple(int(v) for v in _divq_k(_word("af", af), _word("ay0", ay0), _word("x", x),
                                         _flag("aq", aq)))


@overload(divq, jit_options=KERNEL)
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


@overload(divide_signed, jit_options=KERNEL)
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


@overload(divide_unsigned, jit_options=KERNEL)
def _divide_unsigned_ov(hi, lo, divisor):
    return lambda hi, lo, divisor: _divide_unsigned_k(hi, lo, divisor)


# --------------------------------------------------------------------------------------------
# array kernels: the multiply-accumulate loops of the image processor
# --------------------------------------------------------------------------------------------
@callee_kernel
def block_bitlen(img):
    """Bit length of the largest-magnitude 16-bit word of ``img`` (``x`` for x >= 0, ``~x`` for
    x < 0): the block exponent an EXPADJ pass over the block yields, as a count of significant
    bits (0..15). ``img``: integer array, any shape, values in 16-bit range.

    Cases
    -----
    empty : no elements -> 0.
    all-sign : only 0 and -1 -> 0.
    positive : the largest positive word decides (bit length of x).
    negative : a negative word counts as ~x (-256 -> 8, -257 -> 9).
    extremes : 32767 or -32768 -> 15.
    """
    f = img.ravel()
    m = np.int32(0)
    for i in range(f.size):
        a = np.int32(f[i])
        m |= a ^ (a >> np.int32(15))
    return bitlen(m)


@callee_kernel
def bitlen(v):
    """Number of significant bits of a non-negative integer (0 for 0).

    Cases
    -----
    zero : 0 -> 0.
    positive : v > 0 -> its bit length (1 -> 1, 0x7FFF -> 15).
    """
    n = 0
    while v > 0:
        n += 1
        v >>= 1
    return n


@callee_kernel
def finish_mr(acc, rnd, sat):
    """Store step of a MAC loop: the 40-bit accumulation ``acc`` (signed int) -> the word MR1 holds
    after ``(RND)`` on the last MAC and ``IF MV SAT MR``. Returns a signed 16-bit value.

    Cases
    -----
    truncate : rnd False -> MR1 as is (the sum's floor at 2**-15 in Q1.15).
    round-tie-even : rnd True, low word 0x8000 -> rounded to even.
    round : rnd True, other low words -> rounded to nearest.
    sat-positive : sat True, MV, positive -> 32767.
    sat-negative : sat True, MV, negative -> -32768.
    no-sat-wrap : sat False, MV -> MR1 of the overflowed value (wrapped bits).
    wrap-40 : acc beyond 40 bits -> reduced mod 2**40 first, as the chip's MR wraps.
    """
    mr = acc & 0xFFFFFFFFFF
    if rnd:
        mr = rnd40(mr, mr & 0xFFFF)
    if sat and mv_of(mr):
        mr = 0xFF80000000 if (mr >> 39) & 1 else 0x007FFFFFFF
    return s16((mr >> 16) & 0xFFFF)


@callee_kernel
def dot_q15(x, y, rnd=True, sat=True):
    """MAC loop ``MR = sum x[i]*y[i]`` (SS, fractional mode), then RND and SAT, returning MR1.

    x, y : int16/int32/int64 arrays of signed 16-bit values. With Q1.15 operands the result is the
    Q1.15 dot product; with an integer x and a Q1.15 y it is the integer-scaled result. The 40-bit
    accumulator wraps exactly as on the chip (int64 holds every partial sum of <= 2**23 terms, and the
    final value is reduced to 40 bits). Cycles: ``len(x) + 2`` (MACs, SAT, store) plus loop set-up.

    Cases
    -----
    typical : the exact dot product rounded half to even at 2**-15.
    empty : no terms -> 0.
    saturate : the sum leaves [-1, 1) -> 32767 or -32768.
    no-rnd : rnd False -> the exact sum truncated toward minus infinity.
    no-sat : sat False -> the overflowed MR1 (wraps).
    """
    acc = 0
    for i in range(x.shape[0]):
        acc += (np.int64(x[i]) * np.int64(y[i])) << 1
    return finish_mr(acc, rnd, sat)


@callee_kernel
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

    Cases
    -----
    typical : every output equals the exact correlation rounded half to even (SciPy's, scaled).
    saturate-high : a sum at or above +1.0 -> 32767.
    saturate-low : a sum below -1.0 -> -32768.
    single-output : image the kernel's size -> a 1 x 1 output.
    rectangular : a k x k' kernel with k != k' -> (H, W) from each axis.
    no-rnd-no-sat : rnd and sat False -> truncated, wrapping MR1 as the chip stores it.
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
