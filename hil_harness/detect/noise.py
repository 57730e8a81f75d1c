"""The frame's pixel noise for ``uvisi detect``, compiled: the number
:func:`hil_harness.images.noise_sigma` gives, bit for bit, without its whole-frame temporaries.

``noise_sigma`` forms every horizontal and vertical second difference ``x[i-1] - 2 x[i] + x[i+1]``
of the frame in float64 (about ten arrays the frame's size), keeps the finite ones (inside the
mask) and, above 2^21 of them, every k-th. On an 8-Mpx frame that is ~0.3-0.5 s and ~600 MB of
fresh memory per call. :func:`frame_noise` walks the frame twice (count the kept differences, then
pick every k-th of them in the same order: the horizontal ones row by row, then the vertical ones)
and takes the same two medians of the same float64 values: the same result (the differences are
computed in the same order of operations; ``2 x`` is exact, so no contraction can change them).

Public: :func:`frame_noise`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["frame_noise", "MAX_DIFFERENCES"]

#: the most second differences kept (``hil_harness.images``: regularly subsampled above this)
MAX_DIFFERENCES = 1 << 21

#: pixel types read as they are; any other is converted to float64 first (as noise_sigma does)
_DIRECT = (np.dtype(np.uint16), np.dtype(np.float64))


@njit(**KERNEL)
def _walk(x, m, use_mask, step, out):
    """Count the finite second differences of ``x`` (float64 of any numeric [H, W]) whose three
    pixels are inside ``m`` (bool [H, W], when ``use_mask``), horizontal ones first, row by row,
    then the vertical ones; with ``out`` (float64 [k]) non-empty, store every ``step``-th of them
    (the 0th first). Returns the count.

    Cases
    -----
    count : ``out`` empty -> only the count.
    pick : ``out`` of ``ceil(n / step)`` words -> differences 0, step, 2 step, ... in order.
    mask : ``use_mask`` -> only differences whose three pixels are inside.
    non-finite : a difference touching a NaN or an infinity is skipped (not counted).
    narrow : fewer than 3 columns (rows) -> no horizontal (vertical) difference.
    """
    H, W = x.shape
    pick = out.size > 0
    k = 0
    nxt = 0                                   # the next difference to store (a counter, no modulo)
    j = 0
    for vertical in range(2):                # the horizontal differences, then the vertical
        dr, dc = vertical, 1 - vertical
        for r in range(H - 2 * dr):
            for c in range(W - 2 * dc):
                if use_mask and not (m[r, c] and m[r + dr, c + dc] and m[r + 2 * dr, c + 2 * dc]):
                    continue
                d = (np.float64(x[r, c]) - 2.0 * np.float64(x[r + dr, c + dc])
                     + np.float64(x[r + 2 * dr, c + 2 * dc]))
                if not np.isfinite(d):
                    continue
                if pick and k == nxt:
                    out[j] = d
                    j += 1
                    nxt += step
                k += 1
    return k


@njit(**KERNEL)
def _pick_dense(x, step, out):
    """Every ``step``-th second difference of ``x`` (uint16 [H, W]: every difference is finite),
    horizontal ones row by row then vertical ones, into ``out`` (float64 [k]), each found from its
    index without walking the others.

    Cases
    -----
    typical : the same words as :func:`_walk` with no mask.
    narrow : fewer than 3 columns (rows) -> no horizontal (vertical) difference.
    """
    H, W = x.shape
    wh = max(W - 2, 0)
    nh = H * wh
    j = 0
    k = 0                                       # index of difference j: row r, column c
    r, c = 0, 0
    while j < out.size and k < nh:              # horizontal
        out[j] = np.float64(x[r, c]) - 2.0 * np.float64(x[r, c + 1]) + np.float64(x[r, c + 2])
        j += 1
        k += step
        c += step
        while c >= wh and r < H:
            c -= wh
            r += 1
    r, c = (k - nh) // W, (k - nh) % W
    while j < out.size:                         # vertical
        out[j] = np.float64(x[r, c]) - 2.0 * np.float64(x[r + 1, c]) + np.float64(x[r + 2, c])
        j += 1
        c += step
        while c >= W:
            c -= W
            r += 1


@callee_kernel
def _kth(counts, lo, scale, k):
    """The k-th smallest (0-based) of the values whose histogram ``counts`` (int64 [m]) has bin
    ``i`` for the value ``(lo + i) / scale``.

    Cases
    -----
    typical : the value of the bin where the running count first exceeds ``k``.
    """
    s = 0
    for i in range(counts.size):
        s += counts[i]
        if s > k:
            return (lo + i) / scale
    return np.nan


@njit(**KERNEL)
def _median_mad(d):
    """``(median(d), median(|d - median(d)|))`` of integer-valued float64 ``d`` (non-empty, the
    second differences of integer pixels) from two histograms: the values ``np.median`` gives
    (an odd count: the middle value; even: the mean of the two middle values, here exact).

    Cases
    -----
    odd : an odd count -> the middle values.
    even : an even count -> the mean of the two middle values (a half-integer median: the
        deviations are counted in halves).
    """
    n = d.size
    lo, hi = d[0], d[0]
    for v in d:
        lo = min(lo, v)
        hi = max(hi, v)
    c = np.zeros(np.int64(hi - lo) + 1, np.int64)
    for v in d:
        c[np.int64(v - lo)] += 1
    if n % 2:
        med = _kth(c, lo, 1.0, n // 2)
    else:
        med = (_kth(c, lo, 1.0, n // 2 - 1) + _kth(c, lo, 1.0, n // 2)) / 2.0
    a = np.zeros(np.int64(2.0 * max(hi - med, med - lo)) + 1, np.int64)
    for v in d:
        a[np.int64(2.0 * abs(v - med))] += 1       # |v - med| in halves: an integer
    if n % 2:
        mad = _kth(a, 0.0, 2.0, n // 2)
    else:
        mad = (_kth(a, 0.0, 2.0, n // 2 - 1) + _kth(a, 0.0, 2.0, n // 2)) / 2.0
    return med, mad


def _differences(data, mask=None) -> np.ndarray:
    """float64 [n]: the second differences ``hil_harness.images`` keeps (finite, inside ``mask``,
    every k-th above :data:`MAX_DIFFERENCES`), in its order."""
    from hil_harness.images import ImageError
    x = np.asarray(data)
    if x.ndim != 2:
        raise ImageError(f"expected a 2-D image, got shape {x.shape}")
    if x.dtype not in _DIRECT:
        x = np.asarray(x, np.float64)
    x = np.ascontiguousarray(x)
    if mask is None:
        m, use = np.ones((1, 1), np.bool_), False
    else:
        m, use = np.ascontiguousarray(mask, np.bool_), True
        if m.shape != x.shape:
            raise ValueError(f"mask {m.shape} does not match the image {x.shape}")
    H, W = x.shape
    dense = not use and x.dtype == np.uint16           # every difference counts: n is known
    n = H * max(W - 2, 0) + max(H - 2, 0) * W if dense else \
        _walk(x, m, use, 1, np.zeros(0, np.float64))
    step = n // MAX_DIFFERENCES + 1 if n > MAX_DIFFERENCES else 1
    out = np.empty(-(-n // step), np.float64)
    if out.size and dense:
        _pick_dense(x, step, out)
    elif out.size:
        _walk(x, m, use, step, out)
    return out


def frame_noise(data, mask=None) -> float:
    """:func:`hil_harness.images.noise_sigma` of ``data`` (2-D, any numeric dtype) inside ``mask``
    (optional bool [H, W]): ``1.4826 MAD(d) / sqrt(6)`` of the second differences, the same float.
    NaN when there is no difference."""
    d = _differences(data, mask)
    if d.size == 0:
        return math.nan
    dt = np.asarray(data).dtype
    if dt.kind in "uib" and dt.itemsize <= 2:          # small integer differences: histograms
        mad = _median_mad(d)[1]
    else:
        mad = float(np.median(np.abs(d - np.median(d))))
    return 1.4826 * mad / math.sqrt(6.0)
