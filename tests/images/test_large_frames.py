"""Large frames (issue 45): the compiled per-frame statistics of ``uvisi detect`` give the numbers
of the NumPy forms they replaced.

Oracles: :func:`hil_harness.images.noise_sigma` (the pixel noise, the same float), ``np.median``
(the histogram medians), and the NumPy aperture photometry ``uvisi detect`` used before
(:func:`_aperture_flux_numpy`, kept here as it was) on the same points.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from hil_harness.detect.noise import MAX_DIFFERENCES, frame_noise
from hil_harness.detect.photometry import ANNULUS, MAX_RADIUS, MIN_RADIUS, RADIUS_PER_AXIS, \
    aperture_flux
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
        with np.errstate(invalid="ignore"):                       # inf - 2 inf in the oracle
            a = noise_sigma(data, mask)
        b = frame_noise(data, mask)
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


# ------------------------------------------------------------------------------------------------
# aperture photometry
# ------------------------------------------------------------------------------------------------
def _aperture_flux_numpy(img, rows, cols, semimajor, noise, mask=None):
    """The NumPy aperture photometry ``uvisi detect`` used until issue 45 (one point at a time)."""
    a = np.asarray(img, np.float64)
    H, W = a.shape
    rad = np.clip(RADIUS_PER_AXIS * np.asarray(semimajor, float), MIN_RADIUS, MAX_RADIUS)
    m = np.ones(a.shape, bool) if mask is None else np.asarray(mask, bool)
    flux = np.full(rows.size, np.nan)
    snr = np.full(rows.size, np.nan)
    for i in range(rows.size):
        r_out = rad[i] + ANNULUS[1]
        r0, r1 = max(0, int(rows[i] - r_out)), min(H, int(rows[i] + r_out) + 2)
        c0, c1 = max(0, int(cols[i] - r_out)), min(W, int(cols[i] + r_out) + 2)
        if r0 >= r1 or c0 >= c1:
            continue
        yy, xx = np.mgrid[r0:r1, c0:c1]
        d = np.hypot(yy + 0.5 - rows[i], xx + 0.5 - cols[i])
        cut, ok = a[r0:r1, c0:c1], m[r0:r1, c0:c1]
        ap = ok & (d <= rad[i])
        ring = ok & (d >= rad[i] + ANNULUS[0]) & (d <= r_out)
        if not ap.any():
            continue
        bkg = float(np.median(cut[ring])) if ring.sum() >= 8 else float(np.median(cut[ok]))
        flux[i] = float(np.sum(cut[ap] - bkg))
        snr[i] = flux[i] / (max(noise, 1e-9) * math.sqrt(int(ap.sum())))
    return flux, snr


@pytest.mark.cases("hil_harness.detect.photometry._apertures_k", "typical", "outside", "mask",
                   "thin-ring")
def test_aperture_flux_is_the_numpy_form():
    rng = np.random.default_rng(7)
    shape = (400, 530)
    img = rng.poisson(200.0, shape).astype(np.float64)
    for _ in range(60):
        r, c = rng.uniform(0, shape[0]), rng.uniform(0, shape[1])
        yy, xx = np.mgrid[:shape[0], :shape[1]]
        img += rng.uniform(50, 3000) * np.exp(-((yy + 0.5 - r) ** 2 + (xx + 0.5 - c) ** 2) / 3.0)
    img = np.clip(np.rint(img), 0, 4095).astype(np.uint16)
    n = 400
    rows = np.r_[rng.uniform(-25, shape[0] + 25, n), 0.0, shape[0] - 0.01, 100.5, -40.0, 500.0]
    cols = np.r_[rng.uniform(-25, shape[1] + 25, n), 0.0, shape[1] - 0.01, 100.5, 10.0, 700.0]
    semi = np.r_[rng.uniform(0.3, 7.0, n), 1.0, 1.0, 1.0, 1.0, 1.0]
    field = _disc(shape, 200.0, 265.0, 190.0)
    tiny = _disc(shape, 100.5, 100.5, 5.0)             # the aperture only: no annulus pixel
    for mask in (None, field, tiny):
        want = _aperture_flux_numpy(img, rows, cols, semi, 8.3, mask)
        got = aperture_flux(img, rows, cols, semi, 8.3, mask)
        assert np.array_equal(want[0], got[0], equal_nan=True)
        assert np.array_equal(want[1], got[1], equal_nan=True)
    # the points off the frame; about (100.5, 100.5) ``tiny`` (radius 5) holds no annulus pixel
    # (6..11 px): the background is the median of the box's pixels in the field
    assert np.isnan(got[0][-2:]).all() and np.isfinite(got[0][-3])
