"""Flight math library on 1750A float ops (flightsw.arith.m1750_math): max error against numpy on
dense samples (the bounds stated in MAX_ERROR), special cases, and the declared operation mixes."""
import math
from fractions import Fraction

import numpy as np
import pytest
from numba import njit

from flightsw.arith import m1750 as m
from flightsw.arith import m1750_math as mm
from flightsw.budget import m1750_cycles
from flightsw.numba_cache import dispatcher_of

N = 20000
RNG = np.random.default_rng(20240611)
#: pi to 100 digits: the oracle of the argument reduction
PI = Fraction("3.1415926535897932384626433832795028841971693993751058209749445923078164062862"
              "0899862803482534211706798")


# Not cached: both helpers take a compiled function as an argument, and numba keeps a weak
# reference to it in the cache index, which a warm index then fails to save ("ReferenceError:
# underlying object has vanished", numba issues 2956 and 6251; as in test_m1750_lanes.py).
@njit
def _apply1(f, xs):
    out = np.empty_like(xs)
    fl = np.empty_like(xs)
    for i in range(xs.size):
        out[i], fl[i] = f(xs[i])
    return out, fl


@njit
def _apply2(f, ys, xs):
    out = np.empty_like(xs)
    fl = np.empty_like(xs)
    for i in range(xs.size):
        out[i], fl[i] = f(ys[i], xs[i])
    return out, fl


def _ulp_err(got, ref, W):
    """|got - ref| in units of the last place of ref in the 1750A format (2**(e - W), ref = f*2**e,
    f in [0.5, 1))."""
    _, e = np.frexp(ref)
    return np.abs(got - ref) / np.ldexp(1.0, e - W)


FMT = {23: (m.encode32_array, m.decode32_array), 39: (m.encode48_array, m.decode48_array)}


def _check(name, W, x, ref_fn, args=1):
    enc, dec = FMT[W]
    kind, bound = mm.MAX_ERROR[name]
    fn = dispatcher_of(getattr(mm, f"_{name}_k"))   # the kernel behind the public name, first-class
    if args == 1:
        p = enc(x)
        r, fl = _apply1(fn, p)
        ref = ref_fn(dec(p))
    else:
        py, px = enc(x[0]), enc(x[1])
        r, fl = _apply2(fn, py, px)
        ref = ref_fn(dec(py), dec(px))
    assert np.all(fl == 0)
    got = dec(r)
    nz = ref != 0
    err = _ulp_err(got[nz], ref[nz], W) if kind == "ulp" else np.abs(got - ref)
    assert err.max() <= bound, f"{name}: max error {err.max()} > {bound} ({kind})"
    return err.max()


@pytest.mark.parametrize("W,name", [
    pytest.param(23, "sqrt32", marks=[
        pytest.mark.cases("flightsw.arith.m1750_math._sqrt32_k",
                          "even-exponent", "odd-exponent", "range-ends"),
        pytest.mark.cases("flightsw.arith.m1750_math._scale32", "in-range"),
        pytest.mark.cases("flightsw.arith.m1750_math._set_exp32", "replace")]),
    pytest.param(39, "sqrt48", marks=[
        pytest.mark.cases("flightsw.arith.m1750_math._sqrt48_k",
                          "even-exponent", "odd-exponent", "range-ends"),
        pytest.mark.cases("flightsw.arith.m1750_math._scale48", "in-range"),
        pytest.mark.cases("flightsw.arith.m1750_math._set_exp48", "replace")])])
def test_sqrt_error(W, name):
    """x = f * 2**e with e even (0.5, 2.0, 3.0) and odd (2**-128, 0.25, 1.0, 4.0, 1.7e38), and the
    range ends 0.5 * 2**-128 and the largest 32-bit value: within 1.5 ulp of numpy's sqrt."""
    x = np.exp2(RNG.uniform(-127.9, 126.9, N))
    x[:10] = [2.0 ** -128, 0.25, 0.5, 1.0, 2.0, 4.0, 1.7e38, 3.0, 2.0 ** -129, m.decode32(m.MAX32)]
    _check(name, W, x, np.sqrt)


