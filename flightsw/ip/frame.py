"""One frame through the image processor: front end (the uplinked sequence) + back end (colour,
features, normalisation, ranking) -> the IP -> TP candidate message, the stage images, the ledger.

:func:`backend` runs IP steps 6-8 on a thresholded window in one jitted call (the same kernels as
:func:`flightsw.ip.colour.colour`, :func:`flightsw.ip.features.features_words`,
:func:`flightsw.ip.features.normalise_words` and :func:`flightsw.ip.rank.rank_words`, so the
results are identical word for word) and charges the three stages to the ledger on ``"ip1750"``.

:func:`process_frame` runs the whole frame: compaction and window (``flightsw.ip.preprocess``), the
front-end steps of the uplinked sequence (``flightsw.ip.sequence``), then the back end, and packs the
:class:`flightsw.messages.CandidateMessage`. Without stage images (``want_stages=False``, the hot
path) the front end runs fused in one jitted call (``ProcessingSequence.run_frame_fast``,
bit-identical to the steps: tested), so a frame is two jitted calls.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numba import njit

from flightsw.arith.m1750 import decode32_array, encode32
from flightsw.arith.m1750_float import decode32_k
from flightsw.budget import IP1750, Ledger
from flightsw.ip.colour import _CYC as _CYC_COLOUR
from flightsw.ip.colour import _DIRECT, _as_int_image, _colour_kernel
from flightsw.ip.features import (
    _features_fm, _norm_consts, _normalise_fm, features_cycles, words_to_struct,
)
from flightsw.ip.preprocess import _new_subimage
from flightsw.ip.preprocess import window_origin as _window_origin
from flightsw.ip.rank import _CYC as _CYC_RANK
from flightsw.ip.rank import _rank_kernel, _record_words
from flightsw.messages import (
    CANDIDATE_DTYPE, FEATURE_NAMES, MAX_CANDIDATES, CandidateMessage, Feedback,
)

__all__ = ["backend", "BackendResult", "process_frame", "process_window", "FrameResult"]


@lru_cache(maxsize=4096)
def _enc(x: float) -> int:
    """float -> nearest 1750A 32-bit word (cached: window origins/centres repeat frame to frame)."""
    return encode32(float(x), rounding="nearest")


@lru_cache(maxsize=4096)
def _enc4(r0: float, c0: float, mr: float, mc: float) -> tuple:
    """:func:`_enc` of a window origin (row0, col0) and centroid mean (row, col) in one look-up."""
    return _enc(r0), _enc(c0), _enc(mr), _enc(mc)


_CYC_BLOB = features_cycles(1)
_HEAD = 22        # pack header: count, m, flags, 3 cycle totals, 6 colour + 9 rank event counts, bad


@njit(cache=True)
def _backend_kernel(img, rec, prm, r0w, c0w, mean_row, mean_col, override):
    """prm int64 [10] (per record and flags, cached): diagonal, intensity, want_labels, area, lin, f,
    quantize, threshold word, max_out, unused; then the per-frame words: window row0, col0, the mean
    row, col and the override flag.

    Returns (labels, pack): ``pack`` int64 holds the header (_HEAD words), then order [m], gof [m],
    the reported distances [m], every distance [count], the feature words [count, 12] and the
    candidate table [m, 15] (CANDIDATE_DTYPE layout, decoded exactly) -- one array to box."""
    diagonal, intensity, want_labels = prm[0] != 0, prm[1] != 0, prm[2] != 0
    area, lin, fw = prm[3], prm[4], prm[5]
    quantize, thr, max_out = prm[6] != 0, prm[7], prm[8]
    cyc_colour, cyc_blob, cyc_rank = _CYC_COLOUR, _CYC_BLOB, _CYC_RANK
    labels, count, sums, cops, bad = _colour_kernel(img, diagonal, want_labels)
    raw, f1 = _features_fm(sums, count, intensity)               # feature-major [12, count]
    words, f2 = _normalise_fm(raw, area, lin, fw, r0w, c0w)
    order, d, gof, f3, rops = _rank_kernel(words, rec, mean_row, mean_col, override != 0,
                                           quantize, thr, max_out)
    m = order.size
    h = _HEAD
    o_words = h + 3 * m + count
    o_cand = o_words + 12 * count
    pack = np.empty(o_cand + 15 * m, np.int64)
    pack[0] = count
    pack[1] = m
    pack[2] = f1 | f2 | f3
    pack[3] = 0
    for i in range(cops.size):
        pack[3] += cyc_colour[i] * cops[i]
    pack[4] = count * cyc_blob
    pack[5] = 0
    for i in range(rops.size):
        pack[5] += cyc_rank[i] * rops[i]
    pack[6:12] = cops
    pack[12:21] = rops
    pack[21] = 1 if bad else 0
    pack[h:h + m] = order
    pack[h + m:h + 2 * m] = gof
    for q in range(m):
        pack[h + 2 * m + q] = d[order[q]]
    pack[h + 3 * m:o_words] = d
    fwp = pack[o_words:o_cand]                                    # blob-major [count, 12]
    for i in range(12):
        fwp[i::12] = words[i]
    # the candidate table (CANDIDATE_DTYPE layout: label int64, then 14 float64), decoded exactly
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
        Their GOF and distance words.
    all_distance_words : ndarray [count] int64
        Distance of every blob.
    flags : int
        OR of the 1750A PI flags raised.
    cycles : dict
        ``{"colour", "features", "rank"}`` PACE1750A clocks charged.
    """

    __slots__ = ("labels", "count", "flags", "_cyc", "_pack", "_m")

    def __init__(self, labels, pack, count, m, flags, cycles):
        self.labels, self._pack, self.count, self._m, self.flags = labels, pack, count, m, flags
        self._cyc = cycles

    @property
    def cycles(self) -> dict:
        return dict(zip(("colour", "features", "rank"), self._cyc))

    # the arrays are views of the kernel's pack, cut on first use
    @property
    def order(self):
        return self._pack[_HEAD:_HEAD + self._m]

    @property
    def gof_words(self):
        return self._pack[_HEAD + self._m:_HEAD + 2 * self._m]

    @property
    def distance_words(self):
        return self._pack[_HEAD + 2 * self._m:_HEAD + 3 * self._m]

    @property
    def all_distance_words(self):
        o = _HEAD + 3 * self._m
        return self._pack[o:o + self.count]

    @property
    def feature_words(self):
        o = _HEAD + 3 * self._m + self.count
        return self._pack[o:o + 12 * self.count].reshape(self.count, 12)

    @property
    def features(self) -> np.ndarray:
        """Normalised features of every blob, structured (FEATURE_DTYPE)."""
        return words_to_struct(self.feature_words)

    def candidates(self) -> np.ndarray:
        """The reported candidates as a CANDIDATE_DTYPE array (best first)."""
        o = _HEAD + 3 * self._m + 13 * self.count
        # a structured view of the pack's tail (the ndarray constructor skips view()'s checks)
        return np.ndarray((self._m,), CANDIDATE_DTYPE, self._pack, 8 * o)

    def _candidates_decoded(self) -> np.ndarray:
        """:meth:`candidates` rebuilt from the words on the host (a cross-check for tests)."""
        m = len(self.order)
        out = np.zeros(m, CANDIDATE_DTYPE)
        if m:
            out["label"] = self.order + 1
            out["gof"] = decode32_array(self.gof_words)
            out["distance"] = decode32_array(self.distance_words)
            vals = decode32_array(self.feature_words[self.order])
            for i, name in enumerate(FEATURE_NAMES):
                out[name] = vals[:, i]
        return out


