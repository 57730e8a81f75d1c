"""The branch-free 1750A instructions (flightsw.arith.m1750_lanes) against the scalar reference forms
(flightsw.arith.m1750_float, themselves checked against the standard in test_m1750.py): identical
result words and PI flags on random operands over the whole exponent range (so every overflow and
underflow path is taken) and on adversarial ones (zeros, -1.0 and 0.5 mantissas, cancellations,
exact quotients, extreme exponents)."""
import numpy as np
import pytest
from numba import njit

import flightsw.arith.m1750_float as mf
import flightsw.arith.m1750_math as mm
import flightsw.arith.m1750_lanes as ml

N = 200_000


def _operands(W, n, seed):
    """n normalised words: random mantissas, a quarter each with full-range, small, extreme and
    equal-to-a-neighbour exponents; specials spliced in."""
    rng = np.random.default_rng(seed)
    top = 1 << W
    mag = rng.integers(top // 2, top, n, dtype=np.int64)
    m = np.where(rng.random(n) < 0.5, mag, -mag - 1)              # [-2**W, -2**(W-1)-1] for < 0
    kind = rng.integers(0, 4, n)
    e = np.where(kind == 0, rng.integers(-128, 128, n),
                 np.where(kind == 1, rng.integers(-6, 7, n),
                          np.where(kind == 2, rng.choice([-128, -127, -126, 125, 126, 127], n),
                                   rng.integers(-2, 3, n))))
    special = rng.random(n) < 0.15
    sm = rng.choice(np.array([0, top // 2, -top, top - 1, -top // 2 - 1, top // 2 + 1, -top + 1],
                             np.int64), n)
    m = np.where(special, sm, m)
    w = mf.pack32(m, e) if W == 23 else mf.pack48(m, e)
    return np.where(m == 0, 0, w)


def _pairs(W, seed):
    """Operand pairs; an eighth each with b = a, b = -a, b = a with its low bits changed
    (cancellations) and a = b * (small integer) (exact quotients)."""
    a = _operands(W, N, seed)
    b = _operands(W, N, seed + 1)
    rng = np.random.default_rng(seed + 2)
    k = N // 8
    b[:k] = a[:k]
    _apply1(mf._fneg32_k if W == 23 else mf._fneg48_k, a[k:2 * k], b[k:2 * k],
            np.empty(k, np.int64))
    low = rng.integers(0, 256, k) << (8 if W == 23 else 0)
    b[2 * k:3 * k] = np.where(a[2 * k:3 * k] == 0, 0, a[2 * k:3 * k] ^ low)
    small = (mf.encode32_array if W == 23 else mf.encode48_array)(np.arange(k) % 13 + 1.0)
    _apply2(mf._fm32_k if W == 23 else mf._fm48_k, b[3 * k:4 * k], small, a[3 * k:4 * k],
            np.empty(k, np.int64))
    return a, b


@njit(cache=True)
def _apply2(op, a, b, out, flags):
    """out[i], flags[i] = op(a[i], b[i]) for a scalar kernel or a lane form (FC: flags 0)."""
    for i in range(a.size):
        r = op(a[i], b[i])
        if isinstance(r, tuple):
            out[i], flags[i] = r
        else:
            out[i], flags[i] = r, 0


@njit(cache=True)
def _apply1(op, a, out, flags):
    for i in range(a.size):
        out[i], flags[i] = op(a[i])


@njit(cache=True)
def _apply_scale(op, a, k, out, flags):
    for i in range(a.size):
        out[i], flags[i] = op(a[i], k[i])


OPS2 = {"fa32": (mf._fa32_k, ml.fa32_v, ml.fa32_lanes), "fs32": (mf._fs32_k, ml.fs32_v, ml.fs32_lanes),
        "fm32": (mf._fm32_k, ml.fm32_v, ml.fm32_lanes), "fd32": (mf._fd32_k, ml.fd32_v, ml.fd32_lanes),
        "fa48": (mf._fa48_k, ml.fa48_v, ml.fa48_lanes), "fs48": (mf._fs48_k, ml.fs48_v, ml.fs48_lanes),
        "fm48": (mf._fm48_k, ml.fm48_v, ml.fm48_lanes), "fd48": (mf._fd48_k, ml.fd48_v, ml.fd48_lanes),
        "fc32": (mf._fc32_k, ml.fc32_v, None)}


def _check(name, a, ref, res, fref, fres, b=None):
    bad = np.flatnonzero((ref != res) | (fref != fres))
    if bad.size:
        i = bad[0]
        ops = f"{a[i]:#x}" + ("" if b is None else f", {b[i]:#x}")
        pytest.fail(f"{name}({ops}): reference {ref[i]:#x}/{fref[i]:#x}, branch-free "
                    f"{res[i]:#x}/{fres[i]:#x} ({bad.size} of {len(a)} differ)")


def _results(n):
    return [np.empty(n, np.int64) for _ in range(4)]


@pytest.mark.parametrize("name", OPS2)
def test_binary_equal_reference(name):
    """Element by element (words and flags), then the array form (words and the flags' OR)."""
    ref_k, v_k, lanes = OPS2[name]
    W = 39 if "48" in name else 23
    a, b = _pairs(W, 10 + list(OPS2).index(name))
    ref, res, fref, fres = _results(N)
    _apply2(ref_k, a, b, ref, fref)
    _apply2(v_k, a, b, res, fres)
    _check(name, a, ref, res, fref, fres, b)
    if lanes is not None:
        out = np.empty(N, np.int64)
        assert lanes(a, b, out) == np.bitwise_or.reduce(fref)
        assert np.array_equal(out, ref)
    # the operand mix reaches the paths that matter
    if name[:2] in ("fa", "fm", "fd"):
        assert np.any(fref == mf.FLAG_FLOAT_OVERFLOW) and np.any(fref == mf.FLAG_FLOAT_UNDERFLOW)
    assert np.any(ref == 0)


OPS1 = {"flt48": (mf._flt48_k, ml.flt48_v, ml.flt48_lanes),
        "fabs32": (mf._fabs32_k, ml.fabs32_v, ml.fabs32_lanes),
        "fneg32": (mf._fneg32_k, ml.fneg32_v, ml.fneg32_lanes),
        "fix32": (mf._fix32_k, ml.fix32_v, ml.fix32_lanes),
        "scale32": (mm._scale32, ml.scale32_v, None)}


@pytest.mark.parametrize("name", OPS1)
def test_unary_equal_reference(name):
    ref_k, v_k, lanes = OPS1[name]
    op = list(OPS1).index(name)
    rng = np.random.default_rng(50 + op)
    if name == "flt48":
        a = np.concatenate([rng.integers(0, 1 << 32, N - 8, dtype=np.int64),
                            np.array([0, 1, 0xFFFFFFFF, 0x80000000, 0x7FFFFFFF, 0x40000000,
                                      0xC0000000, 0xBFFFFFFF], np.int64)])
    else:
        a = _operands(23, N, 60 + op)
    ref, res, fref, fres = _results(N)
    if lanes is None:                            # scale32: p * 2**k
        k = rng.integers(-300, 300, N)
        _apply_scale(ref_k, a, k, ref, fref)
        _apply_scale(v_k, a, k, res, fres)
    else:
        _apply1(ref_k, a, ref, fref)
        _apply1(v_k, a, res, fres)
        out = np.empty(N, np.int64)
        assert lanes(a, out) == np.bitwise_or.reduce(fref)
        assert np.array_equal(out, ref)
    _check(name, a, ref, res, fref, fres)


@njit(cache=True)
def _key_signs(a, b, out):
    for i in range(a.size):
        d = ml.fc32_key(a[i]) - ml.fc32_key(b[i])
        out[i] = (d > 0) - (d < 0)


def test_fc32_key_orders_as_fc():
    """The ranking sorts by fc32_key: its integer order must be FC's on every pair."""
    a, b = _pairs(23, 90)
    ref, res, fref, fres = _results(N)
    _apply2(mf._fc32_k, a, b, ref, fref)
    _key_signs(a, b, res)
    _check("fc32_key", a, ref, res, fref, fref, b)
    keys = np.array([ml.fc32_key.py_func(int(w)) for w in a[:2000]])
    vals = mf.decode32_array(a[:2000])
    assert np.array_equal(np.argsort(keys, kind="stable"), np.argsort(vals, kind="stable"))


def test_fd32_pos_equals_fd_on_positive_operands():
    """fd32_pos_lanes (sqrt32's Heron division) is FD for positive mantissas and exponent
    differences the format holds: normalised and unnormalised operands, exponents -60..60."""
    rng = np.random.default_rng(91)
    top = 1 << 23
    ma = np.where(rng.random(N) < 0.9, rng.integers(top // 2, top, N), rng.integers(1, top, N))
    mo = np.where(rng.random(N) < 0.9, rng.integers(top // 2, top, N), rng.integers(1, top, N))
    mo[:1000] = ma[:1000]                                        # exact quotients of 1
    a = mf.pack32(ma, rng.integers(-60, 61, N))
    b = mf.pack32(mo, rng.integers(-60, 61, N))
    ref, res, fref, fres = _results(N)
    _apply2(mf._fd32_k, a, b, ref, fref)
    ml.fd32_pos_lanes(a, b, res)
    assert not fref.any()
    _check("fd32_pos", a, ref, res, fref, fref, b)
