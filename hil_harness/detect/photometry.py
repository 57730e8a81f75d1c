"""Aperture photometry at the candidates' centroids: the star job's ground ordering.

The flight IP ranks its blobs by the record; the star job's record gates them on their peak in
the smoothed, detrended image, and a peak favours a small sharp star over a bright broad one. To
report the brightest stars of a field first, ``uvisi detect``'s star job (a ground tool, not the
flight ranking) measures each candidate's flux on the 12-bit frame the IP was given and orders by
it (:func:`aperture_flux`, :func:`order_stars`).

The peak gate (4.5 input-noise sigmas, :data:`hil_harness.detect.jobs.GATE_SIGMA`) was set so that
the gated list of a sharp star-tracker frame matches SEP's 5-sigma list; a camera with a broad
point-spread function (an all-sky imager) puts its real stars below it (their smoothed peak is
spread, not their flux). So free slots are filled with candidates below the gate whose
signal-to-noise in the detection aperture (:func:`detection_snr`: radius :data:`DETECT_RADIUS`
about the centroid) is at least :data:`FILL_SNR`, after every gated one; the JSON marks each
candidate's ``gate``. Two apertures, as photometry pipelines keep them: the flux that orders the
stars is taken in an aperture wide enough to hold a star's light (:func:`aperture_flux`), the
signal-to-noise that admits one in an aperture about its core, where a faint star stands highest
above the sky's noise.

Public: :func:`aperture_flux`, :func:`detection_snr`, :func:`order_stars` and their constants.
"""
from __future__ import annotations

import math
import sys

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL

__all__ = ["aperture_flux", "detection_snr", "order_stars", "MIN_RADIUS", "MAX_RADIUS",
           "RADIUS_PER_AXIS", "ANNULUS", "DETECT_RADIUS", "FILL_SNR", "FILL_PEAK_SIGMA",
           "SAME_STAR_PX"]

#: aperture radius = RADIUS_PER_AXIS x the blob's semimajor axis, within MIN_RADIUS..MAX_RADIUS px
RADIUS_PER_AXIS = 2.0
MIN_RADIUS = 3.0
MAX_RADIUS = 10.0
#: background annulus: from the aperture radius + ANNULUS[0] to + ANNULUS[1] pixels
ANNULUS = (3.0, 8.0)
#: the detection aperture's radius (pixels): the fill's signal-to-noise is measured in it. For a
#: Gaussian star under the sky's noise the signal-to-noise of an aperture of radius r grows as
#: (1 - exp(-r^2 / 2 s^2)) / r, highest at r = 1.585 s; 2 px is that optimum for a star of FWHM
#: 3 px (s = 1.26 px), as star trackers and all-sky imagers sample them. Chosen on the Gakona
#: sequence of data/real/ (1.5 px gives the same counts there; docs/validation.md).
DETECT_RADIUS = 2.0


def aperture_flux(img, rows, cols, semimajor, noise: float, mask=None):
    """Background-subtracted flux in a circular aperture about each point.

    ``img``: 2-D array [H, W] (counts); ``rows``, ``cols``: float [n], full-resolution centroids
    (pixel centres at +0.5); ``semimajor``: float [n], each blob's semimajor axis (pixels), which
    sets its aperture radius ``clip(RADIUS_PER_AXIS * a, MIN_RADIUS, MAX_RADIUS)``; ``noise``: the
    frame's pixel noise (counts); ``mask``: optional bool [H, W], pixels outside take no part.
    The background is the median of the annulus ``r + ANNULUS[0] .. r + ANNULUS[1]``; a pixel
    belongs to a circle when its centre does.

    Returns ``(flux, snr)``: float64 [n] each, ``flux`` in counts (sum over the aperture of pixel
    minus background), ``snr = flux / (noise * sqrt(pixels in the aperture))`` (the background-
    limited signal-to-noise; NaN where the aperture holds no pixel). All the points in one
    compiled call (:func:`_apertures_k`).
    """
    rad = np.clip(RADIUS_PER_AXIS * np.asarray(semimajor, float), MIN_RADIUS, MAX_RADIUS)
    return _apertures(img, rows, cols, rad, noise, mask)


