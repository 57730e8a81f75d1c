"""Labelled training sets for a priori record tuning: every blob's twelve features as the flight IP
computes them, with which blob is "the object".

A set is described by a *set spec* (TOML, or the same as a dict)::

    [set]
    name = "aurora_train"
    sequence = "aurora"          # shipped sequence name or a sequence TOML path
    radius_px = 12.0             # a blob is the object when its centroid is within this distance of
                                 # the label (full-resolution imager pixels)
    object_rule = "radius"       # or "blob": also when the blob holds the labelled pixel (the
                                 # closed-loop replays of optimise / validate; issue 43's rule)
    field_scale = 1.0            # [[real]] frames: the part of a found fisheye circle kept (a
                                 # job's ground-side field, hil_harness.detect.jobs.field_scale)
    predict = "centre"           # feature sets only (uvisi tune set / fit): the prior the IP gets
                                 # for the stored blobs: "centre" (none, the default), "previous"
                                 # (the previous frame's label), "truth" (label + noise: leans on
                                 # truth). uvisi tune optimise / validate ignore it: their prior is
                                 # the flight TP's (hil_harness.tuning.closed)
    predict_noise_px = 3.0       # Gaussian sigma per axis for predict = "truth"
    workers = 1                  # processes used to build the set (runs are independent)

    [[scenario]]                 # synthetic frames from groundsim (any number of entries)
    name = "aurora_surge_wfov_uv"    # shipped scenario name or a scenario TOML path
    seeds = [11, 12]             # or { start = 11, count = 2 }
    frames = 60                  # frames per run (default: the whole scenario)
    start = 0                    # first frame index
    every = 1                    # keep every k-th frame
    object = true                # false: the object is absent (frames count as "without the object")
    group = "m1"                 # cross-validation group prefix (default: the entry's index)
    [scenario.override]          # deep-merged into the scenario file's tables before parsing
    target = { surge_grow_km_s = 1.0, spot_kR = 25.0 }

    [[real]]                     # real imagery with a label CSV (image, frame, row, col)
    images = "data/real/wic_20000828_0928-0957_15frames.npz"
    labels = "data/labels/wic_20000828_surge.csv"
    frames = [1, 2, 3]           # default: every labelled frame
    radius_px = 20.0             # overrides [set] radius_px
    predict = "previous"         # overrides [set] predict
    imager = "wfov_uv"           # pixel-scale for the normalisation (default wfov_vis)

Labels: for a scenario the truth ``target`` pixel (the surge hot spot) when it is in the field and
``object = true``; for real imagery the CSV row (a blank or ``nan`` row/col marks a frame without the
object). The prediction (TP feedback) centres the 64x64 window and replaces the record's centroid
means, exactly as on board; the centroid means used are kept per frame (``mean_row``/``mean_col``)
so that any record can be re-ranked on the set later without re-running the front end: the front end,
colouring and features do not depend on the record.

Relative paths are looked up from the working directory first, then from the spec file's directory.
"""
from __future__ import annotations

import copy
import csv
import dataclasses
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flightsw.arith.m1750 import decode32_array
from flightsw.messages import N_FEATURES
from hil_harness.fileio import temp_beside

__all__ = ["TrainingSet", "SetSpec", "build_set", "load_set", "load_labels", "object_mask",
           "SET_SCHEMA", "PREDICT_MODES", "OBJECT_RULES", "resolve_path", "scenario_from_entry",
           "load_sequence", "reshape_sequence", "map_jobs", "deep_merge", "frame_prediction",
           "real_field"]

SET_SCHEMA = "uvisi-tuning-set/1"
PREDICT_MODES = ("truth", "previous", "centre")
#: when a blob is the object: its centroid within the radius of the label ("radius"), or that or
#: the blob holding the labelled pixel ("blob")
OBJECT_RULES = ("radius", "blob")
_FRAME_FIELDS = ("group", "source", "index", "t", "label_row", "label_col", "mean_row", "mean_col",
                 "radius", "n_blobs", "pred_row", "pred_col")
#: frame fields a set may lack (older sets, open-loop sets): their value when absent
_OPTIONAL_FIELDS = {"label_blob": -1}


