"""The cases listed by the kernels of flightsw.arith.m1750_float, one hand-made input each.

Oracles: the standard's words (MIL-STD-1750A Table III / IV and the overflow results of 5.60 ff.)
and exact rational arithmetic (``fractions.Fraction``) on values built here from the format
definition of 4.1.5 / 4.1.6, independently of the module's packers and encoders. Where a kernel is
private the test drives it through the public instruction that calls it (``fa32`` -> ``_fa32_k`` ->
``_add_core`` -> ``_finish``); a few kernels that no public path can reach in a given case are
called directly.
"""
import math
from fractions import Fraction

import numpy as np
import pytest

import flightsw.arith.m1750_float as mf

OV, UN, FX = 0x1000, 0x0200, 0x0800          # PI bits of levels 3, 6, 4 (bit 0 = MSB)
MAX32, MIN32, MAX48, MIN48 = 0x7FFFFF7F, 0x8000007F, 0x7FFFFF7FFFFF, 0x8000007F0000
ADD = {23: (mf.fa32, mf.fs32), 39: (mf.fa48, mf.fs48)}
MUL = {23: mf.fm32, 39: mf.fm48}
DIV = {23: mf.fd32, 39: mf.fd48}
OVW = {23: (MAX32, MIN32), 39: (MAX48, MIN48)}


def value(p, W):
    """Exact value of a packed word (4.1.5 / 4.1.6 field layout)."""
    if W == 23:
        m, e = (p >> 8) & 0xFFFFFF, p & 0xFF
    else:
        m, e = (((p >> 24) & 0xFFFFFF) << 16) | (p & 0xFFFF), (p >> 16) & 0xFF
    m -= (1 << (W + 1)) if m >> W else 0
    e -= 256 if e & 0x80 else 0
    return Fraction(m, 1 << W) * Fraction(2) ** e


def _fields(m, e, W):
    if W == 23:
        return ((m % (1 << 24)) << 8) | (e % 256)
    m40 = m % (1 << 40)
    return ((m40 >> 16) << 24) | ((e % 256) << 16) | (m40 & 0xFFFF)


def floor_word(q, W):
    """The largest normalised W-bit-fraction word <= q (q exact, exponent in range)."""
    q = Fraction(q)
    if q == 0:
        return 0
    e = 0
    while abs(q) >= Fraction(2) ** e:
        e += 1
    while abs(q) < Fraction(2) ** (e - 1):
        e -= 1
    m = math.floor(q * Fraction(2) ** (W - e))
    if m == -(1 << (W - 1)):                  # -0.5 is not normalised: -1.0 * 2**(e-1)
        m, e = -(1 << W), e - 1
    assert -128 <= e <= 127
    return _fields(m, e, W)


def word(q, W):
    """The word of an exactly representable q."""
    w = floor_word(q, W)
    assert value(w, W) == Fraction(q), q
    return w


P2 = Fraction(2)


# ------------------------------------------------------------------------------------------------
# unpack / pack
# ------------------------------------------------------------------------------------------------
@pytest.mark.cases("flightsw.arith.m1750_float.unpack32", "positive", "negative-mantissa",
                   "negative-exponent", "zero")
@pytest.mark.cases("flightsw.arith.m1750_float.unpack48", "positive", "negative-mantissa",
                   "negative-exponent", "zero")
@pytest.mark.cases("flightsw.arith.m1750_float.pack32", "positive", "negative")
@pytest.mark.cases("flightsw.arith.m1750_float.pack48", "positive", "negative")
@pytest.mark.cases("flightsw.arith.m1750_float.unpack_w", "w23", "w39")
@pytest.mark.cases("flightsw.arith.m1750_float.pack_w", "w23", "w39")
def test_unpack_pack_standard_words():
    # Table III / IV words and their (mantissa, exponent) read off the printed values
    t32 = [(0x40000001, 1 << 22, 1), (0x80000000, -(1 << 23), 0), (0x40000080, 1 << 22, -128),
           (0, 0, 0), (0x9FFFFF04, -0x600001, 4), (0x7FFFFF7F, (1 << 23) - 1, 127)]
    t48 = [(0x400000010000, 1 << 38, 1), (0x800000800000, -(1 << 39), -128),
           (0xA00000FF0000, -(3 << 37), -1), (0, 0, 0), (0x400000000001, (1 << 38) + 1, 0)]
    for W, table, unpack, pack in ((23, t32, mf.unpack32, mf.pack32),
                                   (39, t48, mf.unpack48, mf.pack48)):
        for p, m, e in table:
            assert value(p, W) == Fraction(m, 1 << W) * P2 ** e
            assert unpack(p) == (m, e) and mf.unpack_w(p, W) == (m, e)
            assert pack(m, e) == p and mf.pack_w(m, e, W) == p


