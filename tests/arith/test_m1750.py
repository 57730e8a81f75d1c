"""MIL-STD-1750A float formats, float instructions and integer arithmetic (flightsw.arith.m1750).

Oracles: the standard's Table III/IV and exact rational arithmetic (fractions.Fraction) with the
rules of sections 4.1 and 5.55-5.95 re-stated independently here.
"""
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from numba import njit

from flightsw.arith import m1750 as m
from flightsw.arith.m1750_float import _quotient_floor

SET = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])

# ------------------------------------------------------------------------------------------------
# Table III (32-bit) and Table IV (48-bit) of MIL-STD-1750A: (value as printed, words)
# ------------------------------------------------------------------------------------------------
TABLE_III = [
    (0.9999998 * 2.0 ** 127, 0x7FFFFF7F, False),
    (0.5 * 2.0 ** 127, 0x4000007F, True),
    (0.625 * 2.0 ** 4, 0x50000004, True),
    (0.5 * 2.0 ** 1, 0x40000001, True),
    (0.5, 0x40000000, True),
    (0.5 * 2.0 ** -1, 0x400000FF, True),
    (0.5 * 2.0 ** -128, 0x40000080, True),
    (0.0, 0x00000000, True),
    (-1.0, 0x80000000, True),
    (-0.5000001 * 2.0 ** -128, 0xBFFFFF80, False),
    (-0.7500001 * 2.0 ** 4, 0x9FFFFF04, False),
]
TABLE_IV = [
    (0.5 * 2.0 ** 127, 0x4000007F0000), (0.5, 0x400000000000), (0.5 * 2.0 ** -1, 0x400000FF0000),
    (0.5 * 2.0 ** -128, 0x400000800000), (-1.0 * 2.0 ** 127, 0x8000007F0000),
    (-1.0, 0x800000000000), (-1.0 * 2.0 ** -1, 0x800000FF0000),
    (-1.0 * 2.0 ** -128, 0x800000800000), (0.0, 0x000000000000), (-0.75 * 2.0 ** -1, 0xA00000FF0000),
]


@pytest.mark.parametrize("value,word,exact", TABLE_III)
def test_table_iii_round_trip(value, word, exact):
    d = m.decode32(word)
    assert m.encode32(d) == word and m.encode32(d, rounding="nearest") == word
    if exact:
        assert d == value and m.encode32(value) == word
    else:   # the table prints 7 significant digits
        assert d == pytest.approx(value, rel=2e-7)
        assert abs(m.encode32(value, rounding="nearest") - word) <= 0x100   # 1 mantissa unit


@pytest.mark.parametrize("value,word", TABLE_IV)
def test_table_iv_round_trip(value, word):
    assert m.decode48(word) == value
    assert m.encode48(value) == word and m.encode48(value, rounding="nearest") == word
    # a 32-bit word is the 48-bit word without w2
    assert m.decode32(word >> 16) == value


# ------------------------------------------------------------------------------------------------
# independent reference model
# ------------------------------------------------------------------------------------------------
def parts(p, W):
    if W == 23:
        mm, e = (p >> 8) & 0xFFFFFF, p & 0xFF
    else:
        mm, e = (((p >> 24) & 0xFFFFFF) << 16) | (p & 0xFFFF), (p >> 16) & 0xFF
    if mm >> W:
        mm -= 1 << (W + 1)
    if e & 0x80:
        e -= 256
    return mm, e


def val(p, W):
    mm, e = parts(p, W)
    return Fraction(mm) * Fraction(2) ** (e - W)


def floor_norm(q, W):
    """Exact q -> (m, e) normalised, mantissa truncated toward minus infinity (no range check)."""
    if q == 0:
        return 0, 0
    e = 0
    a = abs(q)
    while a >= Fraction(2) ** e:
        e += 1
    while a < Fraction(2) ** (e - 1):
        e -= 1
    mm = math.floor(q * Fraction(2) ** (W - e))
    if mm == -(1 << (W - 1)):
        mm, e = -(1 << W), e - 1
    return mm, e


def ref_result(q, W):
    """Floor-rounded exact result with the standard's overflow/underflow -> (value, flags)."""
    mm, e = floor_norm(q, W)
    if mm == 0:
        return Fraction(0), 0
    if e > 127:
        return (val(m.MIN32, 23) if mm < 0 else val(m.MAX32, 23)) if W == 23 else \
            (val(m.MIN48, 39) if mm < 0 else val(m.MAX48, 39)), m.FLAG_FLOAT_OVERFLOW
    if e < -128:
        return Fraction(0), m.FLAG_FLOAT_UNDERFLOW
    return Fraction(mm) * Fraction(2) ** (e - W), 0


def floats(W, exp_lo=-128, exp_hi=127):
    top = 1 << W
    mant = st.one_of(st.integers(top >> 1, top - 1), st.integers(-top, -(top >> 1) - 1),
                     st.sampled_from([top >> 1, top - 1, -top, -(top >> 1) - 1]))
    pack = m.pack32.py_func if W == 23 else m.pack48.py_func
    nz = st.builds(lambda mm, e: pack(mm, e), mant, st.integers(exp_lo, exp_hi))
    return st.one_of(nz, st.just(0))