def backend(window, record, diagonal: bool = True, intensity_centroid: bool = True,
            compaction: int = 1, window_origin=(0, 0), imager: str = "wfov_vis",
            centroid_mean=None, ledger: Ledger | None = None, want_labels: bool = True,
            max_candidates: int = MAX_CANDIDATES) -> BackendResult:
    """IP steps 6-8 on a thresholded (binary or clipped) window.

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
    if not isinstance(record, _record_class()):
        raise ValueError(f"record must be a flightsw.records.Record, got {type(record).__name__}")
    for name, v in (("diagonal", diagonal), ("intensity_centroid", intensity_centroid),
                    ("want_labels", want_labels)):
        if v is not True and v is not False and v not in (0, 1):
            raise ValueError(f"{name}={v!r} must be a bool")
    img = _direct(window, "window")
    try:
        r0, c0 = window_origin
        r0w, c0w = _enc(float(r0)), _enc(float(c0))
    except (TypeError, ValueError):
        raise ValueError(f"window_origin={window_origin!r} must be (row0, col0) numbers") from None
    if centroid_mean is None:
        override, mr, mc = 0, 0, 0
    else:
        try:
            r, c = centroid_mean
            if not (math.isfinite(r) and math.isfinite(c)):
                raise ValueError
            override, mr, mc = 1, _enc(float(r)), _enc(float(c))
        except (TypeError, ValueError):
            raise ValueError(f"centroid_mean={centroid_mean!r} must be finite (row, col) or None") \
                from None
    prm = _static_params(record, bool(diagonal), bool(intensity_centroid), bool(want_labels),
                         compaction, imager, max_candidates)
    labels, pack = _backend_kernel(img, _record_words(record), prm, r0w, c0w, mr, mc, override)
    return _backend_result(labels, pack, ledger)


_BACK_KEYS = ((IP1750, "colour"), (IP1750, "features"), (IP1750, "rank"))


def _backend_result(labels, pack, ledger):
    """BackendResult of a kernel's (labels, pack), with the range check and the cycles charged."""
    head = pack[:_HEAD].tolist()
    if head[21]:
        raise ValueError("window holds values outside the 16-bit word range -32768..65535")
    c, f, r = head[3:6]
    if ledger is not None:
        _charge(ledger, _BACK_KEYS, (c, f, r))
    return BackendResult(labels, pack, head[0], head[1], head[2], (c, f, r))


