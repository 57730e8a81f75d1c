"""The image processor's one compiled pipeline: a frame in, the candidate message out.

The MSX paper's Image Processing section in order: the preprocessor board compacts the frame and
cuts the window about the TP's prediction (step 1); the DSP runs the uplinked sequence's front-end
steps (spatial or frequency filters, detrenders, the threshold; steps 2-5); the 1750A colours the
blobs, computes and normalises the features and ranks them against the a priori record (steps 6-8).
:func:`ip_frame_into_k` runs all of it in one jitted call on the window :func:`place_window_k`
placed. The stage images of the paper's Figure 3 (the window, every front-end step's output, the
colour and rank images) are an output option of the same call (stage arrays given or empty), not a
second implementation.

A :class:`FramePlan` holds what does not change from frame to frame for one (sequence, record,
imager): the front-end steps as arrays, the back end's parameters
(:data:`flightsw.ip.backend.BACKEND_PARAMS`), the frame header with the plan's fields filled
(:data:`flightsw.ip.frame_header.FRAME_HEADER`: the kernels place each frame's window in it and
write the frame's words to it), the ledger keys and the static cycles. The :class:`flightsw.ip.ImageProcessor` owns its plan and builds
a new one when an uplink changes the sequence or the record; :func:`plan_for` keeps a few plans for
the one-frame conveniences (:func:`flightsw.ip.process_frame`).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from flightsw.arith.m1750_float import encode_k
from flightsw.budget import IP1750, Ledger
from flightsw.ip import detrend as dt
from flightsw.ip import fftfilter as fft
from flightsw.ip import filters as flt
from flightsw.ip import threshold as th
from flightsw.ip.backend import (BACK_KEYS, BackendResult, backend_k, backend_params,
                                 candidate_table, enc32)
from flightsw.ip.frame_header import FRAME_HEADER, HEADER_WORD, header_of, new_header
from flightsw.ip.preprocess import Subimage, compact_k, window_origin_k
from flightsw.ip.rank import record_words
from flightsw.ip.sequence import (PHASE_LABEL, STEP_REGISTRY, ColourParams, DetrendParams,
                                  FeatureParams, FilterFFTParams, FilterParams, ProcessingSequence,
                                  RankParams, Stage, ThresholdParams)
from flightsw.messages import IMAGER_CODES, CandidateMessage
from flightsw.numba_cache import KERNEL, callee_kernel

__all__ = ["FramePlan", "FrameResult", "FrontOps", "FFTTables", "PolyTables", "place_window_k",
           "ip_frame_at_k", "ip_frame_into_k", "FRAME_HEADER", "plan_for", "step_words",
           "OP_FILTER", "OP_HIGHPASS", "OP_NONE", "OP_THRESHOLD", "OP_FFT", "OP_POLY"]

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

    spec: np.ndarray    #: :data:`flightsw.ip.fftfilter.FFT_SPEC` [m], each with the DC removal on
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


@callee_kernel
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
            spec = ffts.spec[j:j + 1]
            T = spec[0].tile
            kr = np.ascontiguousarray(ffts.kr[j, :T * T]).reshape((T, T))
            ki = np.ascontiguousarray(ffts.ki[j, :T * T]).reshape((T, T))
            out = fft.fft_correlate_k(img, spec, kr, ki, np.ascontiguousarray(ffts.brev[j, :T]),
                                      np.ascontiguousarray(ffts.twc[j, :T // 2]),
                                      np.ascontiguousarray(ffts.tws[j, :T // 2]))[0]
    elif op == OP_POLY:
        if poly is None:                    # a plan without the polynomial detrender: not compiled
            out = img
        else:
            out = dt.polynomial_k(img, poly.tables, poly.js, poly.rs, poly.ps)[0]
    else:                                                  # OP_NONE
        out = img
    return out, op == OP_THRESHOLD, t4, m4, d4, sh


@callee_kernel
def place_window_k(header, pr, pc):
    """Place the frame's window about the TP's predicted full-resolution pixel (``pr``, ``pc``;
    NaN: none) in ``header`` (:data:`FRAME_HEADER` [1]): reads the plan's ``rows``, ``cols``,
    ``win_rows``, ``win_cols``, ``compaction``; writes ``r0``, ``c0`` (compacted pixels), ``o0``,
    ``o1`` (full resolution), their 1750A words ``r0w``, ``c0w``, and the centroid means
    ``mean_row``, ``mean_col`` (1750A words of the prediction, or of the window centre without
    one; ``override`` 1).

    Cases
    -----
    prediction : a prediction -> :func:`flightsw.ip.preprocess.window_origin_k`'s origin, the
        means the prediction.
    no-prediction : ``pr`` NaN -> the window at the image centre, the means its centre.
    """
    hd = header[0]
    f, h, w = hd.compaction, hd.win_rows, hd.win_cols
    r0, c0 = window_origin_k(hd.rows, hd.cols, h, w, f, pr, pc)
    o0, o1 = r0 * f, c0 * f
    if math.isnan(pr):
        pr, pc = o0 + h * f / 2.0, o1 + w * f / 2.0
    hd.r0, hd.c0, hd.o0, hd.o1 = r0, c0, o0, o1
    hd.r0w = encode_k(float(o0), np.int64(23), True)
    hd.c0w = encode_k(float(o1), np.int64(23), True)
    hd.mean_row = encode_k(pr, np.int64(23), True)
    hd.mean_col = encode_k(pc, np.int64(23), True)
    hd.override = 1


@callee_kernel
def copy_plane_k(dst, k, src):
    """``dst[k] = src``, word by word (``dst`` [n, h, w], ``src`` [h, w], each word cast to
    ``dst``'s type as numpy's assignment casts it). A plane-slice assignment would do the same and
    also compile numba's message for mismatched shapes, seconds of a first run.

    Cases
    -----
    same-type : int16 into int16 -> plane ``k`` equals ``src``, the other planes untouched.
    narrowing : int32 into int16 -> each word as numpy's assignment casts it (wrapping).
    """
    for r in range(src.shape[0]):
        for c in range(src.shape[1]):
            dst[k, r, c] = src[r, c]


@njit(**KERNEL)
def ip_frame_at_k(src, header, pred, front, ffts, poly, params, fst, bst):
    """:func:`ip_frame_into_k` on the window :func:`place_window_k` places about ``pred``
    (float64 [2]: the predicted full-resolution row and column, NaN: none): one frame of
    :meth:`FramePlan.run`.

    Cases
    -----
    typical : the window placed as :func:`flightsw.ip.step.ip_step_k` places it, then the same
        pipeline.
    """
    place_window_k(header, pred[0], pred[1])
    return ip_frame_into_k(src, header, front, ffts, poly, params, fst, bst)


@callee_kernel
def ip_frame_into_k(src, header, front, ffts, poly, params, fst, bst):
    """One frame through the image processor.

    Parameters
    ----------
    src : integer [H, W]
        The frame (12-bit counts; the header's ``compaction``, ``r0``, ``c0``, ``win_rows``,
        ``win_cols`` cut the window: compaction factor and window origin and shape in compacted
        pixels), or a window the caller cut (``compaction`` 1, origin 0).
    header : :data:`FRAME_HEADER` [1]
        Reads the cut, ``alpha_q12`` and ``mode`` (the threshold's alpha, Q4.12, and mode) and the
        back end's words (:func:`flightsw.ip.backend.backend_k`); writes the threshold's ``t4``,
        ``mean4``, ``std4``, ``shift`` (0 without a threshold step) and the back end's counts.
    front, ffts, poly : FrontOps, FFTTables or None, PolyTables or None
        None when the sequence has no such step: numba then prunes (does not compile) the FFT or
        polynomial branch, which keeps a first run's compilation to the kernels the sequence uses
    params : :data:`flightsw.ip.backend.BACKEND_PARAMS` [1]
    fst, bst : the stage images, written here: int16 [n + 1, h, w] (the window and each front-end
        step's output) and int32 [2, h, w] (labels, blobs numbered by rank), or both [0, h, w]
        for none (the caller's arrays: nothing to box on return)

    Returns
    -------
    (window int16 [h, w], pack (:func:`flightsw.ip.backend.backend_k`))

    Cases
    -----
    stages : given stage arrays -> the window and each front-end step's output are the stage
        kernels composed in the sequence's order; the colour image is the labels.
    no-stages : empty stage arrays -> nothing written, the same pack and header.
    threshold-words : a threshold step -> its t4, mean4, std4 and shift.
    no-threshold : no threshold step -> those words 0.
    no-steps : an empty front end -> the window goes to the back end as it is.
    rank-image : the rank stage numbers each reported blob's pixels by its rank (1 = best), 0
        elsewhere.
    caller-window : a window the caller cut (``compaction`` 1, origin 0) -> the window stage is
        that window, the rest as for a frame.
    no-blobs : nothing passes the threshold -> count 0, m 0, rank image all 0.
    """
    hd = header[0]
    h, w = hd.win_rows, hd.win_cols
    want_stages = fst.shape[0] != 0
    win = compact_k(src, hd.compaction, hd.r0, hd.c0, h, w)
    aq, mode = hd.alpha_q12, hd.mode
    img = win
    if want_stages:
        copy_plane_k(fst, 0, win)
    hd.t4, hd.mean4, hd.std4, hd.shift = 0, 0, 0, 0
    for i in range(front.ops.size):
        img, is_thr, a, b, c, d = front_step_k(img, i, front, ffts, poly, aq, mode)
        if is_thr:
            hd.t4, hd.mean4, hd.std4, hd.shift = a, b, c, d
        if want_stages:
            copy_plane_k(fst, i + 1, img)
    labels, pack = backend_k(img, params, header)
    if want_stages:
        copy_plane_k(bst, 0, labels)
        lut = np.zeros(hd.count + 1, np.int32)
        for q in range(hd.m):
            lut[pack[q] + 1] = q + 1                            # pack[:m]: the order
        for r in range(h):
            for c in range(w):
                bst[1, r, c] = lut[labels[r, c]]
    return win, pack


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

    What it is made of (the fields): ``plan`` (:class:`FramePlan`), ``header``
    (:class:`flightsw.ip.frame_header.FrameHeader`: the window, the threshold's words, the back
    end's counts and cycles), ``pack`` (:func:`flightsw.ip.backend.backend_k`), ``fst``, ``bst``
    (the stage arrays, empty without stages), ``window`` (the window image, its compacted origin,
    factor and size: :class:`Subimage`'s fields), ``time_tag`` (s), ``front_cycles`` (the DSP's
    cycles a front-end stage) and ``alpha_cycles`` (the alpha logic's, or None when the frame did
    not run it).
    """

    __slots__ = ("plan", "header", "pack", "fst", "bst", "window", "time_tag", "front_cycles",
                 "alpha_cycles", "_ledger", "_message", "_stages", "_backend", "_subimage",
                 "_context")

    def __init__(self, plan: "FramePlan", header, pack, stages: tuple, window: tuple,
                 time_tag: float, cycles: tuple, ledger: Ledger | None):
        """``stages``: (fst, bst); ``cycles``: (front cycles, alpha cycles or None)."""
        self.plan, self.header, self.pack = plan, header, pack
        self.fst, self.bst = stages
        self.window, self.time_tag = window, time_tag
        self.front_cycles, self.alpha_cycles = cycles
        self._message = self._stages = self._backend = self._subimage = self._context = None
        self._ledger = ledger
        if ledger is not None:
            plan.charge(ledger, self)

    def __iter__(self):                         # message, stages, ledger = process_frame(...)
        return iter((self.message, self.stages, self.ledger))

    @property
    def ledger(self) -> Ledger:
        if self._ledger is None:
            self._ledger = Ledger()
            self.plan.charge(self._ledger, self)
        return self._ledger

    @property
    def backend(self) -> BackendResult:
        be = self._backend
        if be is None:
            hd, bst = self.header, self.bst
            labels = bst[0] if bst.shape[0] else _NO_LABELS
            be = self._backend = BackendResult(labels, self.pack, hd.count, hd.m, hd.flags,
                                               (hd.cyc_colour, hd.cyc_features, hd.cyc_rank))
        return be

    @property
    def blob_count(self) -> int:
        return self.header.count

    @property
    def subimage(self) -> Subimage:
        if self._subimage is None:
            self._subimage = Subimage(*self.window)
        return self._subimage

    @property
    def message(self) -> CandidateMessage:
        if self._message is None:
            self._message = self.plan.message_of(self)
        return self._message

    @property
    def stages(self) -> list:
        if self._stages is None:
            self._stages = self.plan.stages_of(self) if self.fst.shape[0] else []
        return self._stages

    @property
    def context(self) -> dict:
        if self._context is None:
            self._context = self.plan.context_of(self)
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
    spec = np.zeros(m, fft.FFT_SPEC)
    kr = np.zeros((m, MAX_TILE * MAX_TILE), np.int64)
    ki = np.zeros_like(kr)
    brev = np.zeros((m, MAX_TILE), np.int64)
    twc = np.zeros((m, MAX_TILE // 2), np.int64)
    tws = np.zeros_like(twc)
    for j, kern in enumerate(kernels):
        T = kern.tile
        c, s, dw = fft.twiddles_q15(T)
        spec[j] = fft.fft_spec(kern, dw, True)[0]
        kr[j, :T * T] = kern.kr.ravel()
        ki[j, :T * T] = kern.ki.ravel()
        brev[j, :T] = fft.bitrev(T)
        twc[j, :T // 2] = c
        tws[j, :T // 2] = s
    return FFTTables(spec, kr, ki, brev, twc, tws)


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


def step_words(front: FrontOps) -> tuple:
    """The front end of a plan packed for :func:`flightsw.ip.step.ip_step_k`: (int64 [3 n]: the
    ``ops``, ``size`` and ``fft`` [n] each; int16 [56 n]: the kernels [n, 7, 7] then the taps
    [n, 7]) for a front end of n steps (:func:`flightsw.ip.step.front_of` unpacks them)."""
    ints = np.concatenate([front.ops, front.size, front.fft]).astype(np.int64)
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
        #: the back end's parameters (:data:`flightsw.ip.backend.BACKEND_PARAMS` [1]) without and
        #: with the label image
        self.prm = {want: backend_params(rec, *self.flags, want, self.f, imager,
                                         self.max_candidates) for want in (False, True)}
        self.keys = (("dsp", "compaction"),) + tuple(("dsp", n) for n in self.step_names) \
            + BACK_KEYS
        self.front_cycles = self.cycles_for(h, w)
        self.msg_imager = imager if imager in IMAGER_CODES else "real"
        self.record_id = rec.record_id
        self.step_keys = self.keys + ((IP1750, "alpha_logic"),)
        self.window_hw = (h, w)
        self.frame_shape = pre.frame_shape
        H, W = pre.compacted_shape
        #: the frame header (:data:`flightsw.ip.frame_header.FRAME_HEADER` [1]) the kernels place
        #: each frame's window in and write the frame's words to, the plan's fields filled here;
        #: ``header_words`` its int64 view (:func:`flightsw.ip.frame_header.header_of`)
        self.header, self.header_words = new_header()
        hd = self.header[0]
        hd["rows"], hd["cols"], hd["win_rows"], hd["win_cols"] = H, W, h, w
        hd["compaction"] = self.f
        hd["imager_word"] = (IMAGER_CODES[self.msg_imager] << 8) | self.f
        hd["record_id"], hd["has_threshold"] = self.record_id, self.threshold_stage is not None
        hd["mode"], hd["alpha_q12"] = self.mode, self.aq
        #: the plan's arguments of :func:`flightsw.ip.step.ip_step_k`, in its order (one tuple:
        #: fewer attribute reads on the per-frame path); the front end packed in two arrays
        #: (:func:`step_words`: each array argument costs ~50 ns a call to type)
        self.step_args = (self.header,) + step_words(self.front) + (self.ffts, self.poly)
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
        words = self.header_words
        words[HEADER_WORD["alpha_q12"]] = self.aq if alpha_q12 is None else int(alpha_q12)
        words[HEADER_WORD["frame_count"]] = frame_count
        stages = self.stage_arrays() if want_stages else self.no_stages
        at = _NO_PREDICTION if pred is None else np.array(pred, np.float64)
        win, pack = ip_frame_at_k(frame, self.header, at, self.front, self.ffts, self.poly,
                                  self.prm[bool(want_stages)], *stages)
        header = header_of(self.header_words)
        if header.bad:
            raise ValueError("window holds values outside the 16-bit word range -32768..65535")
        return FrameResult(self, header, pack, stages, (win, (header.r0, header.c0), self.f,
                                                      self.window_hw),
                           time_tag, (self.front_cycles, None), ledger)

    def run_window(self, sub: Subimage, centroid_mean=None, *, alpha_q12: int | None = None,
                   ledger: Ledger | None = None, frame_count: int = 0, time_tag: float = 0.0,
                   want_stages: bool = False, max_candidates: int | None = None) -> FrameResult:
        """The pipeline after the preprocessor, on a window the caller cut (``sub``: its image, any
        shape, compacted origin and factor); ``centroid_mean`` (full-res (row, col)) replaces the
        record's centroid means, None: the window centre. The ground's full-frame mode."""
        img = np.ascontiguousarray(sub.image, np.int16)
        h, w = img.shape
        f = int(sub.factor)
        mc_limit = self.max_candidates if max_candidates is None else max_candidates
        params = self.prm[bool(want_stages)]
        if f != self.f or mc_limit != self.max_candidates:
            params = backend_params(self.rank_record, *self.flags, bool(want_stages), f,
                                    self.imager, mc_limit)
        poly = self.poly
        if poly is not None and (h, w) != tuple(poly.tables.shape[1:]):
            poly = poly_tables(h, w)
        header, words = self.window_header(f, sub.origin, (h, w), centroid_mean, alpha_q12,
                                           frame_count)
        stages = (np.empty((self.front.ops.size + 1, h, w), np.int16),
                  np.empty((2, h, w), np.int32)) if want_stages else \
            (np.empty((0, h, w), np.int16), np.empty((0, h, w), np.int32))
        _, pack = ip_frame_into_k(img, header, self.front, self.ffts, poly, params, *stages)
        header = header_of(words)
        if header.bad:
            raise ValueError("window holds values outside the 16-bit word range -32768..65535")
        return FrameResult(self, header, pack, stages, (img, tuple(sub.origin), f, (h, w)),
                           time_tag, (self.cycles_for(h, w), None), ledger)

    def window_header(self, f: int, origin, size, centroid_mean=None,
                      alpha_q12: int | None = None, frame_count: int = 0, cut: int = 1) -> tuple:
        """A new frame header (:data:`FRAME_HEADER` [1] and its int64 view) for a window the
        caller places: compaction ``f``, compacted ``origin`` (row, col) and ``size`` (h, w), the
        centroid means ``centroid_mean`` (full-resolution (row, col); None: the window centre),
        the plan's threshold (``alpha_q12`` None: the sequence's) and ``cut``, the factor the
        kernel compacts its input by (1: the caller's window is already compacted; the full
        frame's kernel compacts the frame itself)."""
        header, words = new_header()
        hd = header[0]
        h, w = size
        hd["o0"], hd["o1"], hd["r0w"], hd["c0w"], hd["mean_row"], hd["mean_col"] = \
            _geometry_words(f, int(origin[0]), int(origin[1]), h, w, centroid_mean)
        hd["compaction"], hd["win_rows"], hd["win_cols"], hd["override"] = cut, h, w, 1
        hd["alpha_q12"] = self.aq if alpha_q12 is None else int(alpha_q12)
        hd["mode"], hd["frame_count"] = self.mode, frame_count
        return header, words

    def charge(self, ledger: Ledger, res: FrameResult) -> None:
        """Charge a :class:`FrameResult`'s cycles to ``ledger``."""
        hd = res.header
        back = (hd.cyc_colour, hd.cyc_features, hd.cyc_rank)
        if res.alpha_cycles is None:
            keys, charged = self.keys, res.front_cycles + back
        else:
            keys, charged = self.step_keys, res.front_cycles + back + (res.alpha_cycles,)
        if "dsp" in ledger.processors and "ip1750" in ledger.processors:
            ledger.charge_block(keys, charged)
        else:                          # the ledger raises its own error for the missing processor
            ledger.charge_many(k + (n,) for k, n in zip(keys, charged))

    def message_of(self, res: FrameResult) -> CandidateMessage:
        """The candidate message of a :class:`FrameResult` (the candidates read from the pack
        without the back end's result, ~0.5 us)."""
        hd = res.header
        cand = candidate_table(res.pack, hd.count, hd.m)
        h, w = res.window[3]
        alpha = hd.alpha_q12 / 4096.0 if self.threshold_stage is not None else 0.0
        # positional, in the dataclass's field order (a call by keyword costs ~0.35 us more)
        return CandidateMessage(hd.frame_count, res.time_tag, self.msg_imager, res.window[2],
                                hd.o0, hd.o1, h, w, alpha, self.record_id, cand)

    def context_of(self, res: FrameResult) -> dict:
        """The context dict of a :class:`FrameResult`."""
        ctx = {"imager": self.imager, "record": self.record, "subimage": res.subimage,
               "preprocess": self.pre}
        if self.threshold_stage is not None:
            hd = res.header
            ctx["threshold"] = {"t4": hd.t4, "mean4": hd.mean4, "std4": hd.std4,
                                "shift": hd.shift, "alpha_q12": hd.alpha_q12,
                                "mode": self.mode_name}
        return ctx

    def stages_of(self, res: FrameResult) -> list:
        """The stage images of a :class:`FrameResult` run with stages."""
        fst, bst, be = res.fst, res.bst, res.backend
        out = [Stage("window", fst[0])]
        for i, name in enumerate(self.step_names):
            out.append(Stage(name, fst[i + 1], res.header.t4 if name == self.threshold_stage
                             else None))
        out.append(Stage("colour", bst[0], be.count))
        out.append(Stage("rank", bst[1], be.order))
        return out


_NO_LABELS = np.zeros((0, 0), np.int32)
_NO_PREDICTION = np.array([np.nan, np.nan])
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