def close_pair(W):
    """Pairs with exponents within a few units (cancellation / alignment cases)."""
    return st.integers(-126, 125).flatmap(
        lambda e: st.tuples(floats(W, e, e), floats(W, max(-128, e - 3), min(127, e + 3))))


WIDTHS = {23: (m.fa32, m.fs32, m.fm32, m.fd32, m.decode32), 39: (m.fa48, m.fs48, m.fm48, m.fd48, m.decode48)}


def _check_add(a, b, W, sub):
    fa, fs = WIDTHS[W][0], WIDTHS[W][1]
    r, fl = (fs if sub else fa)(a, b)
    exact = val(a, W) - val(b, W) if sub else val(a, W) + val(b, W)
    got = val(r, W)
    ea, eb = parts(a, W)[1], parts(b, W)[1]
    if fl & m.FLAG_FLOAT_OVERFLOW:
        assert abs(exact) >= Fraction(2) ** 126
        assert r == ((m.MIN32 if exact < 0 else m.MAX32) if W == 23 else
                     (m.MIN48 if exact < 0 else m.MAX48))
        return
    if fl & m.FLAG_FLOAT_UNDERFLOW:
        assert r == 0 and abs(exact) < Fraction(2) ** -128
        return
    assert fl == 0
    assert got <= exact, "FA/FS result above the exact sum"
    # RTL without guard bits: below by less than one unit of the larger operand's last place
    emax = max(ea if parts(a, W)[0] else -999, eb if parts(b, W)[0] else -999)
    if emax > -999:   # (or of the result's, when the sum overflowed the mantissa and was shifted)
        er = parts(r, W)[1] if parts(r, W)[0] else emax
        assert exact - got < Fraction(2) ** (max(emax, er) - W)
    ref, _ = ref_result(exact, W)
    re = parts(r, W)[1]
    if parts(r, W)[0] and re >= emax:   # no cancellation: within 1 ulp of the floor-rounded sum
        assert ref - got <= Fraction(2) ** (re - W)


@SET
@given(close_pair(23))
def test_fa32_fs32_properties(ab):
    a, b = ab
    _check_add(a, b, 23, False)
    _check_add(a, b, 23, True)


@SET
@given(close_pair(39))
def test_fa48_fs48_properties(ab):
    a, b = ab
    _check_add(a, b, 39, False)
    _check_add(a, b, 39, True)


@SET
@given(floats(23), floats(23))
def test_fa32_far_operands(a, b):
    _check_add(a, b, 23, False)


def _expected_mul_div(a, b, W, op):
    """Reference for FM/FD: RTL pre-checks on the exponent sum/difference, then the exact result
    truncated toward minus infinity."""
    (ma, ea), (mb, eb) = parts(a, W), parts(b, W)
    ovf = (m.MIN32 if W == 23 else m.MIN48), (m.MAX32 if W == 23 else m.MAX48)
    if op == "mul":
        if ma == 0 or mb == 0:
            return 0, 0
        n = ea + eb
        if n > 127:
            return ovf[0] if (ma < 0) != (mb < 0) else ovf[1], m.FLAG_FLOAT_OVERFLOW
        if n < -128:
            return 0, m.FLAG_FLOAT_UNDERFLOW
        q = val(a, W) * val(b, W)
    else:
        if mb == 0:
            return (ovf[0] if ma < 0 else ovf[1]), m.FLAG_FLOAT_OVERFLOW
        if ma == 0:
            return 0, 0
        n = ea - eb
        if n > 127:
            return ovf[0] if (ma < 0) != (mb < 0) else ovf[1], m.FLAG_FLOAT_OVERFLOW
        if n < -128:
            return 0, m.FLAG_FLOAT_UNDERFLOW
        q = val(a, W) / val(b, W)
    v, fl = ref_result(q, W)
    return v, fl


@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.parametrize("op", ["mul", "div"])
def test_fm_fd_floor_exact(W, op):
    """FM/FD: exactly the exact product/quotient truncated toward minus infinity (so within one
    ulp and never above it), with the RTL's overflow/underflow rules."""
    fa, fs, fm, fd, dec = WIDTHS[W]
    fn = fm if op == "mul" else fd

    @SET
    @given(floats(W), floats(W))
    def check(a, b):
        r, fl = fn(a, b)
        ev, efl = _expected_mul_div(a, b, W, op)
        assert fl == efl
        if isinstance(ev, Fraction):
            assert val(r, W) == ev
            if fl == 0 and r:
                exact = val(a, W) * val(b, W) if op == "mul" else val(a, W) / val(b, W)
                assert val(r, W) <= exact < val(r, W) + Fraction(2) ** (parts(r, W)[1] - W)
        else:
            assert r == ev
    check()


# ------------------------------------------------------------------------------------------------
# encode / decode
# ------------------------------------------------------------------------------------------------
def _next_up_value(p, W):
    mm, e = parts(p, W)
    if p == 0:
        return Fraction(2) ** -129
    return Fraction(mm + 1) * Fraction(2) ** (e - W)


