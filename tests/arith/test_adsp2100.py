"""ADSP-2100 data path against the manual's documented behaviour and exact rational arithmetic."""
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from numba import njit
from scipy import signal

from flightsw.arith import adsp2100 as dsp

words = st.integers(0, 0xFFFF)


def s16(w):
    return w - 0x10000 if w & 0x8000 else w


def s40(m):
    return m - (1 << 40) if m & (1 << 39) else m


def q15(w):
    return Fraction(s16(w), 1 << 15)


# ---------------------------------------------------------------- MAC
@pytest.mark.cases("flightsw.arith.adsp2100.product40", "signed")
@pytest.mark.cases("flightsw.arith.adsp2100._mac_k", "set")
def test_fractional_product_half_times_half():
    mr, mv = dsp.mac(0, 0x4000, 0x4000, op="=")
    assert mr == 0x00_2000_0000 and mv == 0          # 0.5 * 0.5 = 0.25 in MR1


@pytest.mark.cases("flightsw.arith.adsp2100.product40", "minus-one-squared")
@pytest.mark.cases("flightsw.arith.adsp2100._mac_k", "mv")
def test_minus_one_squared_follows_manual_not_mame():
    mr, mv = dsp.mac(0, 0x8000, 0x8000, op="=", signs="ss")
    assert dsp.DECISION_8000_SQUARED == "manual"
    assert (mr, mv) == (0x00_8000_0000, 1)            # +1.0 does not fit 1.31: MV set


@pytest.mark.cases("flightsw.arith.adsp2100.product40", "unsigned-as-signed")
def test_uu_product_is_taken_as_signed_32_bits():
    mr, _ = dsp.mac(0, 0xFFFF, 0xFFFF, op="=", signs="uu")
    assert s40(mr) == (0xFFFE0001 - (1 << 32)) * 2
    mr, _ = dsp.mac(0, 0x7FFF, 0x7FFF, op="=", signs="uu")
    assert s40(mr) == 0x7FFF * 0x7FFF * 2


@pytest.mark.cases("flightsw.arith.adsp2100.product40", "mixed")
def test_mixed_signedness():
    mr, _ = dsp.mac(0, 0xFFFF, 0x0002, op="=", signs="su")   # -1 * 2
    assert s40(mr) == -4
    mr, _ = dsp.mac(0, 0xFFFF, 0x0002, op="=", signs="us")   # 65535 * 2
    assert s40(mr) == 65535 * 2 * 2


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(words, words, st.sampled_from("+-")), min_size=1, max_size=255))
def test_accumulation_is_exact_rational_sum_and_mv_flags_overflow(terms):
    mr, exact = 0, Fraction(0)
    for x, y, op in terms:
        mr, mv = dsp.mac(mr, x, y, op=op)
        exact += (q15(x) * q15(y)) if op == "+" else -(q15(x) * q15(y))
    assert Fraction(s40(mr), 1 << 31) == exact                 # < 256 terms never wrap 40 bits
    assert mv == (not (-1 <= exact < 1))                        # MV: does not fit 1.31


@pytest.mark.cases("flightsw.arith.adsp2100._mac_k", "wrap-40")
def test_40_bit_wraparound_after_many_overflows():
    mr = 0
    for _ in range(300):                                        # 300 * (+1.0) = 2**31 * 300 > 2**39
        mr, mv = dsp.mac(mr, 0x8000, 0x8000)
    assert mr == (300 * (1 << 31)) & dsp.MASK40


@pytest.mark.cases("flightsw.arith.adsp2100._sat_mr_k", "no-mv", "positive", "negative")
def test_sat_mr_values():
    assert dsp.sat_mr(0x00_8000_0000) == 0x00_7FFF_FFFF
    assert dsp.sat_mr(0xFF_7FFF_FFFF) == 0xFF_8000_0000
    assert dsp.sat_mr(0x01_0000_0000) == 0x00_7FFF_FFFF
    assert dsp.sat_mr(0x80_0000_0000) == 0xFF_8000_0000        # MR2 MSB decides the sign
    assert dsp.sat_mr(0x00_1234_5678) == 0x00_1234_5678        # no MV: unchanged
    assert dsp.sat_mr(0xFF_FFFF_FFFF) == 0xFF_FFFF_FFFF


