"""Fixed frame sequences through the one closed loop (:class:`~hil_harness.event.loop.Event`).

A tuning event (a scenario run rendered once, or a real night's labelled frames) and the frames
``uvisi track`` is given are a fixed sequence: the pointing does not move them. They run through the
same :class:`~hil_harness.event.loop.Event` as a simulated event, its acquisition hook reading the
sequence instead of rendering: the flight IP (:class:`flightsw.ip.ImageProcessor`) and TP
(:class:`flightsw.tp.TrackProcessor`, target-of-opportunity mode: a fixed sequence carries no
nominal trajectory) exchange the same words on the same buses, the IP reads the command with its
checks and runs its own alpha logic::

    frame k --ImageProcessor.step(last command words)--> candidate words (CRC)
            --TrackProcessor.step(words, attitude k)--> command words (CRC) --> the IP, frame k + 1

Three position priors (:data:`PRIOR_MODES`):

``"tp"``
    the flight one (above): the TP's prediction made on the previous frame.
``"centre"``
    no prior: every frame processed from the centre (the TP does not run).
``"truth"``
    the true object position of the frame (an upper bound; a frame without the object gets no
    prior; the TP does not run). The only mode in which truth reaches the IP.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from flightsw.messages import AttitudeData, Feedback
from flightsw.proposals import ALL, expand
from flightsw.tp import ImagerGeometry

from .loop import Event, EventConfig

__all__ = ["FrameSequence", "SequenceEvent", "SequenceScenario", "SequenceWorld", "PRIOR_MODES",
           "stand_in_attitude", "centroid_mean"]

PRIOR_MODES = ("tp", "centre", "truth")


def stand_in_attitude(t: float) -> AttitudeData:
    """A fixed pointing (identity attitude, no rate, no orbit) at time ``t``: the TP then works in
    the imager's own tangent plane."""
    return AttitudeData(t=float(t), r_eci=np.array([7.0e6, 0.0, 0.0]),
                        v_eci=np.array([0.0, 7.5e3, 0.0]))


