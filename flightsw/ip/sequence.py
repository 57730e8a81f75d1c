"""IP steps 1-5 (and, through the registry, 6-8): the uplinkable processing sequence.

The MSX paper: the toolbox routines "can be selected and sequenced to provide the overall processing
algorithm via uplink command before a tracking event". A :class:`ProcessingSequence` is the validated
form of such an uplink: the preprocessor settings plus an ordered list of steps with parameters,
loadable from TOML::

    name = "satellite"
    [preprocess]
    compaction = 1          # 1, 2 or 4
    window = 64             # window size in compacted pixels
    [[steps]]
    op = "filter"           # spatial 3x3/5x5/7x7, Q1.15
    kernel = "smooth"       # "smooth" | "matched" | "custom" (then coefficients = [[Q1.15 words]])
    size = 3
    [[steps]]
    op = "detrend"
    method = "highpass"     # "highpass" (sigma = 1.5 or taps = [7 Q1.15 words]) | "polynomial" | "none"
    [[steps]]
    op = "filter"
    kernel = "matched"
    size = 3
    [[steps]]
    op = "threshold"
    alpha = 3.0             # 0 .. 7.99975 (Q4.12)
    mode = "binarize"       # | "clip"

The frequency-domain filter (the paper's slow path, :mod:`flightsw.ip.fftfilter`) is its own op, so
the spatial ``filter`` keeps rejecting anything but 3/5/7::

    [[steps]]
    op = "filter_fft"
    kernel = "gaussian"     # "gaussian" (sigma, default size/6) | "matched" | "smooth" (3/5/7) | "custom"
    size = 15               # odd, 3..63
    tile = 32               # optional FFT tile 16 | 32 | 64 (default: the cheaper that fits DM)

Ordering rules (what the paper allows): filters and detrenders in any order and number (a filter
"before detrending for noise smoothing ... after detrending to help compensate for any artifacts"),
any of them may be skipped; at most one threshold, after every front-end step; the back-end steps
(blob colouring, features, ranking) after the threshold in their phase order. Each registered step
has a *phase*; a sequence's phases must not decrease, and a ``unique`` step may appear once.

Step registry (for the back end, issue 4)
-----------------------------------------
``register_step(name, validator, runner, phase=..., unique=..., label=...)``:

* ``validator(params: dict, pre: Preprocess) -> object``: the step's TOML table without ``op``; return
  the validated parameters (any object; it is handed to the runner). Raise :class:`FieldError` (names
  the field) or ``ValueError`` to reject; the sequence reports ``step <i> '<op>': field '<f>': ...``.
* ``runner(image, params, ledger, context, stage) -> ndarray | StageOutput``: ``image`` is the image
  the previous step forwarded (the window for the first step), ``ledger`` a
  :class:`flightsw.budget.Ledger` or None, ``context`` a dict shared by the steps of one run (keys set
  here: ``"subimage"``, ``"preprocess"``, ``"threshold"``; callers may pass ``"alpha_q12"`` from the
  :class:`~flightsw.ip.threshold.AlphaController`), ``stage`` the unique ledger stage name of this
  step in this sequence. Return the output image, or a :class:`StageOutput` to also pass data and/or
  forward a different image to the next step (e.g. labelling shows the label image but forwards the
  thresholded one).
* ``label(params) -> str``: the stage name (default: the op name); repeated names get ``#2``...

Phases: :data:`PHASE_FRONT` (filter, detrend) < :data:`PHASE_THRESHOLD` < :data:`PHASE_LABEL` <
:data:`PHASE_FEATURES` < :data:`PHASE_RANK`.

An :class:`IPConfig` holds the sequence in force: ``load_sequence`` validates a new one and, when it
is invalid, raises :class:`SequenceError` and keeps the previous sequence.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numba import njit

import flightsw.ip.detrend as _dt
import flightsw.ip.fftfilter as _fft
import flightsw.ip.filters as _flt
import flightsw.ip.threshold as _th
from flightsw.ip.preprocess import (COMPACTION_FACTORS, FRAME_SHAPE, Subimage, _check_frame,
                                    _compact_k, _new_subimage, preprocess, window_origin,
                                    window_shape)

__all__ = ["ProcessingSequence", "IPConfig", "SequenceError", "FieldError", "StepType", "Step",
           "Stage", "StageOutput", "SequenceResult", "Preprocess", "register_step", "STEP_REGISTRY",
           "PHASE_FRONT", "PHASE_THRESHOLD", "PHASE_LABEL", "PHASE_FEATURES", "PHASE_RANK",
           "SEQUENCE_DIR", "load_default_sequence", "DEFAULT_SEQUENCES"]

PHASE_FRONT, PHASE_THRESHOLD, PHASE_LABEL, PHASE_FEATURES, PHASE_RANK = 0, 10, 20, 30, 40
SEQUENCE_DIR = Path(__file__).resolve().parents[1] / "data"
DEFAULT_SEQUENCES = {"satellite": "sequence_satellite.toml", "aurora": "sequence_aurora.toml",
                     "satellite_c2": "sequence_satellite_c2.toml",
                     "aurora_track": "sequence_aurora_track.toml", "star": "sequence_star.toml",
                     "streak": "sequence_streak.toml"}


class SequenceError(ValueError):
    """An invalid processing sequence; ``step`` (index), ``op`` and ``field`` say where."""

    def __init__(self, message, step=None, op=None, field=None):
        where = []
        if step is not None:
            where.append(f"step {step}" + (f" {op!r}" if op is not None else ""))
        elif op is not None:
            where.append(str(op))
        if field is not None:
            where.append(f"field {field!r}")
        super().__init__(": ".join(where + [str(message)]))
        self.step, self.op, self.field, self.reason = step, op, field, str(message)


class FieldError(ValueError):
    """Raised by step validators to name the offending field."""

    def __init__(self, field, message):
        super().__init__(message)
        self.field = field


@dataclass(frozen=True)
class Preprocess:
    """Preprocessor board settings: compaction factor and window size (compacted pixels)."""

    compaction: int = 1
    window: int = 64
    frame_shape: tuple = FRAME_SHAPE

    @property
    def compacted_shape(self):
        return self.frame_shape[0] // self.compaction, self.frame_shape[1] // self.compaction

    @property
    def window_shape(self):
        return window_shape(self.compacted_shape, self.window)


@dataclass(frozen=True)
class StepType:
    name: str
    validator: Callable
    runner: Callable
    phase: int = PHASE_FRONT
    unique: bool = False
    label: Callable | None = None


STEP_REGISTRY: dict[str, StepType] = {}


def register_step(name, validator, runner, *, phase=PHASE_FRONT, unique=False, label=None,
                  replace=False):
    """Register a toolbox step under ``name`` (see the module docstring for the interface)."""
    if not isinstance(name, str) or not name:
        raise ValueError("step name must be a non-empty string")
    if name in STEP_REGISTRY and not replace:
        raise ValueError(f"step {name!r} is already registered (pass replace=True)")
    STEP_REGISTRY[name] = StepType(name, validator, runner, phase, unique, label)
    return STEP_REGISTRY[name]


@dataclass(frozen=True)
class Step:
    op: str
    params: Any
    raw: dict
    stage: str


@dataclass
class StageOutput:
    """What a runner may return instead of a bare image."""

    image: Any
    data: Any = None
    forward: Any = None          # image for the next step (default: ``image``)


@dataclass
class Stage:
    """One panel of the paper's Figure 3: the stage name, its output image and any data."""

    name: str
    image: Any
    data: Any = None


