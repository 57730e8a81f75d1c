"""Flight math library on 1750A float ops (flightsw.arith.m1750_math): max error against numpy on
dense samples (the bounds stated in MAX_ERROR), special cases, and the declared operation mixes."""
import numpy as np
import pytest
from numba import njit

from flightsw.arith import m1750 as m
from flightsw.arith import m1750_math as mm
from flightsw.budget import m1750_cycles

N = 20000
RNG = np.random.default_rng(20240611)


@njit(cache=True)
def _apply1(f, xs):
    out = np.empty_like(xs)
    fl = np.empty_like(xs)
    for i in range(xs.size):
        out[i], fl[i] = f(xs[i])
    return out, fl


@njit(cache=True)
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
    fn = getattr(mm, f"_{name}_k")       # the kernel behind the public name (first-class in numba)
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


@pytest.mark.parametrize("W,name", [(23, "sqrt32"), (39, "sqrt48")])
def test_sqrt_error(W, name):
    x = np.exp2(RNG.uniform(-127.9, 126.9, N))
    x[:8] = [2.0 ** -128, 0.25, 0.5, 1.0, 2.0, 4.0, 1.7e38, 3.0]
    _check(name, W, x, np.sqrt)


def test_exp32_error():
    x = np.concatenate([RNG.uniform(-88.0, 88.0, N), RNG.uniform(-1e-3, 1e-3, 2000),
                        [-88.7, 88.0, 0.5, -0.5, 1.0]])
    _check("exp32", 23, x, np.exp)


def test_ln32_error():
    x = np.concatenate([np.exp2(RNG.uniform(-127.9, 126.9, N)), 1 + RNG.uniform(-1e-3, 1e-3, 4000),
                        RNG.uniform(0.4, 2.1, 4000), [1.0, 2.0, 0.5, 1.7e38, 2.0 ** -128]])
    _check("ln32", 23, x, np.log)


@pytest.mark.parametrize("W,name,ref", [(23, "sin32", np.sin), (23, "cos32", np.cos),
                                        (39, "sin48", np.sin), (39, "cos48", np.cos)])
def test_sin_cos_error(W, name, ref):
    x = np.concatenate([RNG.uniform(-7.0, 7.0, N), RNG.uniform(-32767.0, 32767.0, N // 4),
                        RNG.uniform(-1e-4, 1e-4, 1000), np.pi / 4 * np.arange(-40, 41)])
    _check(name, W, x, ref)


@pytest.mark.parametrize("W,name", [(23, "atan2_32"), (39, "atan2_48")])
def test_atan2_error(W, name):
    ang = RNG.uniform(-np.pi, np.pi, N)
    rad = np.exp2(RNG.uniform(-20, 20, N))
    y, x = rad * np.sin(ang), rad * np.cos(ang)
    y = np.concatenate([y, [0.0, 0.0, 1.0, -1.0, 1.0, -1.0, 1.0, 1e-30]])
    x = np.concatenate([x, [1.0, -1.0, 0.0, 0.0, 1.0, -1.0, -1.0, -1.0]])
    _check(name, W, (y, x), np.arctan2, args=2)


def test_math_special_cases():
    E32, E48, D32 = m.encode32, m.encode48, m.decode32
    assert m.sqrt32(0) == (0, 0) and m.sqrt48(0) == (0, 0)
    assert m.sqrt32(E32(-4.0)) == (0, m.FLAG_DOMAIN) and m.sqrt48(E48(-4.0)) == (0, m.FLAG_DOMAIN)
    assert D32(m.sqrt32(E32(4.0))[0]) == 2.0 and m.decode48(m.sqrt48(E48(9.0))[0]) == 3.0
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
