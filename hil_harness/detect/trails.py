"""The streak job's ground measurement of a trail: its two ends, length and direction, from the
blob the flight back end labelled.

The flight features give a trail's orientation from intensity-weighted moments, which a bright
head pulls toward its own direction, and no length (a trail's semimajor axis depends on how its
brightness is spread along it). ``uvisi detect``'s streak job adds, per candidate, the ends of its
blob in the thresholded frame along the blob's principal axis (unweighted: every pixel of the blob
counts once): the measurement a user reads off a picture by eye.

Public: :func:`trail_ends`.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

__all__ = ["trail_ends", "trace_trail", "TRACE_STEP", "TRACK_HALF", "SKY_STRIP", "TRACE_SIGMA",
           "TRACE_GAP", "MAX_DRIFT"]


def trail_ends(thresholded, f: int, row: float, col: float, labels=None) -> dict | None:
    """The trail through one candidate.

    ``thresholded``: int16 [h, w], the compacted frame after the threshold (non-zero: kept
    pixels); ``f``: compaction; ``row``, ``col``: the candidate's full-resolution centroid (pixel
    centres at +0.5); ``labels``: optional int [h, w] of ``scipy.ndimage.label`` on it with
    8-connectivity (computed when None). The blob is the one under the centroid, else the nearest
    within 2 compacted pixels; its axis is the line through its pixel centres' mean along the
    eigenvector of their unweighted covariance (every pixel counts once), and its ends are the
    points of that line at the smallest and largest projection of a pixel centre.

    Returns ``{"ends": [[row, col], [row, col]], "length", "orientation"}`` in full-resolution
    pixels and degrees (the axis, from +column toward +row, in [0, 180)); ``length`` is the
    distance between the ends plus one compacted pixel (``f``): the extent along the axis.
    None when no blob lies within 2 compacted pixels of the centroid.
    """
    from scipy.ndimage import label
    if labels is None:
        labels = label(np.asarray(thresholded) != 0, structure=np.ones((3, 3), int))[0]
    h, w = labels.shape
    r, c = int(row // f), int(col // f)
    r0, r1, c0, c1 = max(0, r - 2), min(h, r + 3), max(0, c - 2), min(w, c + 3)
    near = labels[r0:r1, c0:c1]
    if not near.any():
        return None
    if 0 <= r < h and 0 <= c < w and labels[r, c]:
        lab = labels[r, c]
    else:
        yy, xx = np.nonzero(near)
        k = int(np.argmin((yy + r0 - r) ** 2 + (xx + c0 - c) ** 2))
        lab = near[yy[k], xx[k]]
    py, px = np.nonzero(labels == lab)
    y, x = (py + 0.5) * f, (px + 0.5) * f
    if y.size < 2:
        return {"ends": [[float(y[0]), float(x[0])]] * 2, "length": float(f), "orientation": 0.0}
    cov = np.cov(np.vstack([x - x.mean(), y - y.mean()]))
    vals, vecs = np.linalg.eigh(cov)
    ux, uy = vecs[:, int(np.argmax(vals))]
    if uy < 0 or (uy == 0 and ux < 0):                     # one sense: toward +row
        ux, uy = -ux, -uy
    t = (x - x.mean()) * ux + (y - y.mean()) * uy
    lo, hi = float(t.min()), float(t.max())
    ends = [[float(y.mean() + lo * uy), float(x.mean() + lo * ux)],
            [float(y.mean() + hi * uy), float(x.mean() + hi * ux)]]
    length = hi - lo + f
    ang = math.degrees(math.atan2(uy, ux)) % 180.0
    return {"ends": ends, "length": float(length), "orientation": float(ang)}


#: tracing a trail beyond its blob: step along the axis (pixels), half-width of the track and the
#: sky strips beside it (pixels), the significance a step must reach, and the gap allowed
TRACE_STEP = 2.0
TRACK_HALF = 2
SKY_STRIP = (6, 10)
TRACE_SIGMA = 3.0
TRACE_GAP = 2
#: the most the trace moves across the track in one step (pixels)
MAX_DRIFT = 0.5


def trace_trail(img, ends, noise: float, mask=None) -> dict:
    """Follow a trail beyond its blob's ends on the full-resolution frame.

    ``img``: 2-D array [H, W] (counts); ``ends``: ``[[row, col], [row, col]]`` (from
    :func:`trail_ends`); ``noise``: pixel noise (counts); ``mask``: optional bool [H, W], the
    field (the trace stops at its edge). From each end, outward along the direction through both,
    in steps of ``TRACE_STEP`` px: the mean of the pixels within ``TRACK_HALF`` px across the track
    (over one step) minus the median of the sky strips ``SKY_STRIP`` px either side must exceed
    ``TRACE_SIGMA`` times the noise of that mean; such a step moves the track across by the
    centroid of its excess (at most ``MAX_DRIFT`` px a step: the trace follows a gently curved
    trail's ridge) and becomes the new end; ``TRACE_GAP`` failing steps in a row end the trace.
    Returns ``{"ends", "length", "orientation"}`` as :func:`trail_ends`: the direction and the
    distance from one traced end to the other (the ends are the last steps whose centre stands
    out; a point-spread function's wings and half a step beyond balance within a few pixels)."""
    a = np.asarray(img, np.float64)
    H, W = a.shape
    m = np.ones(a.shape, bool) if mask is None else np.asarray(mask, bool)
    (ra, ca), (rb, cb) = ends
    d = math.hypot(rb - ra, cb - ca)
    if d == 0:
        return {"ends": [list(ends[0]), list(ends[1])], "length": TRACE_STEP, "orientation": 0.0}
    ur, uc = (rb - ra) / d, (cb - ca) / d
    nr, nc = uc, -ur
    track = np.arange(-TRACK_HALF, TRACK_HALF + 1, dtype=float)
    sky = np.array([o for k in range(SKY_STRIP[0], SKY_STRIP[1] + 1) for o in (k, -k)], float)

    def sample(r, c, offsets):
        """Per across-track offset, the mean over three points along one step (NaN off the
        field): float [len(offsets)]."""
        vals = np.full((3, offsets.size), np.nan)
        for i, s in enumerate((-0.5 * TRACE_STEP, 0.0, 0.5 * TRACE_STEP)):
            y = np.floor(r + s * ur + offsets * nr).astype(int)
            x = np.floor(c + s * uc + offsets * nc).astype(int)
            ok = (y >= 0) & (y < H) & (x >= 0) & (x < W)
            ok[ok] = m[y[ok], x[ok]]
            vals[i, ok] = a[y[ok], x[ok]]
        return vals

    def walk(r, c, sr, sc):
        last, miss = (r, c), 0
        while miss <= TRACE_GAP:
            r, c = r + sr * TRACE_STEP, c + sc * TRACE_STEP
            if not (0 <= r < H and 0 <= c < W) or not m[int(r), int(c)]:
                break
            on, off = sample(r, c, track), sample(r, c, sky)
            n_on = int(np.isfinite(on).sum())
            if n_on < 3 or np.isfinite(off).sum() < 6:
                break
            bkg = float(np.nanmedian(off))
            with np.errstate(invalid="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)    # an offset off the field
                excess = np.nanmean(on, axis=0) - bkg
            sig = (float(np.nanmean(on)) - bkg) / (max(noise, 1e-9) / math.sqrt(n_on))
            if sig >= TRACE_SIGMA:
                w = np.clip(np.nan_to_num(excess), 0.0, None)
                shift = float(np.clip((w * track).sum() / w.sum(), -MAX_DRIFT, MAX_DRIFT))
                r, c = r + shift * nr, c + shift * nc
                last, miss = (r, c), 0
            else:
                miss += 1
        return last

    (r0, c0) = walk(ra, ca, -ur, -uc)
    (r1, c1) = walk(rb, cb, ur, uc)
    length = math.hypot(r1 - r0, c1 - c0)
    ang = math.degrees(math.atan2(r1 - r0, c1 - c0)) % 180.0
    return {"ends": [[float(r0), float(c0)], [float(r1), float(c1)]], "length": float(length),
            "orientation": float(ang)}