@dataclass
class SequenceResult:
    subimage: Subimage
    stages: list
    context: dict
    image: Any                   # the image the last step forwarded

    def images(self):
        """``[(stage name, image)]`` in order, starting with the window."""
        return [(s.name, s.image) for s in self.stages]


# ---------------------------------------------------------------------------------------------
# validation helpers
# ---------------------------------------------------------------------------------------------
def _fields(params, allowed):
    extra = sorted(set(params) - set(allowed))
    if extra:
        raise FieldError(extra[0], f"unknown field (allowed: {sorted(allowed)})")


def _int_field(params, name, default, lo=None, hi=None, choices=None):
    v = params.get(name, default)
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
        raise FieldError(name, f"{v!r} is not an integer")
    v = int(v)
    if choices is not None and v not in choices:
        raise FieldError(name, f"{v} is not one of {', '.join(map(str, choices))}")
    if (lo is not None and v < lo) or (hi is not None and v > hi):
        raise FieldError(name, f"{v} out of range {lo}..{hi}")
    return v


def _float_field(params, name, default, lo, hi):
    v = params.get(name, default)
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise FieldError(name, f"{v!r} is not a number")
    v = float(v)
    if not lo <= v <= hi:
        raise FieldError(name, f"{v} out of range {lo} .. {hi:.5g}")
    return v