# ------------------------------------------------------------------------------------------------
# normalisation, overflow words, the finishing step
# ------------------------------------------------------------------------------------------------
def _norm_oracle(m, W):
    s = 0
    while not ((1 << (W - 1)) <= (m << s) < (1 << W) or -(1 << W) <= (m << s) < -(1 << (W - 1))):
        s += 1
    return s


@pytest.mark.cases("flightsw.arith.m1750_float.norm_shift", "normalised", "positive", "negative",
                   "minus-power-of-two")
def test_norm_shift():
    cases = {"normalised": [1 << 22, (1 << 23) - 1, -(1 << 23), -(1 << 22) - 1],
             "positive": [1 << 21, 1, 0x123456 >> 3],
             "negative": [-3 << 20, -1, -0x123456 >> 2],
             "minus-power-of-two": [-(1 << 22), -(1 << 21), -(1 << 5)]}
    want = {"normalised": [0, 0, 0, 0], "positive": [1, 22, None], "negative": [1, 23, None],
            "minus-power-of-two": [1, 2, 18]}
    for case, ms in cases.items():
        for m, w in zip(ms, want[case]):
            s = mf.norm_shift(m, 23)
            assert s == _norm_oracle(m, 23) and (w is None or s == w), (case, m)
    # a double-length product (W = 46) and a 40-bit mantissa
    assert mf.norm_shift(1 << 44, 46) == 1 and mf.norm_shift(-(1 << 37), 39) == 2


@pytest.mark.cases("flightsw.arith.m1750_float.overflow_word", "positive-32", "negative-32",
                   "positive-48", "negative-48")
def test_overflow_words_are_the_standards():
    assert value(MAX32, 23) == (1 - P2 ** -23) * P2 ** 127 and value(MIN32, 23) == -P2 ** 127
    assert (mf.overflow_word(False, 23), mf.overflow_word(True, 23)) == (0x7FFFFF7F, 0x8000007F)
    assert (mf.overflow_word(False, 39), mf.overflow_word(True, 39)) == (0x7FFFFF7FFFFF,
                                                                          0x8000007F0000)


@pytest.mark.cases("flightsw.arith.m1750_float._finish", "overflow")
def test_finish_overflow_direct():
    # no instruction passes an exponent above 127 to _finish: called directly
    assert mf._finish(1 << 22, 128, 23) == (MAX32, OV)
    assert mf._finish(-(1 << 39), 200, 39) == (MIN48, OV)
    assert mf._finish(1 << 20, 129, 23) == (word(P2 ** 126, 23), 0)     # normalised back in range


# ------------------------------------------------------------------------------------------------
# FA / FS
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._add_core", "a-zero", "b-zero", "align-b",
                   "align-a", "far-operand", "mantissa-overflow", "overflow", "cancel-zero",
                   "cancel-normalise", "subtract-negate-first", "subtract-minus-one")
