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
    alpha = 3.0             # 0 .. 7.99975 (Q4.12), where the onboard alpha logic starts
    alpha_min = 1.0         # optional, 0 .. alpha: the alpha logic's floor
    alpha_min_sparse = 0.25 # optional, 0 .. alpha_min, with sparse_blobs: the floor while the
    sparse_blobs = 20       #   frame has fewer blobs than sparse_blobs (1 .. 89)
    alpha_min_locked = 0.5  # optional, 0 .. alpha_min, with locked_blobs: while the TP holds lock
    locked_blobs = 60       #   and the frame has fewer blobs (1 .. 89), alpha steps down to this
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

Steps
-----
Each op has a validator (``validator(params: dict, pre: Preprocess) -> params object``; it raises
:class:`FieldError` naming the field, and the sequence reports ``step <i> '<op>': field '<f>':
...``), a phase and a stage-name label, in :data:`STEP_REGISTRY`. The steps run in the image
processor's one compiled pipeline (:mod:`flightsw.ip.pipeline`), which has a kernel for each op.

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

import flightsw.ip.detrend as _dt
import flightsw.ip.fftfilter as _fft
import flightsw.ip.filters as _flt
import flightsw.ip.threshold as _th
from flightsw.ip.preprocess import (COMPACTION_FACTORS, FRAME_SHAPE, check_frame, preprocess,
                                    window_shape)
from flightsw.messages import MAX_CANDIDATES

__all__ = ["ProcessingSequence", "IPConfig", "SequenceError", "FieldError", "StepType", "Step",
           "Stage", "Preprocess", "STEP_REGISTRY", "FilterParams", "FilterFFTParams",
           "DetrendParams", "ThresholdParams", "ColourParams", "FeatureParams", "RankParams",
           "PHASE_FRONT", "PHASE_THRESHOLD", "PHASE_LABEL", "PHASE_FEATURES", "PHASE_RANK",
           "SEQUENCE_DIR", "load_default_sequence", "DEFAULT_SEQUENCES"]

PHASE_FRONT, PHASE_THRESHOLD, PHASE_LABEL, PHASE_FEATURES, PHASE_RANK = 0, 10, 20, 30, 40
SEQUENCE_DIR = Path(__file__).resolve().parents[1] / "data"
DEFAULT_SEQUENCES = {"satellite": "sequence_satellite.toml", "aurora": "sequence_aurora.toml",
                     "satellite_c2": "sequence_satellite_c2.toml",
                     "satellite_track": "sequence_satellite_track.toml",
                     "aurora_track": "sequence_aurora_track.toml", "star": "sequence_star.toml",
                     "streak": "sequence_streak.toml",
                     "aurora_allsky": "sequence_aurora_allsky.toml"}


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
    """A toolbox op: its validator, phase, whether it may appear once, and its stage label."""

    name: str
    validator: Callable
    phase: int = PHASE_FRONT
    unique: bool = False
    label: Callable | None = None


#: op name -> StepType, filled below (the pipeline has a kernel for each)
STEP_REGISTRY: dict[str, StepType] = {}


def _register(name, validator, *, phase=PHASE_FRONT, unique=False, label=None):
    STEP_REGISTRY[name] = StepType(name, validator, phase, unique, label)


@dataclass(frozen=True)
class Step:
    op: str
    params: Any
    raw: dict
    stage: str


@dataclass
class Stage:
    """One panel of the paper's Figure 3: the stage name, its output image and any data."""

    name: str
    image: Any
    data: Any = None


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
            taps = _dt.check_taps(params["taps"])
        except (ValueError, TypeError) as exc:
            raise FieldError("taps", str(exc)) from None
    else:
        sigma = _float_field(params, "sigma", _dt.DEFAULT_HIGHPASS_SIGMA, 0.5, 3.0)
        taps = _dt.default_taps(sigma)
    return DetrendParams("highpass", taps)


@dataclass(frozen=True)
class ThresholdParams:
    alpha_q12: int
    mode: str