def _choice(params, name, default, choices):
    v = params.get(name, default)
    if v not in choices:
        raise FieldError(name, f"{v!r} is not one of {', '.join(map(repr, choices))}")
    return v


# ---------------------------------------------------------------------------------------------
# built-in front-end steps
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FilterParams:
    kernel: np.ndarray = field(repr=False)     # int16 Q1.15 words
    name: str = "smooth"


def _validate_filter(params, pre):
    _fields(params, {"kernel", "size", "sigma", "coefficients"})
    kind = _choice(params, "kernel", "smooth", ("smooth", "matched", "custom"))
    if kind == "custom":
        if "coefficients" not in params:
            raise FieldError("coefficients", "a custom kernel needs coefficients (Q1.15 words)")
        try:
            k = _flt.validate_kernel(params["coefficients"])
        except ValueError as exc:
            raise FieldError("coefficients", str(exc).removeprefix("coefficients: ")) from None
        if "size" in params and params["size"] != k.shape[0]:
            raise FieldError("size", f"{params['size']!r} does not match the {k.shape[0]}x"
                                     f"{k.shape[0]} coefficients")
        return FilterParams(k, "custom")
    if "coefficients" in params:
        raise FieldError("coefficients", f"only allowed with kernel = 'custom', not {kind!r}")
    try:
        size = _int_field(params, "size", 3, choices=_flt.SPATIAL_SIZES)
    except FieldError as exc:
        raise FieldError("size", f"{exc} (the spatial path; larger kernels: op = 'filter_fft')") \
            from None
    if kind == "matched":
        sigma = _float_field(params, "sigma", 1.0, 0.3, 5.0)
        return FilterParams(_flt.matched_kernel(size, sigma), "matched")
    if "sigma" in params:
        raise FieldError("sigma", "the smoothing kernel is the fixed binomial; no sigma")
    return FilterParams(_flt.smoothing_kernel(size), "smooth")


def _words(image):
    if image.dtype != np.int16 or not image.flags.c_contiguous:
        image = _flt._as_words(image)
    return image


def _run_filter(image, p, ledger, context, stage):
    image = _words(image)
    out = _flt.correlate_q15_k(image, p.kernel)
    if ledger is not None:
        ledger.charge("dsp", stage, _flt.filter_cycles(image.shape[0], image.shape[1],
                                                       p.kernel.shape[0]))
    return out


def _label_filter(p):
    k = p.kernel.shape[0]
    return f"filter{k}x{k}_{p.name}"


@dataclass(frozen=True)
class FilterFFTParams:
    kernel: Any = field(repr=False)            # flightsw.ip.fftfilter.FFTKernel
    name: str = "gaussian"


def _validate_filter_fft(params, pre):
    """The frequency-domain filter (the paper's slow path): any odd kernel 3..63, usually > 7x7."""
    _fields(params, {"kernel", "size", "sigma", "coefficients", "tile"})
    kind = _choice(params, "kernel", "gaussian", ("gaussian", "matched", "smooth", "custom"))
    if kind == "custom":
        if "coefficients" not in params:
            raise FieldError("coefficients", "a custom kernel needs coefficients (Q1.15 words)")
        try:
            k = np.asarray(params["coefficients"])
        except Exception as exc:  # ragged lists
            raise FieldError("coefficients", f"not a rectangular array ({exc})") from None
        if k.dtype == object or k.ndim != 2 or k.shape[0] != k.shape[1] or k.shape[0] % 2 == 0 \
                or not 3 <= k.shape[0] <= _fft.MAX_FFT_KERNEL:
            raise FieldError("coefficients", f"kernel shape {k.shape} must be square with an odd "
                                             f"size 3..{_fft.MAX_FFT_KERNEL}")
        if not np.issubdtype(k.dtype, np.integer) or k.min() < -32768 or k.max() > 32767:
            raise FieldError("coefficients", "must be integer Q1.15 words -32768..32767")
        if "size" in params and params["size"] != k.shape[0]:
            raise FieldError("size", f"{params['size']!r} does not match the {k.shape[0]}x"
                                     f"{k.shape[0]} coefficients")
        taps = k.astype(np.int16)
    else:
        if "coefficients" in params:
            raise FieldError("coefficients", f"only allowed with kernel = 'custom', not {kind!r}")
        size = _int_field(params, "size", 9, lo=3, hi=_fft.MAX_FFT_KERNEL)
        if size % 2 == 0:
            raise FieldError("size", f"{size} is not odd")
        if kind == "smooth":
            if "sigma" in params:
                raise FieldError("sigma", "the smoothing kernel is the fixed binomial; no sigma")
            if size not in _flt.SPATIAL_SIZES:
                raise FieldError("size", f"the binomial smoothing kernel exists for 3, 5, 7; use "
                                         f"kernel = 'gaussian' for {size}x{size}")
            taps = _flt.smoothing_kernel(size)
        elif kind == "matched":
            sigma = _float_field(params, "sigma", 1.0, 0.3, 16.0)
            taps = _flt.matched_kernel_any(size, sigma)
        else:
            sigma = _float_field(params, "sigma", size / 6.0, 0.3, 32.0)
            try:
                taps = _fft.gaussian_kernel_q15(size, sigma)
            except ValueError as exc:
                raise FieldError("sigma", str(exc)) from None
    k = taps.shape[0]
    h, w = pre.window_shape
    if "tile" in params:
        tile = _int_field(params, "tile", None, choices=_fft.FFT_TILES)
        if tile <= k:
            raise FieldError("tile", f"a {k}x{k} kernel needs an FFT tile larger than {tile}")
    else:
        tile = _fft.choose_tile(h, w, k) or _fft.choose_tile(h, w, k, _fft.FFT_TILES)
        if tile is None:
            raise FieldError("size", f"no FFT tile fits a {k}x{k} kernel")
    return FilterFFTParams(_fft.fft_kernel(taps, tile), kind)


