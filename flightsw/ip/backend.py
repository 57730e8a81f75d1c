"""The image processor's back end, IP steps 6-8 on the 1750A: blob colouring, the twelve features
and their normalisation, and the ranking against the a priori record, as one compiled stage.

:func:`backend_k` runs the stage kernels of :mod:`flightsw.ip.colour`, :mod:`flightsw.ip.features`
and :mod:`flightsw.ip.rank` in order on a thresholded window and packs everything the host reads into
one int64 array (one array to box). The frame pipeline (:mod:`flightsw.ip.pipeline`) calls it after
the front end; :func:`backend` is its surface for a window the caller already has.
"""
from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from flightsw.arith.m1750 import decode32_array, encode32
from flightsw.arith.m1750_float import decode32_k
from flightsw.budget import IP1750, Ledger
from flightsw.ip.colour import DIRECT_DTYPES, as_int_image, colour_k
from flightsw.ip.colour import OP_CYCLES as COLOUR_OP_CYCLES
from flightsw.ip.features import features_cycles, features_k, norm_consts, normalise_k, \
    words_to_struct
from flightsw.ip.frame_header import header_of, new_header
from flightsw.ip.rank import OP_CYCLES as RANK_OP_CYCLES
from flightsw.ip.rank import rank_k, record_words
from flightsw.messages import CANDIDATE_DTYPE, MAX_CANDIDATES
from flightsw.numba_cache import callee_kernel

__all__ = ["backend", "backend_k", "backend_params", "BackendResult", "enc32", "BACK_KEYS",
           "PACK_HEAD", "candidate_table", "BACKEND_PARAMS", "with_labels", "result_from_head"]

BLOB_CYCLES = features_cycles(1)
#: words of the pack before its tables (none since the back end's counts went to the frame
#: header, :data:`flightsw.ip.frame_header.FRAME_HEADER`)
PACK_HEAD = 0
#: the ledger keys of the back end's three stages, in charge order
BACK_KEYS = ((IP1750, "colour"), (IP1750, "features"), (IP1750, "rank"))

#: The back end's parameters: one record (:func:`backend_params`) :func:`backend_k` reads by field.
BACKEND_PARAMS = np.dtype([
    ("diagonal", np.int64),       # 1: 8-connected colouring (the uplink's diagonal flag)
    ("intensity", np.int64),      # 1: intensity-weighted centroids
    ("want_labels", np.int64),    # 1: form the final label image (a ground product)
    ("area", np.int64),           # area normalisation word (1750A 32-bit float, packed):
                                  #    (compaction, imager) scale, :func:`norm_consts`
    ("lin", np.int64),            # linear (length) normalisation word, 1750A 32-bit float
    ("fw", np.int64),             # the compaction f as a 1750A 32-bit float word
    ("quantize", np.int64),       # 1: the record's sigmoid quantisation of the features
    ("gof_threshold", np.int64),  # the record's GOF threshold, 1750A 32-bit float word
    ("max_out", np.int64),        # the candidate limit (1..1000)
    ("record", np.int64, (5, 12)),  # the record's words (:func:`record_words`): rows mean,
                                    #    sigma, weight, lower, upper; 1750A 32-bit float words
])


@lru_cache(maxsize=4096)
def enc32(x: float) -> int:
    """float -> nearest 1750A 32-bit word (cached: window origins and centres repeat frame to
    frame)."""
    return encode32(float(x), rounding="nearest")


