"""MIL-STD-1750A float emulation speed: per-element cost of the bit-exact 1750A operations and math
routines in a numba loop over 10**5-element arrays of packed words, beside plain numpy float32
(float64 for the 48-bit forms) on the same values. numpy is the floor, not a peer: it is IEEE
round-to-nearest in hardware, not the 1750A's truncating arithmetic. Each contender's result is
checked against the other (loose tolerance) before it is timed.

Our contenders are the ``test_ours_*`` tests (bench/report.py convention); each records
``extra_info["ns_per_element"]`` (median time / N).

Run: ``.venv/bin/python -m pytest bench/bench_m1750.py --benchmark-enable -q``.
"""
import numpy as np
import pytest
from numba import njit

from flightsw.arith import m1750_float as mf
from flightsw.arith import m1750_math as mm
from flightsw.numba_cache import dispatcher_of

N = 100_000
RNG = np.random.default_rng(1750)
XA = RNG.uniform(-1000.0, 1000.0, N)
XB = RNG.uniform(0.5, 2000.0, N) * RNG.choice([-1.0, 1.0], N)
XP = np.exp2(RNG.uniform(-60, 60, N))            # positive, for sqrt
XE = RNG.uniform(-80.0, 80.0, N)                 # exp arguments in range
A32, B32, P32, E32 = (mf.encode32_array(v) for v in (XA, XB, XP, XE))
A48, B48, P48 = (mf.encode48_array(v) for v in (XA, XB, XP))
F32 = {k: mf.decode32_array(v).astype(np.float32) for k, v in
       dict(a=A32, b=B32, p=P32, e=E32).items()}
F64 = {k: mf.decode48_array(v) for k, v in dict(a=A48, b=B48, p=P48).items()}


# not cached: numba keys a cached kernel that takes a kernel as an argument on that kernel's type,
# which holds only a weak reference to it; a cache index written by another process then holds
# dead references, and saving a new entry beside them fails ("underlying object has vanished")
@njit
def _loop2(f, a, b, out):
    fl = 0
    for i in range(a.size):
        out[i], g = f(a[i], b[i])
        fl |= g
    return fl


@njit
def _loop1(f, a, out):
    fl = 0
    for i in range(a.size):
        out[i], g = f(a[i])
        fl |= g
    return fl


def _record(benchmark):
    benchmark.extra_info["n"] = N
    if benchmark.stats is not None:            # None under --benchmark-disable (smoke runs)
        benchmark.extra_info["ns_per_element"] = benchmark.stats.stats.median / N * 1e9


CASES2 = [  # name, kernel, a, b, decoder, numpy ufunc, numpy operands, rtol
    ("fa32", mf._fa32_k, A32, B32, mf.decode32_array, np.add, (F32["a"], F32["b"]), 1e-3),
    ("fm32", mf._fm32_k, A32, B32, mf.decode32_array, np.multiply, (F32["a"], F32["b"]), 1e-6),
    ("fd32", mf._fd32_k, A32, B32, mf.decode32_array, np.divide, (F32["a"], F32["b"]), 1e-6),
    ("fa48", mf._fa48_k, A48, B48, mf.decode48_array, np.add, (F64["a"], F64["b"]), 1e-9),
    ("fm48", mf._fm48_k, A48, B48, mf.decode48_array, np.multiply, (F64["a"], F64["b"]), 1e-11),
    ("atan2_32", mm._atan2_32_k, A32, B32, mf.decode32_array, np.arctan2, (F32["a"], F32["b"]), 1e-5),
]
CASES1 = [
    ("sqrt32", mm._sqrt32_k, P32, mf.decode32_array, np.sqrt, F32["p"], 1e-6),
    ("sqrt48", mm._sqrt48_k, P48, mf.decode48_array, np.sqrt, F64["p"], 1e-11),
    ("exp32", mm._exp32_k, E32, mf.decode32_array, np.exp, F32["e"], 1e-5),
]


@pytest.mark.parametrize("name,kern,a,b,dec,uf,fops,rtol", CASES2, ids=[c[0] for c in CASES2])
def test_ours_m1750_binary(benchmark, name, kern, a, b, dec, uf, fops, rtol):
    benchmark.group = f"m1750 {name} (10^5 elements)"
    out = np.empty(N, np.int64)
    kern = dispatcher_of(kern)                 # a first-class value: numba's dispatcher
    _loop2(kern, a, b, out)
    np.testing.assert_allclose(dec(out), uf(*(x.astype(np.float64) for x in fops)), rtol=rtol,
                               atol=1e-30)
    benchmark(_loop2, kern, a, b, out)
    _record(benchmark)


@pytest.mark.parametrize("name,kern,a,b,dec,uf,fops,rtol", CASES2, ids=[c[0] for c in CASES2])
def test_numpy_float_binary(benchmark, name, kern, a, b, dec, uf, fops, rtol):
    benchmark.group = f"m1750 {name} (10^5 elements)"
    res = np.empty_like(fops[0])
    benchmark(uf, *fops, out=res)
    _record(benchmark)


@pytest.mark.parametrize("name,kern,a,dec,uf,fop,rtol", CASES1, ids=[c[0] for c in CASES1])
def test_ours_m1750_unary(benchmark, name, kern, a, dec, uf, fop, rtol):
    benchmark.group = f"m1750 {name} (10^5 elements)"
    out = np.empty(N, np.int64)
    kern = dispatcher_of(kern)
    _loop1(kern, a, out)
    np.testing.assert_allclose(dec(out), uf(fop.astype(np.float64)), rtol=rtol)
    benchmark(_loop1, kern, a, out)
    _record(benchmark)


@pytest.mark.parametrize("name,kern,a,dec,uf,fop,rtol", CASES1, ids=[c[0] for c in CASES1])
def test_numpy_float_unary(benchmark, name, kern, a, dec, uf, fop, rtol):
    benchmark.group = f"m1750 {name} (10^5 elements)"
    res = np.empty_like(fop)
    benchmark(uf, fop, out=res)
    _record(benchmark)