def _charge(ledger, keys, cycles):
    """Charge ``cycles`` (non-negative ints) to ``keys`` ((processor, stage) pairs on "dsp" and
    "ip1750"): queued in one block when the ledger knows both processors, else through
    ``charge_many`` so that the ledger raises its own error."""
    procs = ledger.processors
    if "dsp" in procs and IP1750 in procs:
        ledger._queue(keys, cycles)
    else:
        ledger.charge_many(k + (n,) for k, n in zip(keys, cycles))


def _static_params(record, diagonal, intensity, want_labels, compaction, imager, max_candidates):
    """The kernel's per-record, per-flag parameter words (validated and built once, kept on the
    record object like its packed words)."""
    key = (diagonal, intensity, want_labels, compaction, imager, max_candidates)
    cache = record.__dict__.get("_backend_prm")
    if cache is None:
        cache = {}
        object.__setattr__(record, "_backend_prm", cache)
    prm = cache.get(key)
    if prm is None:
        area, lin, fw = _norm_consts(compaction, imager)
        if isinstance(max_candidates, bool) or not isinstance(max_candidates, (int, np.integer)) \
                or not 1 <= max_candidates <= 1000:
            raise ValueError(f"max_candidates={max_candidates!r} must be an int in 1..1000")
        prm = np.array((diagonal, intensity, want_labels, area, lin, fw, record.quantize,
                        _enc(record.gof_threshold), int(max_candidates), 0), np.int64)
        if len(cache) > 64:
            cache.clear()
        cache[key] = prm
    return prm


_RECORD = []


def _record_class():
    if not _RECORD:
        from flightsw.records import Record
        _RECORD.append(Record)
    return _RECORD[0]


def _direct(window, name):
    if isinstance(window, np.ndarray) and window.ndim == 2 and window.size \
            and window.dtype.type in _DIRECT and window.flags.c_contiguous:
        return window                                  # the kernel checks the 16-bit range
    return _as_int_image(window, name)


# ================================================================================================
# the sequence steps of the back end (registered with flightsw.ip.sequence)
# ================================================================================================
from flightsw.ip.sequence import (  # noqa: E402
    PHASE_FEATURES, PHASE_LABEL, PHASE_RANK, STEP_REGISTRY, FieldError, ProcessingSequence,
    Stage, StageOutput, _front_fast_k, register_step,
)