@SET
@given(st.floats(min_value=-1.7e38, max_value=1.7e38, allow_nan=False, allow_infinity=False))
def test_encode32_floor_is_largest_below(x):
    if x != 0 and abs(x) < 2.0 ** -127:
        return
    p = m.encode32(x)
    assert m.is_normalized32(p)
    v = Fraction(m.decode32(p))
    assert v <= Fraction(x) < _next_up_value(p, 23)
    pn = m.encode32(x, rounding="nearest")
    assert abs(Fraction(m.decode32(pn)) - Fraction(x)) <= abs(v - Fraction(x))


@SET
@given(st.floats(min_value=-1.7e38, max_value=1.7e38, allow_nan=False, allow_infinity=False))
def test_encode48_floor_is_largest_below(x):
    if x != 0 and abs(x) < 2.0 ** -127:
        return
    p = m.encode48(x)
    assert m.is_normalized48(p)
    v = Fraction(m.decode48(p))
    assert v <= Fraction(x) < _next_up_value(p, 39)


def test_encode_arrays_match_scalar():
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.standard_normal(500) * 10.0 ** rng.integers(-30, 30, 500),
                        [0.0, -0.5, 0.5, -1.0, 1.0, -0.25, 3.0, -3.0, 1e300, -1e300, 1e-300]])
    for rnd in ("floor", "nearest"):
        assert [m.encode32(float(v), rnd) for v in x] == list(m.encode32_array(x, rnd))
        assert [m.encode48(float(v), rnd) for v in x] == list(m.encode48_array(x, rnd))
    # the jitted decoders scale by a power-of-two table: check the exponent extremes too
    ext32 = [0x40000080, 0x80000080, 0xBFFFFF80, 0x7FFFFF7F, 0x8000007F, 0x4000007F]
    ext48 = [0x400000800000, 0x800000800000, 0xBFFFFF80FFFF, 0x7FFFFF7FFFFF, 0x8000007F0000]
    p = np.concatenate([m.encode32_array(x), ext32])
    assert np.array_equal(m.decode32_array(p), [m.decode32(int(w)) for w in p])
    p = np.concatenate([m.encode48_array(x), ext48])
    assert np.array_equal(m.decode48_array(p), [m.decode48(int(w)) for w in p])


@pytest.mark.cases("flightsw.arith.m1750_float._enc_k", "overflow-32", "overflow-48", "underflow")
def test_encode_out_of_range_and_errors():
    assert m.encode32(1e39) == m.MAX32 and m.encode32(-1e39) == m.MIN32
    assert m.encode48(1e300) == m.MAX48 and m.encode48(-1e300) == m.MIN48
    assert m.encode32(1e-40) == 0 and m.encode48(-1e-45) == 0
    assert m.encode32(-2.0 ** 127) == m.MIN32                        # exactly representable
    assert m.encode32(10) == 0x50000004 and m.encode32(2 ** 200) == m.MAX32   # ints, exact
    for bad in (float("nan"), float("inf"), -float("inf")):
        with pytest.raises(ValueError, match="nan|inf"):
            m.encode32(bad)
        with pytest.raises(ValueError, match="nan|inf"):
            m.encode48(bad)
    with pytest.raises(ValueError, match="rounding"):
        m.encode32(1.0, rounding="up")
    with pytest.raises(ValueError, match="0x20000000"):
        m.decode32(0x20000000)                 # mantissa 200000: not normalised
    with pytest.raises(ValueError, match="0x00000005"):
        m.decode32(0x00000005)                 # zero mantissa, non-zero exponent
    with pytest.raises(ValueError, match=str(2 ** 32)):
        m.decode32(2 ** 32)
    with pytest.raises(ValueError, match="-1"):
        m.decode48(-1)
    with pytest.raises(ValueError, match="0xc00000000000"):
        m.decode48(0xC00000000000)
    with pytest.raises(ValueError, match="0x30000000"):
        m.fa32(0x40000001, 0x60000000 >> 1)    # 0x30000000 is not normalised
    with pytest.raises(ValueError):
        m.fa32(1.0, 0x40000001)
    with pytest.raises(ValueError, match="65536"):
        m.flt32(65536)


# ------------------------------------------------------------------------------------------------
# overflow, underflow and the special cases of the RTL
# ------------------------------------------------------------------------------------------------
E32, E48, D32 = m.encode32, m.encode48, m.decode32
OV, UN, FX = m.FLAG_FLOAT_OVERFLOW, m.FLAG_FLOAT_UNDERFLOW, m.FLAG_FIXED_OVERFLOW


def test_flag_constants_are_pi_bits():
    assert (OV, FX, UN) == (0x1000, 0x0800, 0x0200)


@pytest.mark.cases("flightsw.arith.m1750_float._add_core", "overflow", "underflow", "cancel-zero",
                   "a-zero", "align-b")