@callee_kernel
def backend_k(img, params, header):
    """Steps 6-8 on a thresholded window.

    Parameters
    ----------
    img : int [H, W] (16-bit words; non-zero = on)
    params : :data:`BACKEND_PARAMS` [1] (:func:`backend_params`)
    header : :data:`flightsw.ip.frame_header.FRAME_HEADER` [1]: reads the window origin words
        ``r0w``, ``c0w`` and the centroid means ``mean_row``, ``mean_col`` (used if
        ``override``); writes ``count``, ``m``, ``flags``, the three cycle totals and ``bad``

    Returns
    -------
    (labels int32 [H, W] (empty [0, 0] without want_labels), pack int64): ``pack`` holds order
    [m], gof [m], the reported distances [m], every distance [count], the feature words
    [count, 12] and the candidate table [m, 15] (CANDIDATE_DTYPE layout, decoded exactly).

    Cases
    -----
    typical : the stage kernels in order (colour, features, normalise, rank): the same order, words
        and candidate table as the single-stage functions composed with the same flags and record.
    flags : ``diagonal`` off and ``intensity`` off reach the colouring and the features.
    override : ``override != 0`` -> the centroid means are ``mean_row``, ``mean_col``.
    no-override : ``override == 0`` -> the record's centroid means.
    max-out : at most ``max_out`` candidates (``m <= max_out``).
    candidate-table : row q = (order[q] + 1, d, GOF, the twelve features) decoded exactly.
    cycles : ``cyc_colour``, ``cyc_features``, ``cyc_rank`` = the cycles of the event counts.
    no-labels : ``want_labels`` off -> labels an empty [0, 0] array, the same pack.
    no-blobs : an empty window -> count 0, m 0, an empty pack.
    out-of-range : a word outside -32768..65535 -> ``bad`` set (the callers raise).
    """
    p = params[0]
    hd = header[0]
    labels, count, sums, cops, bad = colour_k(img, p.diagonal != 0, p.want_labels != 0)
    if count:
        raw, f1 = features_k(sums, count, p.intensity != 0)      # feature-major [12, count]
        words, f2 = normalise_k(raw, p.area, p.lin, p.fw, hd.r0w, hd.c0w)
    else:        # no blobs: no feature words and no flags (the two stages' ~70 empty lane calls)
        words, f1, f2 = np.zeros((12, 0), np.int64), 0, 0
    order, d, gof, f3, rops = rank_k(words, p.record, hd.mean_row, hd.mean_col,
                                     hd.override != 0, p.quantize != 0, p.gof_threshold,
                                     p.max_out)
    m = order.size
    hd.count = count
    hd.m = m
    hd.flags = f1 | f2 | f3
    hd.cyc_colour = 0
    for i in range(cops.size):
        hd.cyc_colour += COLOUR_OP_CYCLES[i] * cops[i]
    hd.cyc_features = count * BLOB_CYCLES
    hd.cyc_rank = 0
    for i in range(rops.size):
        hd.cyc_rank += RANK_OP_CYCLES[i] * rops[i]
    hd.bad = 1 if bad else 0
    o_words = 3 * m + count
    o_cand = o_words + 12 * count
    pack = np.empty(o_cand + 15 * m, np.int64)
    pack[:m] = order
    pack[m:2 * m] = gof
    for q in range(m):
        pack[2 * m + q] = d[order[q]]
    pack[3 * m:o_words] = d
    fwp = pack[o_words:o_cand]                                    # blob-major [count, 12]
    for i in range(12):
        fwp[i::12] = words[i]
    cand = pack[o_cand:]
    fc = cand.view(np.float64)
    for q in range(m):
        k = order[q]
        b = 15 * q
        cand[b] = k + 1
        fc[b + 1] = decode32_k(d[k])
        fc[b + 2] = decode32_k(gof[q])
        for i in range(12):
            fc[b + 3 + i] = decode32_k(words[i, k])
    return labels, pack


class BackendResult:
    """What the back end produced for one window.

    Attributes
    ----------
    labels : ndarray [H, W] int32
        Blob colours 1..count (an empty [0, 0] array if labels were not requested).
    count : int
        Number of blobs.
    feature_words : ndarray [count, 12] int64
        Normalised features of every blob (packed 1750A 32-bit words).
    order : ndarray [m] int64
        Reported candidates (0-based blob indices), best first.
    gof_words, distance_words : ndarray [m] int64
        GOF and distance of each reported candidate (packed words).
    all_distance_words : ndarray [count] int64
        The distance of every blob.
    flags : int
        1750A exception flags of the back end.
    cycles : dict
        1750A cycles of the colour, features and rank stages.
    """

    __slots__ = ("labels", "pack", "count", "m", "flags", "cycles_tuple")

    def __init__(self, labels, pack, count, m, flags, cycles):
        self.labels, self.pack, self.count, self.m = labels, pack, count, m
        self.flags, self.cycles_tuple = flags, cycles

    @property
    def cycles(self) -> dict:
        return dict(zip(("colour", "features", "rank"), self.cycles_tuple))

    @property
    def order(self):
        return self.pack[:self.m]

    @property
    def gof_words(self):
        return self.pack[self.m:2 * self.m]

    @property
    def distance_words(self):
        return self.pack[2 * self.m:3 * self.m]

    @property
    def all_distance_words(self):
        o = 3 * self.m
        return self.pack[o:o + self.count]

    @property
    def feature_words(self):
        o = 3 * self.m + self.count
        return self.pack[o:o + 12 * self.count].reshape(self.count, 12)

    @property
    def features(self) -> np.ndarray:
        """Normalised features, FEATURE_DTYPE [count] (decoded exactly)."""
        return words_to_struct(self.feature_words)

    def candidates(self) -> np.ndarray:
        """The reported candidates, CANDIDATE_DTYPE [m] (decoded exactly), best first."""
        return candidate_table(self.pack, self.count, self.m)

    def decoded_distances(self) -> np.ndarray:
        """Every blob's distance, float64 [count] (decoded exactly)."""
        return decode32_array(self.all_distance_words)


def candidate_table(pack, count: int, m: int) -> np.ndarray:
    """The candidate table of a :func:`backend_k` pack with ``count`` blobs and ``m`` reported
    candidates: CANDIDATE_DTYPE [m], a view of the pack (decoded exactly), best first."""
    # ``np.ndarray`` on the buffer: 0.2 us, a sliced .view 0.65
    return np.ndarray((m,), CANDIDATE_DTYPE, pack, 8 * (3 * m + 13 * count))


