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


def _words(m, e, W):
    """Normalised mantissas m (W + 1 bit signed) and exponents e -> packed words."""
    m = np.asarray(m, np.int64)
    e = np.asarray(e, np.int64)
    if W == 23:
        return ((m & 0xFFFFFF) << 8) | (e & 0xFF)
    return (((m >> 16) & 0xFFFFFF) << 24) | ((e & 0xFF) << 16) | (m & 0xFFFF)


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
    w = _words(m, e, W)
    return np.where(m == 0, 0, w)


def _pairs(W, seed):
    a = _operands(W, N, seed)
    b = _operands(W, N, seed + 1)
    rng = np.random.default_rng(seed + 2)
    # cancellations and exact relations: b = a, b = -a, b = a with the last bits changed
    k = N // 8
    b[:k] = a[:k]
    neg = a[k:2 * k].copy()
    mask = (1 << 32) - 1 if W == 23 else (1 << 48) - 1
    b[k:2 * k] = neg                            # patched to -a below through the reference op
    b[2 * k:3 * k] = a[2 * k:3 * k] ^ (rng.integers(0, 256, k) << (8 if W == 23 else 0)) & mask
    b[2 * k:3 * k] = np.where(a[2 * k:3 * k] == 0, 0, b[2 * k:3 * k])
    return a, b


@njit(cache=True)
def _neg_all(a, W):
    out = np.empty_like(a)
    for i in range(a.size):
        out[i] = mf._fneg32_k(a[i])[0] if W == 23 else mf._fneg48_k(a[i])[0]
    return out


@njit(cache=True)
def _run2(op, a, b, ref, res, fref, fres):
    for i in range(a.size):
        if op == 0:
            ref[i], fref[i] = mf._fa32_k(a[i], b[i])
            res[i], fres[i] = ml.fa32_v(a[i], b[i])
        elif op == 1:
            ref[i], fref[i] = mf._fs32_k(a[i], b[i])
            res[i], fres[i] = ml.fs32_v(a[i], b[i])
        elif op == 2:
            ref[i], fref[i] = mf._fm32_k(a[i], b[i])
            res[i], fres[i] = ml.fm32_v(a[i], b[i])
        elif op == 3:
            ref[i], fref[i] = mf._fd32_k(a[i], b[i])
            res[i], fres[i] = ml.fd32_v(a[i], b[i])
        elif op == 4:
            ref[i], fref[i] = mf._fa48_k(a[i], b[i])
            res[i], fres[i] = ml.fa48_v(a[i], b[i])
        elif op == 5:
            ref[i], fref[i] = mf._fs48_k(a[i], b[i])
            res[i], fres[i] = ml.fs48_v(a[i], b[i])
        elif op == 6:
            ref[i], fref[i] = mf._fm48_k(a[i], b[i])
            res[i], fres[i] = ml.fm48_v(a[i], b[i])
        elif op == 7:
            ref[i], fref[i] = mf._fd48_k(a[i], b[i])
            res[i], fres[i] = ml.fd48_v(a[i], b[i])
        elif op == 8:
            ref[i], fref[i] = mf._fc32_k(a[i], b[i]), 0
            res[i], fres[i] = ml.fc32_v(a[i], b[i]), 0


@njit(cache=True)
def _run1(op, a, k, ref, res, fref, fres):
    for i in range(a.size):
        if op == 0:
            ref[i], fref[i] = mf._flt48_k(a[i])
            res[i], fres[i] = ml.flt48_v(a[i])
        elif op == 1:
            ref[i], fref[i] = mf._fabs32_k(a[i])
            res[i], fres[i] = ml.fabs32_v(a[i])
        elif op == 2:
            ref[i], fref[i] = mf._fneg32_k(a[i])
            res[i], fres[i] = ml.fneg32_v(a[i])
        elif op == 3:
            ref[i], fref[i] = mf._fix32_k(a[i])
            res[i], fres[i] = ml.fix32_v(a[i])
        elif op == 4:
            ref[i], fref[i] = mm._scale32(a[i], k[i])
            res[i], fres[i] = ml.scale32_v(a[i], k[i])


OPS2 = ["fa32", "fs32", "fm32", "fd32", "fa48", "fs48", "fm48", "fd48", "fc32"]


def _check(name, a, ref, res, fref, fres, b=None):
    bad = np.flatnonzero((ref != res) | (fref != fres))
    if bad.size:
        i = bad[0]
        ops = f"{a[i]:#x}" + ("" if b is None else f", {b[i]:#x}")
        pytest.fail(f"{name}({ops}): reference {ref[i]:#x}/{fref[i]:#x}, branch-free "
                    f"{res[i]:#x}/{fres[i]:#x} ({bad.size} of {len(a)} differ)")


@pytest.mark.parametrize("op", range(len(OPS2)), ids=OPS2)
def test_binary_equal_reference(op):
    name = OPS2[op]
    W = 39 if "48" in name else 23
    a, b = _pairs(W, 10 + op)
    k = N // 8
    b[k:2 * k] = _neg_all(a[k:2 * k], W)
    if name.startswith("fd"):                   # exact quotients: a = b * (small integer) / 2**j
        c = _operands(W, k, 99)
        small = mf.encode32_array(np.arange(1, k + 1) % 13 + 1.0) if W == 23 else \
            mf.encode48_array(np.arange(1, k + 1) % 13 + 1.0)
        mul = mf._fm32_k if W == 23 else mf._fm48_k
        a[3 * k:4 * k] = [mul(int(x), int(y))[0] for x, y in zip(c, small)]
        b[3 * k:4 * k] = c
    ref, res = np.empty(N, np.int64), np.empty(N, np.int64)
    fref, fres = np.empty(N, np.int64), np.empty(N, np.int64)
    _run2(op, a, b, ref, res, fref, fres)
    _check(name, a, ref, res, fref, fres, b)
    # the operand mix reaches the paths that matter
    if name[:2] in ("fa", "fm", "fd"):
        assert np.any(fref == mf.FLAG_FLOAT_OVERFLOW) and np.any(fref == mf.FLAG_FLOAT_UNDERFLOW)
    assert np.any(ref == 0)


OPS1 = ["flt48", "fabs32", "fneg32", "fix32", "scale32"]


@pytest.mark.parametrize("op", range(len(OPS1)), ids=OPS1)
def test_unary_equal_reference(op):
    name = OPS1[op]
    rng = np.random.default_rng(50 + op)
    if name == "flt48":
        a = np.concatenate([rng.integers(0, 1 << 32, N - 8, dtype=np.int64),
                            np.array([0, 1, 0xFFFFFFFF, 0x80000000, 0x7FFFFFFF, 0x40000000,
                                      0xC0000000, 0xBFFFFFFF], np.int64)])
    else:
        a = _operands(23, N, 60 + op)
    k = rng.integers(-300, 300, N)
    ref, res = np.empty(N, np.int64), np.empty(N, np.int64)
    fref, fres = np.empty(N, np.int64), np.empty(N, np.int64)
    _run1(op, a, k, ref, res, fref, fres)
    _check(name, a, ref, res, fref, fres)