# ================================================================================================
# the set
# ================================================================================================
@dataclass
class TrainingSet:
    """Every blob of every frame, with the frame table.

    Attributes
    ----------
    words : ndarray [B, 12] int64
        Normalised features of every blob (packed 1750A 32-bit words), frames concatenated.
    frame : ndarray [B] int64
        Row of :attr:`frames` each blob belongs to (non-decreasing).
    frames : dict of ndarray [F]
        ``group`` (str, cross-validation group: one run/sequence), ``source`` (str), ``index``
        (frame index in its source), ``t`` (s), ``label_row``/``label_col`` (full-res pixels, NaN:
        no object in this frame), ``mean_row``/``mean_col`` (the record centroid means the IP used:
        the prediction or the window centre), ``radius`` (px), ``n_blobs``, ``pred_row``/``pred_col``
        (the prediction fed back, NaN for none); optional ``label_blob`` (int: the frame's blob
        holding the labelled pixel, 0-based within the frame, -1 none or not known).
    meta : dict
        Spec and provenance (JSON-serialisable).
    """

    words: np.ndarray
    frame: np.ndarray
    frames: dict
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.words = np.ascontiguousarray(self.words, np.int64).reshape(-1, N_FEATURES)
        self.frame = np.asarray(self.frame, np.int64).reshape(-1)
        if self.frame.size != self.words.shape[0]:
            raise ValueError("TrainingSet: words and frame differ in length")
        missing = [k for k in _FRAME_FIELDS if k not in self.frames]
        if missing:
            raise ValueError(f"TrainingSet: frame table lacks {missing}")
        n = len(self.frames["t"])
        self.frames = dict(self.frames)
        for k, v in _OPTIONAL_FIELDS.items():
            if k not in self.frames:
                self.frames[k] = np.full(n, v, np.int64)
        for k in (*_FRAME_FIELDS, *_OPTIONAL_FIELDS):
            if len(self.frames[k]) != n:
                raise ValueError(f"TrainingSet: frame field {k!r} has {len(self.frames[k])} rows, "
                                 f"expected {n}")
        if self.frame.size and (self.frame.min() < 0 or self.frame.max() >= n
                                or np.any(np.diff(self.frame) < 0)):
            raise ValueError("TrainingSet: blob frame indices out of order or out of range")
        self._values = None

    # ---- sizes and derived arrays ----
    @property
    def n_frames(self) -> int:
        return len(self.frames["t"])

    @property
    def n_blobs(self) -> int:
        return self.words.shape[0]

    @property
    def values(self) -> np.ndarray:
        """float64 [B, 12]: the features (exact 1750A values)."""
        if self._values is None:
            self._values = decode32_array(self.words).reshape(-1, N_FEATURES)
        return self._values

    @property
    def has_label(self) -> np.ndarray:
        """bool [F]: the object is present (labelled) in the frame."""
        return np.isfinite(self.frames["label_row"]) & np.isfinite(self.frames["label_col"])

    @property
    def starts(self) -> np.ndarray:
        """int64 [F + 1]: blob rows of frame ``f`` are ``starts[f]:starts[f + 1]``."""
        return np.concatenate([[0], np.cumsum(self.frames["n_blobs"])]).astype(np.int64)

    def is_object(self) -> np.ndarray:
        """bool [B]: blob centroid within the frame's radius of the label."""
        return object_mask(self.values, self.frame, self.frames)

    def detected(self) -> np.ndarray:
        """bool [F]: some blob of the frame is the object."""
        out = np.zeros(self.n_frames, bool)
        obj = self.is_object()
        out[self.frame[obj]] = True
        return out

    def groups(self) -> list:
        """Distinct groups in order of first appearance."""
        seen = {}
        for g in self.frames["group"]:
            seen.setdefault(str(g), None)
        return list(seen)

    # ---- selection ----
    def subset(self, frame_mask) -> "TrainingSet":
        """The frames where ``frame_mask`` (bool [F]) holds, with their blobs."""
        m = np.asarray(frame_mask, bool)
        if m.shape != (self.n_frames,):
            raise ValueError(f"subset: mask shape {m.shape}, expected ({self.n_frames},)")
        new_index = np.cumsum(m) - 1
        keep = m[self.frame]
        frames = {k: np.asarray(v)[m] for k, v in self.frames.items()}
        return TrainingSet(self.words[keep], new_index[self.frame[keep]], frames, dict(self.meta))

    def select_groups(self, groups) -> "TrainingSet":
        gs = set(groups)
        return self.subset(np.array([str(g) in gs for g in self.frames["group"]], bool))

    @staticmethod
    def concat(sets, meta=None) -> "TrainingSet":
        sets = list(sets)
        if not sets:
            raise ValueError("concat: no sets")
        words = np.concatenate([s.words for s in sets]) if sets else np.zeros((0, 12), np.int64)
        off = np.cumsum([0] + [s.n_frames for s in sets])
        frame = np.concatenate([s.frame + off[i] for i, s in enumerate(sets)])
        frames = {k: np.concatenate([np.asarray(s.frames[k]) for s in sets])
                  for k in (*_FRAME_FIELDS, *_OPTIONAL_FIELDS)}
        return TrainingSet(words, frame, frames, meta if meta is not None else dict(sets[0].meta))

    # ---- persistence ----
    def save(self, path) -> Path:
        """Write an ``.npz`` atomically (temp file + rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        arrays = {"schema": np.array(SET_SCHEMA), "words": self.words, "frame": self.frame,
                  "meta": np.array(json.dumps(self.meta, default=str))}
        for k in (*_FRAME_FIELDS, *_OPTIONAL_FIELDS):
            v = np.asarray(self.frames[k])
            arrays[f"f_{k}"] = v.astype(str) if v.dtype.kind in "OU" else v
        fd, tmp = temp_beside(path, prefix=path.name + ".", suffix=".tmp.npz")
        os.close(fd)
        try:
            np.savez_compressed(tmp, **arrays)
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.unlink(tmp)
            raise
        return path

    def summary(self) -> str:
        hl = self.has_label
        det = self.detected()
        return (f"{self.n_frames} frames in {len(self.groups())} groups ({int(hl.sum())} with the "
                f"object, {int((~hl).sum())} without), {self.n_blobs} blobs; object segmented in "
                f"{int((det & hl).sum())}/{int(hl.sum())} labelled frames")


def load_set(path) -> TrainingSet:
    """Read a set written by :meth:`TrainingSet.save`."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such training set")
    if p.is_dir():
        raise ValueError(f"{p}: is a folder, not a training-set .npz")
    with open(p, "rb") as fh:
        head = fh.read(4)
    if head[:2] != b"PK":                        # every .npz is a zip archive
        raise ValueError(f"{p}: not a training-set .npz (not a zip archive: `uvisi tune set` "
                         f"writes one)")
    try:
        z = np.load(p, allow_pickle=False)
    except Exception as exc:                    # noqa: BLE001 -- a damaged archive: one line
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "pickle" in first:
            first = "it holds Python objects, which are never loaded"
        raise ValueError(f"{p}: not a training-set .npz ({first})") from None
    with z:
        if "schema" not in z.files or str(z["schema"]) != SET_SCHEMA:
            raise ValueError(f"{p}: not a training set (schema {SET_SCHEMA} expected)")
        frames = {k: z[f"f_{k}"] for k in _FRAME_FIELDS}
        frames.update({k: z[f"f_{k}"] for k in _OPTIONAL_FIELDS if f"f_{k}" in z.files})
        return TrainingSet(z["words"], z["frame"], frames, json.loads(str(z["meta"])))