def _run_filter_fft(image, p, ledger, context, stage):
    return _fft.fft_correlate(_words(image), p.kernel, ledger=ledger, stage=stage)


def _label_filter_fft(p):
    k = p.kernel.size
    return f"filter_fft{k}x{k}_{p.name}"


@dataclass(frozen=True)
class DetrendParams:
    method: str
    taps: Any = field(default=None, repr=False)


def _validate_detrend(params, pre):
    _fields(params, {"method", "sigma", "taps"})
    method = _choice(params, "method", "highpass", ("highpass", "polynomial", "none"))
    if method != "highpass":
        for f in ("sigma", "taps"):
            if f in params:
                raise FieldError(f, f"only allowed with method = 'highpass', not {method!r}")
        return DetrendParams(method)
    if "taps" in params:
        if "sigma" in params:
            raise FieldError("sigma", "give sigma or taps, not both")
        try:
            taps = _dt._check_taps(params["taps"])
        except (ValueError, TypeError) as exc:
            raise FieldError("taps", str(exc)) from None
    else:
        sigma = _float_field(params, "sigma", _dt.DEFAULT_HIGHPASS_SIGMA, 0.5, 3.0)
        taps = _dt._default_taps_cached(sigma)
    return DetrendParams("highpass", taps)


def _run_detrend(image, p, ledger, context, stage):
    if p.method == "highpass":
        image = _words(image)
        out = _dt._highpass_k(image, p.taps, _dt.G_MAX)
        if ledger is not None:
            ledger.charge("dsp", stage, _dt.highpass_cycles(image.shape[0], image.shape[1]))
        return out
    if p.method == "polynomial":
        return _dt.detrend_polynomial(image, ledger, stage)
    return _dt.detrend_none(image, ledger, stage)


@dataclass(frozen=True)
class ThresholdParams:
    alpha_q12: int
    mode: str


def _validate_threshold(params, pre):
    _fields(params, {"alpha", "mode"})
    if "alpha" not in params:
        raise FieldError("alpha", "missing (0 .. 7.99975)")
    alpha = _float_field(params, "alpha", None, _th.ALPHA_MIN, _th.ALPHA_MAX)
    mode = _choice(params, "mode", "binarize", ("binarize", "clip"))
    h, w = pre.window_shape
    if h * w > 16384:
        raise FieldError("alpha", f"the threshold statistics support windows up to 128x128, the "
                                  f"sequence's window is {h}x{w}")
    return ThresholdParams(_th.alpha_to_q12(alpha), mode)