@pytest.mark.cases("flightsw.arith.m1750_float._finish", "zero", "normalised", "normalise-shift")
@pytest.mark.cases("flightsw.arith.m1750_float._overflow", "positive", "negative")
@pytest.mark.cases("flightsw.arith.m1750_float._fa32_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fs32_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fa48_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fs48_k", "typical")
def test_add_sub_cases(W):
    fa, fs = ADD[W]
    w = lambda q: word(q, W)                                       # noqa: E731
    ulp1 = P2 ** (1 - W)                                           # one unit of 1.0's last place
    x = w(Fraction(-5, 2))
    assert fa(0, x) == (x, 0) and fs(0, x) == (w(Fraction(5, 2)), 0)             # a-zero
    assert fa(w(Fraction(13, 4)), 0) == (w(Fraction(13, 4)), 0)                  # b-zero
    assert fs(w(Fraction(13, 4)), 0) == (w(Fraction(13, 4)), 0)
    tiny = P2 ** (-W - 17)
    assert fa(w(1), w(-tiny)) == (w(1 - ulp1), 0)                  # align-b: -tiny costs 1 unit
    assert fa(w(1), w(tiny)) == (w(1), 0)                          # +tiny is lost
    assert fa(w(-tiny), w(1)) == (w(1 - ulp1), 0)                  # align-a
    assert fa(w(Fraction(1, 2)), w(4)) == (w(Fraction(9, 2)), 0)   # EA <- EO
    assert fa(w(1), w(-P2 ** -100)) == (w(1 - ulp1), 0)            # far-operand: shift capped
    assert fa(w(1), w(P2 ** -100)) == (w(1), 0)
    assert fa(w(P2 ** -100), w(1)) == (w(1), 0)
    assert fa(w(Fraction(3, 4)), w(Fraction(3, 4))) == (w(Fraction(3, 2)), 0)    # mantissa ovf
    assert fa(w(-1), w(-1)) == (w(-2), 0)
    assert fa(OVW[W][0], OVW[W][0]) == (OVW[W][0], OV)             # overflow, positive
    assert fa(OVW[W][1], OVW[W][1]) == (OVW[W][1], OV)             # overflow, negative
    assert fs(w(3), w(3)) == (0, 0) and fa(w(3), w(-3)) == (0, 0)  # cancel-zero
    assert fs(w(1), w(Fraction(3, 4))) == (w(Fraction(1, 4)), 0)   # cancel-normalise
    assert fs(w(1), w(1 - ulp1)) == (w(ulp1), 0)
    assert fa(w(Fraction(1, 2)), w(Fraction(1, 4))) == (w(Fraction(3, 4)), 0)    # normalised
    # FS: the subtrahend negated before it is aligned -> truncated toward minus infinity
    r, f = fs(w(1), w(Fraction(1, 2) + P2 ** -W))
    assert (r, f) == (w(Fraction(1, 2) - 2 * P2 ** -W), 0)
    assert value(r, W) < Fraction(1, 2) - P2 ** -W                 # below the exact difference
    assert fs(0, w(-1)) == (w(1), 0)                               # subtract-minus-one
    assert fs(w(Fraction(1, 2)), w(-1)) == (w(Fraction(3, 2)), 0)
    assert fs(0, OVW[W][1]) == (OVW[W][0], OV)                     # -(-1.0 * 2**127) overflows


@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._add_core", "underflow")
@pytest.mark.cases("flightsw.arith.m1750_float._finish", "underflow")
def test_add_underflow(W):
    fa, fs = ADD[W]
    a, b = word(Fraction(3, 4) * P2 ** -128, W), word(Fraction(1, 2) * P2 ** -128, W)
    assert fs(a, b) == (0, UN)                     # 0.25 * 2**-128 needs exponent -129
    assert fa(a, word(-Fraction(5, 8) * P2 ** -128, W)) == (0, UN)    # 0.125 * 2**-128


# ------------------------------------------------------------------------------------------------
# FM / EFM
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._mul_exp_checks", "overflow", "underflow",
                   "in-range")
@pytest.mark.cases("flightsw.arith.m1750_float._fm32_k", "zero-operand", "exp-overflow",
                   "exp-underflow", "minus-one-squared", "minus-one-squared-overflow", "no-shift",
                   "one-shift", "negative-floor", "minus-half", "norm-underflow")
@pytest.mark.cases("flightsw.arith.m1750_float._fm48_k", "zero-operand", "exp-overflow",
                   "exp-underflow", "minus-one-squared", "minus-one-squared-overflow",
                   "positive-no-shift", "positive-shift", "negative-no-shift", "negative-shift",
                   "minus-half", "norm-underflow")