def object_mask(values, frame, frames) -> np.ndarray:
    """bool [B]: blob centroid within ``frames['radius']`` of the frame's label, or the blob is
    the frame's ``label_blob`` (when the set knows it)."""
    lr = np.asarray(frames["label_row"], float)[frame]
    lc = np.asarray(frames["label_col"], float)[frame]
    rad = np.asarray(frames["radius"], float)[frame]
    d2 = (values[:, 2] - lr) ** 2 + (values[:, 1] - lc) ** 2
    with np.errstate(invalid="ignore"):
        near = np.isfinite(d2) & (d2 <= rad * rad)
    lb = frames.get("label_blob")
    if lb is None or frame.size == 0:
        return near
    lb = np.asarray(lb, np.int64)
    starts = np.searchsorted(frame, np.arange(lb.size))
    within = np.arange(frame.size) - starts[frame]
    return near | ((lb[frame] >= 0) & (within == lb[frame]) & np.isfinite(lr))


# ================================================================================================
# spec
# ================================================================================================
def resolve_path(p, base_dir=None) -> Path:
    """A relative path from the working directory, else from ``base_dir`` (the spec's directory)."""
    p = Path(str(p))
    if p.is_absolute() or p.exists() or base_dir is None:
        return p
    q = Path(base_dir) / p
    return q if q.exists() else p