@dataclass(frozen=True)
class ColourParams:
    diagonal: bool = True


@dataclass(frozen=True)
class FeatureParams:
    intensity_centroid: bool = True


@dataclass(frozen=True)
class RankParams:
    record: object = None              # a Record, or None: the record given to process_frame
    max_candidates: int = MAX_CANDIDATES


def _bool_field(params, name, default):
    v = params.get(name, default)
    if not isinstance(v, bool):
        raise FieldError(name, f"{v!r} is not a boolean (true/false)")
    return v


def _only(params, allowed):
    extra = sorted(set(params) - set(allowed))
    if extra:
        raise FieldError(extra[0], f"unknown field (allowed: {sorted(allowed)})")


def _validate_colour(params, pre):
    _only(params, {"diagonal"})
    return ColourParams(_bool_field(params, "diagonal", True))


def _validate_features(params, pre):
    _only(params, {"intensity_centroid"})
    return FeatureParams(_bool_field(params, "intensity_centroid", True))


def _validate_rank(params, pre):
    from flightsw.records import load_record
    _only(params, {"record", "max_candidates"})
    rec = None
    if "record" in params:
        try:
            rec = load_record(params["record"])
        except (ValueError, FileNotFoundError) as exc:
            raise FieldError("record", str(exc)) from None
    m = params.get("max_candidates", MAX_CANDIDATES)
    if isinstance(m, bool) or not isinstance(m, int) or not 1 <= m <= MAX_CANDIDATES:
        raise FieldError("max_candidates", f"{m!r} must be an int in 1..{MAX_CANDIDATES}")
    return RankParams(rec, m)


def _window_geometry(ctx):
    """(compaction, full-res origin (row0, col0), window centre (row, col)) from the context."""
    sub = ctx.get("subimage")
    if sub is None:
        return 1, (0, 0), None
    f = int(sub.factor)
    r0, c0 = int(sub.origin[0]) * f, int(sub.origin[1]) * f
    h, w = sub.size
    return f, (r0, c0), (r0 + h * f / 2.0, c0 + w * f / 2.0)


def _run_colour(image, p, ledger, ctx, stage):
    from flightsw.ip.colour import colour
    res = colour(image, p.diagonal, ledger, stage)
    ctx["colour"] = res
    return StageOutput(res.labels, data=res, forward=image)


def _run_features(image, p, ledger, ctx, stage):
    from flightsw.ip.colour import colour
    from flightsw.ip.features import features_words, normalise_words
    res = ctx.get("colour")
    if res is None:                     # no colouring step: colour with the default flag
        res = colour(image, True, ledger, "colour")
        ctx["colour"] = res
    raw, _ = features_words(res.sums, p.intensity_centroid, ledger, stage)
    f, origin, _ = _window_geometry(ctx)
    words, _ = normalise_words(raw, f, origin, ctx.get("imager", "wfov_vis"), ledger, stage)
    ctx["feature_words"] = words
    return StageOutput(res.labels, data=words_to_struct(words), forward=image)


def _run_rank(image, p, ledger, ctx, stage):
    from flightsw.ip.rank import rank_words
    record = p.record if p.record is not None else ctx.get("record")
    if record is None:
        raise ValueError("rank step: no record (give record = ... in the step or to process_frame)")
    words = ctx.get("feature_words")
    if words is None:
        _run_features(image, FeatureParams(), ledger, ctx, "features")
        words = ctx["feature_words"]
    _, _, centre = _window_geometry(ctx)
    mean = ctx.get("centroid_mean", centre)
    res = rank_words(words, record, mean, ledger, p.max_candidates, stage)
    ctx["rank"] = res
    labels = ctx["colour"].labels
    ranked = np.zeros_like(labels)
    for q, k in enumerate(res.order):          # stage image: blobs numbered by rank (1 = best)
        ranked[labels == k + 1] = q + 1
    return StageOutput(ranked, data=res, forward=image)