def test_mul_cases(W):
    fm = MUL[W]
    w = lambda q: word(q, W)                                       # noqa: E731
    assert fm(0, OVW[W][0]) == (0, 0) and fm(w(P2 ** -128 / 2), 0) == (0, 0)      # zero-operand
    big = w(P2 ** 63)                                              # 0.5 * 2**64
    assert fm(big, big) == (OVW[W][0], OV)                         # n = 128 although 2**126 fits
    assert fm(w(-Fraction(3, 4) * P2 ** 64), big) == (OVW[W][1], OV)
    assert fm(w(P2 ** -100), w(P2 ** -100)) == (0, UN)             # n = -198
    assert fm(w(-P2 ** 5), w(-P2 ** 7)) == (w(P2 ** 12), 0)        # (-1.0)(-1.0), n + 1
    assert fm(w(-P2 ** 63), w(-P2 ** 64)) == (OVW[W][0], OV)       # ... at n = 127
    assert fm(w(Fraction(3, 4)), w(Fraction(3, 4))) == (w(Fraction(9, 16)), 0)    # no shift
    assert fm(w(Fraction(1, 2)), w(Fraction(1, 2))) == (w(Fraction(1, 4)), 0)     # one shift
    assert fm(w(-1), w(Fraction(1, 2))) == (w(-Fraction(1, 2)), 0)                # minus-half
    assert value(fm(w(-1), w(Fraction(1, 2)))[0], W) == -Fraction(1, 2)
    # inexact products, all four sign/shift combinations: truncated toward minus infinity
    u = P2 ** -W
    for a, b in [(1 - u, 1 - u), (Fraction(1, 2) + u, Fraction(1, 2) + u),
                 (1 - u, -(1 - u)), (Fraction(1, 2) + u, -(Fraction(1, 2) + u)),
                 (Fraction(1, 2) + u, -(1 - 3 * u))]:
        r, f = fm(w(a), w(b))
        assert f == 0 and r == floor_word(a * b, W), (a, b)
        assert value(r, W) < a * b                                 # inexact: strictly below
    tiny = w(P2 ** -128 / 2)                                       # 0.5 * 2**-128
    assert fm(tiny, w(Fraction(1, 2))) == (0, UN)                  # 0.25 * 2**-128: norm-underflow
    assert fm(tiny, w(1)) == (tiny, 0)                             # n = -127 + 1 ... in range


@pytest.mark.cases("flightsw.arith.m1750_float.prod80", "zero", "typical", "max", "carry")
def test_prod80_is_the_exact_product():
    top = 1 << 39
    assert mf.prod80(0, top) == (0, 0) and mf.prod80(top, 0) == (0, 0)
    assert mf.prod80(top, top) == (1 << 38, 0)
    rng = np.random.default_rng(80)
    pairs = [(int(a), int(b)) for a, b in rng.integers(0, top + 1, (200, 2))]
    pairs += [(top - 1, top - 1), ((1 << 20) - 1, (1 << 20) - 1), (top - 1, (1 << 20) + 12345)]
    carried = 0
    for a, b in pairs:
        assert mf.prod80(a, b) == divmod(a * b, 1 << 40), (a, b)
        # carry: the limb products below 2**40 sum past it (what the 20-bit split must carry)
        m20 = (1 << 20) - 1
        mid = (a >> 20) * (b & m20) + (a & m20) * (b >> 20)
        carried += ((mid & m20) << 20) + (a & m20) * (b & m20) >= 1 << 40
    assert carried > 0


# ------------------------------------------------------------------------------------------------
# FD / EFD
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._div_core", "divide-by-zero", "exp-overflow",
                   "exp-underflow", "zero-dividend", "no-shift", "quotient-shift",
                   "shift-overflow", "minus-one", "minus-half", "minus-half-underflow",
                   "negative-floor")
