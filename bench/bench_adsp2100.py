"""7x7 Q1.15 correlation over a 64x64 window (200,704 MACs): each contender computes the same result
(16-bit image x Q1.15 kernel, wide accumulation, round half to even, saturation to 16 bits) and is
checked bit-equal to ours before it is timed, on the bench window and on hand-made tie and
saturation cases. The bit-exact library peers are what an expert would write: ``cv2.filter2D`` and
``scipy.ndimage.correlate`` in float64 (the products and their sums are exact in float64) +
``np.rint`` (half to even) + saturation; plain numpy int64 is whole-array shifted windows.
apytypes and fxpmath are fixed-point emulation libraries (the word semantics spelled out per tap),
kept as such, not as the fastest bit-exact peer. The plain numba int64 loop rounds half up and does
not saturate, so it is the floor rather than a peer doing the same work.

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


def _round_saturate(acc):
    """float64 sums of the Q1.15 products (exact: each product < 2**42 and 49 of them < 2**53)
    rounded half to even (``np.rint``, the ADSP's convergent rounding) and saturated to int16."""
    np.rint(acc, out=acc)
    return np.clip(acc, -32768, 32767, out=acc).astype(np.int16)


def cv2_filter2d_float64(img, kern):
    """The bit-exact OpenCV peer: ``cv2.filter2D`` in float64 (direct, not DFT, for 7x7) with the
    kernel as its exact Q1.15 values, the valid part cut out, ``np.rint``, saturation."""
    import cv2
    kh, kw = kern.shape
    acc = cv2.filter2D(img.astype(np.float64), -1, kern.astype(np.float64) / 32768)
    return _round_saturate(acc[kh // 2:img.shape[0] - kh // 2, kw // 2:img.shape[1] - kw // 2])


def scipy_correlate_float64(img, kern):
    """The same in SciPy: ``ndimage.correlate`` in float64, valid part, ``np.rint``, saturation."""
    from scipy import ndimage
    kh, kw = kern.shape
    acc = ndimage.correlate(img.astype(np.float64), kern.astype(np.float64) / 32768)
    return _round_saturate(acc[kh // 2:img.shape[0] - kh // 2, kw // 2:img.shape[1] - kw // 2])


def _edge_cases():
    """Hand-made inputs where the rounding and saturation matter: a kernel of one +1/2 and one
    -1/2 tap on odd and even words (every output an exact half: ties to even), and a kernel of
    49 taps of 32767/32768 on full-scale words (the sums overflow 16 bits both ways)."""
    rng = np.random.default_rng(2100)
    words = rng.integers(-32768, 32768, (20, 20)).astype(np.int16)
    ties = np.zeros((7, 7), np.int16)
    ties[3, 3], ties[0, 6] = 16384, -16384
    big = np.where(rng.random((20, 20)) < 0.5, -32768, 32767).astype(np.int16)
    return [(words, ties), (big, np.full((7, 7), 32767, np.int16)), (words, KERN)]


def _check_bit_exact(peer):
    np.testing.assert_array_equal(peer(IMG, KERN), EXPECT)
    for img, kern in _edge_cases():
        want = correlate_valid_q15(img, kern)
        np.testing.assert_array_equal(peer(img, kern), want)


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
    _check_bit_exact(plain_numpy_int64)
    benchmark(plain_numpy_int64, IMG, KERN)


@pytest.mark.benchmark(group=GROUP)
def test_opencv_filter2d_float64_rint(benchmark):
    pytest.importorskip("cv2")
    _check_bit_exact(cv2_filter2d_float64)
    benchmark(cv2_filter2d_float64, IMG, KERN)


@pytest.mark.benchmark(group=GROUP)
def test_scipy_correlate_float64_rint(benchmark):
    _check_bit_exact(scipy_correlate_float64)
    benchmark(scipy_correlate_float64, IMG, KERN)


def test_edge_cases_reach_ties_and_saturation():
    """The hand-made cases exercise what they are for: many exact halves (odd differences of the
    two +-1/2 taps' words) and both saturation rails."""
    (w, _), (big, full), _ = _edge_cases()
    diff = w[3:-3, 3:-3].astype(np.int64) - w[:-6, 6:].astype(np.int64)
    assert (diff % 2 != 0).mean() > 0.3
    out = correlate_valid_q15(big, full)
    assert (out == 32767).any() and (out == -32768).any()


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
