"""The image processor's one compiled pipeline: a frame in, the candidate message out.

The MSX paper's Image Processing section in order: the preprocessor board compacts the frame and
cuts the window about the TP's prediction (step 1); the DSP runs the uplinked sequence's front-end
steps (spatial or frequency filters, detrenders, the threshold; steps 2-5); the 1750A colours the
blobs, computes and normalises the features and ranks them against the a priori record (steps 6-8).
:func:`ip_frame_k` runs all of it in one jitted call. The stage images of the paper's Figure 3
(the window, every front-end step's output, the colour and rank images) are an output option of the
same call (``want_stages``), not a second implementation.

A :class:`FramePlan` holds what does not change from frame to frame for one (sequence, record,
imager): the front-end steps as arrays, the back end's parameter words, the record's words, the
ledger keys and the static cycles. The :class:`flightsw.ip.ImageProcessor` owns its plan and builds
a new one when an uplink changes the sequence or the record; :func:`plan_for` keeps a few plans for
the one-frame conveniences (:func:`flightsw.ip.process_frame`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from flightsw.budget import IP1750, Ledger
from flightsw.ip import detrend as dt
from flightsw.ip import fftfilter as fft
from flightsw.ip import filters as flt
from flightsw.ip import threshold as th
from flightsw.ip.backend import (BACK_KEYS, BackendResult, backend_k, backend_params,
                                 candidate_table, enc32)
from flightsw.ip.preprocess import Subimage, compact_k, window_origin
from flightsw.ip.rank import record_words
from flightsw.ip.sequence import (PHASE_LABEL, STEP_REGISTRY, ColourParams, DetrendParams,
                                  FeatureParams, FilterFFTParams, FilterParams, ProcessingSequence,
                                  RankParams, Stage, ThresholdParams)
from flightsw.messages import IMAGER_CODES, CandidateMessage

__all__ = ["FramePlan", "FrameResult", "FrontOps", "FFTTables", "PolyTables", "ip_frame_k",
           "ip_frame_into_k", "plan_for", "step_words", "OP_FILTER", "OP_HIGHPASS", "OP_NONE",
           "OP_THRESHOLD", "OP_FFT", "OP_POLY"]

#: front-end op codes (:attr:`FrontOps.ops`)
OP_FILTER, OP_HIGHPASS, OP_NONE, OP_THRESHOLD, OP_FFT, OP_POLY = 1, 2, 3, 4, 5, 6
MAX_SPATIAL = 7                 # the spatial filter's largest kernel (7x7)
MAX_TILE = max(fft.FFT_TILES)   # the largest FFT tile


class FrontOps(NamedTuple):
    """The sequence's front-end steps as arrays (n steps, in order)."""

    ops: np.ndarray     #: int64 [n], OP_* code of each step
    kern: np.ndarray    #: int16 [n, 7, 7], spatial kernels, Q1.15 (top-left size x size)
    size: np.ndarray    #: int64 [n], spatial kernel size (0 for other steps)
    taps: np.ndarray    #: int16 [n, 7], the high-pass detrender's low-pass taps, Q1.15
    fft: np.ndarray     #: int64 [n], the step's row of :class:`FFTTables` (-1: not an FFT step)


class FFTTables(NamedTuple):
    """The frequency filters of a sequence (m of them; see :mod:`flightsw.ip.fftfilter`)."""

    ints: np.ndarray    #: int64 [m, 4]: tile T, kernel size k, spectrum exponent ek, sum of taps
    floats: np.ndarray  #: float64 [m, 4]: kmax, k2mean, dk, dw (the ground's error model)
    kr: np.ndarray      #: int64 [m, T*T]: spectrum words, real, transposed and flattened
    ki: np.ndarray      #: int64 [m, T*T]: imaginary
    brev: np.ndarray    #: int64 [m, 64]: bit reversal of T
    twc: np.ndarray     #: int64 [m, 32]: cosine twiddles, Q1.15
    tws: np.ndarray     #: int64 [m, 32]: sine twiddles, Q1.15