@pytest.mark.cases("flightsw.arith.m1750_float._fd32_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fd48_k", "typical")
def test_div_cases(W):
    fd = DIV[W]
    w = lambda q: word(q, W)                                       # noqa: E731
    assert fd(w(1), 0) == (OVW[W][0], OV) and fd(w(-3), 0) == (OVW[W][1], OV)
    assert fd(0, 0) == (OVW[W][0], OV)
    assert fd(w(P2 ** 100), w(P2 ** -100)) == (OVW[W][0], OV)
    assert fd(w(-P2 ** 100), w(P2 ** -100)) == (OVW[W][1], OV)
    assert fd(w(P2 ** -100), w(P2 ** 100)) == (0, UN)
    assert fd(0, w(P2 ** -120)) == (0, 0)                          # no exponent check on zero
    assert fd(w(Fraction(9, 16)), w(Fraction(3, 4))) == (w(Fraction(3, 4)), 0)    # no shift
    assert fd(w(Fraction(3, 4)), w(Fraction(1, 2))) == (w(Fraction(3, 2)), 0)     # shift
    assert fd(w(-Fraction(3, 4)), w(Fraction(1, 2))) == (w(-Fraction(3, 2)), 0)
    big = w(Fraction(3, 4) * P2 ** 127)
    assert fd(big, w(Fraction(1, 2))) == (OVW[W][0], OV)           # shift at n = 127
    assert fd(big, w(-Fraction(5, 8))) == (OVW[W][1], OV)           # -1.2 * 2**127
    assert fd(w(Fraction(3, 4)), w(-Fraction(3, 4))) == (w(-1), 0)                # minus-one
    assert fd(w(Fraction(1, 2)), w(-1)) == (w(-Fraction(1, 2)), 0)                # minus-half
    assert fd(w(P2 ** -129), w(-1)) == (0, UN)                     # -0.5 at n = -128
    for a, b in [(1, 3), (-1, 3), (1, -3), (2, 7), (-5, 9)]:       # inexact, floor
        r, f = fd(w(a), w(b))
        assert f == 0 and r == floor_word(Fraction(a, b), W)
        assert value(r, W) < Fraction(a, b)


def _estimate_w39(A, B):
    """The float64 estimate of floor(A * 2**40 / B) (IEEE division, exact scaling, truncation)."""
    return (A.astype(np.float64) / B.astype(np.float64) * float(1 << 40)).astype(np.int64)


@pytest.mark.cases("flightsw.arith.m1750_float._quotient_floor", "w23", "w39-estimate-exact",
                   "w39-estimate-high", "exact-quotient")