@settings(max_examples=300, deadline=None)
@given(st.integers(-(1 << 39), (1 << 39) - 1 - 0x8000))
def test_rnd_is_round_half_even_of_mr_over_2_16(v):
    out = dsp.rnd_mr(v & dsp.MASK40)
    expect = round(Fraction(v, 1 << 16))                        # Python rounds halves to even
    assert s40(out) >> 16 == expect
    assert out & 0xFFFF == ((v & 0xFFFF) + 0x8000) & 0xFFFF    # MR0 = old + 0x8000


@pytest.mark.cases("flightsw.arith.adsp2100.rnd40", "tie-even", "above-half")
@pytest.mark.cases("flightsw.arith.adsp2100._rnd_mr_k", "tie-even", "round")
def test_rnd_midpoints():
    assert dsp.rnd_mr(0x00_0001_8000) >> 16 == 0x0002          # 1.5 -> 2
    assert dsp.rnd_mr(0x00_0002_8000) >> 16 == 0x0002          # 2.5 -> 2
    assert dsp.rnd_mr(0x00_0002_8001) >> 16 == 0x0003


@pytest.mark.cases("flightsw.arith.adsp2100._mac_k", "rnd-tie-full-sum")
def test_rnd_midpoint_tests_full_sum_as_the_manual_says():
    # product low word 0x4000, MR low word 0x4000: the sum sits exactly on the midpoint
    mr, _ = dsp.mac(0x00_0000_4000, 0x2000, 0x0001, op="+", rnd=True)
    assert dsp.DECISION_RND_MIDPOINT == "full_sum"
    assert mr >> 16 == 0                                        # 0.5 rounds to even 0 (MAME: 1)


# ---------------------------------------------------------------- ALU
@settings(max_examples=500, deadline=None)
@given(words, words)
def test_alu_add_and_sub_flags_against_integer_arithmetic(x, y):
    ar, ac, av = dsp.alu_add(x, y)
    assert ar == (x + y) & 0xFFFF and ac == int(x + y > 0xFFFF)
    assert av == int(not -32768 <= s16(x) + s16(y) <= 32767)
    ar, ac, av = dsp.alu_sub(x, y)
    assert ar == (x - y) & 0xFFFF and ac == int(x >= y)         # carry = no borrow
    assert av == int(not -32768 <= s16(x) - s16(y) <= 32767)
    sat, _, _ = dsp.alu_add(x, y, ar_sat=True)
    assert s16(sat) == max(-32768, min(32767, s16(x) + s16(y)))
    sat, _, _ = dsp.alu_sub(x, y, ar_sat=True)
    assert s16(sat) == max(-32768, min(32767, s16(x) - s16(y)))


@pytest.mark.cases("flightsw.arith.adsp2100._alu_add_k", "sat-positive", "sat-negative")
def test_ar_sat_rule():
    assert dsp.alu_add(0x7FFF, 0x0001, ar_sat=True) == (0x7FFF, 0, 1)
    assert dsp.alu_add(0x8000, 0xFFFF, ar_sat=True) == (0x8000, 1, 1)


