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
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros

from flightsw.budget import IP1750, Ledger, m1750_cycles
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["label", "colour", "blob_sums", "ColourResult", "NSUM", "SUM_NAMES", "BLOB_SUMS",
           "COLOUR_MIX",
           "colour_cycles"]

SUM_NAMES = ("n", "s", "s_col", "s_row", "s_colcol", "s_rowrow", "s_rowcol",
             "g_col", "g_row", "g_colcol", "g_rowrow", "g_rowcol", "max")
NSUM = len(SUM_NAMES)
#: one blob's sums, a record per blob (all int64: the flight's 32-bit sums, with 64-bit room for
#: windows larger than the flight's): ``n`` pixels; ``s`` sum I; ``s_col``, ``s_row`` sum I c,
#: sum I r; ``s_colcol``, ``s_rowrow``, ``s_rowcol`` sum I c^2, I r^2, I r c (intensity moments);
#: ``g_col`` ... ``g_rowcol`` the same without I (geometric moments); ``max`` the largest I
#: (c, r 0-based column and row in the window)
BLOB_SUMS = np.dtype([(name, np.int64) for name in SUM_NAMES])

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
#: the event counts' names as indices into :func:`colour_k`'s counts (the order of ``_EVENTS``
#: and :data:`OP_CYCLES`: the counts are a vector the cycle costs are dotted with)
EV_PIXEL, EV_ON_PIXEL, EV_NEW_COLOUR, EV_MERGE, EV_FIND_STEP, EV_FOLD = range(len(_EVENTS))


def colour_cycles(ops) -> int:
    """PACE1750A clocks of a scan from its event counts ``ops`` (int array in the order
    pixel, on_pixel, new_colour, merge, find_step, fold)."""
    total = 0
    for name, n in zip(_EVENTS, ops):
        total += m1750_cycles(COLOUR_MIX[name]) * int(n)
    return int(total)


OP_CYCLES = np.array([m1750_cycles(COLOUR_MIX[e]) for e in _EVENTS], np.int64)


# ------------------------------------------------------------------------------------------------
# kernels
# ------------------------------------------------------------------------------------------------
@callee_kernel
def _find(parent, k):
    """Root of colour k along the colour array (path halving); returns (root, steps).

    ``parent``: int32 [>= k + 1] the intermediate colour array (updated in place); ``k``: colour.

    Cases
    -----
    root : ``parent[k] == k`` -> ``(k, 0)``, nothing stored.
    chain : a chain of links -> the root and the number of steps; each visited entry now points to
        its grandparent (path halving).
    """
    steps = 0
    while parent[k] != k:
        parent[k] = parent[parent[k]]        # path halving (a store while walking)
        k = parent[k]
        steps += 1
    return k, steps


@callee_kernel
def _merge(parent, x, y):
    """Link the colours of x and y (the larger root to the smaller); returns the find steps.

    Cases
    -----
    link : different roots -> the larger root's entry is set to the smaller root (either order).
    same-root : already one colour -> no link.
    """
    rx, s1 = _find(parent, x)
    ry, s2 = _find(parent, y)
    if rx < ry:
        parent[ry] = rx
    elif ry < rx:
        parent[rx] = ry
    return s1 + s2


@callee_kernel
def _accumulate(psums, k, v, r, c):
    """Add on pixel (r, c) of intensity v to the sums of colour k.

    ``psums``: :data:`BLOB_SUMS` [>= k + 1] (record k updated); ``v``: pixel word; ``r``, ``c``:
    0-based.

    Cases
    -----
    typical : every sum of :data:`SUM_NAMES` gains the pixel's term.
    first-max : the colour's first pixel sets max I whatever its sign (a negative blob's max is
        its largest negative word, not 0).
    max : a later pixel replaces max I only when larger.
    """
    vi = np.int64(v)
    vc = vi * c
    vr = vi * r
    psums[k].n += 1
    psums[k].s += vi
    psums[k].s_col += vc
    psums[k].s_row += vr
    psums[k].s_colcol += vc * c
    psums[k].s_rowrow += vr * r
    psums[k].s_rowcol += vr * c
    psums[k].g_col += c
    psums[k].g_row += r
    psums[k].g_colcol += c * c
    psums[k].g_rowrow += r * r
    psums[k].g_rowcol += r * c
    if psums[k].n == 1 or vi > psums[k].max:
        psums[k].max = vi


