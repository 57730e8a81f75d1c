"""The cases listed by the kernels of flightsw.arith.adsp2100, one hand-made input each.

Oracles: Python integer arithmetic on the two's-complement definitions (a shift is a floor
multiplication by a power of two, a sum is the exact sum), ``fractions.Fraction`` for the 1.31 /
1.15 values, Python's ``round`` (half to even) for the unbiased RND of the manual, and SciPy's
integer ``correlate2d`` for the correlation. Private kernels are reached through the public
instruction that calls them (``alu_add`` -> ``_alu_add_k``, ``exp_hi`` -> ``_exp_hi_k`` ->
``_redundant_sign_bits``, ...).
"""
from fractions import Fraction
import math

import numpy as np
import pytest
from scipy import signal

from flightsw.arith import adsp2100 as dsp

M32, M40 = (1 << 32) - 1, (1 << 40) - 1


def s16(w):
    w &= 0xFFFF
    return w - 0x10000 if w & 0x8000 else w


def s40(m):
    m &= M40
    return m - (1 << 40) if m & (1 << 39) else m


def redundant(v):
    """Redundant sign bits of a signed 16-bit value (0 and -1: 15)."""
    return 15 - (v if v >= 0 else ~v).bit_length()


def rnd_oracle(mr):
    """MR (RND) by the manual: MR1 rounded half to even from the 40-bit value, MR0 + 0x8000."""
    q = round(Fraction(s40(mr), 1 << 16))
    return ((q << 16) | ((mr + 0x8000) & 0xFFFF)) & M40


# ---------------------------------------------------------------- sign extension, MV
@pytest.mark.cases("flightsw.arith.adsp2100.s16", "positive", "negative", "wide-input")
@pytest.mark.cases("flightsw.arith.adsp2100.s40", "positive", "negative", "wide-input")
@pytest.mark.cases("flightsw.arith.adsp2100.mv_of", "fits", "overflow-positive",
                   "overflow-negative")
def test_sign_extension_and_mv():
    for w, v in [(0, 0), (0x7FFF, 32767), (0x8000, -32768), (0xFFFF, -1), (0x1FFFF, -1),
                 (0x10005, 5)]:
        assert dsp.s16(w) == v
    for m, v in [(0x7F_FFFF_FFFF, (1 << 39) - 1), (0x80_0000_0000, -(1 << 39)), (M40, -1),
                 ((1 << 40) | 5, 5), ((3 << 40) | M40, -1)]:
        assert dsp.s40(m) == v
    for m in [0, 0x00_7FFF_FFFF, 0xFF_8000_0000, M40, 0x00_8000_0000, 0x7F_FFFF_FFFF,
              0xFF_7FFF_FFFF, 0x80_0000_0000, 0x01_0000_0000]:
        assert dsp.mv_of(m) == int(not -(1 << 31) <= s40(m) < (1 << 31)), hex(m)


# ---------------------------------------------------------------- MAC, RND, SAT
@pytest.mark.cases("flightsw.arith.adsp2100.rnd40", "below-half", "above-half", "tie-even",
                   "wrap-40")
@pytest.mark.cases("flightsw.arith.adsp2100._rnd_mr_k", "round", "tie-even")
def test_rnd_cases():
    for mr in [0x00_0002_7FFF, 0x00_0002_8001, 0x00_0001_8000, 0x00_0002_8000, 0xFF_FFFF_8000,
               0x7F_FFFF_8001, 0x00_FFFF_8001, 0xFF_FFFE_8000, 0x80_0000_0000]:
        assert dsp.rnd_mr(mr) == rnd_oracle(mr), hex(mr)
    assert dsp.rnd_mr(0x00_0002_7FFF) >> 16 == 2 and dsp.rnd_mr(0x00_0002_8001) >> 16 == 3
    assert dsp.rnd_mr(0x7F_FFFF_8001) == 0x80_0000_0001                    # wraps negative
    assert dsp.rnd_mr(0xFF_FFFF_8000) == 0                                 # -0.5 -> 0 (even)