def _validate_threshold(params, pre):
    _fields(params, {"alpha", "mode", "alpha_min", "alpha_min_sparse", "sparse_blobs",
                     "alpha_min_locked", "locked_blobs"})
    if "alpha" not in params:
        raise FieldError("alpha", "missing (0 .. 7.99975)")
    alpha = _float_field(params, "alpha", None, _th.ALPHA_MIN, _th.ALPHA_MAX)
    floor = _th.alpha_bounds(alpha)[0]                     # the logic's default floor
    if "alpha_min" in params:        # the alpha logic's floor for this sequence (AlphaController)
        floor = _float_field(params, "alpha_min", None, _th.ALPHA_MIN, alpha)
    # the floor for sparse frames without lock, and the floor while locked: both fields or neither
    for pair in (("alpha_min_sparse", "sparse_blobs"), ("alpha_min_locked", "locked_blobs")):
        given = [k for k in pair if k in params]
        if len(given) == 1:
            other = (set(pair) - set(given)).pop()
            raise FieldError(other, f"missing (it comes with {given[0]})")
        if given:
            _float_field(params, pair[0], None, _th.ALPHA_MIN, floor)
            _int_field(params, pair[1], None, 1, _th.NEAR_COUNT - 1)
    mode = _choice(params, "mode", "binarize", ("binarize", "clip"))
    h, w = pre.window_shape
    if h * w > 16384:
        raise FieldError("alpha", f"the threshold statistics support windows up to 128x128, the "
                                  f"sequence's window is {h}x{w}")
    return ThresholdParams(_th.alpha_to_q12(alpha), mode)


# ---------------------------------------------------------------------------------------------
# back-end steps (IP steps 6-8 on the 1750A: their flags and the record)
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ColourParams:
    diagonal: bool = True


@dataclass(frozen=True)
class FeatureParams:
    intensity_centroid: bool = True


@dataclass(frozen=True)
class RankParams:
    record: object = None              # a Record, or None: the record in force
    max_candidates: int = MAX_CANDIDATES


def _bool_field(params, name, default):
    v = params.get(name, default)
    if not isinstance(v, bool):
        raise FieldError(name, f"{v!r} is not a boolean (true/false)")
    return v


def _validate_colour(params, pre):
    _fields(params, {"diagonal"})
    return ColourParams(_bool_field(params, "diagonal", True))


def _validate_features(params, pre):
    _fields(params, {"intensity_centroid"})
    return FeatureParams(_bool_field(params, "intensity_centroid", True))


def _validate_rank(params, pre):
    from flightsw.records import load_record
    _fields(params, {"record", "max_candidates"})
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


_register("filter", _validate_filter, label=_label_filter)
_register("filter_fft", _validate_filter_fft, label=_label_filter_fft)
_register("detrend", _validate_detrend, label=lambda p: f"detrend_{p.method}")
_register("threshold", _validate_threshold, phase=PHASE_THRESHOLD, unique=True)
_register("colour", _validate_colour, phase=PHASE_LABEL, unique=True, label=lambda p: "colour")
_register("label", _validate_colour, phase=PHASE_LABEL, unique=True, label=lambda p: "colour")
_register("features", _validate_features, phase=PHASE_FEATURES, unique=True)
_register("rank", _validate_rank, phase=PHASE_RANK, unique=True)


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
        """Preprocessor board alone: compaction + window (stage ``"compaction"``, 0 DSP cycles),
        as a :class:`Subimage` (the ground's full-frame mode cuts windows this way)."""
        pre = self.preprocess
        sub = preprocess(frame, pre.compaction, predicted_rowcol_fullres, pre.window, check=check)
        if ledger is not None:
            ledger.charge("dsp", "compaction", 0)
        return sub

    def checked_frame(self, frame, check: bool = True):
        """The frame as the pipeline takes it: a C-contiguous uint16 array of the sequence's frame
        shape (ValueError otherwise); with ``check``, also 12-bit counts 0..4095 (without, the
        caller vouches for the range)."""
        if check:
            frame = check_frame(frame)
        if frame.shape != self.preprocess.frame_shape or frame.dtype.kind not in "ui":
            raise ValueError(f"frame must be a {self.preprocess.frame_shape} integer array, got "
                             f"{frame.dtype} {frame.shape}")
        if frame.dtype != np.uint16 or not frame.flags.c_contiguous:
            frame = np.ascontiguousarray(frame, np.uint16)
        return frame


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