@callee_kernel
def _flush(psums, k, r, run):
    """Add a run (row r) of colour k to its sums.

    ``psums``: :data:`BLOB_SUMS` [>= k + 1]; ``run`` = (``cnt``, ``sv``, ``svc``, ``svcc``, ``sc``,
    ``scc``, ``vmax``): the run's count, sum I, sum I c, sum I c^2, sum c, sum c^2 and max I.

    Cases
    -----
    typical : the run's terms (rows from ``r``) added to every sum, as pixel by pixel.
    first-max : the colour's first run sets max I whatever its sign.
    max : a later run replaces max I only when larger.
    """
    cnt, sv, svc, svcc, sc, scc, vmax = run
    first = psums[k].n == 0
    psums[k].n += cnt
    psums[k].s += sv
    psums[k].s_col += svc
    psums[k].s_row += sv * r
    psums[k].s_colcol += svcc
    psums[k].s_rowrow += sv * r * r
    psums[k].s_rowcol += svc * r
    psums[k].g_col += sc
    psums[k].g_row += cnt * r
    psums[k].g_colcol += scc
    psums[k].g_rowrow += cnt * r * r
    psums[k].g_rowcol += sc * r
    if first or vmax > psums[k].max:
        psums[k].max = vmax


@callee_kernel
def _scan_pixels(img, diagonal, prov, parent, run_r, run_a, run_b):
    """The raster scan, pixel by pixel (any width). Returns (ncol, nrun, n_on, n_merge, n_steps,
    bad) with ``bad`` set when a pixel is outside the 16-bit word range -32768..65535.

    ``img``: integer [H, W]; ``prov``: int32 [H + 1, W + 2] zeroed provisional colours; ``parent``:
    int32 colour array; ``run_r``, ``run_a``, ``run_b``: int32 run lists (row, first, one past).

    Cases
    -----
    diagonal : 8-connectivity -> the labels of ``scipy.ndimage.label`` (3x3 structure).
    four-connected : ``diagonal`` off -> the 4-connected labels.
    merge : U shapes and n = 5/9/13 (10 without diagonals) -> colours merged in the colour array.
    out-of-range : a word outside -32768..65535 -> ``bad`` set.
    off-blocks : 32 off pixels from a column that is a multiple of 32 -> passed at once, the
        same runs and events.
    """
    H, W = img.shape
    bad = False
    for r in range(H):
        src = img[r]
        for c in range(W):
            v = src[c]
            bad |= (v < -32768) | (v > 65535)
    nrun = 0
    n_on = 0
    n_merge = 0
    n_steps = 0
    ncol = 0
    for r in range(H):
        up_row = prov[r]
        row = prov[r + 1]
        src = img[r]
        c = 0
        while c < W:
            if src[c] == 0:
                # host speed-up: an aligned block of 32 off pixels is passed at once (one
                # vectorised OR; the same pixels are visited, most of a wide frame is off)
                if c & 31 == 0 and c + 32 <= W:
                    z = src[c]
                    for q in range(c + 1, c + 32):
                        z |= src[q]
                    if z == 0:
                        c += 32
                        continue
                c += 1
                continue
            # ---- first pixel of a run: the left neighbour a is off. The case statement on
            # n = (abcd) (a = left, b = upper left, c = upper, d = upper right), its 16 cases grouped
            # by action (module docstring): the colour is that of the first on neighbour in the
            # order a, c, b, d; a merge partner exists only for n = 5, 9, 13 (and n = 10 without
            # diagonals); a new colour only for n = 0 ----
            c0 = c
            up = up_row[c + 1]
            if diagonal:
                b = up_row[c]
                d = up_row[c + 2]
            else:
                b = 0
                d = 0
            k = d
            if b != 0:
                k = b
            if up != 0:
                k = up
            if diagonal and up == 0 and d != 0 and d != k:     # n = 5 (b, d on, c off)
                n_steps += _merge(parent, k, d)
                n_merge += 1
            elif k == 0:                             # n = 0: a new colour
                ncol += 1
                parent[ncol] = ncol
                k = ncol
            row[c + 1] = k
            c += 1
            # ---- the rest of the run: a is on, so k = a; only the merge cases remain
            # (n = 9, 13 with diagonals: c off, d on with another colour; n = 10 without) ----
            if diagonal:
                while c < W and src[c] != 0:
                    d = up_row[c + 2]
                    if d != 0 and d != k and up_row[c + 1] == 0:
                        n_steps += _merge(parent, k, d)
                        n_merge += 1
                    row[c + 1] = k
                    c += 1
            else:
                while c < W and src[c] != 0:
                    up = up_row[c + 1]
                    if up != 0 and up != k:
                        n_steps += _merge(parent, k, up)
                        n_merge += 1
                    row[c + 1] = k
                    c += 1
            n_on += c - c0
            run_r[nrun] = r
            run_a[nrun] = c0
            run_b[nrun] = c
            nrun += 1
    return ncol, nrun, n_on, n_merge, n_steps, bad


