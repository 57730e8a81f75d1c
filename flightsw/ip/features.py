"""The twelve features of each coloured blob (IP step 7) and their normalisation, in 1750A float.

The MSX paper's boxed equations, with the paper's column index ``i`` and row index ``j`` (0-based
window indices here, the pixel centre at ``+ 1/2``)::

    Size_n            = sum I_n(i, j)
    column_n          = sum (i + 1/2) p_n(i, j)          row_n = sum (j + 1/2) p_n(i, j)
    p_n(i, j)         = Intensity(i, j) I_n(i, j) / sum Intensity I_n       (intensity flag on)
                      = I_n(i, j) / Size_n                                   (flag off: geometric)
    mu_pq             = sum (i + 1/2 - column_n)^p (j + 1/2 - row_n)^q p_n(i, j)
    theta_n           = 1/2 tan^-1( 2 mu_11 / (mu_20 - mu_02) )
    Eccentricity_n    = ((mu_20 - mu_02)^2 + 4 mu_11^2) / Size_n^2
    Semimajor_n      ~= { 2 [mu_20 cos^2 th + 2 mu_11 cos th sin th + mu_02 sin^2 th] + 1 }^1/2
    Semiminor_n      ~= { 2 [mu_20 sin^2 th - 2 mu_11 cos th sin th + mu_02 cos^2 th] + 1 }^1/2
    Sigma ratio_n     = Semiminor_n / Semimajor_n
    Total brightness  = sum Intensity I_n ;  Average = Total / Size ;  Maximum = max Intensity I_n
    Brightness ratio  = Average / Maximum

Decisions (where the paper leaves the implementation open):

* ``tan^-1`` is the two-argument arctangent ``atan2(2 mu_11, mu_20 - mu_02)``, so that ``theta`` is the
  direction of the *major* axis and Semimajor >= Semiminor always (with a one-argument arctangent
  the two would swap whenever ``mu_02 > mu_20``).
* The semi-axis brackets are evaluated with the double-angle identities ``cos^2 th = (1 + cos 2th)/2``,
  ``sin 2th = 2 mu_11 / r``, ``cos 2th = (mu_20 - mu_02) / r``, ``r = ((mu_20 - mu_02)^2 + 4 mu_11^2)^1/2``,
  which turn them into ``mu_20 + mu_02 +/- r + 1`` exactly -- the same values without a sin and a
  cos per blob on the 1750A (``r^2`` is the eccentricity numerator anyway).
* The moments use the same weights ``p_n`` as the centroids (intensity or geometric by the flag);
  a blob whose intensity sum is <= 0 (possible only for signed clipped input) uses geometric weights.
  The brightness features always use the intensities.
* Arithmetic: the sums (exact integers, :mod:`flightsw.ip.colour`) are converted with EFLT; centroids
  and central moments are formed in 48-bit extended float by division (``sum / W``, exact whenever
  the quotient is representable, so a one-pixel or symmetric blob gets exactly zero moments;
  ``mu = sum/W - mean^2`` cancels about 12 bits, 28 remain); everything after ``r^2`` in 32-bit float, with the ``flightsw.arith.m1750`` sqrt32
  and atan2_32. Results are 32-bit 1750A floats (2 words each), i.e. relative error of a few
  ``2**-23`` except where a feature is ill-conditioned (orientation of a round blob).

Units (before normalisation, processed pixels of the window):

================  ====================================================================
size              pixels
col, row          pixels, window frame, 0-based with centres at +0.5
orientation       degrees in [0, 180), major axis measured from the +column axis toward
                  the +row axis (rows grow downward); 0 for a round blob
eccentricity      pixels^2 (the boxed formula: pixel^4 / pixel^2)
semimajor/minor   pixels
sigma_ratio       1
total_brightness  counts (sum of pixel values)
avg/max           counts per pixel
brightness_ratio  1
================  ====================================================================

Normalisation ("Normalizing statistics"): to the reference scale, the wide-FOV visible imager at
compaction 1. With compaction ``f`` and the imager's pixel scale relative to the WFOV pixel ``s``
(1 for the wide imagers, 1.6/13.1 for the narrow ones) ``size *= (f s)^2``, ``semimajor, semiminor
*= f s``, ``total_brightness *= (f s)^2`` (a compacted pixel is the mean of ``f^2`` pixels, so the
full-resolution sum is ``f^2`` times the processed one), and the centroids are projected to the
imager's full-resolution pixel frame: ``col_full = f * col + C0``, ``row_full = f * row + R0`` with
``(R0, C0)`` the window's top-left corner in full-resolution pixels (a processed pixel ``k`` covers
full-resolution pixels ``[k f, (k + 1) f)``). Other features are scale-free and unchanged.

Host execution (:func:`features_k`): every blob goes through the identical sequence of 1750A
operations (the flight's per-blob routine). The host runs it *blob-parallel*: each instruction of the
routine is applied to all blobs before the next one, in its branch-free lane form
(:mod:`flightsw.arith.m1750_lanes`), so the blobs run side by side in SIMD lanes (the intermediates
are rows of one array). Per blob the operations, their operands and their order are those of the
routine, so the words are the same; the PI flags are OR-ed (order-free).

Cycle costs: :data:`FEATURE_MIX` per blob (plus the math routines) on ``"ip1750"``.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from flightsw.arith.m1750 import (
    ONE32, HALF48, decode32_array, encode32, fa48, flt48, fm48, to32,
)
from flightsw.arith.m1750_lanes import (
    fa32_lanes, fa32_v, fa48_lanes, fc32_v, fd32_lanes, fd32_v, fd48_lanes, fm32_lanes,
    fm48_lanes, flt48_lanes, fs32_lanes, fs48_lanes,
)
from flightsw.arith.m1750_math import MATH_CYCLES, atan2_32_lanes, sqrt32_lanes
from flightsw.budget import IP1750, Ledger, m1750_cycles
from flightsw.ip.colour import BLOB_SUMS, NSUM, blob_sums
from flightsw.messages import FEATURE_NAMES, N_FEATURES
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["features", "features_words", "normalise_words", "normalise", "FEATURE_DTYPE",
           "FEATURE_NAMES", "FEATURE_MIX", "NORMALISE_MIX", "IMAGER_SCALE", "features_cycles",
           "words_to_struct", "struct_to_words"]

#: structured dtype of a feature table (float64 fields holding exact 1750A 32-bit values)
FEATURE_DTYPE = np.dtype([(n, np.float64) for n in FEATURE_NAMES])

#: imager pixel scale relative to the wide-FOV visible pixel (paper FOVs: 13.1 deg and 1.6 deg
#: across 256 columns); unknown imagers (e.g. "real") are taken at the reference scale.
IMAGER_SCALE = {"wfov_vis": 1.0, "wfov_uv": 1.0, "nfov_vis": 1.6 / 13.1, "nfov_uv": 1.6 / 13.1}

#: 1750A operation mix per blob (budget keys) besides the math routines in FEATURE_MATH
FEATURE_MIX = {
    "EFLT": 9 + 3, "EFM": 5 + 3, "EFD": 5, "EFS": 4, "EFA": 5 + 3, "DL": 8,
    "FM": 2, "FD": 4, "FA": 4, "FS": 1, "FC": 2, "JC": 4, "L": 13, "ST": 12,
}
FEATURE_MATH = {"sqrt32": 3, "atan2_32": 1}
#: per blob: 6 FM (size, two axes, total, two centroids) + 2 FA (origin) + load/store
NORMALISE_MIX = {"FM": 6, "FA": 2, "L": 6, "ST": 6}

_CYC_FEATURE = m1750_cycles(FEATURE_MIX) + sum(MATH_CYCLES[k] * n for k, n in FEATURE_MATH.items())
_CYC_NORMALISE = m1750_cycles(NORMALISE_MIX)

_DEG_PER_2RAD = encode32(90.0 / math.pi, rounding="nearest")   # (1/2 atan2) in degrees
_C180 = encode32(180.0)
_TWO31_48 = 0x400000200000                                     # 2**31 as a 48-bit float


def features_cycles(count: int, normalise: bool = True) -> int:
    """PACE1750A clocks of the features (and normalisation) of ``count`` blobs."""
    return int(count) * (_CYC_FEATURE + (_CYC_NORMALISE if normalise else 0))


# ------------------------------------------------------------------------------------------------
# kernels
# ------------------------------------------------------------------------------------------------
@callee_kernel
def _i2f48(v):
    """int64 sum -> 48-bit float: EFLT when it fits 32 bits, else hi * 2**31 + lo (EFLT, EFM,
    EFLT, EFA), as a multiword flight routine would.

    ``v``: int64 (|v| < 2**62). Returns the packed 48-bit float word (int64), exact for
    ``|v| < 2**39``.

    Cases
    -----
    fits-32 : ``-2**31 <= v < 2**31`` -> one EFLT, exact.
    wide : ``v`` beyond 32 bits (either sign) -> ``(v >> 31) * 2**31 + (v & 0x7FFFFFFF)``, exact
        below 2**39.
    """
    if -2147483648 <= v <= 2147483647:
        r, f = flt48(v & 0xFFFFFFFF)
        return r
    hi = v >> 31
    lo = v & 0x7FFFFFFF
    h, f = flt48(hi & 0xFFFFFFFF)
    h, f = fm48(h, _TWO31_48)
    l, f = flt48(lo)
    r, f = fa48(h, l)
    return r


@njit(**KERNEL)
def _features_kernel(sums, count, intensity):
    """sums :data:`~flightsw.ip.colour.BLOB_SUMS` [count + 1] -> (packed 32-bit words int64
    [count, 12], PI flags OR)
    (:func:`features_k`, blob-major).

    Cases
    -----
    typical : row ``k - 1`` holds the twelve features of blob ``k`` (FEATURE_NAMES order).
    no-blobs : ``count == 0`` -> words int64 [0, 12], flags 0.
    """
    o, fl = features_k(sums, count, intensity)
    return np.ascontiguousarray(o.T), fl


@callee_kernel
def features_k(sums, count, intensity):
    """sums :data:`~flightsw.ip.colour.BLOB_SUMS` [count + 1] -> (packed 32-bit words int64
    [12, count], feature-major: row i
    = feature i of every blob; PI flags OR). Every blob runs the flight's per-blob routine; the host
    applies each instruction to all blobs in its lane form (the same words; module docstring).

    Cases
    -----
    intensity : flag on and ``sum I > 0`` -> intensity-weighted centroids and moments.
    geometric : flag off -> every pixel weight 1.
    nonpositive-intensity : flag on, ``sum I <= 0`` -> geometric weights (brightness unchanged).
    one-pixel : zero moments exactly -> semi-axes 1, eccentricity 0, orientation 0.
    line : a one-pixel-wide line -> semiminor exactly 1; orientation 0 or 90.
    negative-angle : ``atan2 < 0`` -> orientation + 180 (always in [0, 180)).
    nonpositive-max : ``max I <= 0`` -> brightness ratio 0 (no division).
    wide-sums : a sum beyond 32 bits -> the multiword conversion (:func:`_i2f48`), same values.
    no-blobs : ``count == 0`` -> words int64 [12, 0].
    """
    K = count
    buf = np.empty((42, K), np.int64)            # the intermediates and the output, one allocation
    iw, ia, ib, ic, idd, ie = buf[0], buf[1], buf[2], buf[3], buf[4], buf[5]      # integer sums
    wf, sc, sr, scc, srr, src = buf[6], buf[7], buf[8], buf[9], buf[10], buf[11]  # their EFLT
    mc, mr, m20, m02, m11 = buf[12], buf[13], buf[14], buf[15], buf[16]
    ta, tb, dm, t, q, sm = buf[17], buf[18], buf[19], buf[20], buf[21], buf[22]
    q32, s32, t32, dm32, rq = buf[23], buf[24], buf[25], buf[26], buf[27]
    n2, th2 = buf[28], buf[29]
    o = buf[30:42]                               # o[i] = feature i of every blob
    wide = False
    for k in range(K):
        s = sums[k + 1]
        geo = not (intensity and s.s > 0)        # geometric weights (flag off, or sum I <= 0)
        iw[k] = s.n if geo else s.s
        ia[k] = s.g_col if geo else s.s_col
        ib[k] = s.g_row if geo else s.s_row
        ic[k] = s.g_colcol if geo else s.s_colcol
        idd[k] = s.g_rowrow if geo else s.s_rowrow
        ie[k] = s.g_rowcol if geo else s.s_rowcol
        o[0, k] = s.n                            # N, sum I, max I (converted below)
        o[8, k] = s.s
        o[10, k] = s.max
    for r in range(6):
        for k in range(K):
            wide |= (buf[r, k] < -2147483648) | (buf[r, k] > 2147483647)
    for r in (0, 8, 10):
        for k in range(K):
            wide |= (o[r, k] < -2147483648) | (o[r, k] > 2147483647)
    if wide:                           # a sum beyond 32 bits (windows larger than the flight's):
        for k in range(K):             # the multiword conversion
            wf[k] = _i2f48(iw[k])
            sc[k] = _i2f48(ia[k])
            sr[k] = _i2f48(ib[k])
            scc[k] = _i2f48(ic[k])
            srr[k] = _i2f48(idd[k])
            src[k] = _i2f48(ie[k])
            for r in (0, 8, 10):
                o[r, k] = to32(_i2f48(o[r, k]))
    else:                              # EFLT (exact: no flags)
        for r in range(6):
            flt48_lanes(buf[r], buf[r + 6])
        for r in (0, 8, 10):
            flt48_lanes(o[r], ta)
            for k in range(K):
                o[r, k] = to32(ta[k])
    fl = 0
    # centroids and central moments (48-bit): divisions, not a reciprocal, so that they are exact
    # whenever the quotient is representable
    fl |= fd48_lanes(sc, wf, mc)
    fl |= fd48_lanes(sr, wf, mr)
    fl |= fd48_lanes(scc, wf, ta)
    fl |= fm48_lanes(mc, mc, tb)
    fl |= fs48_lanes(ta, tb, m20)
    fl |= fd48_lanes(srr, wf, ta)
    fl |= fm48_lanes(mr, mr, tb)
    fl |= fs48_lanes(ta, tb, m02)
    fl |= fd48_lanes(src, wf, ta)
    fl |= fm48_lanes(mc, mr, tb)
    fl |= fs48_lanes(ta, tb, m11)
    fl |= fa48_lanes(mc, np.int64(HALF48), ta)   # col, row: pixel centres at + 1/2
    fl |= fa48_lanes(mr, np.int64(HALF48), tb)
    fl |= fs48_lanes(m20, m02, dm)
    fl |= fa48_lanes(m11, m11, t)
    fl |= fm48_lanes(dm, dm, sm)
    fl |= fm48_lanes(t, t, n2)
    fl |= fa48_lanes(sm, n2, q)                  # r^2 = (mu20 - mu02)^2 + (2 mu11)^2
    fl |= fa48_lanes(m20, m02, sm)
    for k in range(K):                           # ---- 32-bit part ----
        o[1, k] = to32(ta[k])
        o[2, k] = to32(tb[k])
        q32[k] = to32(q[k])
        s32[k] = to32(sm[k])
        t32[k] = to32(t[k])
        dm32[k] = to32(dm[k])
    fl |= sqrt32_lanes(q32, rq)
    fl |= fm32_lanes(o[0], o[0], n2)
    fl |= fd32_lanes(q32, n2, o[4])              # eccentricity r^2 / N^2
    fl |= fa32_lanes(s32, rq, ta)
    fl |= fa32_lanes(ta, np.int64(ONE32), q32)   # major^2 (q32 reused)
    fl |= fs32_lanes(s32, rq, ta)
    fl |= fa32_lanes(ta, np.int64(ONE32), s32)   # minor^2 (s32 reused)
    for k in range(K):                           # rounding only: s - r >= 0 exactly
        s32[k] = 0 if fc32_v(s32[k], 0) < 0 else s32[k]
    fl |= sqrt32_lanes(q32, o[5])                # semimajor
    fl |= sqrt32_lanes(s32, o[6])                # semiminor
    fl |= atan2_32_lanes(t32, dm32, th2)
    fl |= fd32_lanes(o[6], o[5], o[7])           # sigma ratio
    fl |= fm32_lanes(th2, np.int64(_DEG_PER_2RAD), ta)   # theta in degrees, [0, 180)
    fl |= fd32_lanes(o[8], o[0], o[9])           # average = total / N
    for k in range(K):
        th = ta[k]
        r, g = fa32_v(th, _C180)
        neg = fc32_v(th, 0) < 0
        o[3, k] = r if neg else th
        fl |= g if neg else 0
        mx = o[10, k]
        br, g = fd32_v(o[9, k], mx)              # brightness ratio = average / max (max > 0)
        pos = fc32_v(mx, 0) > 0
        o[11, k] = br if pos else 0
        fl |= g if pos else 0
    return o, fl


@callee_kernel
def normalise_k(words, area, lin, f, r0, c0):
    """Feature-major words int64 [12, K] -> (normalised copy [12, K], flags): size, total *= area;
    axes *= lin; col = f col + c0; row = f row + r0 (packed 32-bit floats; the blobs side by side in
    the instructions' lane forms).

    ``area``, ``lin``, ``f``, ``r0``, ``c0``: packed 32-bit words ``(f s)**2``, ``f s``,
    ``f``, and the window's full-resolution origin (row, col).

    Cases
    -----
    typical : size and total times ``area``, axes times ``lin``, centroids ``f x + origin``;
        the other features copied.
    identity : ``f = 1``, scale 1, origin (0, 0) -> the same words.
    empty : ``K == 0`` -> an empty [12, 0] copy, flags 0.
    """
    out = words.copy()
    tmp = np.empty(words.shape[1], np.int64)
    flags = fm32_lanes(words[0], area, out[0])
    flags |= fm32_lanes(words[8], area, out[8])
    flags |= fm32_lanes(words[5], lin, out[5])
    flags |= fm32_lanes(words[6], lin, out[6])
    flags |= fm32_lanes(words[1], f, tmp)
    flags |= fa32_lanes(tmp, c0, out[1])
    flags |= fm32_lanes(words[2], f, tmp)
    flags |= fa32_lanes(tmp, r0, out[2])
    return out, flags


# ------------------------------------------------------------------------------------------------
# conversions
# ------------------------------------------------------------------------------------------------
def words_to_struct(words) -> np.ndarray:
    """Packed 32-bit feature words int64 [k, 12] -> structured array (k,) of FEATURE_DTYPE."""
    w = np.asarray(words, np.int64).reshape(-1, N_FEATURES)
    vals = decode32_array(w)
    out = np.empty(len(w), FEATURE_DTYPE)
    for i, name in enumerate(FEATURE_NAMES):
        out[name] = vals[:, i]
    return out


def struct_to_words(feats) -> np.ndarray:
    """Structured feature array -> packed 32-bit words int64 [k, 12] (nearest 1750A value)."""
    from flightsw.arith.m1750 import encode32_array
    f = np.asarray(feats)
    if f.dtype.names is None or any(n not in f.dtype.names for n in FEATURE_NAMES):
        raise ValueError(f"features must be a structured array with fields {FEATURE_NAMES}")
    vals = np.stack([np.asarray(f[n], np.float64) for n in FEATURE_NAMES], axis=-1).reshape(-1, N_FEATURES)
    return encode32_array(vals, rounding="nearest")


# ------------------------------------------------------------------------------------------------
# public API
# ------------------------------------------------------------------------------------------------
def _check_flag(name, v):
    if v not in (True, False, 0, 1):
        raise ValueError(f"{name}={v!r} must be a bool")
    return bool(v)


def features_words(sums, intensity_centroid: bool = True, ledger: Ledger | None = None,
                   stage: str = "features"):
    """The 12 features of every blob from its colouring sums, as packed 1750A 32-bit words.

    Parameters
    ----------
    sums : ndarray [count + 1] of :data:`~flightsw.ip.colour.BLOB_SUMS`
        Per-blob sums (``ColourResult.sums`` or :func:`flightsw.ip.colour.blob_sums`); an int64
        array [count + 1, NSUM] whose columns are :data:`~flightsw.ip.colour.SUM_NAMES` is read
        as those records.
    intensity_centroid : bool
        The uplink intensity flag (True: intensity-weighted centroids and moments).
    ledger : Ledger, optional
        Charged :func:`features_cycles` (without normalisation) on ``"ip1750"``.

    Returns
    -------
    (words int64 [count, 12], flags int)
    """
    s = np.asarray(sums)
    if s.dtype != BLOB_SUMS:
        if s.ndim != 2 or s.shape[1] != NSUM or s.shape[0] < 1 or s.dtype != np.int64:
            raise ValueError(f"sums must be BLOB_SUMS records [count + 1] or an int64 array "
                             f"[count + 1, {NSUM}], got {s.dtype} {s.shape}")
        s = np.ascontiguousarray(s).view(BLOB_SUMS).reshape(-1)
    if s.ndim != 1 or s.shape[0] < 1:
        raise ValueError(f"sums must hold at least one record (record 0 unused), got {s.shape}")
    count = s.shape[0] - 1
    words, flags = _features_kernel(s, count, _check_flag("intensity_centroid", intensity_centroid))
    if ledger is not None:
        ledger.charge(IP1750, stage, features_cycles(count, normalise=False))
    return words, int(flags)


def features(image, labels, count, intensity_centroid: bool = True) -> np.ndarray:
    """The twelve features (before normalisation) of blobs ``1..count`` of ``image``.

    Parameters
    ----------
    image : array_like [H, W], integer 16-bit values (or bool)
        The thresholded/clipped window (intensities used for weights and brightness).
    labels : array_like [H, W] int
        Blob colours 1..count (0 = off), e.g. from :func:`flightsw.ip.label`.
    count : int
        Number of blobs.
    intensity_centroid : bool
        Intensity (True) or geometric (False) centroids and moments.

    Returns
    -------
    ndarray (count,) of :data:`FEATURE_DTYPE`
        Row ``k - 1`` is blob ``k``; fields in the units of the module docstring (window pixels,
        degrees, counts); every value is an exact 1750A 32-bit float.
    """
    sums = blob_sums(image, labels, count)
    words, _ = features_words(sums, intensity_centroid)
    return words_to_struct(words)


@lru_cache(maxsize=256)
def _norm_consts_cached(compaction, imager):
    scale = IMAGER_SCALE.get(imager, 1.0)
    lin = compaction * scale
    return (encode32(lin * lin, rounding="nearest"), encode32(lin, rounding="nearest"),
            encode32(float(compaction), rounding="nearest"))


def norm_consts(compaction, imager):
    """(area, linear, f) normalisation words for compaction f and an imager id."""
    if isinstance(compaction, (bool, np.bool_)) or not isinstance(compaction, (int, np.integer)) \
            or not 1 <= compaction <= 255:
        raise ValueError(f"compaction={compaction!r} must be an int in 1..255")
    if not isinstance(imager, str):
        raise ValueError(f"imager={imager!r} must be an imager id string")
    return _norm_consts_cached(int(compaction), imager)


def normalise_words(words, compaction: int = 1, window_origin=(0, 0), imager: str = "wfov_vis",
                    ledger: Ledger | None = None, stage: str = "features"):
    """Normalise packed feature words to the reference scale and project the centroids to the
    imager's full-resolution frame (module docstring). ``window_origin`` = (row0, col0) of the
    window's top-left corner in full-resolution pixels. Returns (words int64 [k, 12], flags)."""
    w = np.asarray(words, np.int64)
    if w.ndim != 2 or w.shape[1] != N_FEATURES:
        raise ValueError(f"words must be int64 [k, {N_FEATURES}], got {w.shape}")
    try:
        r0, c0 = (float(v) for v in window_origin)
    except (TypeError, ValueError):
        raise ValueError(f"window_origin={window_origin!r} must be (row0, col0)") from None
    if not (math.isfinite(r0) and math.isfinite(c0)):
        raise ValueError(f"window_origin={window_origin!r} must be finite")
    area, lin, f = norm_consts(compaction, imager)
    out, flags = normalise_k(np.ascontiguousarray(w.T), area, lin, f,
                               encode32(r0, rounding="nearest"), encode32(c0, rounding="nearest"))
    out = np.ascontiguousarray(out.T)
    if ledger is not None:
        ledger.charge(IP1750, stage, len(w) * _CYC_NORMALISE)
    return out, int(flags)


def normalise(feats, compaction: int = 1, window_origin=(0, 0), imager: str = "wfov_vis") -> np.ndarray:
    """:func:`normalise_words` on a structured feature array -> structured array."""
    out, _ = normalise_words(struct_to_words(feats), compaction, window_origin, imager)
    return words_to_struct(out)
