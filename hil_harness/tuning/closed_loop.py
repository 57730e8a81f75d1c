"""Closed-loop replay: the flight IP and TP over a fixed sequence of full frames.

The frames of an event (a scenario run, rendered once) or of a real image sequence are replayed
through the flight IP (:func:`flightsw.ip.process_frame`) and the flight TP
(:class:`flightsw.tp.TrackProcessor`, target-of-opportunity mode) exactly as the event loop
(:mod:`hil_harness.event`) couples them, minus the spacecraft: the pointing does not follow the TP's
command (the frames are fixed), everything else does::

    frame k --process_frame(feedback k)--> CandidateMessage --words (CRC)-->
    TrackProcessor.step(words, attitude k) --> TrackCommand --words (CRC)--> feedback k + 1

The feedback centres the IP's window and replaces the record's centroid means; the first frame of
a sequence has none (window and record centroid at the image centre). Three position priors:

``"tp"``
    the flight one (above): the TP's prediction made on the previous frame.
``"centre"``
    no prior: every frame processed from the centre.
``"truth"``
    the true object position of the frame (an upper bound; a frame without the object gets no
    prior). The only mode in which truth reaches the IP.

Truth (``ReplayEvent.truth_row``/``truth_col``) is otherwise read only by :func:`score_top1`.
Rates come with their count and a Wilson 95 % interval (:func:`rate`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flightsw.ip import process_frame
from flightsw.ip.processor import alpha_controller_for, apply_floor_proposals
from flightsw.messages import AttitudeData, CandidateMessage, Feedback, TrackCommand
from flightsw.proposals import expand
from flightsw.tp import ImagerGeometry, TPConfig, TrackProcessor


__all__ = ["ReplayEvent", "ReplayFrame", "PRIOR_MODES", "replay", "score_top1",
           "stand_in_attitude", "track_state", "window_centre"]

PRIOR_MODES = ("tp", "centre", "truth")


@dataclass
class ReplayEvent:
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

    @property
    def has_object(self) -> np.ndarray:
        """bool [F]: the object is in the frame (truth known)."""
        return np.isfinite(self.truth_row) & np.isfinite(self.truth_col)

    def block(self, a: int, b: int, name: str | None = None) -> "ReplayEvent":
        """Frames ``a:b`` as an event of their own (the loop starts afresh at frame ``a``)."""
        return ReplayEvent(self.frames[a:b], self.t[a:b], self.imager, self.geometry,
                           None if self.attitude is None else self.attitude[a:b],
                           self.frame_count[a:b], self.truth_row[a:b], self.truth_col[a:b],
                           name or f"{self.name}[{a}:{b}]", self.object_type)

    def without_truth(self) -> "ReplayEvent":
        """The same event with every truth position replaced by NaN."""
        return ReplayEvent(self.frames, self.t, self.imager, self.geometry, self.attitude,
                           self.frame_count, None, None, self.name, self.object_type)


@dataclass
class ReplayFrame:
    """One frame of a replay.

    ``candidates`` (CANDIDATE_DTYPE, best first, full-resolution pixels) and ``feature_words``
    ([n_blobs, 12] int64, every blob) are the IP's answer; ``prior`` the (row, col) feedback it got
    (NaN: none: window and record centroid at the image centre); ``centroid_mean`` the record
    centroid means it used; ``track`` the TP's state after the frame (:func:`track_state`; empty
    for the ``"centre"``/``"truth"`` priors, where the TP does not run); ``chosen`` the index of the
    candidate the TP used as the object (-1 none; the rank-1 candidate without a TP);
    ``prediction`` the (row, col) the TP predicts for the next frame."""

    k: int
    t: float
    candidates: np.ndarray
    feature_words: np.ndarray
    window: tuple
    prior: tuple
    centroid_mean: tuple
    alpha: float
    chosen: int = -1
    prediction: tuple = (math.nan, math.nan)
    track: dict = field(default_factory=dict)


def stand_in_attitude(t: float) -> AttitudeData:
    """A fixed pointing (identity attitude, no rate, no orbit) at time ``t``: the TP then works in
    the imager's own tangent plane."""
    return AttitudeData(t=float(t), r_eci=np.array([7.0e6, 0.0, 0.0]),
                        v_eci=np.array([0.0, 7.5e3, 0.0]))


def window_centre(message: CandidateMessage) -> tuple:
    """Centre (row, col) of the message's processing window, full-resolution pixels."""
    f = message.compaction
    return (message.window_row0 + message.window_rows * f / 2.0,
            message.window_col0 + message.window_cols * f / 2.0)


def track_state(cmd: TrackCommand) -> dict:
    """The TP's state after a frame, JSON-ready (NaN -> None)."""
    def num(x):
        x = float(x)
        return x if math.isfinite(x) else None
    return {"locked": bool(cmd.locked), "decided": bool(cmd.decided),
            "coasting": bool(cmd.coasting), "status": cmd.status_names(),
            "object_index": int(cmd.object_index), "object_type": cmd.object_type,
            "predicted_row": num(cmd.predicted_row), "predicted_col": num(cmd.predicted_col),
            "mode": cmd.mode}