_ONES = np.uint64(0xFFFFFFFFFFFFFFFF)


@callee_kernel
def _low(n):
    """uint64 with bits 0..n-1 set (0 <= n <= 64).

    Cases
    -----
    typical : ``n < 64`` -> ``2**n - 1`` (0 for ``n == 0``).
    full : ``n >= 64`` -> all 64 bits.
    """
    if n >= 64:
        return _ONES
    return (np.uint64(1) << np.uint64(n)) - np.uint64(1)


@callee_kernel
def _colour_at(U, S, srow, x):
    """Provisional colour of pixel ``x`` (-1 <= x <= 64) of the row above, from its on mask ``U``,
    its run-start mask ``S`` and its run-start colours ``srow`` (``srow[p + 1]`` = colour of the run
    starting at ``p``; ``srow[0]`` = 0): 0 if the pixel is off. Branch-free.

    Cases
    -----
    outside : ``x < 0`` or ``x >= 64`` -> 0 (the border's off neighbours).
    off : pixel ``x`` off -> 0.
    on : pixel ``x`` on -> the colour of the run it belongs to (its last run start <= x).
    """
    if x < 0 or x >= 64:
        return np.int32(0)
    on = (U >> np.uint64(x)) & np.uint64(1)
    p = 63 - np.int64(leading_zeros(S & _low(x + 1)))      # the last run start <= x (-1: none)
    return srow[p + 1] if on != 0 else np.int32(0)


