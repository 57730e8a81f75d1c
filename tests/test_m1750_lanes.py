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


@njit(cache=True)
def _in_nn_domain(a, b, W):
    """Every lane inside fd32_lanes'/fd48_lanes' positive-form domain?"""
    ok = True
    for i in range(a.size):
        ma, ea = ml.unpack32(a[i]) if W == 23 else ml.unpack48(a[i])
        mo, eo = ml.unpack32(b[i]) if W == 23 else ml.unpack48(b[i])
        ok &= ml._nn_domain(ma, ea, mo, eo)
    return ok


@pytest.mark.parametrize("W", [23, 39])
def test_fd_lanes_positive_form_equals_fd(W):
    """A block whose lanes all have a dividend >= 0, a divisor > 0 and (non-zero dividends) an
    exponent difference in -128..126 takes the positive form: the same words as FD/EFD, no flags,
    zero dividends with any exponent difference, the boundaries -128 and 126 included. One lane
    outside (difference 127: overflow) sends the block through the general form, flags and all."""
    rng = np.random.default_rng(40 + W)
    top = 1 << W
    ma = rng.integers(top // 2, top, N, dtype=np.int64)
    mo = rng.integers(top // 2, top, N, dtype=np.int64)
    mo[:2000] = ma[:2000]                                         # exact quotients of 1
    ea = rng.integers(-128, 128, N)
    eo = np.clip(ea - rng.integers(-128, 127, N), -128, 127)
    n = ea - eo
    n[:4] = (-128, -128, 126, 126)
    eo[:4] = ea[:4] - n[:4]
    keep = (eo >= -128) & (eo <= 127)
    ma, mo, ea, eo = ma[keep], mo[keep], ea[keep], eo[keep]
    ma[rng.random(ma.size) < 0.1] = 0                             # zero dividends, any exponents
    pack = mf.pack32 if W == 23 else mf.pack48
    a = np.where(ma == 0, 0, pack(ma, ea))
    b = pack(mo, eo)
    assert _in_nn_domain(a, b, W) and (ea - eo >= -128).all() and (ea - eo <= 126).all()
    ref_k, _, lanes = OPS2["fd32" if W == 23 else "fd48"]
    ref, res, fref, _ = _results(a.size)
    _apply2(ref_k, a, b, ref, fref)
    assert not fref.any() and lanes(a, b, res) == 0
    _check(f"fd{W + 9}_lanes positive form", a, ref, res, fref, fref, b)
    a[7] = pack(np.int64(top // 2), np.int64(127))                 # 127 - 0: overflow
    b[7] = pack(np.int64(top // 2), np.int64(0))
    assert not _in_nn_domain(a, b, W)
    _apply2(ref_k, a, b, ref, fref)
    assert lanes(a, b, res) == mf.FLAG_FLOAT_OVERFLOW == np.bitwise_or.reduce(fref)
    _check(f"fd{W + 9}_lanes general form", a, ref, res, fref, fref, b)


def test_atan2_lanes_zero_pairs_keep_the_positive_division():
    """atan2_32_lanes on a block of moderate magnitudes with atan2(0, 0), (0, x) and (y, 0) lanes:
    the scalar routine's words (its first division runs in fd32_lanes' positive form)."""
    rng = np.random.default_rng(12)
    v = rng.uniform(-500, 500, 4000)
    x = mf.encode32_array(v)
    y = mf.encode32_array(rng.permutation(v))
    x[:10] = 0
    y[5:15] = 0
    out = np.empty_like(x)
    assert mm.atan2_32_lanes(y, x, out) == 0
    assert out.tolist() == [mm.atan2_32(int(p), int(q))[0] for p, q in zip(y, x)]