# ---------------------------------------------------------------- shifter
@settings(max_examples=300, deadline=None)
@given(words, st.integers(-40, 40))
def test_ashift_lshift_are_multiplications_by_powers_of_two(x, n):
    v = s16(x)
    a_hi = dsp.ashift(x, n, hi=True)
    exact = Fraction(v * (1 << 16)) * Fraction(2) ** n
    if n <= 0:
        assert (a_hi - (1 << 32) if a_hi & (1 << 31) else a_hi) == (exact.numerator // exact.denominator)
    l_lo = dsp.lshift(x, n, hi=False)
    assert l_lo == ((x << n) & 0xFFFFFFFF if n >= 0 else x >> -n) or abs(n) >= 32


@pytest.mark.cases("flightsw.arith.adsp2100._ashift_k", "right-off-scale", "left-off-scale")
@pytest.mark.cases("flightsw.arith.adsp2100._lshift_k", "right-off-scale")
def test_shift_off_scale_counts():
    assert dsp.ashift(0x8000, -40) == 0xFFFFFFFF                # all sign bits
    assert dsp.ashift(0x4000, -40) == 0
    assert dsp.lshift(0x8000, -40) == 0
    assert dsp.ashift(0x0001, 40) == 0


@settings(max_examples=300, deadline=None)
@given(words)
def test_exp_counts_redundant_sign_bits_and_norm_normalises(x):
    v = s16(x)
    redundant = 15 if v in (0, -1) else 15 - (v if v >= 0 else ~v).bit_length()
    se, ss = dsp.exp_hi(x)
    assert se == -redundant and ss == int(v < 0)
    sr = dsp.norm(x, se, hi=True)
    if v not in (0, -1):
        assert (sr >> 31) & 1 != (sr >> 30) & 1                 # normalised: sign != next bit
        assert sr == ((v << 16) << redundant) & 0xFFFFFFFF


@settings(max_examples=300, deadline=None)
@given(st.integers(-(1 << 31), (1 << 31) - 1))
def test_double_precision_exponent(v):
    hi, lo = (v >> 16) & 0xFFFF, v & 0xFFFF
    se, ss = dsp.exp_hi(hi)
    se = dsp.exp_lo(lo, se, ss)
    redundant = min(31, 31 - (v if v >= 0 else ~v).bit_length())
    assert se == -redundant


@pytest.mark.cases("flightsw.arith.adsp2100._exp_hi_k", "hix-overflow")
@pytest.mark.cases("flightsw.arith.adsp2100._norm_k", "hi-carry-right")
def test_exp_hix_after_overflow_and_norm_recovers_with_carry():
    ar, ac, av = dsp.alu_add(0x7000, 0x7000)                    # overflow: 0xE000, carry 0
    se, _ = dsp.exp_hi(ar, hix=True, av=av)
    assert se == 1
    sr = dsp.norm(ar, se, hi=True, ac=ac)
    assert sr >> 16 == 0x7000                                   # (0x7000 + 0x7000) / 2


@pytest.mark.cases("flightsw.arith.adsp2100._expadj_k", "initial", "larger")
def test_expadj_block_exponent():
    sb = -16
    for w in (0x0010, 0xFF00, 0x0200):
        sb = dsp.expadj(w, sb)
    assert sb == max(dsp.exp_hi(w)[0] for w in (0x0010, 0xFF00, 0x0200))


# ---------------------------------------------------------------- division
@settings(max_examples=400, deadline=None)
@given(st.integers(-(1 << 31), (1 << 31) - 1), st.integers(-32768, 32767))
def test_signed_division_within_one_lsb(dividend, divisor):
    if divisor == 0 or abs(dividend) >= abs(divisor) << 16:
        return
    q, _ = dsp.divide_signed((dividend >> 16) & 0xFFFF, dividend & 0xFFFF, divisor & 0xFFFF)
    exact = Fraction(dividend, 1 << 31) / Fraction(divisor, 1 << 15)   # 1.31 / 1.15 -> 1.15
    assert abs(Fraction(s16(q), 1 << 15) - exact) <= Fraction(1, 1 << 15)


@settings(max_examples=400, deadline=None)
@given(st.integers(0, (1 << 32) - 1), st.integers(1, 0x7FFF))
def test_unsigned_division_quotient(dividend, divisor):
    if dividend >> 16 >= divisor:
        with pytest.raises(ValueError):
            dsp.divide_unsigned(dividend >> 16, dividend & 0xFFFF, divisor)
        return
    q, _ = dsp.divide_unsigned(dividend >> 16, dividend & 0xFFFF, divisor)
    assert q == dividend // (2 * divisor)                       # same scaling as 1.31 / 1.15


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize("call", [
    lambda: dsp.mac(0, 0x10000, 1), lambda: dsp.mac(-1, 1, 1), lambda: dsp.mac(0, 1, 1, op="*"),
    lambda: dsp.mac(0, 1, 1, signs="xs"), lambda: dsp.alu_add(1.5, 1), lambda: dsp.sat_mr(1 << 40),
    lambda: dsp.ashift(1, 200), lambda: dsp.divide_signed(0, 0, 0)])
def test_bad_operands_raise_value_error_naming_the_value(call):
    with pytest.raises(ValueError):
        call()


def test_scalar_api_is_callable_from_njit():
    @njit
    def f(n):
        mr = 0
        for i in range(n):
            mr, mv = dsp.mac(mr, 0x4000, 0x4000, "+", "ss", False)
        mr = dsp.sat_mr(mr)
        ar, ac, av = dsp.alu_add(0x7FFF, 1, True)
        return mr, ar

    assert f(3) == (0x00_6000_0000, 0x7FFF)
    assert f(5) == (0x00_7FFF_FFFF, 0x7FFF)


# ---------------------------------------------------------------- array kernels
def _oracle_correlate(img, kern):
    """float64 SciPy correlation, scaled from Q1.15, rounded half-even and clipped to 16 bits."""
    exact = signal.correlate2d(img.astype(np.float64), kern.astype(np.float64), mode="valid") / 32768
    return np.clip(np.round(exact), -32768, 32767).astype(np.int16)


@pytest.mark.parametrize("k", [3, 5, 7])
@pytest.mark.cases("flightsw.arith.adsp2100.correlate_valid_q15", "typical")
def test_correlate_equals_rounded_scipy_on_12_bit_images(k):
    rng = np.random.default_rng(k)
    img = rng.integers(0, 4096, (70, 70)).astype(np.int16)
    kern = rng.integers(-32768, 32768, (k, k)).astype(np.int16)
    np.testing.assert_array_equal(dsp.correlate_valid_q15(img, kern), _oracle_correlate(img, kern))


@pytest.mark.cases("flightsw.arith.adsp2100.correlate_valid_q15", "saturate-high", "saturate-low")
def test_correlate_saturates_near_full_scale():
    img = np.full((9, 9), 32767, np.int16)
    kern = np.full((3, 3), 32767, np.int16)                     # sum ~ 9 * 32767: far over range
    out = dsp.correlate_valid_q15(img, kern)
    assert (out == 32767).all()
    assert (dsp.correlate_valid_q15(-img, kern) == -32768).all()
    np.testing.assert_array_equal(dsp.correlate_valid_q15(-img, kern), _oracle_correlate(-img, kern))


@pytest.mark.cases("flightsw.arith.adsp2100.dot_q15", "typical")
def test_dot_q15_matches_exact_rational_dot_product():
    rng = np.random.default_rng(1)
    x = rng.integers(-32768, 32768, 200)
    y = rng.integers(-32768, 32768, 200)
    exact = sum(Fraction(int(a), 1 << 15) * Fraction(int(b), 1 << 15) for a, b in zip(x, y))
    expect = max(-32768, min(32767, round(exact * (1 << 15))))
    assert dsp.dot_q15(x, y) == expect


def test_correlate_cycle_model():
    # 64x64 output, 7x7 kernel: 49 MACs + 3 per pixel, 3 per row, 10 set-up
    assert dsp.correlate_cycles(64, 64, 7) == 64 * 64 * 52 + 64 * 3 + 10
