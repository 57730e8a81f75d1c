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
from flightsw.numba_cache import dispatcher_of

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


# The three helpers below take a compiled function as an argument, so they are not cached: numba
# pickles such signatures with a weak reference to the argument's dispatcher, and a warm cache
# index that holds one fails to save the next overload ("ReferenceError: underlying object has
# vanished", numba issues 2956 and 6251).
@njit
def _apply2(op, a, b, out, flags):
    """out[i], flags[i] = op(a[i], b[i]) for a scalar kernel or a lane form (FC: flags 0)."""
    for i in range(a.size):
        r = op(a[i], b[i])
        if isinstance(r, tuple):
            out[i], flags[i] = r
        else:
            out[i], flags[i] = r, 0


@njit
def _apply1(op, a, out, flags):
    for i in range(a.size):
        out[i], flags[i] = op(a[i])


@njit
def _apply_scale(op, a, k, out, flags):
    for i in range(a.size):
        out[i], flags[i] = op(a[i], k[i])


OPS2 = {"fa32": (mf._fa32_k, ml.fa32_v, ml.fa32_lanes), "fs32": (mf._fs32_k, ml.fs32_v, ml.fs32_lanes),
        "fm32": (mf._fm32_k, ml.fm32_v, ml.fm32_lanes), "fd32": (mf._fd32_k, ml.fd32_v, ml.fd32_lanes),
        "fa48": (mf._fa48_k, ml.fa48_v, ml.fa48_lanes), "fs48": (mf._fs48_k, ml.fs48_v, ml.fs48_lanes),
        "fm48": (mf._fm48_k, ml.fm48_v, ml.fm48_lanes), "fd48": (mf._fd48_k, ml.fd48_v, ml.fd48_lanes),
        "fc32": (mf._fc32_k, ml.fc32_v, None)}
OPS2 = {k: tuple(dispatcher_of(f) for f in fs) for k, fs in OPS2.items()}   # first-class values


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
OPS1 = {k: tuple(dispatcher_of(f) for f in fs) for k, fs in OPS1.items()}


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


# ------------------------------------------------------------------------------------------------
# every case of the lane forms on hand-worked operands: the expected words are worked out by hand
# from the standard's formats (Table III words: 1.0 = 4000 0001, 10.0 = 5000 0004, -1.0 =
# 8000 0000, ...) and rules (truncation toward minus infinity, overflow 7FFF FF7F / 8000 007F,
# underflow 0); each comment gives the arithmetic
# ------------------------------------------------------------------------------------------------
OV, UN, FX = mf.FLAG_FLOAT_OVERFLOW, mf.FLAG_FLOAT_UNDERFLOW, mf.FLAG_FIXED_OVERFLOW
V = {"fa32": ml.fa32_v, "fs32": ml.fs32_v, "fa48": ml.fa48_v, "fs48": ml.fs48_v, "fm32": ml.fm32_v,
     "fm48": ml.fm48_v, "fd32": ml.fd32_v, "fd48": ml.fd48_v, "fd32_pos": ml.fd32_pos_v,
     "fd48_pos": ml.fd48_pos_v, "flt48": ml.flt48_v, "fc32": ml.fc32_v, "fabs32": ml.fabs32_v,
     "fneg32": ml.fneg32_v, "fix32": ml.fix32_v, "scale32": ml.scale32_v}