@dataclass
class FrameSequence:
    """A fixed sequence of full frames with what the TP and the scorer need.

    Attributes
    ----------
    frames : ndarray [F, H, W] uint16
        12-bit counts, in order.
    t : ndarray [F] float64
        Time tag of each frame, s (the TP's clock).
    imager : str
        Imager id (a key of :data:`flightsw.messages.IMAGER_CODES`).
    geometry : ImagerGeometry
        The imager as the TP knows it.
    attitude : list of AttitudeData, optional
        One per frame (the attitude processor's data); None: a fixed stand-in pointing
        (:func:`stand_in_attitude`).
    frame_count : ndarray [F] int64, optional
        Frame counter sent in each message (default 0..F-1; a gap tells the TP a frame is missing).
    truth_row, truth_col : ndarray [F] float64
        True object position, full-resolution pixels; NaN where the object is absent. Read only to
        score (and by the ``"truth"`` prior, the labelled upper bound).
    name : str
        Event id (scenario#seed, or the image file).
    object_type : str
        Type the TP reports ("aurora", ...).
    """

    frames: np.ndarray
    t: np.ndarray
    imager: str
    geometry: ImagerGeometry
    attitude: list | None = None
    frame_count: np.ndarray | None = None
    truth_row: np.ndarray | None = None
    truth_col: np.ndarray | None = None
    name: str = "event"
    object_type: str = "aurora"

    def __post_init__(self):
        self.frames = np.asarray(self.frames)
        if self.frames.ndim != 3 or self.frames.dtype != np.uint16:
            raise ValueError(f"{self.name}: frames must be uint16 [F, H, W], got "
                             f"{self.frames.dtype} {self.frames.shape}")
        n = self.frames.shape[0]
        self.t = np.asarray(self.t, np.float64).reshape(-1)
        if self.t.size != n or (n > 1 and not np.all(np.diff(self.t) > 0)):
            raise ValueError(f"{self.name}: t must hold {n} increasing time tags")
        if self.frame_count is None:
            self.frame_count = np.arange(n, dtype=np.int64)
        self.frame_count = np.asarray(self.frame_count, np.int64).reshape(-1)
        for k in ("truth_row", "truth_col"):
            v = getattr(self, k)
            v = np.full(n, np.nan) if v is None else np.asarray(v, np.float64).reshape(-1)
            if v.size != n:
                raise ValueError(f"{self.name}: {k} has {v.size} values for {n} frames")
            setattr(self, k, v)
        if self.attitude is not None and len(self.attitude) != n:
            raise ValueError(f"{self.name}: {len(self.attitude)} attitude records for {n} frames")

    @property
    def n_frames(self) -> int:
        return int(self.frames.shape[0])

    @functools.cached_property
    def top(self) -> int:
        """The largest count in the frames (read once: a tuning run replays the same sequence for
        every record it tries)."""
        return int(self.frames.max()) if self.frames.size else 0

    @property
    def has_object(self) -> np.ndarray:
        """bool [F]: the object is in the frame (truth known)."""
        return np.isfinite(self.truth_row) & np.isfinite(self.truth_col)

    def block(self, a: int, b: int, name: str | None = None) -> "FrameSequence":
        """Frames ``a:b`` as an event of their own (the loop starts afresh at frame ``a``)."""
        return FrameSequence(self.frames[a:b], self.t[a:b], self.imager, self.geometry,
                             None if self.attitude is None else self.attitude[a:b],
                             self.frame_count[a:b], self.truth_row[a:b], self.truth_col[a:b],
                             name or f"{self.name}[{a}:{b}]", self.object_type)

    def without_truth(self) -> "FrameSequence":
        """The same event with every truth position replaced by NaN."""
        return FrameSequence(self.frames, self.t, self.imager, self.geometry, self.attitude,
                             self.frame_count, None, None, self.name, self.object_type)

    def nominal_dt(self) -> float:
        """The median frame interval, s (0.5 for a single frame): the TP's ``frame_dt``."""
        d = np.diff(self.t)
        return float(np.median(d)) if d.size else 0.5


# ---- what Event reads of a scenario, for a fixed sequence -------------------------------------------
@dataclass
class _SequenceImager:
    align_onboard: np.ndarray
    scale_col: float
    scale_row: float
    adc_max: int
    n_rows: int
    n_cols: int


@dataclass
class _NoFaults:
    imager_switch: list = field(default_factory=list)
    corrupt_candidate: list = field(default_factory=list)
    corrupt_command: list = field(default_factory=list)


class SequenceWorld:
    """The world of a fixed sequence (the interface of :class:`groundsim.world.World`): frame k's
    attitude data, frame and truth; a pointing command is taken and changes nothing."""

    def __init__(self, seq: FrameSequence):
        self.seq = seq
        self.imager = seq.imager
        self.k = 0

    def reset(self):
        self.k = 0

    @property
    def t(self) -> float:
        return float(self.seq.t[min(self.k, self.seq.n_frames - 1)])

    @property
    def done(self) -> bool:
        return self.k >= self.seq.n_frames

    @property
    def frame_dropped(self) -> bool:
        return False

    def attitude_data(self) -> AttitudeData:
        s = self.seq
        return s.attitude[self.k] if s.attitude is not None else stand_in_attitude(s.t[self.k])

    def render(self):
        s, k = self.seq, self.k
        obj = bool(s.has_object[k])
        truth = {"target": {"row": float(s.truth_row[k]), "col": float(s.truth_col[k]),
                            "in_field": obj}}
        return s.frames[k], truth

    def command(self, q_target_body_to_eci) -> None:
        """The frames are fixed: the pointing does not move them."""

    def advance(self, dt: float = 0.5) -> None:
        self.k += 1


