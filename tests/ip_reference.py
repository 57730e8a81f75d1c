"""Float64 references and error bounds of the image processor's fixed-point steps, for the tests.

The flight code (``flightsw.ip``) holds only what the processors run; what the tests compare it
with lives here: the bounds derived in the modules' docstrings (high-pass detrender, threshold,
frequency filter), the chi-square GOF and the paper's approximation in float64, and the correlation
through the ADSP-2100 MAC emulation (an independent path to the same words).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from flightsw.arith.adsp2100 import correlate_valid_q15
from flightsw.ip.filters import as_words, pad_nearest


def correlate_q15_exact(img, kern):
    """Reference path through :func:`flightsw.arith.adsp2100.correlate_valid_q15` (int64 MR emulation)
    on the replicate-padded image; bit-identical to :func:`flightsw.ip.filters.correlate_q15`."""
    kern = np.asarray(kern, np.int16)
    img = as_words(img)
    return correlate_valid_q15(pad_nearest(img, kern.shape[0] // 2), kern)


def highpass_bound(taps, maxabs, sigma):
    """Bound of ``|ours - (x - gaussian_filter(x, sigma, truncate=3/sigma))|`` for 12-bit data (g=3):
    ``1/2 + 2**-4 + maxabs * sum|t_q t_q^T / 2**30 - T T^T|``."""
    i = np.arange(-3, 4)
    T = np.exp(-0.5 * (i / sigma) ** 2)
    T /= T.sum()
    tq = np.asarray(taps, np.float64) / 32768
    return 0.5 + 2.0 ** -4 + maxabs * np.abs(np.outer(tq, tq) - np.outer(T, T)).sum()


def threshold_bound(alpha, std):
    """Bound of ``|T4/16 - (mean + alpha*std)|`` (s = 0)."""
    eps = 1.0 / (512 * std) if std > 0 else 1 / 16
    return 1 / 32 + alpha * (1 / 16 + eps) + 1 / 32


def bound_map(info, shape):
    """Per-pixel error bound (h, w) from :func:`flightsw.ip.fftfilter.fft_correlate`'s info (each pixel gets its tile's)."""
    V = info["valid"]
    b = info["bounds"]
    h, w = shape
    return np.repeat(np.repeat(b, V, 0), V, 1)[:h, :w]


def gof_chi2(d, n):
    """Exact GOF: ``P(chi2_n >= d) = scipy.stats.chi2.sf(d, n)`` (ground-side comparison)."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n={n!r} must be an int >= 1")
    d = np.asarray(d, np.float64)
    if np.any(d < 0) or not np.all(np.isfinite(d)):
        raise ValueError("d must be finite and >= 0")
    return chi2.sf(d, n)


def gof_approx(d, n):
    """The paper's approximation ``exp(-d^2 ln2 / n^2)`` in float64 (ground-side reference)."""
    if not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n={n!r} must be an int >= 1")
    d = np.asarray(d, np.float64)
    return np.exp(-d * d * math.log(2.0) / (n * n))
