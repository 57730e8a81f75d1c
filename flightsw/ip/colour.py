"""Blob colouring (IP step 6), exactly as the MSX paper's "Feature extraction" section describes it.

One raster pass over the thresholded (binary) or clipped subimage, a row at a time from the upper
left corner; a pixel is *on* when non-zero. For each on pixel the four already-visited neighbours of
Figure 4a form the 4-bit number ::

    n = (abcd) base 2,   a = left, b = upper left, c = upper, d = upper right   (1 = on)

and a case statement on n (0..15) gives the pixel a colour: n = 0 a new colour, otherwise the colour of
an on neighbour; the cases where two on neighbours may carry different colours (n = 5, 9, 13: an upper
right neighbour not joined through the upper one, and with diagonal connectivity off n = 10, left and
upper) *merge* them. "Instead of recoloring the pixels, an intermediate color array" (Figure 4b) holds
the colour of every provisional number: a merge links the larger number's entry to the smaller one, so
the colour of a blob is the smallest provisional number it holds, which is the number its first pixel
in raster order received. Pixels in the first row, first column and last column have their missing
neighbours off (the paper's special cases). With the diagonal flag off only the left and upper
neighbours count (``n`` is masked with ``1010b``), which is 4-connectivity; on is 8-connectivity.

While scanning, the per-blob sums the features need are accumulated for the pixel's provisional
colour and folded into the blob's colour at the end of the scan:

======  =================================  =====================================================
index   sum                                1750A width
======  =================================  =====================================================
0       N, pixel count                     32-bit double word (DA)
1       S = sum I                          32-bit
2, 3    sum I*col, sum I*row               32-bit
4-6     sum I*col^2, I*row^2, I*row*col    64-bit multiword (two double words, DA with carry)
7, 8    sum col, sum row                   32-bit
9-11    sum col^2, row^2, row*col          32-bit
12      max I                              16-bit
======  =================================  =====================================================

(``col``, ``row`` are the 0-based window indices; the paper's ``+ 1/2`` is added in the features.) In
the flight window (64 x 64) the 32-bit sums cannot overflow for pixel values up to 16643:
``sum I*col <= I_max * 64 * (0 + 1 + ... + 63) = I_max * 129024 < 2**31`` (12-bit pixels give at most
5.3e8). The ground's full-frame mode (larger windows) keeps every sum in 64 bits, as a multiword
flight routine would; the integers are the same either way.

Cycle costs (``budget.M1750_PACE_COSTS`` keys, charged to processor ``"ip1750"``, stage ``"colour"``)
follow the operation counts of the scan: see :data:`COLOUR_MIX`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from flightsw.budget import IP1750, Ledger, m1750_cycles

__all__ = ["label", "colour", "blob_sums", "ColourResult", "NSUM", "SUM_NAMES", "COLOUR_MIX",
           "colour_cycles"]

SUM_NAMES = ("n", "s", "s_col", "s_row", "s_colcol", "s_rowrow", "s_rowcol",
             "g_col", "g_row", "g_colcol", "g_rowrow", "g_rowcol", "max")
NSUM = len(SUM_NAMES)
_N, _S, _SC, _SR, _SCC, _SRR, _SRC, _GC, _GR, _GCC, _GRR, _GRC, _MAX = range(NSUM)

#: operation mix of each event of the scan, in budget.M1750_PACE_COSTS keys ([ASSUMED] composition:
#: the flight assembly is not public; counts are those of a straightforward 1750A coding).
COLOUR_MIX = {
    # every pixel: load, zero test, loop index/compare
    "pixel": {"L": 1, "JC": 1, "INCDEC": 1},
    # every on pixel: four neighbour loads + tests forming n (shift/or), the case jump, the colour
    # store, then the sums: count (INCDEC), six 32-bit adds (2 A each), three 64-bit adds (4 A
    # each), the products I*col, I*row (M), I*col^2, I*row^2, I*row*col (32x16: 2 M + 2 A each),
    # col^2, row^2, row*col (M), max compare/branch/store
    "on_pixel": {"L": 5, "JC": 6, "SHIFT": 3, "AR": 3, "ST": 2, "INCDEC": 1,
                 "A": 12 + 12 + 6, "MR": 2 + 6 + 3, "C": 1},
    # a new colour: next number, its colour-array entry, zero its 13 sums
    "new_colour": {"INCDEC": 1, "ST": 1 + NSUM},
    # a merge case (n = 5, 9, 13; 10 with diagonal off): two look-ups, compare, link
    "merge": {"L": 2, "C": 1, "JC": 2, "ST": 1},
    # one step along the colour array while resolving a colour
    "find_step": {"L": 1, "C": 1, "JC": 1},
    # end of scan, per provisional colour: resolve, add its sums into the blob's, max
    "fold": {"L": 2 + NSUM, "A": 2 * 9 + 4 * 3, "ST": NSUM, "C": 1, "JC": 2},
}
_EVENTS = ("pixel", "on_pixel", "new_colour", "merge", "find_step", "fold")


def colour_cycles(ops) -> int:
    """PACE1750A clocks of a scan from its event counts ``ops`` (int array in the order
    pixel, on_pixel, new_colour, merge, find_step, fold)."""
    total = 0
    for name, n in zip(_EVENTS, ops):
        total += m1750_cycles(COLOUR_MIX[name]) * int(n)
    return int(total)


_CYC = np.array([m1750_cycles(COLOUR_MIX[e]) for e in _EVENTS], np.int64)


# ------------------------------------------------------------------------------------------------
# kernels
# ------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _find(parent, k):
    """Root of colour k along the colour array (path halving); returns (root, steps)."""
    steps = 0
    while parent[k] != k:
        parent[k] = parent[parent[k]]        # path halving (a store while walking)
        k = parent[k]
        steps += 1
    return k, steps


@njit(cache=True, inline="always")
def _merge(parent, x, y):
    """Link the colours of x and y (the larger root to the smaller); returns the find steps."""
    rx, s1 = _find(parent, x)
    ry, s2 = _find(parent, y)
    if rx < ry:
        parent[ry] = rx
    elif ry < rx:
        parent[rx] = ry
    return s1 + s2


@njit(cache=True, inline="always")
def _accumulate(psums, k, v, r, c):
    """Add on pixel (r, c) of intensity v to the sums of colour k."""
    vi = np.int64(v)
    vc = vi * c
    vr = vi * r
    psums[k, _N] += 1
    psums[k, _S] += vi
    psums[k, _SC] += vc
    psums[k, _SR] += vr
    psums[k, _SCC] += vc * c
    psums[k, _SRR] += vr * r
    psums[k, _SRC] += vr * c
    psums[k, _GC] += c
    psums[k, _GR] += r
    psums[k, _GCC] += c * c
    psums[k, _GRR] += r * r
    psums[k, _GRC] += r * c
    if psums[k, _N] == 1 or vi > psums[k, _MAX]:
        psums[k, _MAX] = vi


@njit(cache=True, inline="always")
def _flush(psums, k, r, cnt, sv, svc, svcc, sc, scc, vmax):
    """Add a run (row r) of colour k to its sums."""
    first = psums[k, _N] == 0
    psums[k, _N] += cnt
    psums[k, _S] += sv
    psums[k, _SC] += svc
    psums[k, _SR] += sv * r
    psums[k, _SCC] += svcc
    psums[k, _SRR] += sv * r * r
    psums[k, _SRC] += svc * r
    psums[k, _GC] += sc
    psums[k, _GR] += cnt * r
    psums[k, _GCC] += scc
    psums[k, _GRR] += cnt * r * r
    psums[k, _GRC] += sc * r
    if first or vmax > psums[k, _MAX]:
        psums[k, _MAX] = vmax


@njit(cache=True)
def _colour_kernel(img, diagonal, want_labels):
    """Raster-scan blob colouring of ``img`` (int32 [H, W]; non-zero = on).

    Returns (labels int32 [H, W] final colours 1..N (all zero if not ``want_labels``), N,
    sums int64 [N + 1, NSUM] (row 0 unused), ops int64 [6] event counts).

    Host implementation note: the flight accumulates the sums of each pixel's provisional colour
    during the scan and folds them through the colour array at the end (what :data:`COLOUR_MIX`
    charges); the host adds the same integers per final colour in a second sweep over the
    provisional colours (which also writes the label image). Integer sums do not depend on the
    order of addition, so the results are identical."""
    H, W = img.shape
    # provisional colours, with a zero border: row 0 above the first row, columns 0 and W + 1
    # beside the first and last columns (the paper's special cases: those neighbours are off)
    raw = np.zeros((H + 1, W + 2), np.int32)
    cap = (H * W + 1) // 2 + 2                   # most colours a window can need (checkerboard)
    parent = np.empty(cap, np.int32)             # the intermediate colour array
    n_on = 0
    n_merge = 0
    n_steps = 0
    ncol = 0
    for r in range(H):
        up_row = raw[r]
        row = raw[r + 1]
        for c in range(W):
            if img[r, c] == 0:
                continue
            n_on += 1
            # n = (abcd): a = left, b = upper left, c = upper, d = upper right
            a = row[c]
            up = up_row[c + 1]
            if diagonal:
                b = up_row[c]
                d = up_row[c + 2]
            else:
                b = 0
                d = 0
            # ---- the case statement on n, its 16 cases grouped by action (module docstring):
            # the colour is that of the first on neighbour in the order a, c, b, d, a merge
            # partner exists only for n = 5, 9, 13 (and n = 10 without diagonals), a new colour
            # only for n = 0 ----
            k = d
            if b != 0:
                k = b
            if up != 0:
                k = up
            if a != 0:
                k = a
            m = 0
            if diagonal:
                if up == 0 and d != k:               # n = 5, 9, 13 (k is then b or a, d on)
                    m = d
            elif a != 0 and up != a:                 # n = 10 without diagonals
                m = up
            if m != 0:
                n_steps += _merge(parent, k, m)
                n_merge += 1
            elif k == 0:                             # n = 0: a new colour
                ncol += 1
                parent[ncol] = ncol
                k = ncol
            row[c + 1] = k
    # ---- end of scan: resolve the colour array, number blobs in order of their first pixel ----
    final = np.zeros(ncol + 1, np.int32)
    nblob = 0
    for k in range(1, ncol + 1):
        root, st = _find(parent, k)
        n_steps += st
        if root == k:
            nblob += 1
            final[k] = nblob
        else:
            final[k] = final[root]
    ops = np.zeros(6, np.int64)
    ops[0] = H * W
    ops[1] = n_on
    ops[2] = ncol
    ops[3] = n_merge
    ops[4] = n_steps
    ops[5] = ncol
    # ---- the sums, per run of one colour in a row (registers), added per final colour ----
    sums = np.zeros((nblob + 1, NSUM), np.int64)
    labels = np.zeros((H, W), np.int32)
    for r in range(H):
        row = raw[r + 1]
        run_k = 0
        cnt = 0
        sv = 0
        svc = 0
        svcc = 0
        sc = 0
        scc = 0
        vmax = 0
        for c in range(W):
            k = row[c + 1]
            if k == 0:
                continue
            f = final[k]
            if want_labels:
                labels[r, c] = f
            if f != run_k:
                if run_k != 0:
                    _flush(sums, run_k, r, cnt, sv, svc, svcc, sc, scc, vmax)
                run_k = f
                cnt = 0
                sv = 0
                svc = 0
                svcc = 0
                sc = 0
                scc = 0
                vmax = np.int64(img[r, c])
            vi = np.int64(img[r, c])
            cnt += 1
            sv += vi
            vc = vi * c
            svc += vc
            svcc += vc * c
            sc += c
            scc += c * c
            if vi > vmax:
                vmax = vi
        if run_k != 0:
            _flush(sums, run_k, r, cnt, sv, svc, svcc, sc, scc, vmax)
    return labels, nblob, sums, ops


@njit(cache=True)
def _sums_from_labels(img, labels, count):
    """Per-blob sums (as :func:`_colour_kernel`) of an image given its labels 1..count."""
    H, W = img.shape
    sums = np.zeros((count + 1, NSUM), np.int64)
    for r in range(H):
        for c in range(W):
            k = labels[r, c]
            if k <= 0 or k > count:
                continue
            _accumulate(sums, k, img[r, c], r, c)
    return sums


# ------------------------------------------------------------------------------------------------
# public surface
# ------------------------------------------------------------------------------------------------
class ColourResult:
    """Result of :func:`colour`.

    Attributes
    ----------
    labels : ndarray [H, W] int32
        Final colours 1..count (0 = off), numbered in order of each blob's first pixel (raster).
    count : int
        Number of blobs N.
    sums : ndarray [count + 1, NSUM] int64
        Per-blob sums accumulated during the scan (row k = blob k; row 0 unused), columns
        :data:`SUM_NAMES`.
    ops : ndarray [6] int64
        Event counts (pixel, on_pixel, new_colour, merge, find_step, fold) of the scan.
    cycles : int
        PACE1750A clocks charged for the scan.
    """

    __slots__ = ("labels", "count", "sums", "ops", "cycles")

    def __init__(self, labels, count, sums, ops, cycles):
        self.labels, self.count, self.sums, self.ops, self.cycles = labels, count, sums, ops, cycles

    def __iter__(self):
        return iter((self.labels, self.count))


def _as_int_image(image, name="image") -> np.ndarray:
    a = np.asarray(image)
    if a.ndim != 2 or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"{name} must be a non-empty 2-D array, got shape {a.shape}")
    if a.dtype == np.bool_:
        return a.astype(np.int32)
    if np.issubdtype(a.dtype, np.integer):
        if a.size and (a.min() < -32768 or a.max() > 65535):
            raise ValueError(f"{name} holds values outside the 16-bit word range "
                             f"(min {a.min()}, max {a.max()})")
        return np.ascontiguousarray(a, dtype=np.int32)
    if np.issubdtype(a.dtype, np.floating):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} holds NaN or infinite values")
        if np.any(a != np.round(a)) or a.min() < -32768 or a.max() > 65535:
            raise ValueError(f"{name} (float) must hold integral 16-bit pixel values")
        return np.ascontiguousarray(a, dtype=np.int32)
    raise ValueError(f"{name} has unsupported dtype {a.dtype}")


def colour(image, diagonal: bool = True, ledger: Ledger | None = None,
           stage: str = "colour") -> ColourResult:
    """Colour the blobs of a thresholded (binary) or clipped image and accumulate their sums.

    Parameters
    ----------
    image : array_like [H, W], integer (16-bit values) or bool
        Pixel intensities; non-zero = on. Clipped images keep their intensities (used by the sums).
    diagonal : bool
        The uplink diagonal-connectivity flag: True = 8-connectivity, False = left/upper only.
    ledger : Ledger, optional
        Charged ``colour_cycles`` on processor ``"ip1750"``, ``stage``.

    Returns
    -------
    ColourResult
    """
    if diagonal not in (True, False, 0, 1):
        raise ValueError(f"diagonal={diagonal!r} must be a bool")
    img = _as_int_image(image)
    labels, n, sums, ops = _colour_kernel(img, bool(diagonal), True)
    cyc = int(np.dot(_CYC, ops))
    if ledger is not None:
        ledger.charge(IP1750, stage, cyc)
    return ColourResult(labels, int(n), sums, ops, cyc)


def label(image, diagonal: bool = True):
    """Blob colouring as a labelling function: ``(labels int32 [H, W], count)``.

    Non-zero pixels are on; labels are 1..count in order of each blob's first pixel in raster
    order (0 = off), the numbering of ``scipy.ndimage.label`` with the 8-connected structure when
    ``diagonal`` is True and the 4-connected one when False.
    """
    res = colour(image, diagonal)
    return res.labels, res.count


def blob_sums(image, labels, count) -> np.ndarray:
    """Per-blob sums (columns :data:`SUM_NAMES`) of ``image`` over ``labels`` 1..count ->
    int64 [count + 1, NSUM]; the same integers the colouring scan accumulates."""
    img = _as_int_image(image)
    lab = np.asarray(labels)
    if lab.shape != img.shape:
        raise ValueError(f"labels shape {lab.shape} differs from image shape {img.shape}")
    if not np.issubdtype(lab.dtype, np.integer):
        raise ValueError(f"labels must be an integer array, got {lab.dtype}")
    if isinstance(count, (bool, np.bool_)) or not isinstance(count, (int, np.integer)) or count < 0:
        raise ValueError(f"count={count!r} must be a non-negative int")
    if lab.size and (lab.min() < 0 or lab.max() > count):
        raise ValueError(f"labels hold values outside 0..count={count}")
    return _sums_from_labels(img, np.ascontiguousarray(lab, dtype=np.int32), int(count))