@pytest.mark.cases("flightsw.arith.adsp2100._mac_k", "set", "add", "sub", "mv")
def test_mac_ops():
    def val(mr):
        return Fraction(s40(mr), 1 << 31)
    half, q3 = 0x4000, 0x6000                                              # 0.5, 0.75
    mr, mv = dsp.mac(0x12_3456_789A, half, half, op="=")
    assert val(mr) == Fraction(1, 4) and mv == 0                          # old MR ignored
    mr, mv = dsp.mac(mr, half, q3, op="+")
    assert val(mr) == Fraction(1, 4) + Fraction(3, 8) and mv == 0
    mr, mv = dsp.mac(mr, q3, q3, op="-")
    assert val(mr) == Fraction(5, 8) - Fraction(9, 16) and mv == 0
    mr, mv = dsp.mac(0, half, half, op="-")
    assert val(mr) == -Fraction(1, 4)
    mr, mv = dsp.mac(dsp.mac(0, q3, 0x7FFF, op="=")[0], q3, 0x7FFF, op="+")
    assert val(mr) == 2 * Fraction(3, 4) * Fraction(0x7FFF, 1 << 15) and mv == 1   # > 1.0
    mr, mv = dsp.mac(mr, 0x8000, 0x7FFF, op="-")                            # still > 1.0
    assert mv == 1 and mr == (mr & M40) and val(mr) > 1
    mr, mv = dsp.mac(0xFF_0000_0000, 0, 0, op="+")                          # -2.0: MV, no SAT
    assert (mr, mv) == (0xFF_0000_0000, 1)


@pytest.mark.cases("flightsw.arith.adsp2100.product40", "signed")
def test_product40_direct():
    for x in (0x4000, 0x8000, 0x7FFF, 0xFFFF, 0x1234):
        for y in (0x4000, 0x8001, 0x0003):
            assert dsp.product40(x, y, True, True) == 2 * s16(x) * s16(y)


# ---------------------------------------------------------------- ALU
@pytest.mark.cases("flightsw.arith.adsp2100._alu_add_k", "no-overflow", "carry",
                   "overflow-positive", "overflow-negative", "sat-positive", "sat-negative",
                   "sat-no-overflow")
@pytest.mark.cases("flightsw.arith.adsp2100._alu_sub_k", "no-overflow", "borrow",
                   "overflow-positive", "overflow-negative", "sat-positive", "sat-negative")
def test_alu_cases():
    def want(x, y, sub, sat):
        exact = s16(x) - s16(y) if sub else s16(x) + s16(y)
        carry = int(x >= y) if sub else int(x + y > 0xFFFF)
        av = int(not -32768 <= exact <= 32767)
        ar = max(-32768, min(32767, exact)) & 0xFFFF if sat else exact & 0xFFFF
        return ar, carry, av
    pairs = [(0x1234, 0x0001), (0xFFFF, 0x0001), (0x7FFF, 0x0001), (0x8000, 0xFFFF),
             (0x0003, 0x0005), (0x7FFF, 0xFFFF), (0x8000, 0x0001), (0x8000, 0x8000)]
    for x, y in pairs:
        for sat in (False, True):
            assert dsp.alu_add(x, y, sat) == want(x, y, False, sat), (x, y, sat)
            assert dsp.alu_sub(x, y, sat) == want(x, y, True, sat), (x, y, sat)
    assert dsp.alu_add(0xFFFF, 1) == (0, 1, 0)                             # carry, no overflow
    assert dsp.alu_add(0x7FFF, 1) == (0x8000, 0, 1)
    assert dsp.alu_add(0x8000, 0xFFFF) == (0x7FFF, 1, 1)
    assert dsp.alu_add(0x1234, 1, True) == (0x1235, 0, 0)
    assert dsp.alu_sub(3, 5) == (0xFFFE, 0, 0)                             # borrow: AC 0
    assert dsp.alu_sub(0x7FFF, 0xFFFF, True) == (0x7FFF, 0, 1)
    assert dsp.alu_sub(0x8000, 1, True) == (0x8000, 1, 1)


# ---------------------------------------------------------------- shifter
WORDS = [0x0000, 0x0001, 0x1234, 0x4000, 0x7FFF, 0x8000, 0xC001, 0xFFFF]


def _floor_shift(v, se):
    return math.floor(Fraction(v) * Fraction(2) ** se) & M32