@pytest.mark.cases("flightsw.arith.m1750_math._exp32_k", "positive", "negative", "tiny")
@pytest.mark.cases("flightsw.arith.m1750_math._s16", "non-negative", "negative")   # n of both signs
def test_exp32_error():
    x = np.concatenate([RNG.uniform(-88.0, 88.0, N), RNG.uniform(-1e-3, 1e-3, 2000),
                        [-88.7, 88.0, 0.5, -0.5, 1.0]])
    _check("exp32", 23, x, np.exp)


@pytest.mark.cases("flightsw.arith.m1750_math._ln32_k",
                   "low-mantissa", "high-mantissa", "near-one", "range-ends")
def test_ln32_error():
    x = np.concatenate([np.exp2(RNG.uniform(-127.9, 126.9, N)), 1 + RNG.uniform(-1e-3, 1e-3, 4000),
                        RNG.uniform(0.4, 2.1, 4000), [1.0, 2.0, 0.5, 1.7e38, 2.0 ** -128]])
    _check("ln32", 23, x, np.log)


@pytest.mark.parametrize("W,name,ref", [
    pytest.param(23, "sin32", np.sin, marks=[
        pytest.mark.cases("flightsw.arith.m1750_math._sin32_k", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_math._trig32",
                          "quadrant-0", "quadrant-1", "quadrant-2", "quadrant-3", "negative"),
        pytest.mark.cases("flightsw.arith.m1750_math._sin_poly32", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_math._cos_poly32", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_math._reduce_n", "positive", "negative"),
        pytest.mark.cases("flightsw.arith.m1750_math._reduce48",
                          "first-octant", "reduce", "negative"),
        pytest.mark.cases("flightsw.arith.m1750_math._s32", "non-negative", "negative")]),
    pytest.param(23, "cos32", np.cos,
                 marks=pytest.mark.cases("flightsw.arith.m1750_math._cos32_k", "typical")),
    pytest.param(39, "sin48", np.sin, marks=[
        pytest.mark.cases("flightsw.arith.m1750_math._sin48_k", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_math._trig48",
                          "quadrant-0", "quadrant-1", "quadrant-2", "quadrant-3", "negative"),
        pytest.mark.cases("flightsw.arith.m1750_math._sin_poly48", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_math._cos_poly48", "typical")]),
    pytest.param(39, "cos48", np.cos,
                 marks=pytest.mark.cases("flightsw.arith.m1750_math._cos48_k", "typical"))])
def test_sin_cos_error(W, name, ref):
    """Both signs, every quadrant (the pi/4 grid, dense samples over [-7, 7]) and the whole domain:
    within the stated absolute error of numpy (a wrong n, r or quadrant would be far off)."""
    x = np.concatenate([RNG.uniform(-7.0, 7.0, N), RNG.uniform(-32767.0, 32767.0, N // 4),
                        RNG.uniform(-1e-4, 1e-4, 1000), np.pi / 4 * np.arange(-40, 41)])
    _check(name, W, x, ref)


@pytest.mark.parametrize("W,name", [
    pytest.param(23, "atan2_32", marks=pytest.mark.cases(
        "flightsw.arith.m1750_math._atan2_32_k",
        "first-octant", "swap", "negative-x", "negative-y")),
    pytest.param(39, "atan2_48", marks=pytest.mark.cases(
        "flightsw.arith.m1750_math._atan2_48_k",
        "first-octant", "swap", "negative-x", "negative-y"))])
def test_atan2_error(W, name):
    ang = RNG.uniform(-np.pi, np.pi, N)
    rad = np.exp2(RNG.uniform(-20, 20, N))
    y, x = rad * np.sin(ang), rad * np.cos(ang)
    y = np.concatenate([y, [0.0, 0.0, 1.0, -1.0, 1.0, -1.0, 1.0, 1e-30]])
    x = np.concatenate([x, [1.0, -1.0, 0.0, 0.0, 1.0, -1.0, -1.0, -1.0]])
    _check(name, W, (y, x), np.arctan2, args=2)


@pytest.mark.cases("flightsw.arith.m1750_math._sqrt32_k",
                   "zero", "negative", "even-exponent", "odd-exponent")
@pytest.mark.cases("flightsw.arith.m1750_math._sqrt48_k",
                   "zero", "negative", "even-exponent", "odd-exponent")
@pytest.mark.cases("flightsw.arith.m1750_math._exp32_k",
                   "zero", "saturate-high", "saturate-low", "overflow", "underflow")
@pytest.mark.cases("flightsw.arith.m1750_math._scale32", "overflow-positive", "underflow")
@pytest.mark.cases("flightsw.arith.m1750_math._ln32_k", "non-positive", "one")
@pytest.mark.cases("flightsw.arith.m1750_math._trig32", "zero", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._trig48", "zero", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._sin32_k", "zero", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._cos32_k", "zero", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._sin48_k", "zero", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._cos48_k", "zero", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._atan2_32_k",
                   "origin", "positive-x-axis", "negative-x-axis", "y-axis")
@pytest.mark.cases("flightsw.arith.m1750_math._atan2_48_k",
                   "origin", "positive-x-axis", "negative-x-axis", "y-axis")
def test_math_special_cases():
    """exp32 89 / -90 pass the |x| < 256 test and overflow / underflow in the final exponent edit;
    300 / -1e6 are refused at once. Angles of the axes are pi and pi/2 rounded to nearest (the
    encodings of 100-digit pi, checked against the words too)."""
    E32, E48, D32 = m.encode32, m.encode48, m.decode32
    assert m.sin32(E32(-40000.0)) == (0, m.FLAG_DOMAIN)
    assert m.cos32(E32(2.0 ** 15)) == (0, m.FLAG_DOMAIN)
    assert m.sin48(E48(2.0 ** 15)) == (0, m.FLAG_DOMAIN)
    assert m.atan2_32(0, E32(2.5)) == (0, 0) and m.atan2_48(0, E48(2.5)) == (0, 0)
    pi32, pi48 = E32(PI, rounding="nearest"), E48(PI, rounding="nearest")
    pio2_32, pio2_48 = E32(PI / 2, rounding="nearest"), E48(PI / 2, rounding="nearest")
    assert (mm.PI32, mm.PIO2_32, mm.PI48, mm.PIO2_48) == (pi32, pio2_32, pi48, pio2_48)
    assert m.atan2_32(0, E32(-2.0)) == (pi32, 0) and m.atan2_48(0, E48(-1.0)) == (pi48, 0)
    assert m.atan2_32(E32(0.1), 0) == (pio2_32, 0) and m.atan2_48(E48(3.0), 0) == (pio2_48, 0)
    assert m.atan2_48(E48(-3.0), 0) == (m.fneg48(pio2_48)[0], 0)
    assert m.sqrt32(0) == (0, 0) and m.sqrt48(0) == (0, 0)
    assert m.sqrt32(E32(-4.0)) == (0, m.FLAG_DOMAIN) and m.sqrt48(E48(-4.0)) == (0, m.FLAG_DOMAIN)
    assert D32(m.sqrt32(E32(4.0))[0]) == 2.0 and m.decode48(m.sqrt48(E48(9.0))[0]) == 3.0
    assert m.sqrt32(E32(9.0)) == (E32(3.0), 0) and m.sqrt48(E48(4.0)) == (E48(2.0), 0)
    assert m.exp32(0) == (m.ONE32, 0)
    assert m.exp32(E32(89.0)) == (m.MAX32, m.FLAG_FLOAT_OVERFLOW)
    assert m.exp32(E32(300.0)) == (m.MAX32, m.FLAG_FLOAT_OVERFLOW)
    assert m.exp32(E32(-90.0)) == (0, m.FLAG_FLOAT_UNDERFLOW)
    assert m.exp32(E32(-1e6)) == (0, m.FLAG_FLOAT_UNDERFLOW)
    assert m.ln32(0) == (m.MIN32, m.FLAG_DOMAIN) and m.ln32(E32(-1.0)) == (m.MIN32, m.FLAG_DOMAIN)
    assert m.ln32(m.ONE32) == (0, 0)
    assert m.sin32(0) == (0, 0) and m.cos32(0) == (m.ONE32, 0)
    assert m.sin48(0) == (0, 0) and m.cos48(0) == (m.ONE48, 0)
    assert m.sin32(E32(40000.0)) == (0, m.FLAG_DOMAIN) and m.cos48(E48(-1e6)) == (0, m.FLAG_DOMAIN)
    assert m.atan2_32(0, 0) == (0, 0) and m.atan2_48(0, 0) == (0, 0)
    assert m.atan2_32(0, E32(-1.0)) == (mm.PI32, 0)
    assert m.atan2_32(E32(1.0), 0) == (mm.PIO2_32, 0)
    assert m.atan2_32(E32(-1.0), 0)[0] == m.fneg32(mm.PIO2_32)[0]
    with pytest.raises(ValueError, match="0x30000000"):
        m.sqrt32(0x30000000)
    with pytest.raises(ValueError, match="x="):
        m.atan2_48(0, 1.0)


@pytest.mark.cases("flightsw.arith.m1750_math._set_exp32", "replace")
@pytest.mark.cases("flightsw.arith.m1750_math._set_exp48", "replace")
@pytest.mark.cases("flightsw.arith.m1750_math._scale32",
                   "zero", "in-range", "overflow-positive", "overflow-negative", "underflow")
@pytest.mark.cases("flightsw.arith.m1750_math._scale48",
                   "zero", "in-range", "overflow-positive", "overflow-negative", "underflow")
@pytest.mark.cases("flightsw.arith.m1750_math._s16", "non-negative", "negative")
@pytest.mark.cases("flightsw.arith.m1750_math._s32", "non-negative", "negative")
def test_exponent_edits():
    """The word-level helpers on the standard's Table III / IV words: 10.0 = 5000 0004,
    0.5 * 2**127 = 4000 007F, 0.5 * 2**-128 = 4000 0080, -1.0 = 8000 0000; overflow results
    7FFF FF7F / 8000 007F (48-bit: 7FFF FF7F FFFF / 8000 007F 0000)."""
    OV, UN = m.FLAG_FLOAT_OVERFLOW, m.FLAG_FLOAT_UNDERFLOW
    assert mm._set_exp32(0x50000004, -1) == 0x500000FF and m.decode32(0x500000FF) == 0.3125
    assert mm._set_exp48(0x500000041234, 2) == 0x500000021234
    assert mm._set_exp48(0x500000041234, -128) == 0x500000801234
    s32, s48 = mm._scale32, mm._scale48
    assert s32(0, 500) == (0, 0) and s48(0, -500) == (0, 0)
    assert s32(0x50000004, 3) == (0x50000007, 0) and m.decode32(0x50000007) == 80.0
    assert s32(0x40000001, 126) == (0x4000007F, 0)                   # 0.5 * 2**127: top end
    assert s32(0x40000001, -129) == (0x40000080, 0)                  # 0.5 * 2**-128: bottom end
    assert s32(0x80000000, 127) == (0x8000007F, 0)                   # -1.0 * 2**127 fits
    assert s32(0x40000001, 127) == (0x7FFFFF7F, OV)
    assert s32(0x80000000, 128) == (0x8000007F, OV)
    assert s32(0x40000080, -1) == (0, UN)
    assert s48(0x400000010000, 126) == (0x4000007F0000, 0)
    assert s48(0x500000041234, -3) == (0x500000011234, 0)              # w2 kept
    assert s48(0x400000010000, -129) == (0x400000800000, 0)
    assert s48(0x400000010000, 127) == (0x7FFFFF7FFFFF, OV)
    assert s48(0x800000000000, 128) == (0x8000007F0000, OV)
    assert s48(0x400000800000, -1) == (0, UN)
    assert [mm._s16(w) for w in (0, 0x7FFF, 0x8000, 0xFFFF)] == [0, 32767, -32768, -1]
    assert [mm._s32(w) for w in (5, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF)] == \
        [5, 2 ** 31 - 1, -2 ** 31, -1]


@pytest.mark.cases("flightsw.arith.m1750_math._reduce48", "first-octant", "reduce", "negative")
@pytest.mark.cases("flightsw.arith.m1750_math._reduce_n", "positive", "negative")
def test_reduce48_against_exact_pi():
    """n = round(x 2/pi) (halves away from zero) and r = x - n pi/2 against 100-digit pi:
    r = x exactly in the first octant, within 2**-37 elsewhere, |x| up to 32767, both signs."""
    rng = np.random.default_rng(5)
    xs = np.concatenate([rng.uniform(-32767, 32767, 200), rng.uniform(-7, 7, 200),
                         [0.5, -0.7, 0.78, -0.78, 32767.0, -32767.0, 1e-30]])
    for x in xs:
        p = m.encode48(float(x))
        xv = Fraction(m.decode48(p))
        n, r = mm._reduce48(p)
        q = xv * 2 / PI
        assert n == (math.floor(q + Fraction(1, 2)) if q >= 0 else -math.floor(-q + Fraction(1, 2)))
        if abs(xv) < PI / 4:
            assert n == 0 and r == p
        else:
            assert abs(Fraction(m.decode48(r)) - (xv - n * PI / 2)) <= Fraction(2) ** -37, x
            assert abs(m.decode48(r)) <= math.pi / 4 + 1e-9


@pytest.mark.cases("flightsw.arith.m1750_math._sin_poly32", "tiny")
@pytest.mark.cases("flightsw.arith.m1750_math._cos_poly32", "tiny")
@pytest.mark.cases("flightsw.arith.m1750_math._sin_poly48", "tiny")
@pytest.mark.cases("flightsw.arith.m1750_math._cos_poly48", "tiny")
def test_tiny_arguments_flush_the_square():
    """|x| = 1e-30: x*x underflows (below 2**-129) and is flushed without a flag; sin x = x and
    cos x = 1 to far below an ulp (|sin x - x| < |x|**3, 1 - cos x < x**2)."""
    for v in (1e-30, -3e-25):
        p32, p48 = m.encode32(v), m.encode48(v)
        assert m.sin32(p32) == (p32, 0) and m.cos32(p32) == (m.encode32(1.0), 0)
        assert m.sin48(p48) == (p48, 0) and m.cos48(p48) == (m.encode48(1.0), 0)


@pytest.mark.cases("flightsw.arith.m1750_math._trig32", "domain-edge", "domain")
@pytest.mark.cases("flightsw.arith.m1750_math._trig48", "domain-edge", "domain")
def test_trig_domain_edge():
    """Exponent 15 (2**14 <= |x| < 2**15, and -2**15 = -1.0 * 2**15) is evaluated; 2**15 =
    0.5 * 2**16 and -2**15 - 1 are refused (exponent 16)."""
    for v in (32767.0, -32767.5, 16384.0, -20000.25, -32768.0):
        for fn, ref, enc, dec, b in ((m.sin32, math.sin, m.encode32, m.decode32, 3.5 * 2.0 ** -23),
                                     (m.cos32, math.cos, m.encode32, m.decode32, 3.5 * 2.0 ** -23),
                                     (m.sin48, math.sin, m.encode48, m.decode48, 4 * 2.0 ** -39),
                                     (m.cos48, math.cos, m.encode48, m.decode48, 4 * 2.0 ** -39)):
            p = enc(v)
            r, f = fn(p)
            assert f == 0 and abs(dec(r) - ref(dec(p))) <= b, (fn.__name__, v)
    for v in (32768.0, -32769.0):
        assert m.sin32(m.encode32(v)) == (0, m.FLAG_DOMAIN)
        assert m.cos48(m.encode48(v)) == (0, m.FLAG_DOMAIN)


@pytest.mark.cases("flightsw.arith.m1750_math._atan2_32_k", "diagonal", "ratio-underflow")
@pytest.mark.cases("flightsw.arith.m1750_math._atan2_48_k", "diagonal", "ratio-underflow")
def test_atan2_exact_cases():
    """|y| = |x|: exactly atan(1) = pi/4 rounded to nearest (and pi - pi/4 etc. within the bound);
    min/max below 2**-129: t flushes to 0 and the angle is exactly 0 or pi/2 rounded to nearest."""
    for W, fn, enc, dec, bound in ((23, m.atan2_32, m.encode32, m.decode32, 8),
                                   (39, m.atan2_48, m.encode48, m.decode48, 6)):
        for v in (1.0, 3.0, 2.0 ** -100, 2.0 ** 100):
            assert fn(enc(v), enc(v)) == (enc(PI / 4, rounding="nearest"), 0)
            for sy, sx in ((1, -1), (-1, 1), (-1, -1)):
                r, f = fn(enc(sy * v), enc(sx * v))
                ref = math.atan2(sy, sx)
                assert f == 0 and _ulp_err(np.array([dec(r)]), np.array([ref]), W)[0] <= bound
        tiny, big = enc(2.0 ** -128), enc(2.0 ** 120)
        assert fn(tiny, big) == (0, 0)
        assert fn(big, tiny) == (enc(PI / 2, rounding="nearest"), 0)


@pytest.mark.cases("flightsw.arith.m1750_math.sqrt32_lanes",
                   "empty", "zero", "negative", "even-exponent", "odd-exponent", "mixed-block")
def test_sqrt32_lanes_against_numpy():
    """Lanes of every kind in one block: within 1.5 ulp of numpy's sqrt, exact squares exact,
    zero and negative lanes 0, FLAG_DOMAIN in the OR only when a lane is negative."""
    rng = np.random.default_rng(17)
    v = np.concatenate([np.exp2(rng.uniform(-127.9, 126.9, 2000)), [4.0, 9.0, 0.25, 2.0 ** -129]])
    x = m.encode32_array(v)
    out = np.empty_like(x)
    assert mm.sqrt32_lanes(x, out) == 0
    dv = m.decode32_array(x)
    e = np.frexp(dv)[1]
    assert (e % 2 == 0).any() and (e % 2 == 1).any()
    got = m.decode32_array(out)
    assert _ulp_err(got, np.sqrt(dv), 23).max() <= 1.5
    assert got[-4:-1].tolist() == [2.0, 3.0, 0.5]
    alone = out.copy()
    x[:3] = [0, m.encode32(-4.0), m.encode32(-1e-20)]
    assert mm.sqrt32_lanes(x, out) == m.FLAG_DOMAIN
    assert out[:3].tolist() == [0, 0, 0] and np.array_equal(out[3:], alone[3:])
    empty = np.empty(0, np.int64)
    assert mm.sqrt32_lanes(empty, empty.copy()) == 0


@pytest.mark.cases("flightsw.arith.m1750_math.atan2_32_lanes",
                   "empty", "origin", "axes", "octants", "ratio-underflow")
def test_atan2_32_lanes_against_numpy():
    """All octants, both axes, the origin, diagonals and an underflowing ratio in one block:
    within 8 ulp of numpy's arctan2 (no -0 on the 1750A: y = 0, x < 0 gives +pi), exact words
    for the origin, axes, diagonals (pi/4 rounded down) and the flushed ratio."""
    rng = np.random.default_rng(18)
    ang = rng.uniform(-np.pi, np.pi, 3000)
    rad = np.exp2(rng.uniform(-20, 20, 3000))
    yv = np.concatenate([rad * np.sin(ang), [0.0, 0.0, 0.0, 2.5, -2.5, 7.0, 2.0 ** 120]])
    xv = np.concatenate([rad * np.cos(ang), [0.0, 3.0, -3.0, 0.0, 0.0, 7.0, 2.0 ** -128]])
    y, x = m.encode32_array(yv), m.encode32_array(xv)
    out = np.empty_like(x)
    assert mm.atan2_32_lanes(y, x, out) == 0
    got = m.decode32_array(out[:-7])
    ref = np.arctan2(m.decode32_array(y[:-7]), m.decode32_array(x[:-7]))
    assert _ulp_err(got, ref, 23).max() <= 8
    assert {(a > 0, b > 0) for a, b in zip(yv, xv)} == {(1, 1), (1, 0), (0, 1), (0, 0)}
    E32 = m.encode32
    assert out[-7:].tolist() == [0, 0, E32(math.pi), E32(math.pi / 2),
                                 m.fneg32(E32(math.pi / 2))[0], E32(math.pi / 4), E32(math.pi / 2)]
    empty = np.empty(0, np.int64)
    assert mm.atan2_32_lanes(empty, empty, empty.copy()) == 0


# ------------------------------------------------------------------------------------------------
# declared operation mixes: count the float instructions the kernels execute (pure-Python run of
# each kernel with the module's op functions wrapped in counters)
# ------------------------------------------------------------------------------------------------
KEYS = {"fa32": "FA", "fs32": "FS", "fm32": "FM", "fd32": "FD", "fix32": "FIX", "flt32": "FLT",
        "fabs32": "FABS", "fneg32": "FNEG", "fc32": "FC", "fa48": "EFA", "fs48": "EFS",
        "fm48": "EFM", "fd48": "EFD", "fix48": "EFIX", "flt48": "EFLT", "fc48": "EFC",
        "fabs48": "EFS", "fneg48": "EFS"}


def _count(monkeypatch, kern_name, *args):
    counts = {}
    for fname, key in KEYS.items():
        orig = getattr(mm, fname)

        def wrapped(*a, _o=orig, _k=key):
            counts[_k] = counts.get(_k, 0) + 1
            return _o(*a)
        monkeypatch.setattr(mm, fname, wrapped)
    # inline helpers are numba dispatchers too: run their Python versions so the counters see them
    for helper in ("_reduce_n", "_reduce48", "_sin_poly32", "_cos_poly32", "_sin_poly48",
                   "_cos_poly48", "_trig32", "_trig48", "_scale32", "_scale48"):
        monkeypatch.setattr(mm, helper, getattr(mm, helper).py_func)
    for helper in ("_set_exp32", "_set_exp48", "_s16", "_s32"):
        monkeypatch.setattr(mm, helper, getattr(mm, helper).py_func)
    getattr(mm, kern_name).py_func(*args)
    monkeypatch.undo()
    return counts


@pytest.mark.parametrize("name,values", [
    ("sqrt32", [2.0, 3.0, 1e-20]), ("sqrt48", [2.0, 3.0, 1e20]), ("exp32", [1.5, -3.0, 80.0]),
    ("ln32", [0.6, 0.9, 1.3, 1e10]), ("sin32", [0.3, 2.0, 4.0, -5.5]), ("cos32", [0.3, 2.0, -4.0]),
    ("sin48", [0.3, 2.0, 4.0, -5.5]), ("cos48", [0.3, 2.0, -4.0]),
    ("atan2_32", [(1.0, 2.0), (-3.0, -1.0), (0.1, -5.0)]),
    ("atan2_48", [(1.0, 2.0), (-3.0, -1.0), (0.1, -5.0)])])
def test_declared_op_mix_covers_execution(monkeypatch, name, values):
    W48 = name.endswith("48")
    enc = m.encode48 if W48 else m.encode32
    declared = mm.MATH_OP_MIX[name]
    for v in values:
        args = tuple(enc(u) for u in v) if isinstance(v, tuple) else (enc(v),)
        counts = _count(monkeypatch, f"_{name}_k", *args)
        assert counts, name
        for k, c in counts.items():
            assert c <= declared.get(k, 0), (name, v, k, c, declared)
    assert mm.MATH_CYCLES[name] == m1750_cycles(declared) > 0
    assert m.op_cycles(name) == mm.MATH_CYCLES[name]


def test_lane_versions_equal_the_scalar_routines():
    """sqrt32_lanes / atan2_32_lanes (the branch-free lane forms, used by the feature kernel) give the
    scalar routines' words and flags element by element, zeros and domain errors included."""
    rng = np.random.default_rng(11)
    v = np.concatenate([rng.uniform(-50, 1e4, 3000), 10.0 ** rng.uniform(-30, 30, 3000),
                        [0.0, -1.0, 1.0, 0.25, 2.0 ** 126]])
    x = np.array([m.encode32(float(a)) for a in v], np.int64)
    y = np.array([m.encode32(float(a)) for a in rng.permutation(v) * np.sign(rng.normal(size=v.size))],
                 np.int64)
    y[:5] = 0
    x[:3] = 0
    out = np.empty_like(x)
    flags = mm.sqrt32_lanes(x, out)
    want = [mm.sqrt32(int(a)) for a in x]
    assert out.tolist() == [w[0] for w in want]
    f = 0
    for w in want:
        f |= w[1]
    assert flags == f and f & mm.FLAG_DOMAIN
    assert mm.atan2_32_lanes(y, x, out) == 0
    assert out.tolist() == [mm.atan2_32(int(a), int(b))[0] for a, b in zip(y, x)]
