"""The full-frame threshold: every overlapping flight window's ``mean + alpha * std`` at once, and
a pixel kept where *any* window that covers it would keep it.

The flight threshold (:mod:`flightsw.ip.threshold`) of one window is, in DSP integer words (``n``
pixels, block shift ``s``, ``S1 = sum(x >> s)``, ``S2 = sum((x >> s)**2)``, alpha Q4.12)::

    m4 = rhu(16 S1 / n)                       # mean, Q.4
    v8 = rhu(256 (n S2 - S1**2) / n**2)       # variance, Q.8 (clamped to 32 bits)
    d4 = isqrt32(v8)                          # std, Q.4
    T4 = (m4 + rhu(alpha_q12 d4 / 4096)) << s # threshold, Q.4 of unshifted counts

(``rhu``: round half up). A pixel passes window ``w`` when ``16 x > T4(w)``; it passes *some*
window that covers it exactly when ``16 x > min T4`` over those windows. :func:`window_t4_k` gives
every window's words from running column sums of the image (one pass over the frame instead of
one per window), the words themselves by the flight's own
:func:`flightsw.ip.threshold.threshold_words`; :func:`union_threshold_k` keeps (clip) or sets to 1 (binarise) the pixels above
their covering windows' smallest threshold.

Public: :func:`window_t4_k`, :func:`union_threshold_k`, :func:`cover_ranges`.
"""
from __future__ import annotations

import numpy as np

from flightsw.arith.adsp2100 import block_bitlen
from flightsw.ip.threshold import threshold_words
from flightsw.numba_cache import callee_kernel

__all__ = ["window_t4_k", "union_threshold_k", "cover_ranges"]


@callee_kernel
def _column_snapshots(img, marks):
    """Column sums of x and x**2 over rows ``0..m-1`` for each ``m`` of the sorted int64
    ``marks`` (0..H): int64 [2, len(marks), W] (one running pass down the frame).

    Cases
    -----
    typical : row k holds ``img[:marks[k]].sum(0)`` and the same of the squares.
    zero-mark : a mark 0 -> zeros.
    """
    H, W = img.shape
    snap = np.zeros((2, marks.size, W), np.int64)
    a1 = np.zeros(W, np.int64)
    a2 = np.zeros(W, np.int64)
    k = 0
    for r in range(H + 1):
        while k < marks.size and marks[k] == r:
            snap[0, k] = a1
            snap[1, k] = a2
            k += 1
        if k == marks.size:
            break
        src = img[r]
        for c in range(W):
            x = np.int64(src[c])
            a1[c] += x
            a2[c] += x * x
    return snap


@callee_kernel
def _sums_12bit(img, rows, cols, th, tw):
    """S1, S2 (int64 [2, nr, nc]) of every ``th`` x ``tw`` window of ``img`` (int16 [H, W]) at
    ``rows`` x ``cols``, block shift 0.

    Cases
    -----
    typical : the sums of ``x`` and ``x**2`` over each window, exact.
    """
    nr, nc = rows.size, cols.size
    W = img.shape[1]
    marks = np.unique(np.concatenate((rows, rows + th)))
    snap = _column_snapshots(img, marks)
    out = np.empty((2, nr, nc), np.int64)
    pre = np.zeros(W + 1, np.int64)
    for i in range(nr):
        a = np.searchsorted(marks, rows[i])
        b = np.searchsorted(marks, rows[i] + th)
        for q in range(2):
            lo, hi = snap[q, a], snap[q, b]
            for c in range(W):
                pre[c + 1] = pre[c] + (hi[c] - lo[c])
            for j in range(nc):
                out[q, i, j] = pre[cols[j] + tw] - pre[cols[j]]
    return out


@callee_kernel
def window_t4_k(img, rows, cols, th, tw, aq):
    """The flight threshold word ``T4`` of every window of ``img``.

    Parameters
    ----------
    img : int16 [H, W], Q16.0 (the front end's output before the threshold step)
    rows, cols : int64 [nr], [nc], window start rows and columns (pixels); windows are
        ``th`` x ``tw`` pixels, ``th * tw <= 16384`` (the flight's 40-bit sum of squares)
    aq : int, alpha Q4.12

    Returns
    -------
    int64 [nr, nc]: ``T4`` (Q.4 of counts) of window (i, j), the words
    :func:`flightsw.ip.threshold.threshold_k` gives on ``img[rows[i]:+th, cols[j]:+tw]``.

    Cases
    -----
    no-shift : the frame fits 12 bits signed (block shift 0 everywhere) -> every window from the
        running column sums (:func:`_sums_12bit`).
    block-shift : a wider frame -> each window's own shift ``s`` (its EXPADJ pass) and sums of
        ``x >> s`` over the window.
    constant : a constant window -> ``T4 = 16 c``.
    """
    nr, nc = rows.size, cols.size
    n = np.int64(th) * np.int64(tw)
    out = np.empty((nr, nc), np.int64)
    if max(0, block_bitlen(img) - 12) == 0:
        sums = _sums_12bit(img, rows, cols, th, tw)
        for i in range(nr):
            for j in range(nc):
                out[i, j] = threshold_words(sums[0, i, j], sums[1, i, j], n, np.int64(0), aq)[0]
        return out
    for i in range(nr):                       # wide words: each window's own block shift
        for j in range(nc):
            win = img[rows[i]:rows[i] + th, cols[j]:cols[j] + tw]
            s = np.int64(max(0, block_bitlen(win) - 12))
            s1 = np.int64(0)
            s2 = np.int64(0)
            for r in range(th):
                for c in range(tw):
                    x = np.int64(win[r, c]) >> s
                    s1 += x
                    s2 += x * x
            out[i, j] = threshold_words(s1, s2, n, s, aq)[0]
    return out