@pytest.mark.cases("flightsw.arith.adsp2100._ashift_k", "hi", "lo", "left", "right", "zero-count",
                   "left-off-scale", "right-off-scale")
@pytest.mark.cases("flightsw.arith.adsp2100._lshift_k", "hi", "lo", "left", "right",
                   "left-off-scale", "right-off-scale")
def test_shifts_are_floor_multiplications():
    for x in WORDS:
        for se in range(-40, 41):
            assert dsp.ashift(x, se, hi=True) == _floor_shift(s16(x) << 16, se), (x, se)
            assert dsp.ashift(x, se, hi=False) == _floor_shift(s16(x), se), (x, se)
            assert dsp.lshift(x, se, hi=True) == _floor_shift(x << 16, se), (x, se)
            assert dsp.lshift(x, se, hi=False) == _floor_shift(x, se), (x, se)
    assert dsp.ashift(0x8000, 0, hi=False) == 0xFFFF_8000 and dsp.lshift(0x8000, 0, False) == 0x8000
    assert dsp.ashift(0x8000, -40) == M32 and dsp.ashift(0x7FFF, 32) == 0
    assert dsp.ashift(0x8000, -4) == 0xF800_0000 and dsp.lshift(0x8000, -4) == 0x0800_0000


@pytest.mark.cases("flightsw.arith.adsp2100._norm_k", "hi-left", "hi-carry-right", "hi-off-scale",
                   "lo-left", "lo-right", "lo-off-scale")
def test_norm_cases():
    for x in WORDS:
        for se in range(-40, 1):
            assert dsp.norm(x, se, hi=True) == _floor_shift(s16(x) << 16, -se), (x, se)
        for se in range(-40, 41):
            assert dsp.norm(x, se, hi=False) == _floor_shift(x, -se), (x, se)
    # an overflowed ALU sum: the true 17-bit value is AR - 2**16 * AC; NORM by +1 halves it
    for a, b in [(0x7000, 0x7000), (0x8000, 0x8000), (0x8001, 0x8000), (0x7FFF, 0x7FFF)]:
        ar, ac, av = dsp.alu_add(a, b)
        assert av == 1
        true = s16(a) + s16(b)
        assert true == ar - (ac << 16)
        assert dsp.norm(ar, 1, hi=True, ac=ac) == _floor_shift(true << 16, -1)


# ---------------------------------------------------------------- exponents
@pytest.mark.cases("flightsw.arith.adsp2100._exp_hi_k", "typical", "all-sign", "hix-overflow",
                   "hix-no-overflow")
@pytest.mark.cases("flightsw.arith.adsp2100._redundant_sign_bits", "positive", "negative",
                   "normalised", "all-sign")
def test_exp_hi_cases():
    for x, r in [(0x0010, 10), (0xFF00, 7), (0x4000, 0), (0x7FFF, 0), (0x8000, 0), (0xBFFF, 0),
                 (0x0000, 15), (0xFFFF, 15), (0x0001, 14), (0xFFFE, 14)]:
        assert redundant(s16(x)) == r
        assert dsp.exp_hi(x) == (-r, x >> 15)
        assert dsp.exp_hi(x, hix=True, av=0) == (-r, x >> 15)
    assert dsp.exp_hi(0xE000, hix=True, av=1) == (1, 0)      # overflowed positive sum
    assert dsp.exp_hi(0x0000, hix=True, av=1) == (1, 1)      # 0x8000 + 0x8000: negative


@pytest.mark.cases("flightsw.arith.adsp2100._exp_lo_k", "hi-decided", "positive-continue",
                   "negative-continue", "all-sign")
def test_exp_lo_cases():
    for v in [0x1234_5678, 0x0000_0100, 0x0000_8000, 0x0000_0001, 0, -1, -256, -(1 << 15) - 1,
              -(1 << 16), 0x0001_0000, -0x12345]:
        hi, lo = (v >> 16) & 0xFFFF, v & 0xFFFF
        se, ss = dsp.exp_hi(hi)
        want = -(31 - (v if v >= 0 else ~v).bit_length())
        assert dsp.exp_lo(lo, se, ss) == want, hex(v)
    assert dsp.exp_lo(0x0000, -3, 0) == -3                   # HI decided: LO leaves SE alone
    assert dsp.exp_lo(0, -15, 0) == -31 and dsp.exp_lo(0xFFFF, -15, 1) == -31


