"""The track processor's 1750A building blocks (flightsw.tp.f1750) against independent oracles:
the MIL-STD-1750A word layouts written from the format definition (mantissa, exponent), exact
binary fractions for rounding ties, NumPy for vectors and quaternions, SciPy's Rotation for the
direction cosine matrix.
"""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from flightsw.arith.m1750 import (FLAG_DOMAIN, FLAG_FLOAT_OVERFLOW, FLAG_FLOAT_UNDERFLOW,
                                  decode32)
from flightsw.tp.f1750 import (dec32, dot3, enc32, enc48, mtv3, mv1ab, mv3, qdcm, qmul, qnormalize,
                               unit3)


def p32(mant, exp):
    """Packed 32-bit float from the format: 24-bit two's-complement mantissa, then the exponent."""
    return ((mant & 0xFFFFFF) << 8) | (exp & 0xFF)


def p48(mant, exp):
    """Packed 48-bit float: mantissa high 24 bits, exponent, mantissa low 16 bits."""
    m = mant & 0xFFFFFFFFFF
    return ((m >> 16) << 24) | ((exp & 0xFF) << 16) | (m & 0xFFFF)


def w(x):
    p, f = enc32(float(x))
    assert f == 0
    return p


def d(*ps):
    return np.array([dec32(int(p)) for p in ps])


@pytest.mark.parametrize("x, want", [
    (10.0, (p32(0x500000, 4), 0)), (1.0, (p32(0x400000, 1), 0)), (-1.0, (0x80000000, 0)),
    (0.0, (0, 0)),
    (1 + 2.0 ** -23, (p32(0x400000, 1), 0)),           # a tie: to the even mantissa 0x400000
    (1 + 3 * 2.0 ** -23, (p32(0x400002, 1), 0)),       # a tie: to the even mantissa 0x400002
    (1 + 1.1 * 2.0 ** -23, (p32(0x400001, 1), 0)),     # above the tie: up
    (2.0 ** 128, (0x7FFFFF7F, FLAG_FLOAT_OVERFLOW)),
    (-(2.0 ** 128), (0x8000007F, FLAG_FLOAT_OVERFLOW)),
    (2.0 ** -131, (0, FLAG_FLOAT_UNDERFLOW)), (2.0 ** -129, (p32(0x400000, -128), 0)),
    (math.nan, (0, FLAG_DOMAIN)), (-math.inf, (0, FLAG_DOMAIN))])
@pytest.mark.cases("flightsw.tp.f1750._enc", "zero", "non-finite", "nearest", "negative",
                   "overflow", "underflow")
@pytest.mark.cases("flightsw.tp.f1750.enc32", "typical")
def test_enc32_words_from_the_format_definition(x, want):
    assert enc32(x) == want


@pytest.mark.parametrize("x, want", [
    (1.0, (p48(0x4000000000, 1), 0)), (1 + 2.0 ** -38, (p48(0x4000000001, 1), 0)),
    (1 + 2.0 ** -39, (p48(0x4000000000, 1), 0)),       # a tie: even
    (-1.0, (p48(-0x8000000000, 0), 0)),
    (2.0 ** 200, (0x7FFFFF7FFFFF, FLAG_FLOAT_OVERFLOW))])
@pytest.mark.cases("flightsw.tp.f1750.enc48", "typical")
def test_enc48_words_from_the_format_definition(x, want):
    assert enc48(x) == want


@pytest.mark.cases("flightsw.tp.f1750.dot3", "typical", "overflow")
@pytest.mark.cases("flightsw.tp.f1750.mv3", "typical")
@pytest.mark.cases("flightsw.tp.f1750.mtv3", "typical")
@pytest.mark.cases("flightsw.tp.f1750.mv1ab", "typical")
def test_vector_products_against_numpy():
    rng = np.random.default_rng(3)
    R = rng.uniform(-2, 2, (3, 3))
    x = rng.uniform(-3, 3, 3)
    Rp = np.array([w(v) for v in R.ravel()], np.int64)
    xp = [w(v) for v in x]
    Rq, xq = d(*Rp).reshape(3, 3), d(*xp)                 # the values the words hold
    s, f = dot3(*xp, *Rp[:3])
    assert f == 0 and dec32(s) == pytest.approx(xq @ Rq[0], abs=1e-5)
    *y, f = mv3(Rp, *xp)
    assert f == 0 and d(*y) == pytest.approx(Rq @ xq, abs=1e-5)
    *y, f = mtv3(Rp, *xp)
    assert f == 0 and d(*y) == pytest.approx(Rq.T @ xq, abs=1e-5)
    *y, f = mv1ab(Rp, xp[1], xp[2])
    assert f == 0 and d(*y) == pytest.approx(Rq @ np.array([1.0, xq[1], xq[2]]), abs=1e-5)
    big = w(2.0 ** 100)
    assert dot3(big, 0, 0, big, 0, 0)[1] & FLAG_FLOAT_OVERFLOW