for _op in ("colour", "label"):
    register_step(_op, _validate_colour, _run_colour, phase=PHASE_LABEL, unique=True,
                  label=lambda p: "colour", replace=True)
register_step("features", _validate_features, _run_features, phase=PHASE_FEATURES, unique=True,
              replace=True)
register_step("rank", _validate_rank, _run_rank, phase=PHASE_RANK, unique=True, replace=True)


# ================================================================================================
# process_frame
# ================================================================================================
@dataclass
class FrameResult:
    """What :func:`process_frame` returns.

    Attributes
    ----------
    message : CandidateMessage
    stages : list of flightsw.ip.sequence.Stage
        ``window``, every front-end step's output, then ``colour`` (label image), ``rank`` (blobs
        numbered by rank, 1 = best) -- the panels of the paper's Figure 3.
    ledger : Ledger
    backend : BackendResult
    subimage : flightsw.ip.preprocess.Subimage
    """

    message: CandidateMessage
    stages: list
    ledger: Ledger
    backend: BackendResult
    subimage: object = None
    context: dict = field(default_factory=dict)

    def __iter__(self):                         # message, stages, ledger = process_frame(...)
        return iter((self.message, self.stages, self.ledger))


def _frame_parts(frame):
    """ndarray, or an object with the pixels in .image/.pixels/.data and optional .t/.time_tag,
    .imager, .frame_count/.index."""
    if isinstance(frame, np.ndarray):
        return frame, {}
    for name in ("image", "pixels", "data", "frame"):
        img = getattr(frame, name, None)
        if isinstance(img, np.ndarray):
            break
    else:
        raise ValueError(f"frame must be an ndarray or carry one in .image/.pixels/.data, got "
                         f"{type(frame).__name__}")
    meta = {}
    for key, names in (("time_tag", ("time_tag", "t")), ("imager", ("imager", "imager_id")),
                       ("frame_count", ("frame_count", "index", "frame_index"))):
        for n in names:
            if getattr(frame, n, None) is not None:
                meta[key] = getattr(frame, n)
                break
    return img, meta


def check_inputs(alpha_q12, time_tag: float) -> None:
    """The scalar inputs every IP entry point takes with a frame: ``alpha_q12`` None or a Q4.12
    word 0..32767, and a finite time tag; ValueError naming the input otherwise."""
    if alpha_q12 is not None and (isinstance(alpha_q12, bool) or not isinstance(
            alpha_q12, (int, np.integer)) or not 0 <= int(alpha_q12) <= 32767):
        raise ValueError(f"alpha_q12={alpha_q12!r}: must be a Q4.12 word 0..32767 (alpha 0..7.99975)")
    if not math.isfinite(time_tag):
        raise ValueError(f"time_tag={time_tag!r}: must be a finite number of seconds")