@pytest.mark.cases("flightsw.arith.adsp2100._expadj_k", "larger", "not-larger", "initial")
def test_expadj_cases():
    assert dsp.expadj(0x0001, -16) == -14                    # initial: taken
    assert dsp.expadj(0x0001, -3) == -3                      # -14 <= -3: kept
    assert dsp.expadj(0xC000, -3) == -1                      # -1 > -3: taken
    assert dsp.expadj(0x0000, -16) == -15


# ---------------------------------------------------------------- division
@pytest.mark.cases("flightsw.arith.adsp2100._divide_signed_k", "positive", "negative-dividend",
                   "negative-divisor", "both-negative")
@pytest.mark.cases("flightsw.arith.adsp2100._divs_k", "same-sign", "different-sign")
@pytest.mark.cases("flightsw.arith.adsp2100._divq_k", "subtract", "add")
def test_divide_signed_quadrants():
    for n, d in [(0x1000_0000, 0x4000), (0x2345_6789, 0x7000), (0x0000_1234, 0x0100)]:
        for sn, sd in [(1, 1), (-1, 1), (1, -1), (-1, -1)]:
            num, den = sn * n, sd * d
            q, _ = dsp.divide_signed((num >> 16) & 0xFFFF, num & 0xFFFF, den & 0xFFFF)
            exact = Fraction(num, 1 << 31) / Fraction(den, 1 << 15)
            assert abs(Fraction(s16(q), 1 << 15) - exact) <= Fraction(1, 1 << 15), (num, den)
            assert (s16(q) < 0) == (exact < 0) or abs(exact) < Fraction(1, 1 << 15)
    # the first step by the manual: AQ = sign(AF) XOR sign(X), AF:AY0 << 1 with AQ into AY0
    assert dsp.divs(0x1000, 0x8001, 0x4000) == (0x2001, 0x0002, 0)
    assert dsp.divs(0x1000, 0x8001, 0xC000) == (0x2001, 0x0003, 1)
    # one step: AQ = 0 subtracts X, AQ = 1 adds it; the quotient bit is NOT the new AQ
    assert dsp.divq(0x3000, 0x0000, 0x1000, 0) == (0x4000, 0x0001, 0)      # 0x2000 << 1
    assert dsp.divq(0x3000, 0x8000, 0x1000, 1) == (0x8001, 0x0001, 0)      # 0x4000 << 1 | 1


@pytest.mark.cases("flightsw.arith.adsp2100._divide_unsigned_k", "typical", "zero-dividend",
                   "max-quotient")
def test_divide_unsigned_cases():
    for hi, lo, d in [(0x0012, 0x3456, 0x0100), (0, 0, 0x7FFF), (0x7FFE, 0xFFFF, 0x7FFF),
                      (0, 0xFFFF, 1), (4, 0x0001, 5)]:
        q, _ = dsp.divide_unsigned(hi, lo, d)
        assert q == ((hi << 16) | lo) // (2 * d)
    assert dsp.divide_unsigned(0, 0, 3)[0] == 0
    assert dsp.divide_unsigned(0x7FFE, 0xFFFF, 0x7FFF)[0] == 0x7FFF


# ---------------------------------------------------------------- array kernels
@pytest.mark.cases("flightsw.arith.adsp2100.block_bitlen", "empty", "all-sign", "positive",
                   "negative", "extremes")
@pytest.mark.cases("flightsw.arith.adsp2100.bitlen", "zero", "positive")
def test_block_bitlen_and_bitlen():
    for vals, shape in [([], (0,)), ([0, -1, 0, -1], (2, 2)), ([3, 100, -5], (3,)),
                        ([-256, 3], (2,)), ([-257, 0], (1, 2)), ([32767], (1,)),
                        ([-32768, 1], (2,))]:
        img = np.array(vals, np.int16).reshape(shape)
        want = max([(v if v >= 0 else ~v).bit_length() for v in vals], default=0)
        assert dsp.block_bitlen(img) == want, vals
    assert [dsp.bitlen(v) for v in (0, 1, 0x7FFF, 1 << 40)] == [0, 1, 15, 41]