@pytest.mark.cases("flightsw.tp.f1750.unit3", "typical", "zero")
@pytest.mark.cases("flightsw.tp.f1750.qnormalize", "typical", "zero")
def test_unit_vector_and_quaternion_normalisation():
    *u, n, f = unit3(w(3.0), w(-4.0), w(12.0))
    assert f == 0 and d(*u) == pytest.approx(np.array([3, -4, 12]) / 13, abs=1e-7)
    assert dec32(n) == pytest.approx(13.0, rel=1e-6)
    assert unit3(0, 0, 0) == (0, 0, 0, 0, FLAG_DOMAIN)
    *q, n2, f = qnormalize(w(1.0), w(2.0), w(-2.0), w(4.0))
    assert f == 0 and d(*q) == pytest.approx(np.array([1, 2, -2, 4]) / 5, abs=1e-7)
    assert dec32(n2) == pytest.approx(25.0, rel=1e-6)
    q0, q1, q2, q3, n2, f = qnormalize(0, 0, 0, 0)
    assert decode32(q0) == 1.0 and (q1, q2, q3, n2) == (0, 0, 0, 0) and f == FLAG_DOMAIN


@pytest.mark.cases("flightsw.tp.f1750.qmul", "typical")
@pytest.mark.cases("flightsw.tp.f1750.qdcm", "typical")
def test_quaternion_product_and_matrix_against_scipy():
    i, j = (0, w(1.0), 0, 0), (0, 0, w(1.0), 0)
    assert qmul(*i, *j) == (0, 0, 0, w(1.0), 0)           # i j = k
    assert qmul(*j, *i) == (0, 0, 0, w(-1.0), 0)          # j i = -k
    ra = Rotation.from_rotvec([0.3, -0.2, 0.9])
    rb = Rotation.from_rotvec([-0.5, 0.4, 0.1])
    qa = np.roll(ra.as_quat(), 1)                          # scalar first
    qb = np.roll(rb.as_quat(), 1)
    *c, f = qmul(*[w(v) for v in qa], *[w(v) for v in qb])
    want = np.roll((ra * rb).as_quat(), 1)
    assert f == 0 and d(*c) * np.sign(d(*c)[0]) == pytest.approx(want * np.sign(want[0]), abs=1e-6)
    R = np.zeros(9, np.int64)
    assert qdcm(*[w(v) for v in qa], R) == 0
    assert d(*R).reshape(3, 3) == pytest.approx(ra.as_matrix(), abs=1e-6)


@pytest.mark.cases("flightsw.arith.m1750_float.madd48", "typical", "flags")
@pytest.mark.cases("flightsw.arith.m1750_float._mul48_core", "typical")
def test_madd48_is_efm_then_efa():
    """The covariance's and RK4's multiply-accumulate: exactly EFA(acc, EFM(a, b)) -- both
    truncations, both instructions' flags (EFM and EFA are checked against exact rational
    arithmetic in test_m1750)."""
    from flightsw.arith.m1750 import encode48, fa48, fm48, madd48

    rng = np.random.default_rng(5)
    x = rng.normal(0, 1, (400, 3)) * 10.0 ** rng.integers(-6, 7, (400, 3))
    x[:40, 0] = -x[:40, 1] * x[:40, 2]                 # cancellation: acc ~ -a b
    for acc, a, b in x:
        acc, a, b = (encode48(float(v), rounding="nearest") for v in (acc, a, b))
        p, f1 = fm48(a, b)
        s, f2 = fa48(acc, p)
        assert madd48(acc, a, b) == (s, f1 | f2)
    tiny = p48(1 << 38, -100)                          # 0.5 * 2**-100: the square underflows
    assert madd48(encode48(1.0), tiny, tiny) == (encode48(1.0), FLAG_FLOAT_UNDERFLOW)