class SequenceScenario:
    """What :class:`~hil_harness.event.loop.Event` reads of a scenario, for a fixed sequence: one
    imager, no uplinks, no faults, target-of-opportunity mode."""

    tp_mode = "opportunity"
    uplinks: tuple = ()
    flight_with: tuple = ()
    seed = 0

    def __init__(self, seq: FrameSequence):
        g = seq.geometry
        self.seq = seq
        self.name = self.path = seq.name
        self.imager = seq.imager
        self.imagers = {seq.imager: _SequenceImager(np.asarray(g.q_imager_to_body, float),
                                                    float(g.scale_col), float(g.scale_row),
                                                    seq.top, int(g.n_rows), int(g.n_cols))}
        self.target_type = seq.object_type
        self.n_frames = seq.n_frames
        self.duration = float(seq.t[-1] - seq.t[0]) + seq.nominal_dt() if seq.n_frames else 0.0
        self.compaction = None
        self.faults = _NoFaults()

    def world(self) -> SequenceWorld:
        return SequenceWorld(self.seq)


class SequenceEvent(Event):
    """A :class:`FrameSequence` through the closed loop, with the IP's position prior from the TP
    (``"tp"``) or from the ground (``"centre"``, ``"truth"``: :data:`PRIOR_MODES`).

    Parameters
    ----------
    seq : FrameSequence
    sequence : flightsw.ip.ProcessingSequence
        Its preprocess frame shape must match the frames.
    record : flightsw.records.Record
    prior : "tp" | "centre" | "truth"
    withheld : bool [F], optional
        Frames whose message does not reach the TP (flagged frames: the IP's answer is kept, the
        track coasts over them).
    proposals : tuple of str
        The proposals in force (default none: the paper's system).
    keep_features : bool
        Keep every blob's feature words on each outcome (``outcome.feature_words``; tuning).
    """

    def __init__(self, seq: FrameSequence, sequence, record, prior: str = "tp", *, withheld=None,
                 proposals=(), keep_features: bool = False):
        if prior not in PRIOR_MODES:
            raise ValueError(f"prior={prior!r} must be one of {PRIOR_MODES}")
        self.seq, self.prior = seq, prior
        self.keep_features = bool(keep_features)
        n = seq.n_frames
        self._withheld = np.zeros(n, bool) if withheld is None else np.asarray(withheld, bool)
        if self._withheld.shape != (n,):
            raise ValueError(f"{seq.name}: withheld must hold {n} flags")
        given = expand(proposals or (), "proposals")
        cfg = EventConfig(scenario=SequenceScenario(seq), sequence=sequence, record=record,
                          tp={"frame_dt": seq.nominal_dt()}, stage_frame=-1,
                          proposals="all" if given == ALL else given, proposals_where="proposals")
        super().__init__(cfg, keep_frames=False)

    def frame_count(self, k: int) -> int:
        """The frame counter of frame ``k``'s message: the sequence's (16 bits)."""
        return int(self.seq.frame_count[k]) & 0xFFFF

    def withheld(self, k: int) -> bool:
        """Frame ``k``'s message does not reach the TP: a flagged frame, or a ground prior."""
        return self.prior != "tp" or bool(self._withheld[k])

    def _prediction_for(self, out, imager: str):
        if self.prior == "tp":
            return super()._prediction_for(out, imager)
        k, ot = out.k, self.record.object_type
        if self.prior == "truth" and self.seq.has_object[k]:
            fb = Feedback(float(self.seq.truth_row[k]), float(self.seq.truth_col[k]), ot, True)
        else:
            fb = Feedback(object_type=ot)
        out.pred_row, out.pred_col = fb.predicted_row, fb.predicted_col
        return fb


def centroid_mean(out, message) -> tuple:
    """The record centroid means the IP used on a frame: the prediction in force, else the centre
    of the message's window."""
    if math.isfinite(out.pred_row) and math.isfinite(out.pred_col):
        return float(out.pred_row), float(out.pred_col)
    f = message.compaction
    return (message.window_row0 + message.window_rows * f / 2.0,
            message.window_col0 + message.window_cols * f / 2.0)
