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

import numpy as np

__all__ = ["trail_ends", "trace_trail", "TRACE_STEP", "TRACK_HALF", "SKY_STRIP", "TRACE_SIGMA",
           "TRACE_GAP"]


def trail_ends(thresholded, f: int, row: float, col: float, labels=None) -> dict | None:
    """The trail through one candidate.

    ``thresholded``: int16 [h, w], the compacted frame after the threshold (non-zero: kept
    pixels); ``f``: compaction; ``row``, ``col``: the candidate's full-resolution centroid (pixel
    centres at +0.5); ``labels``: optional int [h, w] of ``scipy.ndimage.label`` on it with
    8-connectivity (computed when None). The blob is the one under the centroid, else the nearest
    within 2 compacted pixels; its pixel centres are projected on its principal axis (the
    eigenvector of their unweighted covariance).

    Returns ``{"ends": [[row, col], [row, col]], "length", "orientation"}`` in full-resolution
    pixels and degrees (from +column toward +row, in [0, 180)); ``length`` is the distance between
    the two end pixels' centres plus one compacted pixel (``f``): the extent along the axis.
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
    t = (x - x.mean()) * ux + (y - y.mean()) * uy
    a, b = int(np.argmin(t)), int(np.argmax(t))
    ends = [[float(y[a]), float(x[a])], [float(y[b]), float(x[b])]]
    length = math.hypot(y[b] - y[a], x[b] - x[a]) + f
    ang = math.degrees(math.atan2(y[b] - y[a], x[b] - x[a])) % 180.0
    return {"ends": ends, "length": float(length), "orientation": float(ang)}


#: tracing a trail beyond its blob: step along the axis (pixels), half-width of the track and the
#: sky strips beside it (pixels), the significance a step must reach, and the gap allowed
TRACE_STEP = 2.0
TRACK_HALF = 2
SKY_STRIP = (6, 10)
TRACE_SIGMA = 3.0
TRACE_GAP = 2


def trace_trail(img, ends, noise: float, mask=None) -> dict:
    """Follow a trail beyond its blob's ends on the full-resolution frame.

    ``img``: 2-D array [H, W] (counts); ``ends``: ``[[row, col], [row, col]]`` (from
    :func:`trail_ends`); ``noise``: pixel noise (counts); ``mask``: optional bool [H, W], the
    field (the trace stops at its edge). From each end, outward along the line through both, in
    steps of ``TRACE_STEP`` px: the mean of the pixels within ``TRACK_HALF`` px across the track
    (over one step) minus the median of the sky strips ``SKY_STRIP`` px either side must exceed
    ``TRACE_SIGMA`` times the noise of that mean; the end moves to the last step that does,
    allowing ``TRACE_GAP`` failing steps in a row. Returns ``{"ends", "length", "orientation"}``
    as :func:`trail_ends` (length: the distance between the ends plus one step)."""
    a = np.asarray(img, np.float64)
    H, W = a.shape
    m = np.ones(a.shape, bool) if mask is None else np.asarray(mask, bool)
    (ra, ca), (rb, cb) = ends
    d = math.hypot(rb - ra, cb - ca)
    if d == 0:
        return {"ends": [list(ends[0]), list(ends[1])], "length": TRACE_STEP, "orientation": 0.0}
    ur, uc = (rb - ra) / d, (cb - ca) / d
    nr, nc = uc, -ur

    def sample(r, c, offsets):
        out = []
        for s in (-0.5 * TRACE_STEP, 0.0, 0.5 * TRACE_STEP):
            for o in offsets:
                y, x = int(math.floor(r + s * ur + o * nr)), int(math.floor(c + s * uc + o * nc))
                if 0 <= y < H and 0 <= x < W and m[y, x]:
                    out.append(a[y, x])
        return np.asarray(out)

    track = range(-TRACK_HALF, TRACK_HALF + 1)
    sky = [o for k in range(SKY_STRIP[0], SKY_STRIP[1] + 1) for o in (k, -k)]

    def walk(r, c, sr, sc):
        last, miss, k = (r, c), 0, 1
        while miss <= TRACE_GAP:
            pr, pc = r + sr * k * TRACE_STEP, c + sc * k * TRACE_STEP
            if not (0 <= pr < H and 0 <= pc < W) or not m[int(pr), int(pc)]:
                break
            on, off = sample(pr, pc, track), sample(pr, pc, sky)
            if on.size < 3 or off.size < 6:
                break
            sig = (on.mean() - np.median(off)) / (max(noise, 1e-9) / math.sqrt(on.size))
            if sig >= TRACE_SIGMA:
                last, miss = (pr, pc), 0
            else:
                miss += 1
            k += 1
        return last

    (r0, c0) = walk(ra, ca, -ur, -uc)
    (r1, c1) = walk(rb, cb, ur, uc)
    length = math.hypot(r1 - r0, c1 - c0) + TRACE_STEP
    ang = math.degrees(math.atan2(r1 - r0, c1 - c0)) % 180.0
    return {"ends": [[float(r0), float(c0)], [float(r1), float(c1)]], "length": float(length),
            "orientation": float(ang)}