def _seeds(v, where):
    if isinstance(v, int) and not isinstance(v, bool):
        return [v]
    if isinstance(v, list) and v and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0
                                          for x in v):
        return list(v)
    if isinstance(v, dict) and set(v) <= {"start", "count"} and "count" in v:
        s, c = v.get("start", 0), v["count"]
        if all(isinstance(x, int) and not isinstance(x, bool) for x in (s, c)) and s >= 0 and c >= 1:
            return range(s, s + c)             # listed when rendered: counted first
    raise ValueError(f"{where}: seeds must be an int >= 0, a list of them, or "
                     f"{{start = S, count = N}}, got {v!r}")


def _num(d, k, where, default, lo=None, positive=False):
    v = d.get(k, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{where}.{k}: expected a number, got {v!r}")
    if positive and not v > 0:
        raise ValueError(f"{where}.{k}: must be > 0, got {v!r}")
    if lo is not None and v < lo:
        raise ValueError(f"{where}.{k}: must be >= {lo}, got {v!r}")
    return float(v)


def _int(d, k, where, default, lo=0):
    v = d.get(k, default)
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, int) or v < lo:
        raise ValueError(f"{where}.{k}: expected an integer >= {lo}, got {v!r}")
    return v


def _predict(d, k, where, default):
    v = d.get(k, default)
    if v not in PREDICT_MODES:
        raise ValueError(f"{where}.{k}: must be one of {list(PREDICT_MODES)}, got {v!r}")
    return v