def _tp_for(event: ReplayEvent, frame_dt: float, tp_overrides: dict | None):
    kw = dict(imagers={event.imager: event.geometry}, mode="opportunity",
              object_type=event.object_type, frame_dt=float(frame_dt))
    kw.update(tp_overrides or {})
    return TrackProcessor(TPConfig(**kw))


def _nominal_dt(t) -> float:
    d = np.diff(np.asarray(t, float))
    return float(np.median(d)) if d.size else 0.5


def replay(event: ReplayEvent, sequence, record, prior: str = "tp", *, tp_overrides=None,
           skip=None, attitude_times=None, proposals=()) -> list:
    """Replay ``event`` through the IP (and, for ``prior="tp"``, the TP) -> list of
    :class:`ReplayFrame`, one per frame.

    Parameters
    ----------
    event : ReplayEvent
    sequence : flightsw.ip.sequence.ProcessingSequence
        Its preprocess frame shape must match the frames.
    record : flightsw.records.Record
    prior : "tp" | "centre" | "truth"
        Where the IP's position prior comes from (module docstring).
    tp_overrides : dict, optional
        :class:`flightsw.tp.TPConfig` fields (default: opportunity mode, ``frame_dt`` the median
        frame interval).
    skip : bool [F], optional
        Frames whose message does not reach the TP (flagged frames: the IP's answer is kept, the
        track coasts over them).
    attitude_times : ndarray [F], optional
        Time tags given the TP (default ``event.t``).
    proposals : tuple of str
        The proposals in force (:mod:`flightsw.proposals`; default none, the paper's system): the
        TP's (``opp_startup``) and the alpha logic's floors.
    """
    if prior not in PRIOR_MODES:
        raise ValueError(f"prior={prior!r} must be one of {PRIOR_MODES}")
    n = event.n_frames
    skip = np.zeros(n, bool) if skip is None else np.asarray(skip, bool)
    times = event.t if attitude_times is None else np.asarray(attitude_times, float)
    proposals = expand(proposals, "proposals")
    tp = _tp_for(event, _nominal_dt(times), {"proposals": proposals, **(tp_overrides or {})}) \
        if prior == "tp" else None
    if tp is not None:
        tp.reset()
    sequence = apply_floor_proposals(sequence, proposals)
    alpha = alpha_controller_for(sequence, proposals)
    fb = Feedback(object_type=record.object_type)
    out = []
    for k in range(n):
        if prior == "centre":
            fb = Feedback(object_type=record.object_type)
        elif prior == "truth":
            fb = Feedback(float(event.truth_row[k]), float(event.truth_col[k]), record.object_type,
                          bool(event.has_object[k]))
        res = process_frame(event.frames[k], sequence, record, fb, imager=event.imager,
                            frame_count=int(event.frame_count[k]) & 0xFFFF,
                            time_tag=float(times[k]), alpha_q12=alpha.q12, want_stages=False)
        words = res.message.to_words()
        msg = CandidateMessage.from_words(words)                 # what crosses the bus
        mean = (fb.predicted_row, fb.predicted_col) if fb.has_prediction else window_centre(msg)
        rf = ReplayFrame(k, float(times[k]), msg.candidates, res.backend.feature_words.copy(),
                         (msg.window_row0, msg.window_col0, msg.window_rows, msg.window_cols,
                          msg.compaction), (fb.predicted_row, fb.predicted_col),
                         (float(mean[0]), float(mean[1])), float(msg.alpha),
                         chosen=0 if msg.count else -1)
        alpha.update(int(res.backend.count), bool(fb.locked))
        if tp is not None:
            rf.chosen = -1
            if not skip[k]:
                att = (event.attitude[k] if event.attitude is not None
                       else stand_in_attitude(times[k]))
                cmd = TrackCommand.from_words(tp.step(words, att).to_words())
                fb = cmd.feedback()
                rf.chosen = int(cmd.object_index) if 0 <= cmd.object_index < msg.count else -1
                rf.track = track_state(cmd)
            else:
                rf.track = {"skipped": True}
            rf.prediction = (fb.predicted_row, fb.predicted_col)
        out.append(rf)
    return out


def score_top1(event: ReplayEvent, frames: list, radius_px: float) -> np.ndarray:
    """bool [F]: the IP's rank-1 candidate lies within ``radius_px`` of the true object position
    (False where nothing is reported or the object is absent). The only reader of truth."""
    hit = np.zeros(event.n_frames, bool)
    for k, rf in enumerate(frames):
        if rf.candidates.size and event.has_object[k]:
            c = rf.candidates[0]
            d = math.hypot(float(c["row"]) - event.truth_row[k],
                           float(c["col"]) - event.truth_col[k])
            hit[k] = d <= radius_px
    return hit