class PolyTables(NamedTuple):
    """The polynomial detrender's ground constants for the window shape (h, w)."""

    tables: np.ndarray  #: int16 [6, h, w] scaled basis tables
    js: np.ndarray      #: int64 [6] table shifts
    rs: np.ndarray      #: int64 [6] reciprocals
    ps: np.ndarray      #: int64 [6] their exponents


@njit(cache=True)
def front_step_k(img, i, front, ffts, poly, aq, mode):
    """Front-end step ``i`` of ``front`` on the int16 [h, w] image ``img``. Returns (image int16
    [h, w], is_threshold, t4, mean4, std4, shift): the threshold's words (Q.4 and the block
    shift) when the step is the threshold, else zeros.

    ``front``: :class:`FrontOps`; ``ffts``: :class:`FFTTables`; ``poly``: :class:`PolyTables`;
    ``aq``: alpha, Q4.12 word; ``mode``: ``threshold.BINARIZE`` or ``CLIP``.

    Cases
    -----
    filter : ``OP_FILTER`` -> :func:`flightsw.ip.filters.correlate_q15_k` with the step's k x k
        kernel.
    highpass : ``OP_HIGHPASS`` -> :func:`flightsw.ip.detrend.highpass_k` with the step's taps.
    threshold : ``OP_THRESHOLD`` -> :func:`flightsw.ip.threshold.threshold_k` and its words
        (t4, mean4, std4, shift), ``is_threshold`` true.
    fft : ``OP_FFT`` -> :func:`flightsw.ip.fftfilter.fft_correlate_k` with the step's tables
        (DC removal on).
    poly : ``OP_POLY`` -> :func:`flightsw.ip.detrend.polynomial_k` with the window's tables.
    none : ``OP_NONE`` -> the image unchanged.
    not-threshold : any other op -> the threshold words 0 and ``is_threshold`` false.
    """
    op = front.ops[i]
    t4, m4, d4, sh = np.int64(0), np.int64(0), np.int64(0), np.int64(0)
    if op == OP_FILTER:
        k = front.size[i]
        out = flt.correlate_q15_k(img, np.ascontiguousarray(front.kern[i, :k, :k]))
    elif op == OP_HIGHPASS:
        out = dt.highpass_k(img, front.taps[i], dt.G_MAX)
    elif op == OP_THRESHOLD:
        out, t4, m4, d4, s = th.threshold_k(img, aq, mode)
        sh = np.int64(s)
    elif op == OP_FFT:
        if ffts is None:                    # a plan without FFT steps: this branch is not compiled
            out = img
        else:
            j = front.fft[i]
            T, kk, ek, ksum = ffts.ints[j, 0], ffts.ints[j, 1], ffts.ints[j, 2], ffts.ints[j, 3]
            kr = np.ascontiguousarray(ffts.kr[j, :T * T]).reshape((T, T))
            ki = np.ascontiguousarray(ffts.ki[j, :T * T]).reshape((T, T))
            out = fft.fft_correlate_k(img, T, kk, kr, ki, ek, ffts.floats[j, 0],
                                      ffts.floats[j, 1], ffts.floats[j, 2], ksum,
                                      np.ascontiguousarray(ffts.brev[j, :T]),
                                      np.ascontiguousarray(ffts.twc[j, :T // 2]),
                                      np.ascontiguousarray(ffts.tws[j, :T // 2]),
                                      ffts.floats[j, 3], True)[0]
    elif op == OP_POLY:
        if poly is None:                    # a plan without the polynomial detrender: not compiled
            out = img
        else:
            out = dt.polynomial_k(img, poly.tables, poly.js, poly.rs, poly.ps)[0]
    else:                                                  # OP_NONE
        out = img
    return out, op == OP_THRESHOLD, t4, m4, d4, sh


@njit(cache=True)
def ip_frame_k(src, f, r0, c0, h, w, front, ffts, poly, aq, mode, rec, prm, r0w, c0w, mean_row,
               mean_col, want_stages):
    """One frame through the image processor (:func:`ip_frame_into_k` with the stage arrays made
    here).

    Parameters
    ----------
    src : integer [H, W]
        The frame (12-bit counts; ``f``, ``r0``, ``c0``, ``h``, ``w`` cut the window: compaction
        factor and window origin and shape in compacted pixels), or a window the caller cut
        (``f = 1``, origin 0).
    front, ffts, poly : FrontOps, FFTTables or None, PolyTables or None
        None when the sequence has no such step: numba then prunes (does not compile) the FFT or
        polynomial branch, which keeps a first run's compilation to the kernels the sequence uses
    aq, mode : the threshold's alpha (Q4.12 word) and mode (``threshold.BINARIZE``/``CLIP``)
    rec, prm, r0w, c0w, mean_row, mean_col : the back end's words (:func:`backend_k`; the centroid
        means are always given: the TP's prediction or the window centre)
    want_stages : bool
        Also fill the stage images.

    Returns
    -------
    (window int16 [h, w], pack (:func:`backend_k`), front stages int16 [n + 1, h, w] (the window
    and each step's output; [0, h, w] without want_stages), back stages int32 [2, h, w] (labels,
    blobs numbered by rank; [0, h, w] without), count, m, flags, colour, features and rank cycles,
    the range flag, the threshold's t4, mean4, std4 and shift): a flat tuple, which boxes faster
    than a header slice.

    Cases
    -----
    stages : ``want_stages`` -> the window and each front-end step's output are the stage kernels
        composed in the sequence's order; the colour image is the labels.
    no-stages : ``want_stages`` off -> empty [0, h, w] stage arrays, the same pack and words.
    threshold-words : a threshold step -> its t4, mean4, std4 and shift.
    no-threshold : no threshold step -> those words 0.
    no-steps : an empty front end -> the window goes to the back end as it is.
    rank-image : the rank stage numbers each reported blob's pixels by its rank (1 = best), 0
        elsewhere.
    caller-window : a window the caller cut (``f = 1``, origin 0) -> the window stage is that
        window, the rest as for a frame.
    no-blobs : nothing passes the threshold -> count 0, m 0, rank image all 0.
    """
    n = front.ops.size
    fst = np.empty((n + 1 if want_stages else 0, h, w), np.int16)
    bst = np.empty((2 if want_stages else 0, h, w), np.int32)
    return ip_frame_into_k(src, f, r0, c0, h, w, front, ffts, poly, aq, mode, rec, prm, r0w, c0w,
                           mean_row, mean_col, fst, bst)


@njit(cache=True)
def ip_frame_into_k(src, f, r0, c0, h, w, front, ffts, poly, aq, mode, rec, prm, r0w, c0w,
                    mean_row, mean_col, fst, bst):
    """:func:`ip_frame_k` with the stage images written into the caller's ``fst`` int16
    [n + 1, h, w] and ``bst`` int32 [2, h, w] (n front-end steps), or none with both empty
    ([0, h, w]: ``want_stages`` off); returns the same tuple, ``fst`` and ``bst`` in it.
    :func:`flightsw.ip.step.ip_step_k` passes arrays it was given (no stage arrays to box on
    return).

    Cases
    -----
    into : given stage arrays -> filled with :func:`ip_frame_k`'s stage images, the same pack.
    empty : empty stage arrays -> nothing written, the same pack.
    """
    want_stages = fst.shape[0] != 0
    win = compact_k(src, f, r0, c0, h, w)
    n = front.ops.size
    img = win
    if want_stages:
        fst[0] = win
    t4, m4, d4, sh = np.int64(0), np.int64(0), np.int64(0), np.int64(0)
    for i in range(n):
        img, is_thr, a, b, c, d = front_step_k(img, i, front, ffts, poly, aq, mode)
        if is_thr:
            t4, m4, d4, sh = a, b, c, d
        if want_stages:
            fst[i + 1] = img
    labels, pack = backend_k(img, rec, prm, r0w, c0w, mean_row, mean_col, np.int64(1))
    if want_stages:
        bst[0] = labels
        lut = np.zeros(pack[0] + 1, np.int32)
        for q in range(pack[1]):
            lut[pack[22 + q] + 1] = q + 1                       # pack[22:]: order (PACK_HEAD)
        for r in range(h):
            for c in range(w):
                bst[1, r, c] = lut[labels[r, c]]
    return (win, pack, fst, bst, pack[0], pack[1], pack[2], pack[3], pack[4], pack[5], pack[21],
            t4, m4, d4, sh)


# ================================================================================================
# the plan
# ================================================================================================
class FrameResult:
    """What one frame through the IP produced.

    Attributes
    ----------
    message : CandidateMessage
    stages : list of flightsw.ip.sequence.Stage
        ``window``, every front-end step's output, then ``colour`` (label image), ``rank`` (blobs
        numbered by rank, 1 = best): the panels of the paper's Figure 3 (empty unless asked for).
    ledger : Ledger
    backend : BackendResult
    blob_count : int
        The back end's blob count (``backend.count``, without building the back end's result).
    subimage : flightsw.ip.preprocess.Subimage
    context : dict
        ``imager``, ``record``, ``subimage``, ``preprocess`` and, with a threshold step,
        ``threshold`` (its words t4, mean4, std4 (Q.4), shift, alpha_q12 and mode).

    Made by :meth:`FramePlan.result` from the compiled call's outputs; each attribute is built when
    first read (a caller of :meth:`flightsw.ip.ImageProcessor.step` reading only the words saves
    ~2.5 us a frame; the closed loop reads the message and the blob count, and saves the back end,
    context, subimage and stages). A caller's ledger is charged at once; the ledger made when
    none was given is made and charged when first read.
    """

    __slots__ = ("_plan", "_raw", "_ledger", "_message", "_stages", "_backend", "_subimage",
                 "_context")

    def __init__(self, plan: "FramePlan", raw: tuple, ledger: Ledger | None):
        #: raw: (pack, fst, bst, (window image, origin, factor, size), full-res origin, aq,
        #: threshold words, front cycles, frame count, time tag, alpha cycles or None, the pack's
        #: words 0-5 as ints)
        self._plan, self._raw = plan, raw
        self._message = self._stages = self._backend = self._subimage = self._context = None
        self._ledger = ledger
        if ledger is not None:
            plan._charge(ledger, raw)

    def __iter__(self):                         # message, stages, ledger = process_frame(...)
        return iter((self.message, self.stages, self.ledger))

    @property
    def ledger(self) -> Ledger:
        if self._ledger is None:
            self._ledger = Ledger()
            self._plan._charge(self._ledger, self._raw)
        return self._ledger

    @property
    def backend(self) -> BackendResult:
        be = self._backend
        if be is None:
            pack, bst = self._raw[0], self._raw[2]
            count, m, flags, c, fe, rk = self._raw[11]
            labels = bst[0] if bst.shape[0] else _NO_LABELS
            be = self._backend = BackendResult(labels, pack, count, m, flags, (c, fe, rk))
        return be

    @property
    def blob_count(self) -> int:
        return self._raw[11][0]

    @property
    def subimage(self) -> Subimage:
        if self._subimage is None:
            self._subimage = Subimage(*self._raw[3])
        return self._subimage

    @property
    def message(self) -> CandidateMessage:
        if self._message is None:
            self._message = self._plan._message(self._raw)
        return self._message

    @property
    def stages(self) -> list:
        if self._stages is None:
            fst, bst, thr = self._raw[1], self._raw[2], self._raw[6]
            self._stages = self._plan._stages(fst, bst, self.backend, thr[0]) if fst.shape[0] \
                else []
        return self._stages

    @property
    def context(self) -> dict:
        if self._context is None:
            self._context = self._plan._context(self._raw, self.subimage)
        return self._context


def backend_steps(sequence: ProcessingSequence):
    """(ColourParams, FeatureParams, RankParams) of a sequence's back-end steps (defaults for the
    absent ones); ValueError for a step the pipeline has no place for."""
    colour_p, feat_p, rank_p = ColourParams(), FeatureParams(), RankParams()
    for st in sequence.steps:
        if st.op in ("colour", "label"):
            colour_p = st.params
        elif st.op == "features":
            feat_p = st.params
        elif st.op == "rank":
            rank_p = st.params
        elif STEP_REGISTRY[st.op].phase >= PHASE_LABEL:
            raise ValueError(f"step {st.op!r} is not a front-end or back-end step")
    return colour_p, feat_p, rank_p


def _fft_tables(kernels):
    m = len(kernels)
    ints = np.zeros((m, 4), np.int64)
    floats = np.zeros((m, 4), np.float64)
    kr = np.zeros((m, MAX_TILE * MAX_TILE), np.int64)
    ki = np.zeros_like(kr)
    brev = np.zeros((m, MAX_TILE), np.int64)
    twc = np.zeros((m, MAX_TILE // 2), np.int64)
    tws = np.zeros_like(twc)
    for j, kern in enumerate(kernels):
        T = kern.tile
        c, s, dw = fft.twiddles_q15(T)
        ints[j] = (T, kern.size, kern.ek, kern.ksum)
        floats[j] = (kern.kmax, kern.k2mean, kern.dk, dw)
        kr[j, :T * T] = kern.kr.ravel()
        ki[j, :T * T] = kern.ki.ravel()
        brev[j, :T] = fft.bitrev(T)
        twc[j, :T // 2] = c
        tws[j, :T // 2] = s
    return FFTTables(ints, floats, kr, ki, brev, twc, tws)


def poly_tables(h: int, w: int, used: bool = True) -> PolyTables | None:
    """:class:`PolyTables` for an h x w window (None when no step uses them)."""
    if not used:
        return None
    tables, js, _, rs, ps = dt.polynomial_basis(h, w)
    return PolyTables(tables, js, rs, ps)


def _front(sequence: ProcessingSequence):
    """(FrontOps, the FFT kernels, stage names, a step cost function per step, threshold params)."""
    ops, kern, size, taps, fslot, kernels, names, costs = [], [], [], [], [], [], [], []
    thr = None
    for st in sequence.steps:
        if STEP_REGISTRY[st.op].phase >= PHASE_LABEL:
            continue
        p = st.params
        k = np.zeros((MAX_SPATIAL, MAX_SPATIAL), np.int16)
        t = np.zeros(7, np.int16)
        n, slot = 0, -1
        if isinstance(p, FilterParams):
            op, n = OP_FILTER, p.kernel.shape[0]
            k[:n, :n] = p.kernel
            cost = (lambda h, w, n=n: flt.filter_cycles(h, w, n))
        elif isinstance(p, FilterFFTParams):
            op, slot = OP_FFT, len(kernels)
            kernels.append(p.kernel)
            cost = (lambda h, w, q=p.kernel: fft.fft_filter_cycles(h, w, q.size, q.tile))
        elif isinstance(p, DetrendParams) and p.method == "highpass":
            op, t = OP_HIGHPASS, np.asarray(p.taps, np.int16)
            cost = dt.highpass_cycles
        elif isinstance(p, DetrendParams) and p.method == "polynomial":
            op, cost = OP_POLY, dt.polynomial_cycles
        elif isinstance(p, DetrendParams):
            op, cost = OP_NONE, (lambda h, w: 0)
        elif isinstance(p, ThresholdParams):
            op, cost, thr = OP_THRESHOLD, th.threshold_cycles, (st.stage, p)
        else:
            raise ValueError(f"step {st.op!r}: no front-end kernel for {type(p).__name__}")
        ops.append(op)
        kern.append(k)
        size.append(n)
        taps.append(t)
        fslot.append(slot)
        names.append(st.stage)
        costs.append(cost)
    m = len(ops)
    front = FrontOps(np.array(ops, np.int64),
                     np.stack(kern) if m else np.zeros((0, MAX_SPATIAL, MAX_SPATIAL), np.int16),
                     np.array(size, np.int64),
                     np.stack(taps) if m else np.zeros((0, 7), np.int16),
                     np.array(fslot, np.int64))
    return front, kernels, names, costs, thr


def step_words(geo, front: FrontOps, recw) -> tuple:
    """The fixed arrays of a plan packed for :func:`flightsw.ip.step.ip_step_k`: (int64 [8 + 3 n +
    60]: ``geo`` [8], then the front end's ``ops``, ``size`` and ``fft`` [n] each, then the
    record's words [5, 12] row by row; int16 [56 n]: the kernels [n, 7, 7] then the taps [n, 7])
    for a front end of n steps."""
    ints = np.concatenate([np.asarray(geo, np.int64), front.ops, front.size, front.fft,
                           np.asarray(recw, np.int64).ravel()]).astype(np.int64)
    i16 = np.concatenate([front.kern.ravel(), front.taps.ravel()]).astype(np.int16)
    return ints, i16


def _geometry_words(f, r0, c0, h, w, pred):
    """(origin row, origin col (full-resolution pixels), then the 1750A words of the origin and of
    the centroid means: the prediction ``pred``, or the window centre if None)."""
    o0, o1 = r0 * f, c0 * f
    if pred is None:
        pred = (o0 + h * f / 2.0, o1 + w * f / 2.0)
    return o0, o1, enc32(o0), enc32(o1), enc32(pred[0]), enc32(pred[1])


class FramePlan:
    """The pipeline's fixed inputs for one (sequence, record, imager), built once.

    Parameters
    ----------
    sequence : ProcessingSequence
        The sequence in force (its back-end steps set the colouring and feature flags and may name
        their own record).
    record : flightsw.records.Record
        The a priori record in force.
    imager : str
        The imager id (pixel scale of the normalisation; message header).
    """

    def __init__(self, sequence: ProcessingSequence, record, imager: str = "wfov_vis"):
        colour_p, feat_p, rank_p = backend_steps(sequence)
        rec = rank_p.record if rank_p.record is not None else record
        pre = sequence.preprocess
        self.sequence, self.record, self.imager, self.rank_record = sequence, record, imager, rec
        self.f, self.pre = pre.compaction, pre
        self.front, kernels, self.step_names, self.costs, thr = _front(sequence)
        self.ffts = _fft_tables(kernels) if kernels else None
        self.uses_poly = bool((self.front.ops == OP_POLY).any())
        h, w = pre.window_shape
        self.poly = poly_tables(h, w, self.uses_poly)
        self.threshold_stage, tp = thr if thr is not None else (None, None)
        self.aq = tp.alpha_q12 if tp is not None else 0
        self.mode_name = tp.mode if tp is not None else "binarize"
        self.mode = th.BINARIZE if self.mode_name == "binarize" else th.CLIP
        self.flags = (colour_p.diagonal, feat_p.intensity_centroid)
        self.max_candidates = rank_p.max_candidates
        self.recw = record_words(rec)
        self.prm = {want: backend_params(rec, *self.flags, want, self.f, imager,
                                         self.max_candidates) for want in (False, True)}
        self.keys = (("dsp", "compaction"),) + tuple(("dsp", n) for n in self.step_names) \
            + BACK_KEYS
        self.front_cycles = self.cycles_for(h, w)
        r0, c0 = window_origin(pre.compacted_shape, self.f, None, pre.window)
        self.default = (h, w, r0, c0) + _geometry_words(self.f, r0, c0, h, w, None)
        self.msg_imager = imager if imager in IMAGER_CODES else "real"
        self.record_id = rec.record_id
        self.step_keys = self.keys + ((IP1750, "alpha_logic"),)
        self.window_hw = (h, w)
        self.frame_shape = pre.frame_shape
        H, W = pre.compacted_shape
        #: what :func:`flightsw.ip.step.ip_step_k` needs of the plan besides the pipeline's arrays
        self.geo = np.array([H, W, h, w, self.f, (IMAGER_CODES[self.msg_imager] << 8) | self.f,
                             self.record_id, self.threshold_stage is not None], np.int64)
        fr = self.front
        #: the plan's arguments of :func:`flightsw.ip.step.ip_step_k`, in its order (one tuple:
        #: fewer attribute reads on the per-frame path); the fixed arrays packed in two
        #: (:func:`flightsw.ip.step.step_words`: each array argument costs ~50 ns a call to type)
        self.step_args = step_words(self.geo, fr, self.recw) + (self.ffts, self.poly, self.mode)
        #: the stage arrays of a frame without stages (empty: one pair serves every frame)
        self.no_stages = (np.empty((0, h, w), np.int16), np.empty((0, h, w), np.int32))

    def stage_arrays(self) -> tuple:
        """New stage arrays for a frame with stages (:func:`ip_frame_into_k`): int16
        [n + 1, h, w] for the window and each front-end step, int32 [2, h, w] for the colour and
        rank images."""
        h, w = self.window_hw
        return (np.empty((self.front.ops.size + 1, h, w), np.int16),
                np.empty((2, h, w), np.int32))

    def cycles_for(self, h: int, w: int) -> tuple:
        """The front end's DSP cycles on an h x w window: compaction (0), then each step."""
        return (0,) + tuple(int(cost(h, w)) for cost in self.costs)

    # ------------------------------------------------------------------------------------------
    def run(self, frame, pred=None, *, alpha_q12: int | None = None, ledger: Ledger | None = None,
            frame_count: int = 0, time_tag: float = 0.0, want_stages: bool = False) -> FrameResult:
        """One checked frame (uint16 [244, 256], C order) through the pipeline; ``pred`` the TP's
        predicted pixel (full resolution) or None (the window is the image centre and the centroid
        means are the window centre)."""
        if pred is None:
            h, w, r0, c0, o0, o1, r0w, c0w, mr, mc = self.default
        else:
            pre = self.pre
            h, w = pre.window_shape
            r0, c0 = window_origin(pre.compacted_shape, self.f, pred, pre.window)
            o0, o1, r0w, c0w, mr, mc = _geometry_words(self.f, r0, c0, h, w, pred)
        aq = self.aq if alpha_q12 is None else int(alpha_q12)
        out = ip_frame_k(frame, self.f, r0, c0, h, w, self.front, self.ffts, self.poly, aq,
                         self.mode, self.recw, self.prm[bool(want_stages)], r0w, c0w, mr, mc,
                         bool(want_stages))
        return self._result(out, (out[0], (r0, c0), self.f, (h, w)), (o0, o1), aq,
                            self.front_cycles, ledger, frame_count, time_tag)

    def run_window(self, sub: Subimage, centroid_mean=None, *, alpha_q12: int | None = None,
                   ledger: Ledger | None = None, frame_count: int = 0, time_tag: float = 0.0,
                   want_stages: bool = False, max_candidates: int | None = None) -> FrameResult:
        """The pipeline after the preprocessor, on a window the caller cut (``sub``: its image, any
        shape, compacted origin and factor); ``centroid_mean`` (full-res (row, col)) replaces the
        record's centroid means, None: the window centre. The ground's full-frame mode."""
        img = np.ascontiguousarray(sub.image, np.int16)
        h, w = img.shape
        f = int(sub.factor)
        o0, o1, r0w, c0w, mr, mc = _geometry_words(f, int(sub.origin[0]), int(sub.origin[1]), h,
                                                   w, centroid_mean)
        mc_limit = self.max_candidates if max_candidates is None else max_candidates
        prm = self.prm[bool(want_stages)]
        if f != self.f or mc_limit != self.max_candidates:
            prm = backend_params(self.rank_record, *self.flags, bool(want_stages), f,
                                 self.imager, mc_limit)
        poly = self.poly
        if poly is not None and (h, w) != tuple(poly.tables.shape[1:]):
            poly = poly_tables(h, w)
        aq = self.aq if alpha_q12 is None else int(alpha_q12)
        out = ip_frame_k(img, 1, 0, 0, h, w, self.front, self.ffts, poly, aq, self.mode,
                         self.recw, prm, r0w, c0w, mr, mc, bool(want_stages))
        return self._result(out, (img, tuple(sub.origin), f, (h, w)), (o0, o1), aq,
                            self.cycles_for(h, w), ledger, frame_count, time_tag)

    def _result(self, out, sub, origin, aq, front_cycles, ledger, frame_count, time_tag):
        (_, pack, fst, bst, count, m, flags, c, fe, rk, bad, t4, m4, d4, s) = out
        if bad:
            raise ValueError("window holds values outside the 16-bit word range -32768..65535")
        return self.result(pack, fst, bst, sub, origin, aq, (t4, m4, d4, s), front_cycles, ledger,
                           frame_count, time_tag, None, (count, m, flags, c, fe, rk))

    def result(self, pack, fst, bst, sub, origin, aq, thr, front_cycles, ledger, frame_count,
               time_tag, alpha_cycles=None, head=None) -> FrameResult:
        """The :class:`FrameResult` of one pass of :func:`ip_frame_k` (its ``pack``, stage arrays,
        the window ``sub`` (a Subimage or its fields (image, compacted origin, factor, size)), the
        window origin ``origin`` in full-resolution pixels, alpha ``aq`` and the threshold words
        ``thr`` (t4, mean4, std4, shift)), the stages' cycles charged to ``ledger`` (a new one if
        None) and, with ``alpha_cycles``, the alpha logic's after them. ``head``: the pack's words
        0-5 as ints when the caller has them (read from ``pack`` if None)."""
        if head is None:
            head = pack[:6].tolist()
        if isinstance(sub, Subimage):
            sub = (sub.image, sub.origin, sub.factor, sub.size)
        return FrameResult(self, (pack, fst, bst, sub, origin, aq, thr, front_cycles, frame_count,
                                  time_tag, alpha_cycles, head), ledger)

    def _charge(self, ledger: Ledger, raw: tuple) -> None:
        """Charge a :class:`FrameResult`'s cycles (``raw``: its fields) to ``ledger``."""
        front_cycles, alpha_cycles = raw[7], raw[10]
        c, fe, rk = raw[11][3:6]
        if alpha_cycles is None:
            keys, charged = self.keys, front_cycles + (c, fe, rk)
        else:
            keys, charged = self.step_keys, front_cycles + (c, fe, rk, alpha_cycles)
        if "dsp" in ledger.processors and "ip1750" in ledger.processors:
            ledger.charge_block(keys, charged)
        else:                          # the ledger raises its own error for the missing processor
            ledger.charge_many(k + (n,) for k, n in zip(keys, charged))

    def _message(self, raw: tuple) -> CandidateMessage:
        """The candidate message of a :class:`FrameResult` (``raw``: its fields; the candidates
        read from the pack without the back end's result, ~0.5 us)."""
        cand = candidate_table(raw[0], raw[11][0], raw[11][1])
        sub, origin = raw[3], raw[4]
        h, w = sub[3]
        alpha = raw[5] / 4096.0 if self.threshold_stage is not None else 0.0
        # positional, in the dataclass's field order (a call by keyword costs ~0.35 us more)
        return CandidateMessage(raw[8], raw[9], self.msg_imager, sub[2], origin[0], origin[1], h,
                                w, alpha, self.record_id, cand)

    def _context(self, raw: tuple, sub: Subimage) -> dict:
        """The context dict of a :class:`FrameResult` (``raw``: its fields)."""
        ctx = {"imager": self.imager, "record": self.record, "subimage": sub,
               "preprocess": self.pre}
        if self.threshold_stage is not None:
            t4, m4, d4, s = raw[6]
            ctx["threshold"] = {"t4": t4, "mean4": m4, "std4": d4, "shift": s, "alpha_q12": raw[5],
                                "mode": self.mode_name}
        return ctx

    def _stages(self, fst, bst, be, t4):
        out = [Stage("window", fst[0])]
        for i, name in enumerate(self.step_names):
            out.append(Stage(name, fst[i + 1], int(t4) if name == self.threshold_stage else None))
        out.append(Stage("colour", bst[0], be.count))
        out.append(Stage("rank", bst[1], be.order))
        return out


_NO_LABELS = np.zeros((0, 0), np.int32)
_PLANS: dict = {}


def plan_for(sequence: ProcessingSequence, record, imager: str = "wfov_vis") -> FramePlan:
    """The :class:`FramePlan` of (sequence, record, imager), built on first use and kept (up to 64
    plans; a plan holds its sequence and record, so a kept key always names the same objects)."""
    key = (id(sequence), id(record), imager)
    plan = _PLANS.get(key)
    if plan is None or plan.sequence is not sequence or plan.record is not record:
        if len(_PLANS) >= 64:
            _PLANS.clear()
        plan = _PLANS[key] = FramePlan(sequence, record, imager)
    return plan