def _run_threshold(image, p, ledger, context, stage):
    aq = context.get("alpha_q12", p.alpha_q12)
    image = _words(image)
    out, t4, m4, d4, s = _th.threshold_k(image, aq, _th.BINARIZE if p.mode == "binarize"
                                         else _th.CLIP)
    if ledger is not None:
        ledger.charge("dsp", stage, _th.threshold_cycles(image.shape[0], image.shape[1]))
    context["threshold"] = {"t4": t4, "mean4": m4, "std4": d4, "shift": s, "alpha_q12": aq,
                            "mode": p.mode}
    return StageOutput(out, t4)


register_step("filter", _validate_filter, _run_filter, phase=PHASE_FRONT, label=_label_filter)
register_step("filter_fft", _validate_filter_fft, _run_filter_fft, phase=PHASE_FRONT,
              label=_label_filter_fft)
register_step("detrend", _validate_detrend, _run_detrend, phase=PHASE_FRONT,
              label=lambda p: f"detrend_{p.method}")
register_step("threshold", _validate_threshold, _run_threshold, phase=PHASE_THRESHOLD, unique=True)


# ---------------------------------------------------------------------------------------------
# the fused front end: a validated sequence's front-end steps in one jitted call
# ---------------------------------------------------------------------------------------------
OP_FILTER, OP_HIGHPASS, OP_NONE, OP_THRESHOLD = 1, 2, 3, 4


@njit(cache=True)
def _front_fast_k(frame, f, r0, c0, h, w, ops, kbuf, ksz, tbuf, alpha_q12, mode):
    """Compaction + window, then the ops (``ops[i]``: OP_FILTER with the ``ksz[i]``-square kernel
    ``kbuf[i]``, OP_HIGHPASS with the taps ``tbuf[i]``, OP_NONE, OP_THRESHOLD). The very kernels of
    the step-by-step path, called in the same order on the same words: bit-identical results.
    Returns (window, image, t4, m4, d4, s)."""
    win = _compact_k(frame, f, r0, c0, h, w)
    img = win
    t4 = np.int64(0)
    m4 = np.int64(0)
    d4 = np.int64(0)
    sh = 0
    for i in range(ops.size):
        op = ops[i]
        if op == 1:
            k = ksz[i]
            img = _flt.correlate_q15_k(img, np.ascontiguousarray(kbuf[i, :k, :k]))
        elif op == 2:
            img = _dt._highpass_k(img, tbuf[i], _dt.G_MAX)
        elif op == 4:
            img, t4, m4, d4, sh = _th.threshold_k(img, alpha_q12, mode)
    return win, img, t4, m4, d4, sh


class _FastFront:
    """The arrays :func:`_front_fast_k` runs, built once per sequence (None if a front-end step has
    no fused form, e.g. the polynomial detrender or ``filter_fft``: those sequences run step by
    step)."""

    __slots__ = ("ops", "kbuf", "ksz", "tbuf", "alpha_q12", "mode", "mode_name", "charge_keys",
                 "charge_cycles", "threshold_stage")

    @classmethod
    def build(cls, steps, pre):
        ops, kb, ks, tb = [], [], [], []
        self = cls()
        self.alpha_q12, self.mode, self.mode_name, self.threshold_stage = 0, 0, "binarize", None
        h, w = pre.window_shape
        cycles = [("compaction", 0)]               # (stage, DSP cycles), in charge order
        zk, zt = np.zeros((7, 7), np.int16), np.zeros(7, np.int16)
        for st in steps:
            if STEP_REGISTRY[st.op].phase >= PHASE_LABEL:
                continue
            p = st.params
            k, t = zk, zt
            if st.op == "filter" and isinstance(p, FilterParams):
                op = OP_FILTER
                n = p.kernel.shape[0]
                k = np.zeros((7, 7), np.int16)
                k[:n, :n] = p.kernel
                cyc = _flt.filter_cycles(h, w, n)
                ks.append(n)
            elif st.op == "detrend" and isinstance(p, DetrendParams) and p.method == "highpass":
                op, t, cyc = OP_HIGHPASS, np.asarray(p.taps, np.int16), _dt.highpass_cycles(h, w)
                ks.append(0)
            elif st.op == "detrend" and isinstance(p, DetrendParams) and p.method == "none":
                op, cyc = OP_NONE, 0
                ks.append(0)
            elif st.op == "threshold" and isinstance(p, ThresholdParams):
                op, cyc = OP_THRESHOLD, _th.threshold_cycles(h, w)
                self.alpha_q12, self.mode_name = p.alpha_q12, p.mode
                self.mode = _th.BINARIZE if p.mode == "binarize" else _th.CLIP
                self.threshold_stage = st.stage
                ks.append(0)
            else:
                return None
            ops.append(op)
            kb.append(k)
            tb.append(t)
            cycles.append((st.stage, int(cyc)))
        self.charge_keys = tuple(("dsp", stage) for stage, _ in cycles)
        self.charge_cycles = tuple(c for _, c in cycles)
        n = len(ops)
        self.ops = np.array(ops, np.int64)
        self.kbuf = np.stack(kb) if n else np.zeros((0, 7, 7), np.int16)
        self.ksz = np.array(ks, np.int64)
        self.tbuf = np.stack(tb) if n else np.zeros((0, 7), np.int16)
        return self