V = {k: dispatcher_of(f) for k, f in V.items()}
LANE_CASES = [
    # 1 + 1 = 2: the sum reaches 1.0, shifted right, exponent + 1
    pytest.param("fa32", (0x40000001, 0x40000001), (0x40000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "exact"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "mantissa-overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._finish_v", "normalised")]),
    # 10 + 0.5 = 10.5: 0.5 shifted right 4
    pytest.param("fa32", (0x50000004, 0x40000000), (0x54000004, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "exact"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "align-right")]),
    # 1 + (-2**-40) = 1 - 2**-22: -2**-40 shifted out leaves -1 unit
    pytest.param("fa32", (0x40000001, 0x800000D8), (0x7FFFFE00, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "truncate"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "shifted-out"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._finish_v", "left-shift")]),
    # 0 + -2.5
    pytest.param("fa32", (0, 0xB0000002), (0xB0000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "zero-operand")]),
    # 3 + -3
    pytest.param("fa32", (0x60000002, 0xA0000002), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "cancel"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._finish_v", "zero")]),
    # -0.75 + 0.25 = -0.5 -> -1.0 * 2**-1
    pytest.param("fa32", (0xA0000000, 0x400000FF), (0x800000FF, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "exact"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._finish_v", "negative-power")]),
    # MAX + MAX
    pytest.param("fa32", (0x7FFFFF7F, 0x7FFFFF7F), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._finish_v", "overflow")]),
    # -2**127 + -2**127
    pytest.param("fa32", (0x8000007F, 0x8000007F), (0x8000007F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "overflow")]),
    # 0.75 * 2**-128 - 0.625 * 2**-128 needs exponent -130
    pytest.param("fa32", (0x60000080, 0xB0000080), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_v", "underflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "underflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._finish_v", "underflow")]),
    # 1 - 2 = -1
    pytest.param("fs32", (0x40000001, 0x40000002), (0x80000000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_v", "exact"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "subtract")]),
    # 1 - (0.5 + 2**-23) = 0.5 - 2**-22: negated first, then shifted (floor)
    pytest.param("fs32", (0x40000001, 0x40000100), (0x7FFFFCFF, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_v", "truncate"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "subtract")]),
    # 0 - -2.5 = 2.5
    pytest.param("fs32", (0, 0xB0000002), (0x50000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_v", "zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "zero-operand")]),
    # 3 - 3
    pytest.param("fs32", (0x60000002, 0x60000002), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_v", "zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "cancel")]),
    # MIN - MAX
    pytest.param("fs32", (0x8000007F, 0x7FFFFF7F), (0x8000007F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_v", "overflow")]),
    # 0.75 * 2**-128 - 0.5 * 2**-128
    pytest.param("fs32", (0x60000080, 0x40000080), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_v", "underflow")]),
    # 1 + 1
    pytest.param("fa48", (0x400000010000, 0x400000010000), (0x400000020000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_v", "exact"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "mantissa-overflow")]),
    # 1 + (-2**-60) = 1 - 2**-38
    pytest.param("fa48", (0x400000010000, 0x800000C40000), (0x7FFFFF00FFFE, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_v", "truncate"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._add_v", "shifted-out")]),
    # 0 + -2.5
    pytest.param("fa48", (0, 0xB00000020000), (0xB00000020000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_v", "zero")]),
    # MAX48 + MAX48
    pytest.param("fa48", (0x7FFFFF7FFFFF, 0x7FFFFF7FFFFF), (0x7FFFFF7FFFFF, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_v", "overflow")]),
    # 0.75 * 2**-128 - 0.625 * 2**-128
    pytest.param("fa48", (0x600000800000, 0xB00000800000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_v", "underflow")]),
    # 1 - 2 = -1
    pytest.param("fs48", (0x400000010000, 0x400000020000), (0x800000000000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_v", "exact")]),
    # 1 - (0.5 + 2**-39) = 0.5 - 2**-38
    pytest.param("fs48", (0x400000010000, 0x400000000001), (0x7FFFFFFFFFFC, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_v", "truncate")]),
    # 3 - 3
    pytest.param("fs48", (0x600000020000, 0x600000020000), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_v", "zero")]),
    # MIN48 - MAX48
    pytest.param("fs48", (0x8000007F0000, 0x7FFFFF7FFFFF), (0x8000007F0000, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_v", "overflow")]),
    # 0.75 * 2**-128 - 0.5 * 2**-128
    pytest.param("fs48", (0x600000800000, 0x400000800000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_v", "underflow")]),
    # 1.5 * 2.5 = 3.75 (one normalising shift)
    pytest.param("fm32", (0x60000001, 0x50000002), (0x78000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._mul_pre_v", "pass")]),
    # (1 + 2**-22) * -(1 + 2**-22) = -(1 + 2**-21 + 2**-44) -> -(1 + 3 * 2**-22)
    pytest.param("fm32", (0x40000101, 0xBFFFFF01), (0xBFFFFD01, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "floor")]),
    # (-1.0 * 2**5)(-1.0 * 2**7) = 0.5 * 2**13
    pytest.param("fm32", (0x80000005, 0x80000007), (0x4000000D, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "minus-one-squared")]),
    # n = 127, the result needs 128
    pytest.param("fm32", (0x8000003F, 0x80000040), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "minus-one-squared-overflow")]),
    # (0.5 * 2**64)**2: n = 128 > 127 before the multiply
    pytest.param("fm32", (0x40000040, 0x40000040), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "exp-overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._mul_pre_v", "exp-overflow")]),
    # negative product: 8000 007F
    pytest.param("fm32", (0xA0000040, 0x40000040), (0x8000007F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "exp-overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._mul_pre_v", "exp-overflow")]),
    # (2**-100)**2: n = -198
    pytest.param("fm32", (0x4000009D, 0x4000009D), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "exp-underflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._mul_pre_v", "exp-underflow")]),
    # 0.5 * 2**-128 * 0.5: normalising needs -129
    pytest.param("fm32", (0x40000080, 0x40000000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "norm-underflow")]),
    # 0 * MAX
    pytest.param("fm32", (0, 0x7FFFFF7F), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_v", "zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._mul_pre_v", "zero-operand")]),
    # 1.5 * 2.5 = 3.75
    pytest.param("fm48", (0x600000010000, 0x500000020000), (0x780000020000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "typical")]),
    # -1.5 * 2.5 = -3.75
    pytest.param("fm48", (0xA00000010000, 0x500000020000), (0x880000020000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "negative")]),
    # (1 + 2**-38) * -(1 + 2**-38) -> -(1 + 3 * 2**-38) (floor)
    pytest.param("fm48", (0x400000010001, 0xBFFFFF01FFFF), (0xBFFFFF01FFFD, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "negative")]),
    # -1.0 * 0.5 = -0.5 -> -1.0 * 2**-1
    pytest.param("fm48", (0x800000000000, 0x400000000000), (0x800000FF0000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "minus-half")]),
    # (-1.0 * 2**5)(-1.0 * 2**7)
    pytest.param("fm48", (0x800000050000, 0x800000070000), (0x4000000D0000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "minus-one-squared")]),
    # n = 127, result needs 128
    pytest.param("fm48", (0x8000003F0000, 0x800000400000), (0x7FFFFF7FFFFF, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "minus-one-squared-overflow")]),
    # (0.5 * 2**64)**2
    pytest.param("fm48", (0x400000400000, 0x400000400000), (0x7FFFFF7FFFFF, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "exp-overflow")]),
    # (2**-100)**2
    pytest.param("fm48", (0x4000009D0000, 0x4000009D0000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "exp-underflow")]),
    # 0.5 * 2**-128 * 0.5
    pytest.param("fm48", (0x400000800000, 0x400000000000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "norm-underflow")]),
    # 0 * MAX48
    pytest.param("fm48", (0, 0x7FFFFF7FFFFF), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_v", "zero")]),
    # 1 / 3 (floor)
    pytest.param("fd32", (0x40000001, 0x60000002), (0x555555FF, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "typical")]),
    # -1 / 3 -> floor, -(0x555556)
    pytest.param("fd32", (0x80000000, 0x60000002), (0xAAAAAAFF, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "negative")]),
    # 3 / 1.5 = 2: quotient 1.0 shifted right, n + 1
    pytest.param("fd32", (0x60000002, 0x60000001), (0x40000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "shift")]),
    # MAX / 0.5: n = 127, the shift needs 128
    pytest.param("fd32", (0x7FFFFF7F, 0x40000000), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "shift-overflow")]),
    # 0.5 / -1.0 = -0.5 -> -1.0 * 2**-1
    pytest.param("fd32", (0x40000000, 0x80000000), (0x800000FF, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "typical"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "minus-half")]),
    # 0.5 * 2**-128 / -1.0 needs -129
    pytest.param("fd32", (0x40000080, 0x80000000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "underflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "minus-half-underflow")]),
    # 1 / 0
    pytest.param("fd32", (0x40000001, 0), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "divide-by-zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "divide-by-zero")]),
    # -1 / 0
    pytest.param("fd32", (0x80000000, 0), (0x8000007F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "divide-by-zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "divide-by-zero")]),
    # 0 / 0
    pytest.param("fd32", (0, 0), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "divide-by-zero")]),
    # 0 / 3
    pytest.param("fd32", (0, 0x60000002), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "zero"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "zero-dividend")]),
    # 2**100 / 2**-100: n = 200
    pytest.param("fd32", (0x40000065, 0x4000009D), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "overflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "exp-overflow")]),
    # -2**101 / 2**-100
    pytest.param("fd32", (0x80000065, 0x4000009D), (0x8000007F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "exp-overflow")]),
    # 2**-100 / 2**100
    pytest.param("fd32", (0x4000009D, 0x40000065), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_v", "underflow"),
        pytest.mark.cases("flightsw.arith.m1750_lanes._div_v", "exp-underflow")]),
    # 1 / 3 (floor)
    pytest.param("fd48", (0x400000010000, 0x600000020000), (0x555555FF5555, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "typical")]),
    # -1 / 3 (floor)
    pytest.param("fd48", (0x800000000000, 0x600000020000), (0xAAAAAAFFAAAA, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "typical")]),
    # 3 / 1.5 = 2
    pytest.param("fd48", (0x600000020000, 0x600000010000), (0x400000020000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "typical")]),
    # 0.5 / -1.0 = -0.5
    pytest.param("fd48", (0x400000000000, 0x800000000000), (0x800000FF0000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "typical")]),
    # 1 / 0
    pytest.param("fd48", (0x400000010000, 0), (0x7FFFFF7FFFFF, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "divide-by-zero")]),
    # 0 / 3
    pytest.param("fd48", (0, 0x600000020000), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "zero")]),
    # 2**100 / 2**-100
    pytest.param("fd48", (0x400000650000, 0x4000009D0000), (0x7FFFFF7FFFFF, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "overflow")]),
    # 2**-100 / 2**100
    pytest.param("fd48", (0x4000009D0000, 0x400000650000), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_v", "underflow")]),
    # 1 / 3
    pytest.param("fd32_pos", (0x40000001, 0x60000002), 0x555555FF, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_pos_v", "below-one")]),
    # 3 / 1.5
    pytest.param("fd32_pos", (0x60000002, 0x60000001), 0x40000002, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_pos_v", "at-least-one")]),
    # 1 / 3
    pytest.param("fd48_pos", (0x400000010000, 0x600000020000), 0x555555FF5555, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_pos_v", "below-one")]),
    # 3 / 1.5
    pytest.param("fd48_pos", (0x600000020000, 0x600000010000), 0x400000020000, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_pos_v", "at-least-one")]),
    pytest.param("flt48", (0,), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_v", "zero")]),
    # 1 = 0.5 * 2**1
    pytest.param("flt48", (1,), (0x400000010000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_v", "positive")]),
    # 2**31 - 1
    pytest.param("flt48", (0x7FFFFFFF,), (0x7FFFFF1FFF00, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_v", "positive")]),
    # -2**31 = -1.0 * 2**31
    pytest.param("flt48", (0x80000000,), (0x8000001F0000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_v", "negative")]),
    # -1 = -1.0 * 2**0
    pytest.param("flt48", (0xFFFFFFFF,), (0x800000000000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_v", "negative")]),
    # 1 > -1
    pytest.param("fc32", (0x40000001, 0x80000000), 1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "different-signs")]),
    # 0 < 1
    pytest.param("fc32", (0, 0x40000001), -1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "different-signs")]),
    # -2.5 < 0
    pytest.param("fc32", (0xB0000002, 0), -1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "different-signs")]),
    pytest.param("fc32", (0, 0), 0, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "both-zero")]),
    # 2 > 1
    pytest.param("fc32", (0x40000002, 0x40000001), 1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "exponent")]),
    # -2 < -1
    pytest.param("fc32", (0x80000001, 0x80000000), -1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "exponent")]),
    # 1.5 > 1
    pytest.param("fc32", (0x60000001, 0x40000001), 1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "mantissa")]),
    # -1.5 > -2
    pytest.param("fc32", (0xA0000001, 0x80000001), 1, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "mantissa")]),
    # 10 = 10
    pytest.param("fc32", (0x50000004, 0x50000004), 0, marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_v", "equal")]),
    # |2.5|
    pytest.param("fabs32", (0x50000002,), (0x50000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_v", "non-negative")]),
    pytest.param("fabs32", (0,), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_v", "non-negative")]),
    # |-2.5|
    pytest.param("fabs32", (0xB0000002,), (0x50000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_v", "negative")]),
    # |-1.0| = 0.5 * 2**1
    pytest.param("fabs32", (0x80000000,), (0x40000001, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_v", "minus-one")]),
    # |-1.0 * 2**-128| = 0.5 * 2**-127
    pytest.param("fabs32", (0x80000080,), (0x40000081, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_v", "minus-one")]),
    # |-2**127|
    pytest.param("fabs32", (0x8000007F,), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_v", "minus-one-overflow")]),
    pytest.param("fneg32", (0,), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "zero")]),
    # -(2.5)
    pytest.param("fneg32", (0x50000002,), (0xB0000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "typical")]),
    # -(-2.5)
    pytest.param("fneg32", (0xB0000002,), (0x50000002, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "typical")]),
    # -(-1.0) = 0.5 * 2**1
    pytest.param("fneg32", (0x80000000,), (0x40000001, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "minus-one")]),
    # -(-2**127)
    pytest.param("fneg32", (0x8000007F,), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "minus-one-overflow")]),
    # -(0.5 * 2**5) = -1.0 * 2**4
    pytest.param("fneg32", (0x40000005,), (0x80000004, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "half")]),
    # -(0.5 * 2**-128) needs -129
    pytest.param("fneg32", (0x40000080,), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_v", "half-underflow")]),
    # 2.75 -> 2
    pytest.param("fix32", (0x58000002,), (2, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "positive")]),
    # 32767.996 -> 32767
    pytest.param("fix32", (0x7FFFFF0F,), (0x7FFF, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "positive")]),
    # -2.75 -> -2 (toward zero)
    pytest.param("fix32", (0xA8000002,), (0xFFFE, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "negative")]),
    # -32768
    pytest.param("fix32", (0x8000000F,), (0x8000, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "negative")]),
    # 32768 = 0.5 * 2**16
    pytest.param("fix32", (0x40000010,), (0, FX), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "overflow")]),
    # -65536
    pytest.param("fix32", (0x80000010,), (0, FX), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "overflow")]),
    # 2**-100 -> 0
    pytest.param("fix32", (0x4000009D,), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "small")]),
    # -2**-99 -> 0, not -1
    pytest.param("fix32", (0x8000009D,), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "small")]),
    # 0
    pytest.param("fix32", (0,), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_v", "small")]),
    pytest.param("scale32", (0, 500), (0, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "zero")]),
    # 10 * 8 = 80
    pytest.param("scale32", (0x50000004, 3), (0x50000007, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "in-range")]),
    # 0.5 * 2**127
    pytest.param("scale32", (0x40000001, 126), (0x4000007F, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "in-range")]),
    # 0.5 * 2**-128
    pytest.param("scale32", (0x40000001, -129), (0x40000080, 0), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "in-range")]),
    pytest.param("scale32", (0x40000001, 127), (0x7FFFFF7F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "overflow-positive")]),
    pytest.param("scale32", (0x80000000, 128), (0x8000007F, OV), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "overflow-negative")]),
    pytest.param("scale32", (0x40000080, -1), (0, UN), marks=[
        pytest.mark.cases("flightsw.arith.m1750_lanes.scale32_v", "underflow")]),
]