@pytest.mark.cases("flightsw.arith.m1750_float._overflow", "positive", "negative")
def test_add_overflow_underflow():
    assert m.fa32(m.MAX32, m.MAX32) == (m.MAX32, OV)
    assert m.fa32(m.MIN32, m.MIN32) == (m.MIN32, OV)
    assert m.fs32(m.MIN32, m.MAX32) == (m.MIN32, OV)
    assert m.fa48(m.MAX48, m.MAX48) == (m.MAX48, OV)
    # 0.75*2**-128 - 0.5*2**-128 = 0.25*2**-128: normalising needs exponent -129 -> underflow
    assert m.fs32(E32(0.75 * 2.0 ** -128), E32(0.5 * 2.0 ** -128)) == (0, UN)
    assert m.fs48(E48(0.75 * 2.0 ** -128), E48(0.5 * 2.0 ** -128)) == (0, UN)
    assert m.fs32(E32(3.0), E32(3.0)) == (0, 0)
    assert m.fa32(0, E32(-2.5)) == (E32(-2.5), 0) and m.fs32(0, E32(-2.5)) == (E32(2.5), 0)
    # no guard bits: 1.0 + (-tiny) drops one unit of 1.0's last place
    assert m.fa32(E32(1.0), E32(-2.0 ** -40)) == (E32(1.0 - 2.0 ** -22), 0)


@pytest.mark.cases("flightsw.arith.m1750_float._fm32_k", "minus-one-squared",
                   "minus-one-squared-overflow", "exp-overflow", "exp-underflow",
                   "norm-underflow", "zero-operand")
def test_fm_special_cases():
    assert m.fm32(0x80000000, 0x80000000) == (0x40000001, 0)            # (-1)(-1) = 0.5*2**1
    assert m.fm32(0x80000005, 0x80000007) == (0x4000000D, 0)            # 0.5 * 2**(5+7+1)
    assert m.fm48(0x800000050000, 0x800000070000) == (0x4000000D0000, 0)
    assert m.fm32(0x8000003F, 0x80000040) == (m.MAX32, OV)              # n + m = 7F -> overflow
    assert m.fm48(0x8000003F0000, 0x800000400000) == (m.MAX48, OV)
    assert m.fm32(E32(0.5 * 2.0 ** 64), E32(0.5 * 2.0 ** 64)) == (m.MAX32, OV)   # RTL pre-check
    assert m.fm32(E32(-0.75 * 2.0 ** 64), E32(0.5 * 2.0 ** 64)) == (m.MIN32, OV)
    assert m.fm32(E32(2.0 ** -100), E32(2.0 ** -100)) == (0, UN)
    assert m.fm32(0x40000080, 0x40000000) == (0, UN)                    # normalisation underflow
    assert m.fm32(0, m.MAX32) == (0, 0)


@pytest.mark.cases("flightsw.arith.m1750_float._div_core", "divide-by-zero", "zero-dividend",
                   "exp-overflow", "exp-underflow", "minus-half", "minus-one", "negative-floor")
def test_fd_special_cases():
    assert m.fd32(E32(1.0), 0) == (m.MAX32, OV) and m.fd32(E32(-1.0), 0) == (m.MIN32, OV)
    assert m.fd32(0, 0) == (m.MAX32, OV)
    assert m.fd48(E48(-3.0), 0) == (m.MIN48, OV)
    assert m.fd32(0, E32(3.0)) == (0, 0)
    assert m.fd32(E32(2.0 ** 100), E32(2.0 ** -100)) == (m.MAX32, OV)
    assert m.fd32(E32(2.0 ** -100), E32(2.0 ** 100)) == (0, UN)
    assert m.fd32(E32(0.5), E32(-1.0)) == (E32(-0.5), 0)                 # -0.5 normalised
    assert m.fd32(E32(0.75), E32(-0.75)) == (E32(-1.0), 0)
    assert m.fd32(E32(1.0), E32(3.0))[0] == E32(1.0 / 3.0)
    assert m.fd32(E32(-1.0), E32(3.0))[0] == E32(-1.0 / 3.0)             # floor, not chop


@pytest.mark.cases("flightsw.arith.m1750_float._fabs_core", "minus-one", "overflow", "negative")
@pytest.mark.cases("flightsw.arith.m1750_float._fneg_core", "minus-one", "minus-one-overflow",
                   "half", "half-underflow", "zero", "typical")
def test_fabs_fneg():
    for n in (-128, -5, 0, 7, 126):
        w = m.pack32.py_func(-(1 << 23), n)
        assert m.fabs32(w) == (m.pack32.py_func(1 << 22, n + 1), 0)       # 0.5 * 2**(n+1)
        assert m.fneg32(w) == (m.pack32.py_func(1 << 22, n + 1), 0)
        w48 = m.pack48.py_func(-(1 << 39), n)
        assert m.fabs48(w48) == (m.pack48.py_func(1 << 38, n + 1), 0)
    assert m.fabs32(m.MIN32) == (m.MAX32, OV) and m.fneg32(m.MIN32) == (m.MAX32, OV)
    assert m.fabs48(m.MIN48) == (m.MAX48, OV) and m.fneg48(m.MIN48) == (m.MAX48, OV)
    assert m.fneg32(0x40000080) == (0, UN) and m.fneg48(0x400000800000) == (0, UN)
    assert m.fneg32(0x40000005) == (0x80000004, 0)                     # 0.5*2**5 -> -1.0*2**4
    assert m.fneg32(E32(2.5)) == (E32(-2.5), 0) and m.fabs32(E32(-2.5)) == (E32(2.5), 0)
    assert m.fneg32(0) == (0, 0) and m.fabs32(0) == (0, 0)
    for W, neg, sub in ((23, m.fneg32, m.fs32), (39, m.fneg48, m.fs48)):
        @SET
        @given(floats(W))
        def same_as_zero_minus(a):
            assert neg(a) == sub(0, a)
        same_as_zero_minus()