# ---------------------------------------------------------------------------------------------
# the sequence
# ---------------------------------------------------------------------------------------------
def _validate_preprocess(d):
    if not isinstance(d, dict):
        raise SequenceError("must be a table", op="preprocess")
    extra = sorted(set(d) - {"compaction", "window"})
    if extra:
        raise SequenceError("unknown field", op="preprocess", field=extra[0])
    try:
        c = _int_field(d, "compaction", 1, choices=COMPACTION_FACTORS)
        w = _int_field(d, "window", 64, lo=8)
    except FieldError as exc:
        raise SequenceError(str(exc), op="preprocess", field=exc.field) from None
    pre = Preprocess(c, w)
    H, W = pre.compacted_shape
    if w > H and w > W:
        raise SequenceError(f"window {w} is larger than the compacted image {H}x{W} "
                            f"(compaction {c})", op="preprocess", field="window")
    return pre


class ProcessingSequence:
    """A validated, ordered list of toolbox steps plus the preprocessor settings.

    Parameters
    ----------
    steps : list of dict
        Each ``{"op": name, **params}`` (the TOML ``[[steps]]`` tables).
    preprocess : dict or Preprocess, optional
        ``{"compaction": 1|2|4, "window": 64}``.
    name : str

    Raises :class:`SequenceError` naming the step index, op and field of the first problem.
    """

    def __init__(self, steps, preprocess=None, name="", description=""):
        if isinstance(preprocess, Preprocess):
            pre = preprocess
        else:
            pre = _validate_preprocess({} if preprocess is None else preprocess)
        if not isinstance(steps, (list, tuple)):
            raise SequenceError("steps must be a list of tables")
        built, seen, last_phase, names = [], set(), None, {}
        for i, raw in enumerate(steps):
            if not isinstance(raw, dict):
                raise SequenceError("a step must be a table", step=i)
            op = raw.get("op")
            if not isinstance(op, str) or op not in STEP_REGISTRY:
                raise SequenceError(f"unknown step (known: {', '.join(sorted(STEP_REGISTRY))})",
                                    step=i, op=op, field="op")
            st = STEP_REGISTRY[op]
            if st.unique and op in seen:
                raise SequenceError("may appear only once in a sequence", step=i, op=op)
            if last_phase is not None and st.phase < last_phase:
                raise SequenceError(f"out of order: must come before the earlier steps of a later "
                                    f"phase ({st.phase} < {last_phase})", step=i, op=op)
            params = {k: v for k, v in raw.items() if k != "op"}
            try:
                vp = st.validator(params, pre)
            except FieldError as exc:
                raise SequenceError(str(exc), step=i, op=op, field=exc.field) from None
            except SequenceError:
                raise
            except (ValueError, TypeError, KeyError, IndexError, OverflowError) as exc:
                raise SequenceError(str(exc), step=i, op=op) from None
            label = st.label(vp) if st.label else op
            names[label] = names.get(label, 0) + 1
            if names[label] > 1:
                label = f"{label}#{names[label]}"
            built.append(Step(op, vp, dict(raw), label))
            seen.add(op)
            last_phase = st.phase
        self.preprocess = pre
        self._default_window = (pre.window_shape,
                                window_origin(pre.compacted_shape, pre.compaction, None, pre.window))
        self._runners = tuple((STEP_REGISTRY[st.op].runner, st) for st in built)
        self._fast = _FastFront.build(built, pre)
        self.steps = tuple(built)
        self.name = str(name)
        self.description = str(description)

    # ---- construction ----------------------------------------------------------------------
    @classmethod
    def from_dict(cls, d):
        if not isinstance(d, dict):
            raise SequenceError("a sequence must be a table")
        extra = sorted(set(d) - {"name", "description", "preprocess", "steps"})
        if extra:
            raise SequenceError("unknown top-level field", field=extra[0])
        return cls(d.get("steps", []), d.get("preprocess"), d.get("name", ""),
                   d.get("description", ""))

    @classmethod
    def from_toml(cls, path_or_text):
        """Load from a TOML file path or TOML text (text is recognised by a newline or ``=``).
        Errors from a file name the file."""
        src = None
        if isinstance(path_or_text, Path) or (isinstance(path_or_text, str)
                                              and "\n" not in path_or_text
                                              and "=" not in path_or_text):
            src = str(path_or_text)
            try:
                text = Path(path_or_text).read_text()
            except (OSError, ValueError) as exc:       # ValueError: undecodable, NUL in the path
                raise SequenceError(f"{src}: cannot read sequence file: {exc}") from None
        else:
            text = str(path_or_text)
        try:
            d = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SequenceError(f"{src + ': ' if src else ''}not valid TOML: {exc}") from None
        if not d.get("steps"):
            # a file without steps is a mistake (the window alone, no threshold, no blobs)
            raise SequenceError(f"{src + ': ' if src else ''}no [[steps]]: a sequence file needs at "
                                f"least a threshold step", field="steps")
        if src is None:
            return cls.from_dict(d)
        try:
            return cls.from_dict(d)
        except SequenceError as exc:
            err = SequenceError(f"{src}: {exc}")
            err.step, err.op, err.field, err.reason = exc.step, exc.op, exc.field, exc.reason
            raise err from None

    def to_dict(self):
        return {"name": self.name, "description": self.description,
                "preprocess": {"compaction": self.preprocess.compaction,
                               "window": self.preprocess.window},
                "steps": [dict(s.raw) for s in self.steps]}

    def __repr__(self):
        ops = ", ".join(s.stage for s in self.steps)
        return (f"ProcessingSequence({self.name!r}, compaction={self.preprocess.compaction}, "
                f"window={self.preprocess.window}, [{ops}])")

    # ---- running ---------------------------------------------------------------------------
    def window(self, frame, predicted_rowcol_fullres=None, ledger=None, check=True):
        """Preprocessor board: compaction + window (stage ``"compaction"``, 0 DSP cycles)."""
        pre = self.preprocess
        if check or predicted_rowcol_fullres is not None:
            sub = preprocess(frame, pre.compaction, predicted_rowcol_fullres, pre.window, check=check)
        else:                                   # hot path: default centre, shapes precomputed
            (h, w), (r0, c0) = self._default_window
            if frame.shape != pre.frame_shape or not frame.flags.c_contiguous:
                raise ValueError(f"frame must be a C-contiguous {pre.frame_shape} array")
            img = _compact_k(frame, pre.compaction, r0, c0, h, w)
            sub = Subimage(img, (r0, c0), pre.compaction, (h, w))
        if ledger is not None:
            ledger.charge("dsp", "compaction", 0)
        return sub

    def run(self, subimage, ledger=None, context=None):
        """Run the steps on a :class:`Subimage`; returns a :class:`SequenceResult` whose ``stages``
        are the window followed by every step's output image, in order."""
        ctx = {} if context is None else context
        ctx["subimage"] = subimage
        ctx["preprocess"] = self.preprocess
        img = subimage.image
        stages = [Stage("window", img)]
        for runner, st in self._runners:
            out = runner(img, st.params, ledger, ctx, st.stage)
            if isinstance(out, StageOutput):
                stages.append(Stage(st.stage, out.image, out.data))
                img = out.image if out.forward is None else out.forward
            else:
                stages.append(Stage(st.stage, out))
                img = out
        return SequenceResult(subimage, stages, ctx, img)

    def run_frame(self, frame, predicted_rowcol_fullres=None, ledger=None, context=None,
                  check=True):
        """Preprocess a full frame and run the steps."""
        sub = self.window(frame, predicted_rowcol_fullres, ledger, check)
        return self.run(sub, ledger, context)


    @property
    def fusable(self):
        """True when the front end runs as one jitted call (:meth:`run_frame_fast`)."""
        return self._fast is not None

    def run_frame_fast(self, frame, predicted_rowcol_fullres=None, ledger=None, context=None,
                       check=True):
        """The front end of :meth:`run_frame` (preprocessor and every step before the labelling)
        in one jitted call, without the intermediate stage images: ``(subimage, image, context)``,
        ``image`` bit-identical to ``run_frame(...).image`` up to the threshold (tested); the same
        cycles are charged and ``context["threshold"]`` is set the same way. Falls back to the
        step-by-step path when a step has no fused form (:attr:`fusable`)."""
        fast = self._fast
        ctx = {} if context is None else context
        if fast is None:
            front = ProcessingSequence(
                [st.raw for st in self.steps if STEP_REGISTRY[st.op].phase < PHASE_LABEL],
                self.preprocess, self.name) if any(STEP_REGISTRY[st.op].phase >= PHASE_LABEL
                                                   for st in self.steps) else self
            res = front.run_frame(frame, predicted_rowcol_fullres, ledger, ctx, check)
            return res.subimage, res.image, ctx
        frame, (h, w), (r0, c0) = self._fast_window(frame, predicted_rowcol_fullres, check)
        aq = ctx.get("alpha_q12", fast.alpha_q12)
        win, img, t4, m4, d4, s = _front_fast_k(frame, self.preprocess.compaction, r0, c0, h, w,
                                                fast.ops, fast.kbuf, fast.ksz, fast.tbuf, aq,
                                                fast.mode)
        sub = self._fast_finish(win, (r0, c0), (h, w), t4, m4, d4, s, aq, ledger, ctx)
        return sub, img, ctx

    def checked_frame(self, frame, check: bool = True):
        """The frame as both paths take it: a C-contiguous integer array of the sequence's frame
        shape (ValueError otherwise); with ``check``, also 12-bit counts 0..4095."""
        if check:
            frame = _check_frame(frame)
        if frame.shape != self.preprocess.frame_shape or frame.dtype.kind not in "ui":
            raise ValueError(f"frame must be a {self.preprocess.frame_shape} integer array, got "
                             f"{frame.dtype} {frame.shape}")
        if not frame.flags.c_contiguous:
            frame = np.ascontiguousarray(frame)
        return frame

    def _fast_window(self, frame, predicted_rowcol_fullres, check):
        """The fused path's checked frame, window shape and origin (compacted pixels)."""
        frame = self.checked_frame(frame, check)
        if predicted_rowcol_fullres is None:
            return (frame,) + self._default_window
        pre = self.preprocess
        return frame, pre.window_shape, window_origin(pre.compacted_shape, pre.compaction,
                                                      predicted_rowcol_fullres, pre.window)

    def _fast_finish(self, win, origin, size, t4, m4, d4, s, aq, ledger, ctx):
        """After the fused front end: the Subimage, ``ctx`` (subimage, preprocess, threshold) and
        the front end's cycles charged, as the step-by-step path does."""
        fast = self._fast
        sub = _new_subimage(win, origin, self.preprocess.compaction, size)
        ctx["subimage"] = sub
        ctx["preprocess"] = self.preprocess
        if fast.threshold_stage is not None:
            ctx["threshold"] = {"t4": t4, "mean4": m4, "std4": d4, "shift": s, "alpha_q12": aq,
                                "mode": fast.mode_name}
        if ledger is not None:
            ledger.charge_many(k + (c,) for k, c in zip(fast.charge_keys, fast.charge_cycles))
        return sub


