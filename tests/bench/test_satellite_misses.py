"""The ideal matched-filter SNR the satellite diagnosis reports (bench/satellite_misses.py), against
independent oracles: on pure Gaussian noise the statistic has mean 0 and standard deviation 1; on a
star rendered by sub-pixel sampling (10x10 points a pixel, not the erf integral the function uses)
its mean is flux * ||PSF|| / sigma."""
import numpy as np

from bench.satellite_misses import ideal_snr


def _star(shape, r0, c0, flux, sigma, sub=10):
    rr, cc = np.mgrid[0:shape[0] * sub, 0:shape[1] * sub]
    y, x = (rr + 0.5) / sub, (cc + 0.5) / sub
    g = np.exp(-((y - r0) ** 2 + (x - c0) ** 2) / (2 * sigma ** 2))
    img = g.reshape(shape[0], sub, shape[1], sub).sum(axis=(1, 3))
    return flux * img / img.sum()


def test_ideal_snr_is_unit_normal_on_noise():
    rng = np.random.default_rng(5)
    v = [ideal_snr(100.0 + 2.0 * rng.standard_normal((31, 31)), 15.3, 15.7, 0.7) for _ in range(400)]
    assert abs(np.mean(v)) < 0.15 and 0.85 < np.std(v) < 1.2


def test_ideal_snr_of_a_star_is_flux_times_psf_norm_over_sigma():
    rng = np.random.default_rng(6)
    star = _star((31, 31), 15.3, 15.7, 60.0, 0.7)
    want = 60.0 * np.sqrt(((star / 60.0) ** 2).sum()) / 2.0
    v = [ideal_snr(100.0 + star + 2.0 * rng.standard_normal((31, 31)), 15.3, 15.7, 0.7)
         for _ in range(300)]
    assert abs(np.mean(v) - want) < 0.05 * want
    assert np.isnan(ideal_snr(np.zeros((31, 31)), 3.0, 15.0, 0.7))       # the box leaves the frame