@dataclass
class SetSpec:
    """A parsed set spec (module docstring)."""

    name: str
    sequence: str
    radius_px: float
    predict: str
    predict_noise_px: float
    scenarios: list
    reals: list
    workers: int = 1
    base_dir: str | None = None
    raw: dict = field(default_factory=dict)
    object_rule: str = "radius"

    def for_record(self, record) -> "SetSpec":
        """The spec as a record's job runs it: where the spec names no ``sequence`` the record's
        job sequence (:func:`hil_harness.detect.jobs.default_sequence_name`: ``--record
        aurora_allsky`` runs ``aurora_allsky``), and where it names no ``field_scale`` the job's
        ground-side field (:func:`hil_harness.detect.jobs.field_scale`). Returns self when
        nothing changes, else a changed copy."""
        from hil_harness.detect.jobs import default_sequence_name, field_scale
        head = self.raw.get("set") or {}
        seq = self.sequence if "sequence" in head else default_sequence_name(record)
        scale = None if "field_scale" in head else field_scale(record)
        if seq == self.sequence and (scale is None or all(e.get("field_scale", 1.0) == scale
                                                          for e in self.reals)):
            return self
        reals = [dict(e, field_scale=scale) if scale is not None else dict(e)
                 for e in self.reals]
        return dataclasses.replace(self, sequence=seq, reals=reals)

    @classmethod
    def load(cls, path) -> "SetSpec":
        from hil_harness.fileio import read_toml
        p = Path(path)
        return cls.from_dict(read_toml(p, "set spec"), source=str(p), base_dir=str(p.parent))

    @classmethod
    def from_dict(cls, data, source="<spec>", base_dir=None) -> "SetSpec":
        if not isinstance(data, dict):
            raise ValueError(f"{source}: a set spec must be a table")
        extra = sorted(set(data) - {"set", "scenario", "real"})
        if extra:
            raise ValueError(f"{source}: unknown top-level key(s) {extra} (set, scenario, real)")
        head = data.get("set", {})
        if not isinstance(head, dict):
            raise ValueError(f"{source}: [set] must be a table")
        w = f"{source}: set"
        bad = sorted(set(head) - {"name", "sequence", "radius_px", "predict", "predict_noise_px",
                                  "workers", "object_rule", "field_scale"})
        if bad:
            raise ValueError(f"{w}: unknown key(s) {bad}")
        name = str(head.get("name", Path(source).stem))
        seq = head.get("sequence", "aurora")
        if not isinstance(seq, str):
            raise ValueError(f"{w}.sequence: expected a name or path, got {seq!r}")
        radius = _num(head, "radius_px", w, 12.0, positive=True)
        predict = _predict(head, "predict", w, "centre")
        noise = _num(head, "predict_noise_px", w, 3.0, lo=0.0)
        workers = _int(head, "workers", w, 1, lo=1)
        fscale = _num(head, "field_scale", w, 1.0, positive=True)
        if fscale > 1.0:
            raise ValueError(f"{w}.field_scale: {fscale} must be in (0, 1]")
        rule = head.get("object_rule", "radius")
        if rule not in OBJECT_RULES:
            raise ValueError(f"{w}.object_rule: expected \"radius\" or \"blob\", got {rule!r}")
        scen, reals = [], []
        for i, e in enumerate(data.get("scenario", [])):
            we = f"{source}: scenario[{i}]"
            if not isinstance(e, dict):
                raise ValueError(f"{we}: must be a table")
            bad = sorted(set(e) - {"name", "seeds", "frames", "start", "every", "object", "group",
                                   "override", "radius_px", "predict", "predict_noise_px"})
            if bad:
                raise ValueError(f"{we}: unknown key(s) {bad}")
            if not isinstance(e.get("name"), str):
                raise ValueError(f"{we}.name: missing (a shipped scenario name or a TOML path)")
            ov = e.get("override", {})
            if not isinstance(ov, dict):
                raise ValueError(f"{we}.override: must be a table of scenario tables")
            obj = e.get("object", True)
            if not isinstance(obj, bool):
                raise ValueError(f"{we}.object: expected true or false, got {obj!r}")
            scen.append(dict(
                name=e["name"], seeds=_seeds(e.get("seeds", 0), we),
                frames=_int(e, "frames", we, None, lo=1), start=_int(e, "start", we, 0),
                every=_int(e, "every", we, 1, lo=1), object=obj, override=ov,
                group=str(e.get("group", f"s{i}")),
                radius_px=_num(e, "radius_px", we, radius, positive=True),
                predict=_predict(e, "predict", we, predict),
                predict_noise_px=_num(e, "predict_noise_px", we, noise, lo=0.0)))
        for i, e in enumerate(data.get("real", [])):
            we = f"{source}: real[{i}]"
            if not isinstance(e, dict):
                raise ValueError(f"{we}: must be a table")
            bad = sorted(set(e) - {"images", "labels", "frames", "radius_px", "predict",
                                   "predict_noise_px", "imager", "group", "channel"})
            if bad:
                raise ValueError(f"{we}: unknown key(s) {bad}")
            for k in ("images", "labels"):
                if not isinstance(e.get(k), str):
                    raise ValueError(f"{we}.{k}: missing (a file path)")
            fr = e.get("frames")
            if fr is not None and not (isinstance(fr, list) and all(
                    isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in fr)):
                raise ValueError(f"{we}.frames: expected a list of frame indices, got {fr!r}")
            ch = e.get("channel")
            if ch is not None and ch not in ("l", "r", "g", "b"):
                raise ValueError(f"{we}.channel: expected \"l\", \"r\", \"g\" or \"b\", got "
                                 f"{ch!r}")
            reals.append(dict(images=e["images"], labels=e["labels"], frames=fr, channel=ch,
                              radius_px=_num(e, "radius_px", we, radius, positive=True),
                              predict=_predict(e, "predict", we, predict),
                              predict_noise_px=_num(e, "predict_noise_px", we, noise, lo=0.0),
                              imager=str(e.get("imager", "wfov_vis")),
                              group=str(e.get("group", f"r{i}")), field_scale=fscale))
        if not scen and not reals:
            raise ValueError(f"{source}: no [[scenario]] or [[real]] entries")
        return cls(name, seq, radius, predict, noise, scen, reals, workers, base_dir, data, rule)


# ================================================================================================
# building
# ================================================================================================
def load_sequence(name_or_path, base_dir=None, frame_shape=None):
    """The processing sequence (shipped name or TOML path), its frame shape set to
    ``frame_shape`` when given."""
    from flightsw.ip.sequence import DEFAULT_SEQUENCES, ProcessingSequence, load_default_sequence
    if name_or_path in DEFAULT_SEQUENCES:
        seq = load_default_sequence(name_or_path)
    else:
        p = resolve_path(name_or_path, base_dir)
        if not p.exists():
            raise ValueError(f"sequence {name_or_path!r}: not a shipped sequence "
                             f"({sorted(DEFAULT_SEQUENCES)}) nor a file")
        seq = ProcessingSequence.from_toml(p)
    return reshape_sequence(seq, frame_shape)


