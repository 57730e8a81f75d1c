"""7x7 Q1.15 correlation over a 64x64 window (200,704 MACs): each contender computes the same result
(16-bit image x Q1.15 kernel, wide accumulation, round half to even, saturation to 16 bits) and is
checked equal to ours before it is timed (plain numpy int64 too: whole-array shifted windows); the
plain numba int64 loop rounds half up and does not saturate, so it is the floor rather than a peer
doing the same work.

Run: ``.venv/bin/python -m pytest bench/bench_adsp2100.py --benchmark-enable``.
"""
import numpy as np
import pytest
from numba import njit

from flightsw.arith.adsp2100 import correlate_valid_q15

GROUP = "mac: 7x7 Q15 correlation, 64x64 window"


def _inputs():
    rng = np.random.default_rng(7)
    img = rng.integers(0, 4096, (70, 70)).astype(np.int16)     # 12-bit pixels, padded window
    g = np.exp(-0.5 * ((np.arange(7) - 3) / 1.5) ** 2)
    kern = np.round(np.outer(g, g) / np.outer(g, g).sum() * 32768).astype(np.int16)
    return img, kern


IMG, KERN = _inputs()
EXPECT = correlate_valid_q15(IMG, KERN)


@njit(cache=True)
def plain_numba_int64(img, kern):
    kh, kw = kern.shape
    h, w = img.shape[0] - kh + 1, img.shape[1] - kw + 1
    out = np.empty((h, w), np.int64)
    for r in range(h):
        for c in range(w):
            acc = 0
            for i in range(kh):
                for j in range(kw):
                    acc += np.int64(img[r + i, c + j]) * np.int64(kern[i, j])
            out[r, c] = (acc + 16384) >> 15
    return out


def plain_numpy_int64(img, kern):
    """The same arithmetic in whole-array numpy int64: 49 shifted-window multiply-adds of the
    fractional-mode products, round half to even at bit 16, saturation to 16 bits."""
    x = img.astype(np.int64)
    kh, kw = kern.shape
    h, w = x.shape[0] - kh + 1, x.shape[1] - kw + 1
    acc = np.zeros((h, w), np.int64)
    for i in range(kh):
        for j in range(kw):
            acc += x[i:i + h, j:j + w] * (int(kern[i, j]) << 1)
    q = (acc + 0x8000) >> 16
    q -= ((acc & 0xFFFF) == 0x8000) & (q & 1 == 1)               # a tie goes to the even word
    return np.clip(q, -32768, 32767).astype(np.int16)


def apytypes_correlate(img, kern):
    import apytypes as apy
    x = apy.APyFixedArray.from_float(img.astype(np.float64), int_bits=16, frac_bits=0)
    acc = None
    for i in range(7):
        for j in range(7):
            c = apy.APyFixed.from_float(float(kern[i, j]) / 32768, int_bits=1, frac_bits=15)
            tap = x[i:i + 64, j:j + 64] * c
            acc = tap if acc is None else acc + tap
    out = acc.cast(int_bits=16, frac_bits=0, quantization=apy.QuantizationMode.RND_CONV,
                   overflow=apy.OverflowMode.SAT)
    return out.to_numpy()


def fxpmath_correlate(img, kern):
    from fxpmath import Fxp
    x = Fxp(img.astype(np.int64), signed=True, n_word=16, n_frac=0)
    acc = None
    for i in range(7):
        for j in range(7):
            c = Fxp(float(kern[i, j]) / 32768, signed=True, n_word=16, n_frac=15)
            tap = Fxp(x[i:i + 64, j:j + 64] * c, signed=True, n_word=40, n_frac=15)
            acc = tap if acc is None else Fxp(acc + tap, signed=True, n_word=40, n_frac=15)
    out = Fxp(acc, signed=True, n_word=16, n_frac=0, rounding="around", overflow="saturate")
    return np.asarray(out.get_val())


@pytest.mark.benchmark(group=GROUP)
def test_ours_uvisi(benchmark):
    out = benchmark(correlate_valid_q15, IMG, KERN)
    np.testing.assert_array_equal(out, EXPECT)


@pytest.mark.benchmark(group=GROUP)
def test_plain_numba_int64(benchmark):
    out = benchmark(plain_numba_int64, IMG, KERN)
    assert np.abs(out - EXPECT).max() <= 1                     # same sums, round-half-up


@pytest.mark.benchmark(group=GROUP)
def test_plain_numpy_int64(benchmark):
    out = benchmark(plain_numpy_int64, IMG, KERN)
    np.testing.assert_array_equal(out, EXPECT)


@pytest.mark.benchmark(group=GROUP)
def test_apytypes(benchmark):
    pytest.importorskip("apytypes")
    out = benchmark(apytypes_correlate, IMG, KERN)
    np.testing.assert_array_equal(out, EXPECT)


@pytest.mark.benchmark(group=GROUP)
def test_fxpmath(benchmark):
    pytest.importorskip("fxpmath")
    out = benchmark.pedantic(fxpmath_correlate, (IMG, KERN), rounds=3, iterations=1)
    np.testing.assert_array_equal(out, EXPECT)