@pytest.mark.cases("flightsw.arith.adsp2100.finish_mr", "truncate", "round-tie-even", "round",
                   "sat-positive", "sat-negative", "no-sat-wrap", "wrap-40")
def test_finish_mr_cases():
    def want(acc, rnd, sat):
        v = Fraction(s40(acc), 1 << 16)                  # MR / 2**16, MR the 40-bit wrap of acc
        q = round(v) if rnd else math.floor(v)           # MR2:MR1 after (RND), half to even
        q24 = (q + (1 << 23)) % (1 << 24) - (1 << 23)    # ... in 24 bits (RND may wrap MR)
        if sat and not -32768 <= q24 < 32768:            # MV of the rounded MR
            return 32767 if q24 > 0 else -32768
        return s16(q & 0xFFFF)
    accs = [3 * 65536 + 0xFFFF, -1, 3 * 65536 + 0x8001, 3 * 65536 + 0x7FFF, 3 * 65536 + 0x8000,
            2 * 65536 + 0x8000, 1 << 31, -(1 << 32), -(1 << 31), (1 << 40) + 5 * 65536,
            (1 << 31) - 0x8000, -(3 << 38)]
    for acc in accs:
        for rnd in (False, True):
            for sat in (False, True):
                assert dsp.finish_mr(acc, rnd, sat) == want(acc, rnd, sat), (acc, rnd, sat)
    assert dsp.finish_mr(3 * 65536 + 0x8000, True, True) == 4
    assert dsp.finish_mr(2 * 65536 + 0x8000, True, True) == 2
    assert dsp.finish_mr(1 << 31, False, True) == 32767 and dsp.finish_mr(1 << 31, False, False) \
        == -32768
    assert dsp.finish_mr(-(1 << 32), True, True) == -32768
    assert dsp.finish_mr((1 << 40) + 5 * 65536, True, True) == 5


@pytest.mark.cases("flightsw.arith.adsp2100.dot_q15", "empty", "saturate", "no-rnd", "no-sat")
def test_dot_q15_cases():
    z = np.zeros(0, np.int64)
    assert dsp.dot_q15(z, z) == 0
    big = np.full(3, 32767, np.int64)
    assert dsp.dot_q15(big, big) == 32767
    assert dsp.dot_q15(np.full(2, -32768, np.int64), np.full(2, 32767, np.int64)) == -32768
    one, neg = np.array([1], np.int64), np.array([-1], np.int64)
    assert dsp.dot_q15(one, one, False, True) == 0 and dsp.dot_q15(neg, one, False, True) == -1
    assert dsp.dot_q15(neg, one, True, True) == 0                      # -2**-30 rounds to 0
    acc = 3 * 32767 * 32767 * 2                                        # about 3.0 in 1.31
    assert dsp.dot_q15(big, big, True, False) == s16(round(Fraction(acc, 1 << 16)) & 0xFFFF)


@pytest.mark.cases("flightsw.arith.adsp2100.correlate_valid_q15", "single-output", "rectangular",
                   "no-rnd-no-sat")
def test_correlate_shapes_and_raw_store():
    rng = np.random.default_rng(7)
    img = rng.integers(-32768, 32768, (10, 12)).astype(np.int16)
    kern = rng.integers(-32768, 32768, (3, 5)).astype(np.int16)
    exact = signal.correlate2d(img.astype(np.int64), kern.astype(np.int64), mode="valid")
    assert exact.shape == (8, 8)
    rounded = [[max(-32768, min(32767, round(Fraction(int(v), 1 << 15)))) for v in row]
               for row in exact]
    assert dsp.correlate_valid_q15(img, kern).tolist() == rounded
    raw = [[s16(((int(v) * 2) & M40) >> 16) for v in row] for row in exact]      # floor, wrap
    assert dsp.correlate_valid_q15(img, kern, False, False).tolist() == raw
    one = dsp.correlate_valid_q15(img[:3, :5], kern)
    assert one.shape == (1, 1) and one[0, 0] == rounded[0][0]