def reshape_sequence(seq, frame_shape=None, window=None):
    """``seq`` (a :class:`flightsw.ip.sequence.ProcessingSequence`) with its frame shape set to
    ``frame_shape`` and its window (compacted pixels) to ``window`` where given; ``seq`` itself
    when neither changes."""
    from flightsw.ip.sequence import Preprocess, ProcessingSequence
    pre = seq.preprocess
    shape = tuple(pre.frame_shape) if frame_shape is None else tuple(frame_shape)
    window = pre.window if window is None else window
    if shape == tuple(pre.frame_shape) and window == pre.window:
        return seq
    pre = Preprocess(pre.compaction, window, frame_shape=shape)
    return ProcessingSequence([dict(s.raw) for s in seq.steps], pre, seq.name, seq.description)


def deep_merge(base, over):
    """A deep copy of the table ``base`` with ``over`` merged in (nested tables merged key by key,
    anything else replaced)."""
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def scenario_from_entry(name, override=None, seed=None, base_dir=None):
    """A :class:`groundsim.scenario.Scenario` from a shipped name / path, with ``override`` tables
    deep-merged into the file's and ``seed`` (None: the file's)."""
    from groundsim.scenario import Scenario
    p = resolve_path(name, base_dir) if (str(name).endswith(".toml")) else name
    scn = Scenario.load(p)
    if not override:
        return scn if seed is None else Scenario.from_dict(scn.raw, scn.path, seed=seed)
    if not isinstance(override, dict):
        raise ValueError(f"scenario override must be a table, got {override!r}")
    return Scenario.from_dict(deep_merge(scn.raw, override), scn.path, seed=seed)


def _window_centre(sub):
    f = int(sub.factor)
    r0, c0 = int(sub.origin[0]) * f, int(sub.origin[1]) * f
    h, w = sub.size
    return r0 + h * f / 2.0, c0 + w * f / 2.0


def _ip_frame(img, seq, record, pred, imager):
    """Run the flight IP on one frame -> (feature words [k, 12], centroid means (row, col))."""
    from flightsw.ip.frame import process_frame
    from flightsw.messages import Feedback
    fb = None if pred is None else Feedback(float(pred[0]), float(pred[1]), record.object_type,
                                            True)
    res = process_frame(img, seq, record, fb, imager=imager, want_stages=False)
    mean = pred if pred is not None else _window_centre(res.subimage)
    return res.backend.feature_words.copy(), (float(mean[0]), float(mean[1])), res


def frame_prediction(mode, label, prev, noise, rng):
    """The TP prediction for a frame (None: no prediction), pixels ``(row, col)``.

    ``mode`` is one of :data:`PREDICT_MODES`: "centre" (none), "previous" (``prev``, else
    ``label``), "truth" (``label`` plus Gaussian noise of ``noise`` px drawn from ``rng``)."""
    if mode == "centre":
        return None
    if mode == "previous":
        base = prev if prev is not None else label
        if base is None or not all(math.isfinite(x) for x in base):
            return None
        return base
    if label is None or not all(math.isfinite(x) for x in label):
        return None
    if noise > 0:
        return (label[0] + noise * rng.standard_normal(), label[1] + noise * rng.standard_normal())
    return label


class _Acc:
    """Accumulates frames into a TrainingSet."""

    def __init__(self):
        self.words, self.rows = [], {k: [] for k in _FRAME_FIELDS}

    def add(self, words, **row):
        self.words.append(np.asarray(words, np.int64).reshape(-1, N_FEATURES))
        row["n_blobs"] = self.words[-1].shape[0]
        for k in _FRAME_FIELDS:
            self.rows[k].append(row[k])

    def build(self, meta):
        words = np.concatenate(self.words) if self.words else np.zeros((0, N_FEATURES), np.int64)
        n = np.array(self.rows["n_blobs"], np.int64)
        frame = np.repeat(np.arange(n.size), n)
        frames = {}
        for k in _FRAME_FIELDS:
            v = self.rows[k]
            frames[k] = (np.array(v, dtype=str) if k in ("group", "source")
                         else np.array(v, np.int64) if k in ("index", "n_blobs")
                         else np.array(v, np.float64))
        return TrainingSet(words, frame, frames, meta)