@callee_kernel
def _scan_masks(img, diagonal, prov, parent, run_r, run_a, run_b):
    """The same raster scan for windows up to 64 columns, a row at a time through its on-pixel
    bitmask: the runs come from the mask (trailing-zero counts), the first pixel of a run gets the
    full case statement, the rest of the run only the merge cases, looked up where the mask of the
    row above says they can occur (diagonal: upper pixel off and upper-right on, n = 9/13; without
    diagonals: upper pixel on, n = 10) -- the same pixels, in the same order, as
    :func:`_scan_pixels` (the host needs fewer unpredictable branches; the events are identical).
    A run holds one provisional colour (its first pixel's), so ``prov`` keeps it only at the run's
    first pixel and the row above is read through its masks (:func:`_colour_at`); ``prov`` need not
    be cleared (only column 0, the "no run" slot, which this function zeroes).
    Returns (ncol, nrun, n_on, n_merge, n_steps, bad).

    Cases
    -----
    diagonal : 8-connectivity -> the labels of ``scipy.ndimage.label`` (3x3 structure).
    four-connected : ``diagonal`` off -> the 4-connected labels.
    merge : U shapes and n = 5/9/13 (10 without diagonals) -> colours merged in the colour array.
    full-width : a run reaching column 63 of a 64-column window (mask bit 63) -> ends at 64.
    out-of-range : a word outside -32768..65535 -> ``bad`` set.
    """
    H, W = img.shape
    bad = False
    nrun = 0
    n_on = 0
    n_merge = 0
    n_steps = 0
    ncol = 0
    one = np.uint64(1)
    U = np.uint64(0)                  # the row above: on mask, run-start mask
    S = np.uint64(0)
    prov[0, 0] = 0
    for r in range(H):
        # most rows of a thresholded window are all off: an OR over the row (vectorised, no row
        # views: their reference counts cost more than the test) finds them, mask 0, no run
        anyon = np.int64(0)
        for c in range(W):
            anyon |= np.int64(img[r, c])
        prov[r + 1, 0] = 0
        if anyon == 0:
            U = np.uint64(0)
            S = np.uint64(0)
            continue
        src = img[r]
        M = np.uint64(0)
        for c in range(W):
            v = src[c]
            M |= np.uint64(v != 0) << np.uint64(c)
            bad |= (v < -32768) | (v > 65535)
        Mrow = M
        up_row = prov[r]
        row = prov[r + 1]
        while M != 0:
            s = np.int64(trailing_zeros(M))
            rest = ~(M >> np.uint64(s))
            e = np.int64(64) if rest == 0 else s + np.int64(trailing_zeros(rest))
            M &= ~_low(e)
            # ---- first pixel: a off; the case statement (see _scan_pixels) ----
            up = _colour_at(U, S, up_row, s)
            if diagonal:
                b = _colour_at(U, S, up_row, s - 1)
                d = _colour_at(U, S, up_row, s + 1)
            else:
                b = np.int32(0)
                d = np.int32(0)
            k = d
            k = b if b != 0 else k
            k = up if up != 0 else k
            if diagonal and up == 0 and d != 0 and d != k:     # n = 5
                n_steps += _merge(parent, k, d)
                n_merge += 1
            elif k == 0:                                         # n = 0: a new colour
                ncol += 1
                parent[ncol] = ncol
                k = ncol
            row[s + 1] = k
            # ---- the rest of the run: k = a; the merge cases where the row above allows ----
            if e - s > 1:
                inner = _low(e) & ~_low(s + 1)
                if diagonal:
                    # upper pixel c off, c + 1 on: c + 1 starts a run above, colour up_row[c + 2]
                    cand = (~U) & (U >> one) & inner
                    while cand != 0:
                        c = np.int64(trailing_zeros(cand))
                        cand &= cand - one
                        d = up_row[c + 2]
                        if d != k:                               # n = 9, 13
                            n_steps += _merge(parent, k, d)
                            n_merge += 1
                else:
                    cand = U & inner
                    while cand != 0:
                        c = np.int64(trailing_zeros(cand))
                        up = _colour_at(U, S, up_row, c)
                        if up == k:          # the whole overlap with this run above: no event
                            cand &= ~_low(_run_end(U, c))
                            continue
                        cand &= cand - one
                        n_steps += _merge(parent, k, up)         # n = 10
                        n_merge += 1
            n_on += e - s
            run_r[nrun] = r
            run_a[nrun] = s
            run_b[nrun] = e
            nrun += 1
        U = Mrow
        S = Mrow & ~(Mrow << one)
    return ncol, nrun, n_on, n_merge, n_steps, bad


@callee_kernel
def _run_end(U, c):
    """One past the last pixel of the run of mask ``U`` that contains pixel ``c``.

    Cases
    -----
    inside : the run ends before bit 63 -> the first off bit above ``c``.
    to-bit-63 : the run reaches bit 63 -> 64.
    """
    rest = ~(U >> np.uint64(c))
    return np.int64(64) if rest == 0 else c + np.int64(trailing_zeros(rest))