def process_frame(frame, sequence, record, feedback: Feedback | None = None, *,
                  ledger: Ledger | None = None, imager: str | None = None,
                  frame_count: int | None = None, time_tag: float | None = None,
                  alpha_q12: int | None = None, check: bool = True,
                  want_stages: bool = True) -> FrameResult:
    """One frame through the IP: preprocess, the sequence's front-end steps, colour, features,
    ranking, and the candidate message.

    Parameters
    ----------
    frame : ndarray [244, 256] uint16 (12-bit counts), or an object carrying one (``.image`` ...)
        with optional ``.t``/``.time_tag``, ``.imager``, ``.frame_count``.
    sequence : flightsw.ip.sequence.ProcessingSequence
        The uplinked sequence. Its back-end steps (``colour``/``label`` with ``diagonal``,
        ``features`` with ``intensity_centroid``, ``rank`` with optional ``record``) set the flags;
        absent ones run with their defaults (diagonal on, intensity centroids, ``record``).
    record : flightsw.records.Record
        The a priori record in force (a ``record`` in the sequence's rank step overrides it).
    feedback : Feedback, optional
        The TP's predicted object pixel (full resolution; NaN if none), type and lock: centres the
        window and replaces the record's centroid means; without a prediction the window is the
        image centre and the means are the window centre.
    ledger : Ledger, optional
        Charged by every stage (a new one if None).
    imager, frame_count, time_tag : optional
        Message header values (override the frame object's).
    alpha_q12 : int, optional
        Alpha from the onboard AlphaController (Q4.12), overriding the sequence's threshold alpha.
    want_stages : bool
        Keep the stage images (False: only the message; the label image is not formed).

    Returns
    -------
    FrameResult (iterates as ``message, stages, ledger``)
    """
    if not isinstance(sequence, ProcessingSequence):
        raise ValueError(f"sequence must be a ProcessingSequence, got {type(sequence).__name__}")
    if not isinstance(record, _record_class()):
        raise ValueError(f"record must be a flightsw.records.Record, got {type(record).__name__}")
    if feedback is not None and not isinstance(feedback, Feedback):
        raise ValueError(f"feedback must be a flightsw.messages.Feedback, got "
                         f"{type(feedback).__name__}")
    img, meta = _frame_parts(frame)
    imager = imager if imager is not None else str(meta.get("imager", "wfov_vis"))
    frame_count = int(frame_count if frame_count is not None else meta.get("frame_count", 0)) & 0xFFFF
    time_tag = float(time_tag if time_tag is not None else meta.get("time_tag", 0.0))
    check_inputs(alpha_q12, time_tag)
    img = sequence.checked_frame(img, check)          # one frame check for both paths
    check = False
    ledger = Ledger() if ledger is None else ledger
    pred = None
    if feedback is not None and feedback.has_prediction:
        pred = (float(feedback.predicted_row), float(feedback.predicted_col))
    if not want_stages and sequence.fusable:
        # hot path: front end and back end in one jitted call (bit-identical to the steps, tested)
        return _process_fused(img, sequence, record, pred, ledger, imager, frame_count, time_tag,
                              alpha_q12, check)
    sub = sequence.window(img, pred, ledger, check=check)
    return process_window(sub, sequence, record, pred, ledger=ledger, imager=imager,
                          frame_count=frame_count, time_tag=time_tag, alpha_q12=alpha_q12,
                          want_stages=want_stages)


def process_window(sub, sequence, record, centroid_mean=None, *, ledger: Ledger | None = None,
                   imager: str = "wfov_vis", frame_count: int = 0, time_tag: float = 0.0,
                   alpha_q12: int | None = None, want_stages: bool = True,
                   max_candidates: int | None = None) -> FrameResult:
    """The part of :func:`process_frame` after the preprocessor, on a given ``Subimage`` ``sub``
    (used by the ground's full-frame mode, which cuts its own windows). ``centroid_mean`` (full-res
    (row, col)) replaces the record's centroid means; None: the window centre."""
    ledger = Ledger() if ledger is None else ledger
    pred = centroid_mean
    ctx = {"subimage": sub, "preprocess": sequence.preprocess, "imager": imager, "record": record}
    if alpha_q12 is not None:
        ctx["alpha_q12"] = int(alpha_q12)
    # ---- front end through the registry ----
    x = sub.image
    stages = [Stage("window", x)] if want_stages else []
    for st in sequence.steps:
        if STEP_REGISTRY[st.op].phase < PHASE_LABEL:
            out = STEP_REGISTRY[st.op].runner(x, st.params, ledger, ctx, st.stage)
            if isinstance(out, StageOutput):
                if want_stages:
                    stages.append(Stage(st.stage, out.image, out.data))
                x = out.image if out.forward is None else out.forward
            else:
                if want_stages:
                    stages.append(Stage(st.stage, out))
                x = out
    return _back_end(sub, x, ctx, sequence, record, pred, ledger, imager, frame_count, time_tag,
                     want_stages, stages, max_candidates)


def _backend_params(sequence):
    """(ColourParams, FeatureParams, RankParams) of a sequence's back-end steps (defaults for the
    absent ones), computed once per sequence."""
    bp = sequence.__dict__.get("_backend_params")
    if bp is None:
        colour_p, feat_p, rank_p = ColourParams(), FeatureParams(), RankParams()
        for st in sequence.steps:
            if st.op in ("colour", "label"):
                colour_p = st.params
            elif st.op == "features":
                feat_p = st.params
            elif st.op == "rank":
                rank_p = st.params
            elif STEP_REGISTRY[st.op].phase >= PHASE_LABEL:
                raise ValueError(f"process_frame: step {st.op!r} is not a front-end or back-end "
                                 f"step")
        bp = (colour_p, feat_p, rank_p)
        sequence.__dict__["_backend_params"] = bp
    return bp


