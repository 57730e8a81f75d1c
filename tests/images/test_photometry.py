"""The star job's detection aperture (:func:`hil_harness.detect.photometry.detection_snr`) and the
fill it decides (:func:`order_stars`).

Oracles: SEP's ``sum_circle`` (pixel-centre sampling, ``subpix=1``; its annulus mean is the sky
on a frame whose sky is constant) for the aperture sums; the pixel count of the circle from a
grid of pixel centres; a hand-made faint compact star whose signal-to-noise in each aperture is
known in closed form.
"""
import math

import numpy as np
import pytest

from hil_harness.detect.photometry import (ANNULUS, DETECT_RADIUS, FILL_SNR, aperture_flux,
                                           detection_snr, order_stars)

SKY = 100.0


def _star_frame(points, sigma=1.0, shape=(96, 112)):
    """A constant sky with Gaussian stars ``(row, col, flux)`` (centres at +0.5), no noise."""
    rr, cc = np.mgrid[:shape[0], :shape[1]] + 0.5
    img = np.full(shape, SKY)
    for r, c, f in points:
        img += f / (2 * math.pi * sigma ** 2) * np.exp(-((rr - r) ** 2 + (cc - c) ** 2)
                                                       / (2 * sigma ** 2))
    return img


def _pixels_within(r, c, radius):
    """How many pixel centres lie within ``radius`` of (r, c): the grid about the point."""
    k = int(radius) + 2
    rows = np.floor(r) + np.arange(-k, k + 1) + 0.5
    cols = np.floor(c) + np.arange(-k, k + 1) + 0.5
    return int((np.hypot(*np.meshgrid(rows - r, cols - c, indexing="ij")) <= radius).sum())


def test_detection_snr_is_seps_circle_sum_over_the_noise():
    sep = pytest.importorskip("sep")
    pts = [(30.37, 40.81, 900.0), (61.12, 72.64, 250.0), (45.9, 20.2, 60.0)]
    img = _star_frame(pts)
    rows = np.array([p[0] for p in pts])
    cols = np.array([p[1] for p in pts])
    noise = 7.5
    got = detection_snr(img, rows, cols, noise)
    flux, _, _ = sep.sum_circle(img, cols - 0.5, rows - 0.5, DETECT_RADIUS, subpix=1,
                                bkgann=(DETECT_RADIUS + ANNULUS[0], DETECT_RADIUS + ANNULUS[1]))
    n = np.array([_pixels_within(r, c, DETECT_RADIUS) for r, c in zip(rows, cols)])
    # the stars' far wings (~1e-5 of the sky) reach the annulus: its median and SEP's mean
    # differ by that much
    np.testing.assert_allclose(got, flux / (noise * np.sqrt(n)), rtol=1e-5)


def test_detection_snr_honours_the_mask_and_the_frame_edge():
    img = _star_frame([(30.5, 40.5, 900.0)])
    mask = np.ones(img.shape, bool)
    mask[:, :40] = False                        # the left half of the star is outside the field
    whole = detection_snr(img, [30.5], [40.5], 5.0)[0]
    half = detection_snr(img, [30.5], [40.5], 5.0, mask)[0]
    assert 0 < half < whole
    assert np.isnan(detection_snr(img, [-40.0], [-40.0], 5.0)[0])   # no pixel in the aperture


def test_a_faint_compact_star_fills_a_free_slot():
    """A star of sigma 1 px and flux F over pixel noise n: in the detection aperture (13 pixels,
    about 86 % of its light) S/N ~ 0.86 F / (n sqrt 13); in the 3-px flux aperture (29 pixels, all
    of it) S/N ~ F / (n sqrt 29). With F = 260, n = 10: ~6.2 against ~4.8, either side of 5."""
    noise, f = 10.0, 260.0
    img = np.rint(_star_frame([(48.5, 56.5, f)])).astype(np.uint16)
    cand = {"row": 48.5, "col": 56.5, "rank": 7, "features": {"semimajor": 1.4}}
    wide = aperture_flux(img, [48.5], [56.5], [1.4], noise)[1][0]
    core = detection_snr(img, [48.5], [56.5], noise)[0]
    assert wide < FILL_SNR < core, (wide, core)
    assert core == pytest.approx(0.8647 * f / (noise * math.sqrt(13)), rel=0.03)
    out = order_stars(img, [], [cand], noise, 23)
    assert [(c["row"], c["col"], c["gate"]) for c in out] == [(48.5, 56.5, False)]
    assert out[0]["snr"] == pytest.approx(core)
    assert out[0]["flux"] == pytest.approx(aperture_flux(img, [48.5], [56.5], [1.4], noise)[0][0])


def test_a_star_below_the_fill_stays_out():
    img = np.rint(_star_frame([(48.5, 56.5, 120.0)])).astype(np.uint16)
    cand = {"row": 48.5, "col": 56.5, "rank": 3, "features": {"semimajor": 1.4}}
    assert detection_snr(img, [48.5], [56.5], 10.0)[0] < FILL_SNR   # ~2.9
    assert order_stars(img, [], [cand], 10.0, 23) == []