def test_quotient_floor_fix_up_branches():
    """Operand pairs whose float64 estimate is one too high and right: the kernel's quotient and
    sticky bit equal Python's integer division on each kind. No pair has an estimate one too low
    (the kernel's docstring says why): 0 of 60,000 here."""
    rng = np.random.default_rng(39)
    lo, hi = 1 << 38, 1 << 39
    A = rng.integers(lo, hi + 1, 60_000)
    B = rng.integers(lo, hi + 1, 60_000)
    est = _estimate_w39(A, B)
    exact = [(int(a) << 40) // int(b) for a, b in zip(A, B)]
    kinds = {"high": [], "low": [], "exact": []}
    for i, (e, q) in enumerate(zip(est.tolist(), exact)):
        kinds["high" if e > q else "low" if e < q else "exact"].append(i)
    assert len(kinds["high"]) > 0 and len(kinds["exact"]) > 0 and len(kinds["low"]) == 0
    for idx in kinds.values():
        for i in idx[:40]:
            a, b = int(A[i]), int(B[i])
            assert mf._quotient_floor(a, b, 39) == ((a << 40) // b, (a << 40) % b != 0)
    for a, b, W in [(lo, hi, 39), (hi, lo, 39), (3 << 37, 3 << 36, 39), (1 << 22, 3 << 21, 23),
                    (5 << 20, 1 << 23, 23), (1 << 23, 1 << 23, 23)]:
        q, s = mf._quotient_floor(a, b, W)
        assert (q, s) == ((a << (W + 1)) // b, (a << (W + 1)) % b != 0)
    assert mf._quotient_floor(lo, hi, 39) == (1 << 39, False)                    # exact


# ------------------------------------------------------------------------------------------------
# FABS / FNEG, FIX / FLT, FC
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._fabs_core", "non-negative", "negative",
                   "minus-one", "overflow")
@pytest.mark.cases("flightsw.arith.m1750_float._fneg_core", "zero", "typical", "minus-one",
                   "minus-one-overflow", "half", "half-underflow")
@pytest.mark.cases("flightsw.arith.m1750_float._fabs32_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fabs48_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fneg32_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fneg48_k", "typical")
def test_fabs_fneg_cases(W):
    fabs, fneg = (mf.fabs32, mf.fneg32) if W == 23 else (mf.fabs48, mf.fneg48)
    w = lambda q: word(q, W)                                       # noqa: E731
    for q in (Fraction(5, 2), P2 ** -128 / 2, 0):
        assert fabs(w(q)) == (w(q), 0)                             # non-negative: unchanged
    assert fabs(w(Fraction(-5, 2))) == (w(Fraction(5, 2)), 0)
    assert fabs(w(-P2 ** 3)) == (w(P2 ** 3), 0)                    # -1.0 * 2**3 -> 0.5 * 2**4
    assert fabs(OVW[W][1]) == (OVW[W][0], OV)
    assert fneg(0) == (0, 0)
    assert fneg(w(Fraction(5, 2))) == (w(Fraction(-5, 2)), 0)
    assert fneg(w(Fraction(-3, 4))) == (w(Fraction(3, 4)), 0)
    assert fneg(w(-P2 ** 3)) == (w(P2 ** 3), 0)
    assert fneg(OVW[W][1]) == (OVW[W][0], OV)
    assert fneg(w(P2 ** 4)) == (w(-P2 ** 4), 0)                    # 0.5 * 2**5 -> -1.0 * 2**4
    assert fneg(w(P2 ** -129)) == (0, UN)                          # 0.5 * 2**-128


@pytest.mark.cases("flightsw.arith.m1750_float._fix32_k", "overflow", "positive", "negative",
                   "minus-32768", "tiny", "zero")
@pytest.mark.cases("flightsw.arith.m1750_float._fix48_k", "overflow", "positive", "negative",
                   "minus-2-31", "tiny", "zero")
def test_fix_cases():
    for fix, W, bits in ((mf.fix32, 23, 16), (mf.fix48, 39, 32)):
        w = lambda q: word(q, W)                                   # noqa: E731
        mask = (1 << bits) - 1
        assert fix(w(P2 ** (bits - 1))) == (0, FX)                 # exponent bits > 15 / 31
        assert fix(w(-P2 ** (bits - 1) - P2 ** (bits - 2))) == (0, FX)
        assert fix(w(P2 ** (bits - 1) - Fraction(1, 4))) == ((1 << (bits - 1)) - 1, 0)
        assert fix(w(Fraction(-3, 2))) == (mask, 0)                # -1, toward zero
        assert fix(w(Fraction(-7, 2))) == (-3 & mask, 0)
        assert fix(w(Fraction(3, 4))) == (0, 0) and fix(w(Fraction(-3, 4))) == (0, 0)
        assert fix(w(-P2 ** (bits - 1))) == (1 << (bits - 1), 0)   # -32768 / -2**31 fit
        for q in (P2 ** -129, -P2 ** -128, P2 ** -60):             # shift capped at 63
            assert fix(w(q)) == (0, 0)
        assert fix(0) == (0, 0)


@pytest.mark.cases("flightsw.arith.m1750_float._flt32_k", "zero", "positive", "negative")
@pytest.mark.cases("flightsw.arith.m1750_float._flt48_k", "zero", "positive", "negative")
def test_flt_cases():
    for flt, W, bits in ((mf.flt32, 23, 16), (mf.flt48, 39, 32)):
        assert flt(0) == (0, 0)
        for i in (1, 3, 1000, (1 << (bits - 1)) - 1):
            assert flt(i) == (word(i, W), 0)
        for i in (-1, -3, -(1 << (bits - 1)), -12345):
            assert flt(i & ((1 << bits) - 1)) == (word(i, W), 0)
    assert mf.flt32(0x8000) == (0x8000000F, 0) and mf.flt48(0x80000000) == (0x8000001F0000, 0)


@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._fc_core", "sign-differs", "both-zero",
                   "exponent-differs", "mantissa-differs", "equal")
@pytest.mark.cases("flightsw.arith.m1750_float._fc32_k", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float._fc48_k", "typical")
def test_fc_cases(W):
    fc = mf.fc32 if W == 23 else mf.fc48
    qs = [0, P2 ** -129, -P2 ** -128, Fraction(1, 2), Fraction(3, 4), 2, 3, -2, -3,
          Fraction(-1, 2), Fraction(-3, 4), P2 ** 126, -P2 ** 127]
    for a in qs:
        for b in qs:
            assert fc(word(a, W), word(b, W)) == (a > b) - (a < b), (a, b)


# ------------------------------------------------------------------------------------------------
# width conversions
# ------------------------------------------------------------------------------------------------
@pytest.mark.cases("flightsw.arith.m1750_float.to48", "typical")
@pytest.mark.cases("flightsw.arith.m1750_float.to32", "exact", "truncate-positive",
                   "truncate-negative")
def test_to48_to32():
    for q in (Fraction(1, 2), 2, Fraction(-5, 2), -P2 ** 127, P2 ** -129):
        assert mf.to48(word(q, 23)) == word(q, 39)
        assert mf.to32(word(q, 39)) == word(q, 23)
    u = P2 ** -39
    for q in (Fraction(1, 2) + u, 1 - u, -Fraction(1, 2) - u, -1 + u, Fraction(-3, 4) - 5 * u):
        r = mf.to32(word(q, 39))
        assert r == floor_word(q, 23) and value(r, 23) < q


# ------------------------------------------------------------------------------------------------
# encoders and decoders
# ------------------------------------------------------------------------------------------------
def _enc_oracle(x, W, nearest):
    """enc_mantissa from exact rationals: frexp's exponent, the scaled value floored or rounded
    half to even (Python's round of a Fraction), then the carry and minus-half rules."""
    _, e = math.frexp(x)
    v = Fraction(x) * P2 ** (W - e)
    mi = round(v) if nearest else math.floor(v)
    if mi >= 1 << W:
        mi, e = mi >> 1, e + 1
    if mi == -(1 << (W - 1)):
        mi, e = -(1 << W), e - 1
    return mi, e


@pytest.mark.cases("flightsw.arith.m1750_float.enc_mantissa", "exact", "floor", "nearest",
                   "nearest-tie-even", "round-up-carry", "minus-half", "subnormal")
def test_enc_mantissa_against_exact_rationals():
    """Random doubles of every magnitude and sign, the half-unit ties and their neighbours of
    both widths, powers of two and subnormals, against :func:`_enc_oracle`."""
    rng = np.random.default_rng(7)
    xs = list(rng.standard_normal(1500) * 10.0 ** rng.integers(-300, 300, 1500))
    xs += [math.ldexp(float(k), int(s)) for k, s in zip(rng.integers(1, 2 ** 53, 300),
                                                       rng.integers(-1100, 900, 300))]
    for W in (23, 39):
        for k in range(1, 64):                       # ties: half a unit of 24 / 40 bits
            t = math.ldexp(float((1 << W) + 2 * k + 1), -W - 1) * (1 + (k % 3))
            xs += [t, math.nextafter(t, 0.0), math.nextafter(t, math.inf)]
    xs += [2.0 ** k for k in range(-1070, 1020, 37)] + [5e-324, 2.2e-308, 1e-310, 2.0 ** -1074]
    xs += [-x for x in xs]
    for W in (23, 39):
        for nearest in (False, True):
            for x in xs:
                assert mf.enc_mantissa(x, W, nearest) == _enc_oracle(x, W, nearest), (x, W)


def test_enc_mantissa():
    for W in (23, 39):
        def v(mi, e):
            return Fraction(mi) * P2 ** (e - W)
        assert mf.enc_mantissa(10.0, W, False) == (5 << (W - 3), 4)               # exact
        for x in (1 / 3, -1 / 3, 1e-30, -7e20):
            mi, e = mf.enc_mantissa(x, W, False)
            assert (1 << (W - 1)) <= abs(mi) <= (1 << W)
            assert v(mi, e) <= Fraction(x) < v(mi + 1, e)                         # floor
            mi, e = mf.enc_mantissa(x, W, True)
            assert abs(v(mi, e) - Fraction(x)) <= v(1, e) / 2                     # nearest
        unit = P2 ** (1 - W)                                       # unit of 1.0's last place
        assert mf.enc_mantissa(float(1 + unit / 2), W, True) == (1 << (W - 1), 1)   # tie, even
        assert mf.enc_mantissa(float(1 + 3 * unit / 2), W, True) == ((1 << (W - 1)) + 2, 1)
        assert mf.enc_mantissa(float(1 + unit / 2), W, False) == (1 << (W - 1), 1)
        assert mf.enc_mantissa(1 - 2.0 ** -45, W, True) == (1 << (W - 1), 1)   # carry to 1.0
        assert mf.enc_mantissa(-4.0, W, False) == (-(1 << W), 2)               # -0.5 * 2**3
        assert mf.enc_mantissa(-4.0 - 2.0 ** -48, W, True) == (-(1 << W), 2)   # rounded to it


@pytest.mark.cases("flightsw.arith.m1750_float._enc_k", "zero", "typical-32", "typical-48",
                   "underflow", "overflow-32", "overflow-48")
@pytest.mark.cases("flightsw.arith.m1750_float._enc_array_k", "all-finite", "non-finite", "empty")
def test_enc_kernels():
    x = np.array([10.0, -2.5, 0.0, -0.0, 0.5, -1.0, 1e39, -1e39, 1e-40, -1e-45])
    want32 = [0x50000004, word(-2.5, 23), 0, 0, 0x40000000, 0x80000000, MAX32, MIN32, 0, 0]
    want48 = [word(10, 39), word(-2.5, 39), 0, 0, 0x400000000000, 0x800000000000, MAX48, MIN48,
              0, 0]
    for W, want in ((23, want32), (39, want48)):
        assert [mf.encode_k(float(v), W, False) for v in x] == want
        out = np.full(x.size, -7, np.int64)
        assert mf._enc_array_k(x, W, False, out) and out.tolist() == want
        for bad in (np.nan, np.inf, -np.inf):
            out = np.full(3, -7, np.int64)
            assert not mf._enc_array_k(np.array([1.0, bad, 2.0]), W, True, out)
            assert out.tolist() == [-7, -7, -7]                    # nothing written
        assert mf._enc_array_k(np.empty(0), W, False, np.empty(0, np.int64))
    assert mf.encode_k(1e300, 39, True) == MAX48 and mf.encode_k(-1e300, 39, True) == MIN48


@pytest.mark.cases("flightsw.arith.m1750_float._dec32_k", "zero", "typical", "exponent-extremes")
@pytest.mark.cases("flightsw.arith.m1750_float._dec48_k", "zero", "typical", "exponent-extremes")
@pytest.mark.cases("flightsw.arith.m1750_float._dec_array_k", "w23", "w39", "empty")
def test_dec_kernels():
    w32 = [0, 0x40000001, 0x9FFFFF04, 0x50000004, 0x40000080, 0xBFFFFF80, 0x7FFFFF7F, 0x8000007F]
    w48 = [0, 0x400000010000, 0xA00000FF0000, 0x400000000001, 0x400000800000, 0x7FFFFF7FFFFF,
           0x8000007F0000, 0xBFFFFF80FFFF]
    for W, words, dec in ((23, w32, mf.decode32_k), (39, w48, mf.decode48_k)):
        want = [float(value(p, W)) for p in words]
        assert [Fraction(float(v)) for v in want] == [value(p, W) for p in words]   # exact
        assert [dec(p) for p in words] == want
        arr = (mf.decode32_array if W == 23 else mf.decode48_array)(np.array(words, np.int64))
        assert arr.tolist() == want
        out = np.full(0, 1.0)
        mf._dec_array_k(np.empty(0, np.int64), W, out)
        assert out.size == 0


@pytest.mark.cases("flightsw.arith.m1750_float._norm32_k", "zero", "zero-mantissa", "normalised",
                   "not-normalised")
@pytest.mark.cases("flightsw.arith.m1750_float._norm48_k", "zero", "zero-mantissa", "normalised",
                   "not-normalised")
def test_norm_kernels():
    # 4.1.5: normalised iff bits 0 and 1 of the mantissa differ; zero only as all-zero words
    for p, ok in [(0, True), (0x00000005, False), (0x40000001, True), (0x80000000, True),
                  (0x7FFFFF7F, True), (0xBFFFFF80, True), (0x20000000, False),
                  (0xC0000000, False), (0xFFFFFF00, False)]:
        assert mf.is_normalized32_k(p) is ok, hex(p)
    for p, ok in [(0, True), (0x000000010000, False), (0x400000000000, True),
                  (0x800000800000, True), (0xC00000000000, False), (0x200000000001, False),
                  (0x000000000001, False), (0xFFFFFF00FFFF, False)]:
        assert mf.is_normalized48_k(p) is ok, hex(p)