def detection_snr(img, rows, cols, noise: float, mask=None):
    """Signal-to-noise of each point in the detection aperture, radius :data:`DETECT_RADIUS`.

    ``img``: 2-D array [H, W] (counts); ``rows``, ``cols``: float [n], full-resolution centroids
    (pixel centres at +0.5); ``noise``: the frame's pixel noise (counts); ``mask``: optional bool
    [H, W], pixels outside take no part. As :func:`aperture_flux` with every radius
    ``DETECT_RADIUS`` (the background the median of its annulus): returns float64 [n], ``flux /
    (noise * sqrt(pixels in the aperture))``, NaN where the aperture holds no pixel.
    """
    rad = np.full(np.size(rows), DETECT_RADIUS)
    return _apertures(img, rows, cols, rad, noise, mask)[1]


def _apertures(img, rows, cols, rad, noise: float, mask):
    """``(flux, snr)`` of every point in apertures of radii ``rad`` (float [n], pixels); the
    arguments as :func:`aperture_flux`'s."""
    a = np.asarray(img)
    if a.dtype not in (np.uint16, np.float64):
        a = a.astype(np.float64)
    a = np.ascontiguousarray(a)
    rows = np.ascontiguousarray(rows, float)
    cols = np.ascontiguousarray(cols, float)
    if mask is None:
        m, use = np.ones((1, 1), np.bool_), False
    else:
        m, use = np.ascontiguousarray(mask, np.bool_), True
    return _apertures_k(a, rows, cols, np.ascontiguousarray(rad, float), float(noise), m, use,
                        float(ANNULUS[0]), float(ANNULUS[1]))


@njit(**KERNEL)
def _apertures_k(a, rows, cols, rad, noise, m, use_mask, ann0, ann1):
    """:func:`aperture_flux` of every point: ``a`` (uint16 or float64 [H, W]), ``rows``, ``cols``,
    ``rad`` (float [n]: the aperture radii), the pixel noise, the mask ``m`` (bool [H, W], read when
    ``use_mask``) and the annulus ``r + ann0 .. r + ann1``. Returns ``(flux, snr)`` float64 [n].

    The same numbers as the NumPy form it replaced: the pixel centre's distance by ``np.hypot``,
    the medians of the same values (an even count: the mean of the two middle ones), the flux the
    sum of ``pixel - background`` (exact for counts: integers and a half-integer background).

    Cases
    -----
    typical : the median of the annulus pixels is the background; the flux sums the aperture.
    thin-ring : fewer than 8 annulus pixels (the frame's edge, a mask) -> the median of every
        pixel inside the box about the point (and the field) instead.
    outside : a point whose box misses the frame, or whose aperture holds no pixel -> NaN, NaN.
    mask : ``use_mask`` -> pixels outside ``m`` take no part in the aperture, annulus or box.
    """
    H, W = a.shape
    n = rows.size
    flux = np.full(n, np.nan)
    snr = np.full(n, np.nan)
    size = 2 * (int(rad.max() + ann1) + 2) + 2 if n else 0
    ring = np.empty(size * size, np.float64)          # the box's annulus pixels
    box = np.empty(size * size, np.float64)           # ... every pixel in the field
    ap = np.empty(size * size, np.float64)            # ... the aperture's
    for i in range(n):
        r_out = rad[i] + ann1
        r0, r1 = max(0, int(rows[i] - r_out)), min(H, int(rows[i] + r_out) + 2)
        c0, c1 = max(0, int(cols[i] - r_out)), min(W, int(cols[i] + r_out) + 2)
        if r0 >= r1 or c0 >= c1:
            continue
        nap, nring, nbox = 0, 0, 0
        for r in range(r0, r1):
            for c in range(c0, c1):
                if use_mask and not m[r, c]:
                    continue
                v = np.float64(a[r, c])
                box[nbox] = v
                nbox += 1
                d = np.hypot(r + 0.5 - rows[i], c + 0.5 - cols[i])
                if d <= rad[i]:
                    ap[nap] = v
                    nap += 1
                if d >= rad[i] + ann0 and d <= r_out:
                    ring[nring] = v
                    nring += 1
        if nap == 0:
            continue
        bkg = np.median(ring[:nring]) if nring >= 8 else np.median(box[:nbox])
        s = 0.0
        for k in range(nap):
            s += ap[k] - bkg
        flux[i] = s
        snr[i] = s / (max(noise, 1e-9) * math.sqrt(nap))
    return flux, snr