def scenario_run_set(entry, seed, sequence, base_dir=None, record=None) -> TrainingSet:
    """One scenario run (an entry of the spec with one seed) -> its TrainingSet."""
    from flightsw.records import load_record
    record = load_record("aurora") if record is None else record
    scn = scenario_from_entry(entry["name"], entry.get("override"), seed, base_dir)
    seq = load_sequence(sequence, base_dir)
    world = scn.world()
    world.reset()
    rng = np.random.default_rng([int(seed), 0x7E57])
    acc = _Acc()
    k, kept, prev = 0, 0, None
    start, every, nmax = entry.get("start", 0), entry.get("every", 1), entry.get("frames")
    group = f"{entry.get('group', 's')}/seed{seed}"
    while not world.done and (nmax is None or kept < nmax):
        if not world.frame_dropped and k >= start and (k - start) % every == 0:
            frame, truth = world.render()
            tg = truth["target"]
            pos = (float(tg["row"]), float(tg["col"])) if tg.get("in_field") else None
            pred = frame_prediction(entry.get("predict", "centre"), pos, prev,
                                    entry.get("predict_noise_px", 0.0), rng)
            label = pos if entry.get("object", True) else None
            words, mean, _ = _ip_frame(frame, seq, record, pred, truth["imager"])
            acc.add(words, group=group, source=f"{scn.name}#{seed}", index=k, t=float(world.t),
                    label_row=label[0] if label else math.nan,
                    label_col=label[1] if label else math.nan, mean_row=mean[0],
                    mean_col=mean[1], radius=entry.get("radius_px", 12.0),
                    pred_row=pred[0] if pred else math.nan, pred_col=pred[1] if pred else math.nan)
            prev = pos
            kept += 1
        world.advance(0.5)
        k += 1
    return acc.build({"kind": "scenario", "scenario": scn.name, "seed": int(seed)})