@njit(cache=True)
def _frame_kernel(frame, compaction, r0, c0, h, w, ops, kbuf, ksz, tbuf, aq, mode, rec, prm, r0w,
                  c0w, mean_row, mean_col):
    """:func:`flightsw.ip.sequence._front_fast_k` then :func:`_backend_kernel` (centroid means
    overridden) in one call: (window int16 [h, w], pack, then the header words the host reads:
    count, m, flags, the colour, features and rank cycles, the range flag, and the threshold's t4,
    mean4, std4 and shift) -- a flat tuple boxes faster than a header slice turned into a list."""
    win, img, t4, m4, d4, s = _front_fast_k(frame, compaction, r0, c0, h, w, ops, kbuf, ksz, tbuf,
                                            aq, mode)
    _, pack = _backend_kernel(img, rec, prm, r0w, c0w, mean_row, mean_col, 1)
    return (win, pack, pack[0], pack[1], pack[2], pack[3], pack[4], pack[5], pack[21], t4, m4, d4,
            s)


class _FusedPlan:
    """Everything the fused frame path needs that does not change from frame to frame for one
    (sequence, record, imager): built on the first frame and kept on the sequence, so that a frame
    costs the jitted call plus the few objects of its result."""

    __slots__ = ("record", "rec", "recw", "prm", "f", "pre", "ops", "kbuf", "ksz", "tbuf", "mode",
                 "aq", "mode_name", "threshold", "keys", "front_cycles", "default",
                 "msg_imager", "record_id")

    def __init__(self, sequence, record, imager):
        fast = sequence._fast
        colour_p, feat_p, rank_p = _backend_params(sequence)
        rec = rank_p.record if rank_p.record is not None else record
        f = sequence.preprocess.compaction
        self.record, self.rec, self.f, self.pre = record, rec, f, sequence.preprocess
        self.prm = _static_params(rec, colour_p.diagonal, feat_p.intensity_centroid, False, f,
                                  imager, rank_p.max_candidates)
        self.recw = _record_words(rec)
        self.ops, self.kbuf, self.ksz, self.tbuf, self.mode = (fast.ops, fast.kbuf, fast.ksz,
                                                               fast.tbuf, fast.mode)
        self.aq, self.mode_name = fast.alpha_q12, fast.mode_name
        self.threshold = fast.threshold_stage is not None
        self.keys = fast.charge_keys + _BACK_KEYS
        self.front_cycles = fast.charge_cycles
        (h, w), (r0, c0) = sequence._default_window
        self.default = (h, w, r0, c0) + _geometry_words(f, r0, c0, h, w, None)
        self.msg_imager = imager if imager in _IMAGERS else "real"
        self.record_id = rec.record_id


def _geometry_words(f, r0, c0, h, w, pred):
    """(origin row, origin col (full-res pixels), then the 1750A words of the origin and of the
    centroid means: the prediction ``pred``, or the window centre if None)."""
    o0, o1 = r0 * f, c0 * f
    if pred is None:
        return (o0, o1) + _enc4(o0, o1, o0 + h * f / 2.0, o1 + w * f / 2.0)
    return (o0, o1) + _enc4(o0, o1, pred[0], pred[1])


def _fused_plan(sequence, record, imager):
    plans = sequence.__dict__.get("_fused_plans")
    if plans is None:
        plans = sequence.__dict__["_fused_plans"] = {}
    plan = plans.get((id(record), imager))
    if plan is None or plan.record is not record:
        plan = _FusedPlan(sequence, record, imager)
        if len(plans) > 64:
            plans.clear()
        plans[(id(record), imager)] = plan
    return plan


