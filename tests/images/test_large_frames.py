"""Large frames (issue 45): the compiled per-frame statistics of ``uvisi detect`` give the numbers
of the NumPy forms they replaced.

Oracles: :func:`hil_harness.images.noise_sigma` (the pixel noise, the same float), ``np.median``
(the histogram medians).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from hil_harness.detect.noise import MAX_DIFFERENCES, frame_noise
from hil_harness.images import noise_sigma


def _same(a, b):
    return a == b or (math.isnan(a) and math.isnan(b))


def _disc(shape, row, col, radius):
    yy, xx = np.mgrid[:shape[0], :shape[1]]
    return (yy + 0.5 - row) ** 2 + (xx + 0.5 - col) ** 2 < radius ** 2


# ------------------------------------------------------------------------------------------------
# the pixel noise
# ------------------------------------------------------------------------------------------------
@pytest.mark.cases("hil_harness.detect.noise._walk", "count", "pick", "mask", "non-finite")
@pytest.mark.cases("hil_harness.detect.noise._pick_dense", "typical")
@pytest.mark.cases("hil_harness.detect.noise._median_mad", "odd", "even")
@pytest.mark.cases("hil_harness.detect.noise._kth", "typical")
def test_frame_noise_is_noise_sigma():
    rng = np.random.default_rng(45)
    counts = np.clip(rng.normal(300, 9, (1500, 1500)), 0, 4095).astype(np.uint16)
    counts[700:705, 900:905] = 4095                                  # a saturated star
    assert 2 * 1500 * 1498 > MAX_DIFFERENCES                          # subsampled
    disc = _disc(counts.shape, 740.3, 760.8, 700.0)
    flt = rng.normal(100, 5, (300, 411)).astype(np.float32)
    flt[5, :] = np.nan
    flt[:, 7] = np.inf
    frames = [(counts, None), (counts, disc), (counts[:301, :257], None),
              (counts.astype(np.float64) * 1.37, None), (counts.astype(np.float64), disc),
              (flt, None), (flt, rng.random(flt.shape) < 0.9),
              (rng.integers(0, 256, (97, 130)).astype(np.uint8), None),
              (rng.integers(-500, 500, (40, 61)).astype(np.int16), None),
              (np.full((50, 60), 7, np.uint16), None)]
    for data, mask in frames:
        a, b = noise_sigma(data, mask), frame_noise(data, mask)
        assert _same(a, b), (data.dtype, data.shape, mask is None, a, b)


@pytest.mark.cases("hil_harness.detect.noise._walk", "narrow")
@pytest.mark.cases("hil_harness.detect.noise._pick_dense", "narrow")
@pytest.mark.parametrize("shape", [(2, 50), (50, 2), (3, 3), (1, 9), (9, 1), (2, 2)])
def test_frame_noise_of_narrow_frames(shape):
    rng = np.random.default_rng(sum(shape))
    for data in (rng.integers(0, 4096, shape).astype(np.uint16), rng.normal(0, 3, shape)):
        assert _same(noise_sigma(data), frame_noise(data))
    with pytest.raises(ValueError, match="2-D"):
        frame_noise(np.zeros(5))


def test_histogram_medians_are_numpys():
    from hil_harness.detect.noise import _median_mad
    rng = np.random.default_rng(3)
    for trial in range(300):
        d = rng.integers(-20, 21, int(rng.integers(1, 60))).astype(np.float64)
        if trial % 5 == 0:
            d[:] = 7.0
        med = np.median(d)
        assert _median_mad(d) == (med, np.median(np.abs(d - med)))