def load_labels(path) -> dict:
    """Label CSV -> ``{(image, frame): (row, col) or None}``. Columns ``image, frame, row, col``
    (header required, ``#`` comment lines allowed); blank / ``nan`` row and col: no object."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such label file")
    out = {}
    lines = [ln for ln in p.read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    rd = csv.DictReader(lines)
    need = {"image", "frame", "row", "col"}
    if rd.fieldnames is None or not need <= {f.strip() for f in rd.fieldnames}:
        raise ValueError(f"{p}: header must name the columns image, frame, row, col "
                         f"(got {rd.fieldnames})")
    for n, r in enumerate(rd, start=2):
        r = {k.strip(): (v or "").strip() for k, v in r.items() if k is not None}
        try:
            fr = int(r["frame"])
        except ValueError:
            raise ValueError(f"{p}: line {n}: frame {r['frame']!r} is not an integer") from None
        rs, cs = r["row"], r["col"]
        if rs.lower() in ("", "nan") and cs.lower() in ("", "nan"):
            pos = None
        else:
            try:
                pos = (float(rs), float(cs))
            except ValueError:
                raise ValueError(f"{p}: line {n}: row/col {rs!r}, {cs!r} are not numbers") from None
            if not all(math.isfinite(x) for x in pos):
                raise ValueError(f"{p}: line {n}: row/col must be finite (blank for no object)")
        key = (r["image"], fr)
        if key in out:
            raise ValueError(f"{p}: line {n}: duplicate label for image {key[0]!r} frame {fr}")
        out[key] = pos
    if not out:
        raise ValueError(f"{p}: no labels")
    return out


def real_field(frames, entry) -> np.ndarray:
    """bool [H, W]: the field of a ``[[real]]`` entry's frames, as ``uvisi track`` finds it for
    the file (:func:`hil_harness.field.sequence_field`), scaled by the entry's ``field_scale``
    (the part of a found fisheye circle the entry's job keeps)."""
    from hil_harness.field import sequence_field
    return sequence_field(frames).scaled(entry.get("field_scale", 1.0)).mask


def real_set(entry, sequence, base_dir=None, record=None) -> TrainingSet:
    """Real imagery + label CSV (a ``[[real]]`` entry) -> TrainingSet."""
    from flightsw.records import load_record
    from hil_harness.images import read_images, to_counts
    record = load_record("aurora") if record is None else record
    ipath = resolve_path(entry["images"], base_dir)
    labels = load_labels(resolve_path(entry["labels"], base_dir))
    frames = read_images(ipath, entry.get("channel") or "l")
    name = ipath.name
    mine = {fr: pos for (im, fr), pos in labels.items() if im == name}
    if not mine:
        raise ValueError(f"{entry['labels']}: no label rows for image {name!r} "
                         f"(images named: {sorted({im for im, _ in labels})})")
    want = entry.get("frames")
    if want is None:
        want = sorted(mine)
    for fr in want:
        if fr not in mine:
            raise ValueError(f"{entry['labels']}: frame {fr} of {name} has no label row")
        if fr >= len(frames):
            raise ValueError(f"{name}: frame {fr} out of range ({len(frames)} frames)")
    rng = np.random.default_rng([len(want), 0x7E57])
    acc = _Acc()
    prev = None
    seq_cache = {}
    field = real_field(frames, entry)
    for fr in sorted(want):
        img = to_counts(frames[fr].data, field=field, bits=frames[fr].bits)[0]
        if img.shape not in seq_cache:
            seq_cache[img.shape] = load_sequence(sequence, base_dir, img.shape)
        seq = seq_cache[img.shape]
        label = mine[fr]
        # previous mode: the previous *labelled* frame of the sequence (the TP's last fix)
        prev_l = mine.get(fr - 1) if (fr - 1) in mine else prev
        pred = frame_prediction(entry.get("predict", "centre"), label, prev_l,
                                entry.get("predict_noise_px", 0.0), rng)
        words, mean, _ = _ip_frame(img, seq, record, pred, entry.get("imager", "wfov_vis"))
        acc.add(words, group=entry.get("group", "r"), source=f"{name}", index=fr, t=float(fr),
                label_row=label[0] if label else math.nan,
                label_col=label[1] if label else math.nan, mean_row=mean[0], mean_col=mean[1],
                radius=entry.get("radius_px", 20.0), pred_row=pred[0] if pred else math.nan,
                pred_col=pred[1] if pred else math.nan)
        if label is not None:
            prev = label
    return acc.build({"kind": "real", "images": str(ipath), "labels": str(entry["labels"])})


def _run_job(job):
    kind, entry, arg, seq, base_dir = job
    if kind == "scenario":
        return scenario_run_set(entry, arg, seq, base_dir)
    return real_set(entry, seq, base_dir)


def map_jobs(fn, jobs: list, workers: int, desc: str, unit: str, progress: bool) -> list:
    """``[fn(j) for j in jobs]``, in order, on ``workers`` processes when there are several jobs and
    workers (``fn`` module-level), with a progress bar when ``progress``."""
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(jobs), desc=desc, unit=unit)
    out = []
    try:
        if workers > 1 and len(jobs) > 1:
            from concurrent.futures import ProcessPoolExecutor
            with ProcessPoolExecutor(min(workers, len(jobs))) as ex:
                results = ex.map(fn, jobs)
                for r in results:
                    out.append(r)
                    if bar:
                        bar.update(1)
        else:
            for j in jobs:
                out.append(fn(j))
                if bar:
                    bar.update(1)
    finally:
        if bar:
            bar.close()
    return out


def build_set(spec, progress: bool = False, workers: int | None = None) -> TrainingSet:
    """Build a TrainingSet from a :class:`SetSpec`, a spec dict or a spec TOML path (or load a
    saved ``.npz`` set)."""
    if isinstance(spec, (str, Path)):
        p = Path(spec)
        if p.suffix == ".npz":
            return load_set(p)
        spec = SetSpec.load(p)
    elif isinstance(spec, dict):
        spec = SetSpec.from_dict(spec)
    elif not isinstance(spec, SetSpec):
        raise ValueError(f"build_set: expected a SetSpec, dict or path, got {type(spec).__name__}")
    load_sequence(spec.sequence, spec.base_dir)              # fail early on a bad sequence
    jobs = [("scenario", e, s, spec.sequence, spec.base_dir) for e in spec.scenarios
            for s in e["seeds"]]
    jobs += [("real", e, None, spec.sequence, spec.base_dir) for e in spec.reals]
    workers = spec.workers if workers is None else workers
    parts = map_jobs(_run_job, jobs, workers, f"[tune] set {spec.name}", "run", progress)
    meta = {"name": spec.name, "sequence": spec.sequence, "radius_px": spec.radius_px,
            "predict": spec.predict, "predict_noise_px": spec.predict_noise_px,
            "spec": spec.raw}
    return TrainingSet.concat(parts, meta)