@pytest.mark.cases("flightsw.arith.m1750_float._fix32_k", "overflow", "positive", "negative",
                   "minus-32768", "tiny", "zero")
@pytest.mark.cases("flightsw.arith.m1750_float._fix48_k", "overflow", "positive", "negative",
                   "minus-2-31")
@pytest.mark.cases("flightsw.arith.m1750_float._flt32_k", "zero", "positive", "negative")
@pytest.mark.cases("flightsw.arith.m1750_float._flt48_k", "positive", "negative")
def test_fix_flt():
    s16 = m.to_signed16
    assert m.fix32(E32(32767.99)) == (32767, 0)
    assert m.fix32(E32(-32768.0)) == (0x8000, 0)
    assert m.fix32(E32(32768.0)) == (0, FX)                              # exponent 10 > 0F
    assert m.fix32(E32(-1.5)) == (0xFFFF, 0) and s16(m.fix32(E32(-0.7))[0]) == 0
    assert m.fix32(E32(2.0 ** -128)) == (0, 0) and m.fix32(0) == (0, 0)
    assert m.fix48(E48(2.0 ** 31 - 0.5)) == (0x7FFFFFFF, 0)
    assert m.fix48(E48(-(2.0 ** 31))) == (0x80000000, 0)
    assert m.fix48(E48(2.0 ** 31)) == (0, FX)
    assert m.fix48(E48(-123456.9)) == (m.to_signed32(-123456) & 0xFFFFFFFF, 0)
    assert m.flt32(0x8000) == (0x8000000F, 0)                           # -1.0 * 2**15
    assert m.flt32(0) == (0, 0) and m.flt32(1) == (0x40000001, 0)
    assert m.flt48(0x80000000) == (0x8000001F0000, 0) and m.flt48(0x7FFFFFFF)[0] == E48(2.0 ** 31 - 1)


@njit(cache=True)
def _flt_fix_all():
    bad = 0
    for i in range(65536):
        p, f = m.flt32(i)
        j, g = m.fix32(p)
        if j != i or f != 0 or g != 0:
            bad += 1
    return bad


def test_flt_fix_round_trip_every_int16():
    assert _flt_fix_all() == 0


@SET
@given(st.integers(0, 0xFFFFFFFF))
def test_flt48_exact(i):
    p, f = m.flt48(i)
    assert f == 0 and m.decode48(p) == m.to_signed32(i) and m.fix48(p) == (i, 0)


@SET
@given(floats(23, -128, 20))
def test_fix32_truncates_toward_zero(a):
    r, f = m.fix32(a)
    v = val(a, 23)
    if parts(a, 23)[1] > 15:
        assert (r, f) == (0, FX)
    else:
        assert f == 0 and m.to_signed16(r) == math.trunc(v)


@SET
@given(floats(23), floats(23))
def test_fc32_orders_values(a, b):
    c = m.fc32(a, b)
    va, vb = val(a, 23), val(b, 23)
    assert c == (va > vb) - (va < vb)
    c48 = m.fc48(m.to48.py_func(a), m.to48.py_func(b))
    assert c48 == c


# ------------------------------------------------------------------------------------------------
# integer arithmetic
# ------------------------------------------------------------------------------------------------
def _s(v, bits):
    return v - (1 << bits) if v >> (bits - 1) else v


@SET
@given(st.integers(0, 0xFFFF), st.integers(0, 0xFFFF))
def test_int16_ops(a, b):
    sa, sb = _s(a, 16), _s(b, 16)
    for fn, exact in ((m.add16, sa + sb), (m.sub16, sa - sb), (m.mul16, sa * sb)):
        r, f = fn(a, b)
        assert r == exact & 0xFFFF
        assert f == (FX if not -32768 <= exact <= 32767 else 0)
    assert m.mul16x32(a, b) == ((sa * sb) & 0xFFFFFFFF, 0)
    q, r, f = m.div16(a, b)
    if sb == 0:
        assert (q, r, f) == (0, 0, FX)
    else:
        tq = abs(sa) // abs(sb) * (1 if (sa < 0) == (sb < 0) else -1)
        tr = sa - tq * sb
        assert q == tq & 0xFFFF and r == tr & 0xFFFF
        assert tr == 0 or (tr < 0) == (sa < 0)
        assert f == (FX if tq > 32767 else 0)