def load_default_sequence(name="satellite"):
    """A shipped flight sequence (``flightsw/data/sequence_<name>.toml``)."""
    if name not in DEFAULT_SEQUENCES:
        raise ValueError(f"no shipped sequence {name!r}; known: {sorted(DEFAULT_SEQUENCES)}")
    return ProcessingSequence.from_toml(SEQUENCE_DIR / DEFAULT_SEQUENCES[name])


class IPConfig:
    """The IP's uplinkable configuration: the processing sequence in force.

    ``load_sequence`` accepts a :class:`ProcessingSequence`, a dict, TOML text or a path; an invalid
    one raises :class:`SequenceError` (also kept in ``last_error``) and the previous sequence stays.
    """

    def __init__(self, sequence=None):
        self._sequence = load_default_sequence("satellite") if sequence is None else sequence
        self.last_error = None

    @property
    def sequence(self) -> ProcessingSequence:
        return self._sequence

    def load_sequence(self, seq):
        try:
            if isinstance(seq, ProcessingSequence):
                new = seq
            elif isinstance(seq, dict):
                new = ProcessingSequence.from_dict(seq)
            else:
                new = ProcessingSequence.from_toml(seq)
        except SequenceError as exc:
            self.last_error = exc
            raise
        self._sequence = new
        self.last_error = None
        return new