#: the star job's fill: a candidate below the peak gate may fill a free slot when its
#: signal-to-noise in the detection aperture (:func:`detection_snr`) is at least FILL_SNR; the IP
#: is re-run with its peak gate at FILL_PEAK_SIGMA input-noise sigmas to find them
FILL_SNR = 5.0
FILL_PEAK_SIGMA = 1.0
#: a fill candidate within this distance (pixels) of a gated one is the same star
SAME_STAR_PX = 2.0


_BIG = sys.float_info.max


def _brightest_first(c) -> float:
    """Sort key of a measured candidate: ``-np.nan_to_num(flux, nan=-inf)`` (NaN last, infinities
    as the largest floats) without a NumPy call per candidate."""
    f = c["flux"]
    return math.inf if f != f else -min(max(f, -_BIG), _BIG)


def order_stars(img12, gated: list, below: list, noise: float, max_candidates: int,
                mask=None) -> list:
    """The star job's ground ordering of ``uvisi detect``'s candidates (the flight ranking is not
    changed; this orders what it reported): every candidate that passed the peak gate, brightest
    aperture flux first; then, in the slots left up to ``max_candidates``, the candidates of a run
    with the gate lowered to ``FILL_PEAK_SIGMA`` that are not a gated star (``SAME_STAR_PX``) and
    whose signal-to-noise in the detection aperture (:func:`detection_snr`) is at least
    ``FILL_SNR``, brightest first.

    ``img12``: uint16 [H, W], the counts the IP was given; ``gated``, ``below``: candidate dicts
    (``row``, ``col``, ``features``: as :func:`hil_harness.cli.detect.detect_one` makes them)
    from the gated and the lowered run; ``noise``: pixel noise of ``img12`` (counts); ``mask``:
    optional bool [H, W], the field. Returns new dicts with ``rank`` (1-based, this order),
    ``flight_rank`` (in its run), ``gate`` (True: passed the peak gate), ``flux`` (counts, in
    :func:`aperture_flux`'s aperture) and ``snr`` (in the detection aperture) added."""
    def measured(cands, gate):
        if not cands:
            return []
        r = np.array([c["row"] for c in cands])
        c_ = np.array([c["col"] for c in cands])
        a = np.array([c["features"]["semimajor"] for c in cands])
        flux = aperture_flux(img12, r, c_, a, noise, mask)[0]
        snr = detection_snr(img12, r, c_, noise, mask)
        return [dict(c, flight_rank=c["rank"], gate=gate, flux=float(f), snr=float(s))
                for c, f, s in zip(cands, flux, snr)]

    first = measured(gated, True)
    first.sort(key=_brightest_first)
    rest = []
    if len(first) < max_candidates and below:
        pos = np.array([[c["row"], c["col"]] for c in first]).reshape(-1, 2)
        new = [c for c in below if not len(pos)
               or np.hypot(pos[:, 0] - c["row"], pos[:, 1] - c["col"]).min() > SAME_STAR_PX]
        rest = [c for c in measured(new, False) if c["snr"] >= FILL_SNR]
        rest.sort(key=lambda c: -c["flux"])
    out = (first + rest)[:max_candidates]
    for i, c in enumerate(out):
        c["rank"] = i + 1
    return out