@pytest.mark.parametrize("op,args,want", LANE_CASES)
def test_lane_op_hand_worked(op, args, want):
    """One operation of the branch-free forms on hand-worked operands: result word and PI flags."""
    out, flags = np.empty(1, np.int64), np.empty(1, np.int64)
    ops = [np.array([v], np.int64) for v in args]
    if op == "scale32":
        _apply_scale(V[op], *ops, out, flags)
    elif len(args) == 2:
        _apply2(V[op], *ops, out, flags)
    else:
        _apply1(V[op], *ops, out, flags)
    got = (int(out[0]), int(flags[0]))
    assert got == (want if isinstance(want, tuple) else (want, 0)), [hex(v) for v in got]


LANES = {"fa32": ml.fa32_lanes, "fs32": ml.fs32_lanes, "fm32": ml.fm32_lanes, "fd32": ml.fd32_lanes,
         "fa48": ml.fa48_lanes, "fs48": ml.fs48_lanes, "fm48": ml.fm48_lanes, "fd48": ml.fd48_lanes,
         "flt48": ml.flt48_lanes, "fabs32": ml.fabs32_lanes, "fneg32": ml.fneg32_lanes,
         "fix32": ml.fix32_lanes}


def _rows(op):
    return [p.values for p in LANE_CASES if p.values[0] == op]


@pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_lanes", "general-block")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_lanes", "general-block")
@pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_lanes", "arrays")
@pytest.mark.cases("flightsw.arith.m1750_lanes._all_nn", "one-out")
def test_lanes_hand_worked_blocks():
    """All hand-worked cases of one instruction in one block: every lane its own word, the flags'
    OR returned (the division blocks hold negative operands and zero divisors: the general form)."""
    for op, lanes in LANES.items():
        rows = _rows(op)
        ops = [np.array([r[1][i] for r in rows], np.int64) for i in range(len(rows[0][1]))]
        out = np.empty(len(rows), np.int64)
        flags = lanes(*ops, out)
        assert out.tolist() == [r[2][0] for r in rows], op
        assert flags == np.bitwise_or.reduce([r[2][1] for r in rows]), op
        if op in ("fd32", "fd48"):
            assert not ml._all_nn(ops[0], ops[1], len(rows), 23 if op == "fd32" else 39)


@pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_lanes", "positive-block")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_lanes", "positive-block")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_pos_lanes", "positive")
@pytest.mark.cases("flightsw.arith.m1750_lanes._all_nn", "all-in", "one-out", "empty")
def test_fd_lanes_positive_block_hand_worked():
    """1 / 3, 3 / 1.5 and 0 / 3 (zero dividend) in one block: the positive form, FD's words (hand
    worked) and no flags; one negative lane sends the block through the general form."""
    for W, lanes, pos in ((23, ml.fd32_lanes, "fd32_pos"), (39, ml.fd48_lanes, "fd48_pos")):
        rows = _rows(pos)
        three = 0x60000002 if W == 23 else 0x600000020000
        a = np.array([r[1][0] for r in rows] + [0], np.int64)
        b = np.array([r[1][1] for r in rows] + [three], np.int64)
        out = np.empty(a.size, np.int64)
        assert ml._all_nn(a, b, a.size, W)
        assert lanes(a, b, out) == 0 and out.tolist() == [r[2] for r in rows] + [0]
        if W == 23:
            ml.fd32_pos_lanes(a[:-1], b[:-1], out[:-1])
            assert out[:-1].tolist() == [r[2] for r in rows]
        a[0] = 0x80000000 if W == 23 else 0x800000000000                  # -1 / 3: one lane out
        assert not ml._all_nn(a, b, a.size, W)
        assert lanes(a, b, out) == 0 and out[0] == (0xAAAAAAFF if W == 23 else 0xAAAAAAFFAAAA)
    empty = np.empty(0, np.int64)
    assert ml._all_nn(empty, empty, 0, 23)


@pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_lanes", "scalar-operand")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_lanes", "scalar-operand")
def test_lanes_scalar_operand():
    """One word for every lane, on either side: v + 1, 1 - v, 2 v, v / 2 and 4 / v are exact for
    these v, so the closed form is the oracle."""
    v = np.array([1.0, 2.0, 4.0, -8.0, 0.5, 0.25, -0.5])
    for enc, sfx in ((mf.encode32_array, "32"), (mf.encode48_array, "48")):
        x = enc(v)
        one, two, four = (int(enc(np.array([c]))[0]) for c in (1.0, 2.0, 4.0))
        out = np.empty(v.size, np.int64)
        for name, a, b, want in (("fa", x, one, v + 1), ("fs", one, x, 1 - v),
                                 ("fm", two, x, 2 * v), ("fd", x, two, v / 2),
                                 ("fd", four, x, 4 / v)):
            assert LANES[name + sfx](a, b, out) == 0
            assert np.array_equal(out, enc(want)), (name + sfx, want)


@pytest.mark.cases("flightsw.arith.m1750_lanes.fa32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fs32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fm32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fa48_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fs48_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fm48_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd48_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.flt48_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fabs32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fneg32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fix32_lanes", "empty")
@pytest.mark.cases("flightsw.arith.m1750_lanes.fd32_pos_lanes", "empty")
def test_lanes_empty():
    """K = 0: nothing to do, flags 0."""
    e = np.empty(0, np.int64)
    for op, lanes in LANES.items():
        binary = op not in ("flt48", "fabs32", "fneg32", "fix32")
        assert (lanes(e, e, e.copy()) if binary else lanes(e, e.copy())) == 0
    ml.fd32_pos_lanes(e, e, e.copy())