def cover_ranges(starts, tile, n):
    """For each pixel 0..n-1 along an axis, the first and last window (indices into ``starts``)
    that covers it: int64 [n, 2]. ``starts``: sorted window starts, windows ``tile`` long,
    covering 0..n-1 (:func:`hil_harness.detect.fullframe.tile_starts`)."""
    s = np.asarray(starts, np.int64)
    p = np.arange(n)
    lo = np.searchsorted(s + tile, p, side="right")         # first window with start + tile > p
    hi = np.searchsorted(s, p, side="right") - 1             # last window with start <= p
    if np.any(lo > hi):
        raise ValueError("windows do not cover the axis")
    return np.stack([lo, hi], axis=1).astype(np.int64)


@callee_kernel
def _bands(rng):
    """Distinct consecutive (first, last) pairs of an [n, 2] cover table: (band of each pixel
    int64 [n], the bands' pairs int64 [nb, 2]).

    Cases
    -----
    typical : pixels with the same covering windows share a band, bands numbered in order.
    """
    n = rng.shape[0]
    band = np.empty(n, np.int64)
    pairs = np.empty((n, 2), np.int64)
    nb = 0
    for p in range(n):
        if nb == 0 or rng[p, 0] != pairs[nb - 1, 0] or rng[p, 1] != pairs[nb - 1, 1]:
            pairs[nb, 0] = rng[p, 0]
            pairs[nb, 1] = rng[p, 1]
            nb += 1
        band[p] = nb - 1
    return band, pairs[:nb]


@callee_kernel
def union_threshold_k(img, t4, rcover, ccover, mode):
    """Keep the pixels that pass any covering window's threshold.

    Parameters
    ----------
    img : int16 [H, W], Q16.0
    t4 : int64 [nr, nc], every window's threshold word (:func:`window_t4_k`), Q.4
    rcover, ccover : int64 [H, 2], [W, 2], the first and last window row (column) that covers each
        pixel row (column) (:func:`cover_ranges`)
    mode : 0 binarise, 1 clip (``flightsw.ip.threshold.BINARIZE`` / ``CLIP``)

    Returns
    -------
    int16 [H, W]: where ``16 x > min T4`` over the covering windows, 1 (binarise) or ``x`` (clip);
    elsewhere 0.

    Cases
    -----
    union : a pixel passes when it passes at least one covering window (the smallest ``T4``).
    equal-fails : ``16 x == min T4`` -> 0, as in the flight window.
    one-window : a single window -> the flight threshold of that window.
    binarize : ``mode == 0`` -> 1 for a passing pixel.
    """
    H, W = img.shape
    rb, rp = _bands(rcover)
    cb, cp = _bands(ccover)
    nrb, ncb = rp.shape[0], cp.shape[0]
    tmin = np.empty((nrb, W), np.int64)          # per row band, each column's threshold
    mb = np.empty(ncb, np.int64)
    for a in range(nrb):
        for b in range(ncb):
            m = t4[rp[a, 0], cp[b, 0]]
            for i in range(rp[a, 0], rp[a, 1] + 1):
                for j in range(cp[b, 0], cp[b, 1] + 1):
                    m = min(m, t4[i, j])
            mb[b] = m
        for c in range(W):
            tmin[a, c] = mb[cb[c]]
    out = np.empty((H, W), np.int16)
    for r in range(H):
        trow = tmin[rb[r]]
        src = img[r]
        dst = out[r]
        if mode == 0:
            for c in range(W):
                dst[c] = np.int16(np.int64(src[c]) * 16 > trow[c])
        else:
            for c in range(W):
                x = src[c]
                dst[c] = x if np.int64(x) * 16 > trow[c] else np.int16(0)
    return out