def backend_params(record, diagonal: bool, intensity: bool, want_labels: bool, compaction: int,
                   imager: str, max_candidates: int) -> np.ndarray:
    """The back end's parameters, :data:`BACKEND_PARAMS` [1] (:func:`backend_k`'s ``params``): the
    flags, the normalisation words of (compaction, imager), the record's quantisation flag, GOF
    threshold word and words, and the candidate limit (1..1000; ValueError otherwise)."""
    area, lin, fw = norm_consts(compaction, imager)
    if isinstance(max_candidates, bool) or not isinstance(max_candidates, (int, np.integer)) \
            or not 1 <= max_candidates <= 1000:
        raise ValueError(f"max_candidates={max_candidates!r} must be an int in 1..1000")
    params = np.zeros(1, BACKEND_PARAMS)
    p = params[0]
    p["diagonal"], p["intensity"], p["want_labels"] = diagonal, intensity, want_labels
    p["area"], p["lin"], p["fw"] = area, lin, fw
    p["quantize"], p["gof_threshold"] = record.quantize, enc32(record.gof_threshold)
    p["max_out"], p["record"] = int(max_candidates), record_words(record)
    return params


def with_labels(params: np.ndarray, want_labels: bool) -> np.ndarray:
    """A copy of the :data:`BACKEND_PARAMS` ``params`` with ``want_labels`` set."""
    out = params.copy()
    out[0]["want_labels"] = bool(want_labels)
    return out


def result_from_head(labels, pack, header, ledger=None) -> BackendResult:
    """BackendResult of a kernel's (labels, pack) and the frame header it wrote
    (:data:`flightsw.ip.frame_header.FRAME_HEADER` [1]), with the 16-bit range check and the back
    end's cycles charged to ``ledger``."""
    hd = header_of(header.view(np.int64))
    if hd.bad:
        raise ValueError("window holds values outside the 16-bit word range -32768..65535")
    cycles = (hd.cyc_colour, hd.cyc_features, hd.cyc_rank)
    if ledger is not None:
        ledger.charge_many(k + (c,) for k, c in zip(BACK_KEYS, cycles))
    return BackendResult(labels, pack, hd.count, hd.m, hd.flags, cycles)


def _window_array(window):
    if isinstance(window, np.ndarray) and window.ndim == 2 and window.size \
            and window.dtype.type in DIRECT_DTYPES and window.flags.c_contiguous:
        return window                                  # the kernel checks the 16-bit range
    return as_int_image(window, "window")


def _mean_words(centroid_mean):
    if centroid_mean is None:
        return 0, 0, 0
    try:
        r, c = centroid_mean
        if not (math.isfinite(r) and math.isfinite(c)):
            raise ValueError
        return 1, enc32(float(r)), enc32(float(c))
    except (TypeError, ValueError):
        raise ValueError(f"centroid_mean={centroid_mean!r} must be finite (row, col) or None") \
            from None


def backend(window, record, *, diagonal: bool = True, intensity_centroid: bool = True,
            compaction: int = 1, window_origin=(0, 0), imager: str = "wfov_vis",
            centroid_mean=None, ledger: Ledger | None = None, want_labels: bool = True,
            max_candidates: int = MAX_CANDIDATES) -> BackendResult:
    """IP steps 6-8 on a thresholded (binary or clipped) window.

    A public convenience whose keyword-only options are the reason for its nine more
    parameters (each is one of the uplink's flags or the window's geometry; the compiled stage
    :func:`backend_k` takes them as two records).

    Parameters
    ----------
    window : array_like [H, W] integer (16-bit values)
        The thresholded window; non-zero = on, values are the intensities.
    record : flightsw.records.Record
    diagonal, intensity_centroid : bool
        The uplink flags of the colouring and feature steps.
    compaction : int
        Compaction factor f of the window.
    window_origin : (row0, col0)
        Window top-left corner in full-resolution imager pixels (compacted origin * f).
    imager : str
        Imager id (pixel scale for the normalisation).
    centroid_mean : (row, col) or None
        The record's centroid means this frame (TP prediction or window centre, full-res pixels);
        None keeps the record's values.
    ledger : Ledger, optional
        Charged stages "colour", "features", "rank" on "ip1750".
    want_labels : bool
        Produce the final label image (a ground product: the flight keeps only the colour array).
    """
    from flightsw.records import Record
    if not isinstance(record, Record):
        raise ValueError(f"record must be a flightsw.records.Record, got {type(record).__name__}")
    for name, v in (("diagonal", diagonal), ("intensity_centroid", intensity_centroid),
                    ("want_labels", want_labels)):
        if v is not True and v is not False and v not in (0, 1):
            raise ValueError(f"{name}={v!r} must be a bool")
    img = _window_array(window)
    try:
        r0, c0 = window_origin
        r0w, c0w = enc32(float(r0)), enc32(float(c0))
    except (TypeError, ValueError):
        raise ValueError(f"window_origin={window_origin!r} must be (row0, col0) numbers") from None
    header, _ = new_header()
    h = header[0]
    h["override"], h["mean_row"], h["mean_col"] = _mean_words(centroid_mean)
    h["r0w"], h["c0w"] = r0w, c0w
    params = backend_params(record, bool(diagonal), bool(intensity_centroid), bool(want_labels),
                         compaction, imager, max_candidates)
    labels, pack = backend_k(img, params, header)
    return result_from_head(labels, pack, header, ledger)