@SET
@given(st.integers(0, 0xFFFFFFFF), st.integers(0, 0xFFFFFFFF), st.integers(0, 0xFFFF))
def test_int32_ops(a, b, c):
    sa, sb, sc = _s(a, 32), _s(b, 32), _s(c, 16)
    for fn, exact in ((m.add32, sa + sb), (m.sub32, sa - sb), (m.mul32, sa * sb)):
        r, f = fn(a, b)
        assert r == exact & 0xFFFFFFFF
        assert f == (FX if not -2 ** 31 <= exact < 2 ** 31 else 0)
    q, f = m.div32(a, b)
    if sb == 0:
        assert (q, f) == (0, FX)
    else:
        tq = abs(sa) // abs(sb) * (1 if (sa < 0) == (sb < 0) else -1)
        assert q == tq & 0xFFFFFFFF and f == (FX if tq >= 2 ** 31 else 0)
    q, r, f = m.div32_16(a, c)
    if sc == 0:
        assert (q, r, f) == (0, 0, FX)
    else:
        tq = abs(sa) // abs(sc) * (1 if (sa < 0) == (sc < 0) else -1)
        tr = sa - tq * sc
        assert q == tq & 0xFFFF and r == tr & 0xFFFF
        assert f == (FX if not -32768 <= tq <= 32767 else 0)


def test_int_special_cases():
    assert m.div16(0x8000, 0xFFFF) == (0x8000, 0, FX)
    assert m.div16(0xFFF9, 2) == (0xFFFD, 0xFFFF, 0)                    # -7/2 = -3 rem -1
    assert m.div16(7, 0xFFFE) == (0xFFFD, 1, 0)                         # 7/-2 = -3 rem 1
    assert m.div16(5, 0) == (0, 0, FX)
    assert m.div32(0x80000000, 0xFFFFFFFF) == (0x80000000, FX)
    assert m.div32_16(0x00010000, 1) == (0, 0, FX)                       # 65536 does not fit
    assert m.mul16x32(0x8000, 0x8000) == (0x40000000, 0)
    assert m.mul16(0x8000, 0xFFFF) == (0x8000, FX) and m.mul16(0, 0x8000) == (0, 0)
    assert m.mul16(0xFF00, 0x0080) == (0x8000, 0)                        # -32768 fits
    assert m.mul32(0x80000000, 0x80000000) == (0, FX)
    assert m.add16(0x7FFF, 1) == (0x8000, FX) and m.sub16(0x8000, 1) == (0x7FFF, FX)
    assert m.neg16(0x8000) == (0x8000, FX) and m.neg16(1) == (0xFFFF, 0)
    assert m.abs16(0x8000) == (0x8000, FX) and m.abs16(0xFFFF) == (1, 0)
    assert m.neg32(0x80000000) == (0x80000000, FX) and m.abs32(0xFFFFFFFE) == (2, 0)
    with pytest.raises(ValueError, match="-1"):
        m.add16(-1, 0)
    with pytest.raises(ValueError, match="65536"):
        m.div32_16(0, 65536)