def _process_fused(img, sequence, record, pred, ledger, imager, frame_count, time_tag, alpha_q12,
                   check):
    """:func:`process_frame` without stage images for a sequence whose front end is fusable: the
    same words, context and cycles as the step path (tested), with one jitted call."""
    plan = _fused_plan(sequence, record, imager)
    frame = sequence.checked_frame(img, check)
    if pred is None:
        h, w, r0, c0, o0, o1, r0w, c0w, mr, mc = plan.default
    else:
        pre = plan.pre
        h, w = pre.window_shape
        r0, c0 = _window_origin(pre.compacted_shape, plan.f, pred, pre.window)
        o0, o1, r0w, c0w, mr, mc = _geometry_words(plan.f, r0, c0, h, w, pred)
    aq = plan.aq if alpha_q12 is None else int(alpha_q12)
    f = plan.f
    win, pack, count, m, flags, c, fe, rk, bad, t4, m4, d4, s = _frame_kernel(
        frame, f, r0, c0, h, w, plan.ops, plan.kbuf, plan.ksz, plan.tbuf, aq, plan.mode, plan.recw,
        plan.prm, r0w, c0w, mr, mc)
    if bad:
        raise ValueError("window holds values outside the 16-bit word range -32768..65535")
    sub = _new_subimage(win, (r0, c0), f, (h, w))
    ctx = {"imager": imager, "record": record, "subimage": sub, "preprocess": plan.pre}
    if plan.threshold:
        ctx["threshold"] = {"t4": t4, "mean4": m4, "std4": d4, "shift": s, "alpha_q12": aq,
                            "mode": plan.mode_name}
        alpha = aq / 4096.0
    else:
        alpha = 0.0
    _charge(ledger, plan.keys, plan.front_cycles + (c, fe, rk))    # the front end's cycles first
    be = BackendResult(_NO_LABELS, pack, count, m, flags, (c, fe, rk))
    # positional, in the field order (frame_count, time_tag, imager, compaction, window_row0,
    # window_col0, window_rows, window_cols, alpha, record_id, candidates): a third of the time of
    # the keyword form, on the per-frame path
    msg = CandidateMessage(frame_count, time_tag, plan.msg_imager, f, o0, o1, h, w, alpha,
                           plan.record_id, be.candidates())
    return FrameResult(msg, [], ledger, be, sub, ctx)


_NO_LABELS = np.zeros((0, 0), np.int32)


def _message(be, rec, ctx, sub, f, origin, imager, frame_count, time_tag):
    """The candidate message of a frame (the stages path; :func:`_process_fused` builds it the same
    way from its plan)."""
    th = ctx.get("threshold")
    h, w = sub.size
    return CandidateMessage(frame_count, time_tag, imager if imager in _IMAGERS else "real", f,
                            origin[0], origin[1], int(h), int(w),
                            th["alpha_q12"] / 4096.0 if th else 0.0, rec.record_id,
                            be.candidates())


def _back_end(sub, x, ctx, sequence, record, pred, ledger, imager, frame_count, time_tag,
              want_stages, stages, max_candidates):
    """The back end (one jitted call) and the message, after the front end forwarded ``x``."""
    colour_p, feat_p, rank_p = _backend_params(sequence)
    rec = rank_p.record if rank_p.record is not None else record
    f, origin, centre = _window_geometry(ctx)
    mean = pred if pred is not None else centre
    be = backend(x, rec, colour_p.diagonal, feat_p.intensity_centroid, f, origin, imager, mean,
                 ledger, want_stages,
                 rank_p.max_candidates if max_candidates is None else max_candidates)
    if want_stages:
        stages.append(Stage("colour", be.labels, be.count))
        ranked = np.zeros_like(be.labels)
        if len(be.order):
            lut = np.zeros(be.count + 1, np.int32)
            lut[be.order + 1] = np.arange(1, len(be.order) + 1)
            ranked = lut[be.labels]
        stages.append(Stage("rank", ranked, be.order))
    msg = _message(be, rec, ctx, sub, f, origin, imager, frame_count, time_tag)
    return FrameResult(msg, stages, ledger, be, sub, ctx)


from flightsw.messages import IMAGER_CODES as _IMAGERS  # noqa: E402