@pytest.mark.cases("flightsw.arith.m1750_lanes._nn_domain",
                   "positive", "zero-dividend", "negative", "exponent-range")
def test_nn_domain_hand_worked():
    """(ma, ea, mo, eo) -> inside the positive division form?"""
    top = 1 << 22
    inside = [(top, 5, 3 * top // 2, -3), (top, -128, top, 0), (top, 126, top, 0),
              (0, 127, top, -128)]
    outside = [(-top, 0, top, 0), (top, 0, -top, 0), (top, 0, 0, 0), (0, 0, 0, 0),
               (top, 127, top, 0), (top, -128, top, 1)]
    assert [bool(ml._nn_domain(*q)) for q in inside] == [True] * 4
    assert [bool(ml._nn_domain(*q)) for q in outside] == [False] * 6


@njit(cache=True)
def _keys(a, out):
    for i in range(a.size):
        out[i] = ml.fc32_key(a[i])


@pytest.mark.cases("flightsw.arith.m1750_lanes.fc32_key", "zero", "positive", "negative", "order")
def test_fc32_key_hand_worked():
    """Keys of increasing values increase strictly (the value order, independent of FC); zero is
    key 0, positive keys are (e + 128) 2**24 + m, negative ones minus that of the magnitude."""
    v = [-mf.decode32(mf.MAX32), -2.0, -1.5, -1.0, -0.5, -2.0 ** -128, 0.0, 2.0 ** -129, 0.5, 1.0,
         1.5, 2.0, 10.0, mf.decode32(mf.MAX32)]
    w = mf.encode32_array(np.array(v))
    k = np.empty(w.size, np.int64)
    _keys(w, k)
    assert (np.diff(k) > 0).all() and k[6] == 0
    assert k[9] == (1 + 128) * 2 ** 24 + 0x400000                         # 1.0 = 0.5 * 2**1
    assert k[3] == -((0 + 128) * 2 ** 24 + 0x800000)                     # -1.0 = -1.0 * 2**0