# every case of the m1750_int kernels on hand-worked operands: (function, operands, expected), the
# expected words worked out by hand (the comment gives the signed arithmetic)
INT_CASES = [
    # -1 + 2
    pytest.param("add16", (0xFFFF, 2), (1, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_int._add16_k", "no-overflow"),
        pytest.mark.cases("flightsw.arith.m1750_int._s16", "negative", "non-negative")]),
    # 32767 + 1
    pytest.param("add16", (0x7FFF, 1), (0x8000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._add16_k", "overflow-positive")),
    # -32768 - 1
    pytest.param("add16", (0x8000, 0xFFFF), (0x7FFF, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._add16_k", "overflow-negative")),
    # 1 - 2 = -1
    pytest.param("sub16", (1, 2), (0xFFFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._sub16_k", "no-overflow")),
    # 32767 - -1
    pytest.param("sub16", (0x7FFF, 0xFFFF), (0x8000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._sub16_k", "overflow-positive")),
    # -32768 - 1
    pytest.param("sub16", (0x8000, 1), (0x7FFF, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._sub16_k", "overflow-negative")),
    # -1 + -1
    pytest.param("add32", (0xFFFFFFFF, 0xFFFFFFFF), (0xFFFFFFFE, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_int._add32_k", "no-overflow"),
        pytest.mark.cases("flightsw.arith.m1750_int._s32", "negative")]),
    # 2**31 - 1 + 1
    pytest.param("add32", (0x7FFFFFFF, 1), (0x80000000, FX), marks=[
        pytest.mark.cases("flightsw.arith.m1750_int._add32_k", "overflow-positive"),
        pytest.mark.cases("flightsw.arith.m1750_int._s32", "non-negative")]),
    # -2**32
    pytest.param("add32", (0x80000000, 0x80000000), (0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._add32_k", "overflow-negative")),
    # 0 - 1
    pytest.param("sub32", (0, 1), (0xFFFFFFFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._sub32_k", "no-overflow")),
    # 2**31 - 1 - -1
    pytest.param("sub32", (0x7FFFFFFF, 0xFFFFFFFF), (0x80000000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._sub32_k", "overflow-positive")),
    # -2**31 - 1
    pytest.param("sub32", (0x80000000, 1), (0x7FFFFFFF, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._sub32_k", "overflow-negative")),
    pytest.param("neg16", (5,), (0xFFFB, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._neg16_k", "typical")),
    pytest.param("neg16", (0,), (0, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._neg16_k", "typical")),
    pytest.param("neg16", (0x8000,), (0x8000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._neg16_k", "most-negative")),
    pytest.param("neg32", (0xFFFFFFFB,), (5, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._neg32_k", "typical")),
    pytest.param("neg32", (0x80000000,), (0x80000000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._neg32_k", "most-negative")),
    pytest.param("abs16", (0x7FFF,), (0x7FFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs16_k", "non-negative")),
    pytest.param("abs16", (0,), (0, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs16_k", "non-negative")),
    # |-32767|
    pytest.param("abs16", (0x8001,), (0x7FFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs16_k", "negative")),
    pytest.param("abs16", (0x8000,), (0x8000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs16_k", "most-negative")),
    pytest.param("abs32", (0x12345678,), (0x12345678, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs32_k", "non-negative")),
    pytest.param("abs32", (0xFFFFFFFE,), (2, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs32_k", "negative")),
    pytest.param("abs32", (0x80000000,), (0x80000000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._abs32_k", "most-negative")),
    # -256 * 128 = -32768
    pytest.param("mul16", (0xFF00, 0x80), (0x8000, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16_k", "fits")),
    # -3 * 7 = -21
    pytest.param("mul16", (0xFFFD, 7), (0xFFEB, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16_k", "fits")),
    pytest.param("mul16", (0, 0x8000), (0, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16_k", "fits")),
    # +32768
    pytest.param("mul16", (0x8000, 0xFFFF), (0x8000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16_k", "overflow")),
    # 65536
    pytest.param("mul16", (0x100, 0x100), (0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16_k", "overflow")),
    # -21
    pytest.param("mul16x32", (0xFFFD, 7), (0xFFFFFFEB, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16x32_k", "typical")),
    # 2**30
    pytest.param("mul16x32", (0x8000, 0x8000), (0x40000000, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16x32_k", "most-negative")),
    # -32768 * 32767
    pytest.param("mul16x32", (0x8000, 0x7FFF), (0xC0008000, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul16x32_k", "most-negative")),
    # -(2**31 - 1)
    pytest.param("mul32", (0xFFFFFFFF, 0x7FFFFFFF), (0x80000001, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul32_k", "fits")),
    pytest.param("mul32", (0x10000, 0x7FFF), (0x7FFF0000, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul32_k", "fits")),
    # 2**62
    pytest.param("mul32", (0x80000000, 0x80000000), (0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul32_k", "overflow")),
    # +2**31
    pytest.param("mul32", (0x10000, 0x8000), (0x80000000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._mul32_k", "overflow")),
    pytest.param("div16", (7, 2), (3, 1, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_int._div16_k", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_int._tdivmod", "same-signs")]),
    # -7/2 = -3 r -1
    pytest.param("div16", (0xFFF9, 2), (0xFFFD, 0xFFFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._tdivmod", "negative-dividend")),
    # 7/-2 = -3 r 1
    pytest.param("div16", (7, 0xFFFE), (0xFFFD, 1, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._tdivmod", "negative-divisor")),
    # -7/-2 = 3 r -1
    pytest.param("div16", (0xFFF9, 0xFFFE), (3, 0xFFFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._tdivmod", "both-negative")),
    pytest.param("div16", (12, 4), (3, 0, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._tdivmod", "exact")),
    pytest.param("div16", (5, 0), (0, 0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div16_k", "divide-by-zero")),
    # -32768/-1
    pytest.param("div16", (0x8000, 0xFFFF), (0x8000, 0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div16_k", "overflow")),
    # -65536/3 = -21845 r -1
    pytest.param("div32_16", (0xFFFF0000, 3), (0xAAAB, 0xFFFF, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k", "typical")),
    # 32767 fits
    pytest.param("div32_16", (0x7FFF, 1), (0x7FFF, 0, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k", "typical")),
    # -32768 fits
    pytest.param("div32_16", (0xFFFF8000, 1), (0x8000, 0, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k", "typical")),
    pytest.param("div32_16", (5, 0), (0, 0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k", "divide-by-zero")),
    # +32768
    pytest.param("div32_16", (0x8000, 1), (0x8000, 0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k",
                                         "overflow-positive")),
    # 65537/2 = 32768 r 1
    pytest.param("div32_16", (0x10001, 2), (0x8000, 1, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k",
                                         "overflow-positive")),
    # -32769
    pytest.param("div32_16", (0xFFFF7FFF, 1), (0x7FFF, 0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_16_k",
                                         "overflow-negative")),
    # -7/2 = -3
    pytest.param("div32", (0xFFFFFFF9, 2), (0xFFFFFFFD, 0),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_k", "typical")),
    pytest.param("div32", (5, 0), (0, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_k", "divide-by-zero")),
    # -2**31/-1
    pytest.param("div32", (0x80000000, 0xFFFFFFFF), (0x80000000, FX),
                 marks=pytest.mark.cases("flightsw.arith.m1750_int._div32_k", "overflow")),
]


@pytest.mark.parametrize("fn,args,want", INT_CASES)
def test_int_kernel_cases(fn, args, want):
    """Each integer kernel case on hand-worked operands; the Python-integer oracle below agrees."""
    assert getattr(m, fn)(*args) == want
    bits = {"add16": 16, "sub16": 16, "add32": 32, "sub32": 32, "mul16": 16, "mul32": 32}
    if fn in bits:                                 # the exact result, reduced and range-checked
        n = bits[fn]
        a, b = (_s(v, n) for v in args)
        exact = {"add": a + b, "sub": a - b, "mul": a * b}[fn[:3]]
        fits = -2 ** (n - 1) <= exact < 2 ** (n - 1)
        assert want == (exact & ((1 << n) - 1), 0 if fits else FX)


# ------------------------------------------------------------------------------------------------
# numba path and costs
# ------------------------------------------------------------------------------------------------
@njit(cache=True)
def _njit_mix(a, b, i, j):
    r1 = m.fa32(a, b)
    r2 = m.fs48(m.to48(a), m.to48(b))
    r3 = m.fd32(a, b)
    r4 = m.fm48(m.to48(a), m.to48(b))
    r5 = m.fix32(a)
    r6 = m.div16(i, j)
    return r1, r2, r3, r4, r5, r6, m.fc32(a, b)


def test_njit_callers_match_python():
    a, b = E32(-3.25), E32(1e-3)
    got = _njit_mix(a, b, 0xFFF9, 2)
    want = (m.fa32(a, b), m.fs48(a << 16, b << 16), m.fd32(a, b), m.fm48(a << 16, b << 16),
            m.fix32(a), m.div16(0xFFF9, 2), m.fc32(a, b))
    assert tuple(tuple(int(v) for v in g) if isinstance(g, tuple) else int(g) for g in got) == want


def test_cycle_costs_from_budget():
    from flightsw.budget import PACE1750A
    assert m.op_cycles("fa32") == PACE1750A.cost("FA") == m.CYCLES["fa32"] == m.CYC_FA32
    assert m.op_cycles("fm48") == PACE1750A.cost("EFM")
    assert m.op_mix("fd32") == {"FD": 1}
    for name in ("fa32", "fs32", "fm32", "fd32", "fa48", "fs48", "fm48", "fd48", "flt32", "fix32",
                 "fabs32", "fneg32", "flt48", "fix48", "fabs48", "fneg48", "fc32", "fc48"):
        assert m.op_cycles(name) > 0
    with pytest.raises(KeyError, match="nope"):
        m.op_mix("nope")


# ------------------------------------------------------------------------------------------------
# the host-side quotient kernel behind FD/EFD (float64 estimate + exact integer fix-up)
# ------------------------------------------------------------------------------------------------
@njit
def _quotients(A, B, W):
    q = np.empty(A.size, np.int64)
    s = np.empty(A.size, np.bool_)
    for i in range(A.size):
        q[i], s[i] = _quotient_floor(A[i], B[i], W)
    return q, s


def _adversarial(W, rng, n):
    """Operand magnitudes whose quotient A * 2**(W+1) / B lies just below, at or just above an
    integer -- where a float64 estimate is most easily off by one."""
    lo, hi = 1 << (W - 1), 1 << W
    c = rng.integers(0, 4096, n)
    d = rng.integers(-4096, 4096, n)
    kind = rng.integers(0, 4, n)
    B = np.where(kind % 2 == 0, hi - c, lo + c)
    base = np.choose(kind, [B, B // 2 + lo // 2, np.full(n, hi), np.full(n, lo)])
    A = np.clip(base + d, lo, hi)
    # and quotients engineered to be N - 1/B, N, N + 1/B for random integers N
    Bq = rng.integers(lo, hi + 1, n)
    Nq = rng.integers(1 << W, 1 << (W + 1), n)
    Aq = np.array([max(lo, min(hi, (int(nq) * int(b)) >> (W + 1))) + int(e)
                   for nq, b, e in zip(Nq, Bq, rng.integers(-1, 2, n))], np.int64)
    return np.concatenate([A, np.clip(Aq, lo, hi)]), np.concatenate([B, Bq])


@pytest.mark.parametrize("W", [23, 39])
@pytest.mark.cases("flightsw.arith.m1750_float._quotient_floor", "w23", "w39-estimate-exact",
                   "exact-quotient")
def test_quotient_floor_equals_integer_division(W):
    """floor(A 2**(W+1) / B) and the sticky bit from one float64 division + fix-up equal Python's
    exact integer division on 400,000 random and adversarial operand pairs per width."""
    rng = np.random.default_rng(W)
    lo, hi = 1 << (W - 1), 1 << W
    A = rng.integers(lo, hi + 1, 200_000)
    B = rng.integers(lo, hi + 1, 200_000)
    A2, B2 = _adversarial(W, rng, 50_000)
    A = np.concatenate([A, A2, [lo, hi, lo, hi]]).astype(np.int64)
    B = np.concatenate([B, B2, [hi, lo, lo, hi]]).astype(np.int64)
    q, s = _quotients(A, B, W)
    want_q = [(int(a) << (W + 1)) // int(b) for a, b in zip(A, B)]
    want_s = [((int(a) << (W + 1)) % int(b)) != 0 for a, b in zip(A, B)]
    assert q.tolist() == want_q
    assert s.tolist() == want_s