@callee_kernel
def colour_k(img, diagonal, want_labels, want_sums=True):
    """Raster-scan blob colouring of ``img`` (integer or bool [H, W]; non-zero = on).

    Returns (labels int32 [H, W] final colours 1..N (an empty [0, 0] array if not ``want_labels``), N,
    sums :data:`BLOB_SUMS` [N + 1] (record 0 unused; zeros if not ``want_sums``), ops int64 [6] event counts,
    bad: a pixel lies outside the 16-bit word range -32768..65535 -- the callers raise).

    Host implementation note: the flight accumulates the sums of each pixel's provisional colour
    during the scan and folds them through the colour array at the end (what :data:`COLOUR_MIX`
    charges); the host records each run of on pixels of a row during the scan (a run is connected
    through the left neighbours, so it holds one provisional colour, that of its first pixel) and
    adds the same integers per run into the final colour's sums afterwards (which also writes the
    label image). Integer sums do not depend on the order of addition, so the results are
    identical.

    Cases
    -----
    labels : blobs numbered 1..N in the order of their first pixel (``scipy.ndimage.label``'s
        numbering), 8- or 4-connected by ``diagonal``.
    sums : ``want_sums`` -> row k holds blob k's :data:`SUM_NAMES` integers.
    no-sums : ``want_sums`` false -> sums all zero (labels and N unchanged).
    no-labels : ``want_labels`` false -> labels an empty [0, 0] array (sums unchanged).
    no-blobs : no on pixel -> N = 0, sums [1] zeros, labels all 0.
    narrow : ``W <= 64`` -> the mask scan.
    wide : ``W > 64`` -> the pixel scan, the same labels.
    out-of-range : a word outside -32768..65535 -> ``bad`` true.
    events : ``ops`` = (pixels, on pixels, new colours, merges, find steps, folds).
    """
    H, W = img.shape
    # provisional colours, with a zero border: row 0 above the first row, columns 0 and W + 1
    # beside the first and last columns (the paper's special cases: those neighbours are off)
    prov = np.empty((H + 1, W + 2), np.int32) if W <= 64 else np.zeros((H + 1, W + 2), np.int32)
    cap = (H * W + 1) // 2 + 2                   # most colours a window can need (checkerboard)
    rcap = H * ((W + 1) // 2) + 1                # most runs a window can hold
    work = np.empty((4, max(cap, rcap)), np.int32)    # one allocation for:
    parent = work[0]                             # the intermediate colour array
    run_r, run_a, run_b = work[1], work[2], work[3]   # the runs: row, first, one-past-last column
    if W <= 64:
        ncol, nrun, n_on, n_merge, n_steps, bad = _scan_masks(img, diagonal, prov, parent, run_r,
                                                              run_a, run_b)
    else:
        ncol, nrun, n_on, n_merge, n_steps, bad = _scan_pixels(img, diagonal, prov, parent, run_r,
                                                               run_a, run_b)
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
    ops[EV_PIXEL] = H * W
    ops[EV_ON_PIXEL] = n_on
    ops[EV_NEW_COLOUR] = ncol
    ops[EV_MERGE] = n_merge
    ops[EV_FIND_STEP] = n_steps
    ops[EV_FOLD] = ncol
    # ---- the sums and the labels, per run (one final colour each) ----
    sums = np.zeros(nblob + 1, BLOB_SUMS)
    for q in range(nrun):
        r = run_r[q]
        c0 = run_a[q]
        c1 = run_b[q]
        f = final[prov[r + 1, c0 + 1]]
        if want_sums:
            src = img[r]
            sv = np.int64(0)
            svc = np.int64(0)
            svcc = np.int64(0)
            vmax = np.int64(src[c0])
            for c in range(c0, c1):
                vi = np.int64(src[c])
                vc = vi * c
                sv += vi
                svc += vc
                svcc += vc * c
                if vi > vmax:
                    vmax = vi
            cnt = np.int64(c1 - c0)
            # sum c and sum c^2 over c0..c1-1 (closed forms of the same integers)
            sc = (np.int64(c1) * (c1 - 1) - np.int64(c0) * (c0 - 1)) // 2
            scc = (np.int64(c1 - 1) * c1 * (2 * c1 - 1) - np.int64(c0 - 1) * c0 * (2 * c0 - 1)) // 6
            _flush(sums, f, r, (cnt, sv, svc, svcc, sc, scc, vmax))
    # the label image in a loop of its own: its int32 stores inside the sums loop would keep the
    # compiler from holding the sums in registers (they might alias; measured 8.3 vs 4.6 us)
    labels = np.zeros((H, W) if want_labels else (0, 0), np.int32)
    if want_labels:
        for q in range(nrun):
            r = run_r[q]
            f = final[prov[r + 1, run_a[q] + 1]]
            lrow = labels[r]
            for c in range(run_a[q], run_b[q]):
                lrow[c] = f
    return labels, nblob, sums, ops, bad


@njit(**KERNEL)
def _label_kernel(img, diagonal):
    """:func:`colour_k` without the sums: (labels, N, bad) (fewer arrays to hand back).

    Cases
    -----
    typical : the labels and N of :func:`colour_k`.
    out-of-range : ``bad`` true for a word outside the 16-bit range.
    """
    labels, n, _, _, bad = colour_k(img, diagonal, True, False)
    return labels, n, bad


@njit(**KERNEL)
def _sums_from_labels(img, labels, count):
    """Per-blob sums (as :func:`colour_k`) of an image given its labels 1..count.

    ``img``: int32 [H, W]; ``labels``: int32 [H, W]; ``count``: int. Returns :data:`BLOB_SUMS`
    [count + 1].

    Cases
    -----
    typical : record k holds the :data:`SUM_NAMES` integers of the pixels labelled k.
    outside-labels : labels ``<= 0`` or ``> count`` are skipped.
    no-blobs : ``count == 0`` -> one zero record.
    """
    H, W = img.shape
    sums = np.zeros(count + 1, BLOB_SUMS)
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
    sums : ndarray [count + 1] of :data:`BLOB_SUMS`
        Per-blob sums accumulated during the scan (record k = blob k; record 0 unused), fields
        :data:`SUM_NAMES` (``sums["s"]``: every blob's sum I).
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


def as_int_image(image, name="image") -> np.ndarray:
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


#: dtypes the kernels take as they are (no copy); others go through :func:`as_int_image`
DIRECT_DTYPES = (np.bool_, np.uint8, np.int8, np.uint16, np.int16, np.int32, np.uint32, np.int64)
_RANGE_MSG = "holds values outside the 16-bit word range -32768..65535"


def _direct(image):
    """``image`` itself when the kernels can read it without a copy (C-contiguous 2-D, non-empty,
    an integer or bool dtype; the 16-bit range is checked inside the scan), else the checked copy."""
    if isinstance(image, np.ndarray) and image.ndim == 2 and image.size \
            and image.dtype.type in DIRECT_DTYPES and image.flags.c_contiguous:
        return image
    return as_int_image(image)


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
    img = _direct(image)
    labels, n, sums, ops, bad = colour_k(img, bool(diagonal), True)
    if bad:
        raise ValueError(f"image {_RANGE_MSG}")
    cyc = int(np.dot(OP_CYCLES, ops))
    if ledger is not None:
        ledger.charge(IP1750, stage, cyc)
    return ColourResult(labels, int(n), sums, ops, cyc)


def label(image, diagonal: bool = True):
    """Blob colouring as a labelling function: ``(labels int32 [H, W], count)``.

    Non-zero pixels are on; labels are 1..count in order of each blob's first pixel in raster
    order (0 = off), the numbering of ``scipy.ndimage.label`` with the 8-connected structure when
    ``diagonal`` is True and the 4-connected one when False. The same scan as :func:`colour`
    without the per-blob sums.
    """
    if diagonal is not True and diagonal is not False and diagonal not in (0, 1):
        raise ValueError(f"diagonal={diagonal!r} must be a bool")
    labels, n, bad = _label_kernel(_direct(image), bool(diagonal))
    if bad:
        raise ValueError(f"image {_RANGE_MSG}")
    return labels, n


def blob_sums(image, labels, count) -> np.ndarray:
    """Per-blob sums (fields :data:`SUM_NAMES`) of ``image`` over ``labels`` 1..count ->
    :data:`BLOB_SUMS` [count + 1]; the same integers the colouring scan accumulates."""
    img = as_int_image(image)
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
