"""Closed-loop replay for tuning and ``uvisi track``: a fixed sequence of full frames through the
one closed loop (:class:`hil_harness.event.frames.SequenceEvent`, an
:class:`~hil_harness.event.loop.Event` fed from the sequence), with each frame's answer kept as a
:class:`ReplayFrame`.

The feedback centres the IP's window and replaces the record's centroid means; the first frame of
a sequence has none (window and record centroid at the image centre). The position priors are
:data:`~hil_harness.event.frames.PRIOR_MODES` (``"tp"``: the flight one; ``"centre"``; ``"truth"``,
the labelled upper bound, the only mode in which truth reaches the IP).

Truth (``FrameSequence.truth_row``/``truth_col``) is otherwise read only by :func:`score_top1`.
Rates come with their count and a Wilson 95 % interval (:func:`hil_harness.rates.rate`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flightsw.messages import CandidateMessage, TrackCommand
from hil_harness.event.frames import (PRIOR_MODES, FrameSequence, SequenceEvent, centroid_mean,
                                      stand_in_attitude)

__all__ = ["FrameSequence", "ReplayFrame", "PRIOR_MODES", "replay", "score_top1",
           "stand_in_attitude", "track_state"]


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


def replay(event: FrameSequence, sequence, record, prior: str = "tp", *, skip=None,
           proposals=()) -> list:
    """Replay ``event`` through the closed loop -> list of :class:`ReplayFrame`, one per frame.

    Parameters
    ----------
    event : FrameSequence
    sequence : flightsw.ip.sequence.ProcessingSequence
        Its preprocess frame shape must match the frames.
    record : flightsw.records.Record
    prior : "tp" | "centre" | "truth"
        Where the IP's position prior comes from (module docstring).
    skip : bool [F], optional
        Frames whose message does not reach the TP (flagged frames: the IP's answer is kept, the
        track coasts over them).
    proposals : tuple of str
        The proposals in force (:mod:`flightsw.proposals`; default none, the paper's system).
    """
    ev = SequenceEvent(event, sequence, record, prior, withheld=skip, proposals=proposals,
                       keep_features=True)
    out = []
    while not ev.done:
        o = ev.step()
        msg = CandidateMessage.from_words(o.message_words)          # what crossed the bus
        rf = ReplayFrame(o.k, float(o.t), msg.candidates, o.feature_words,
                         (msg.window_row0, msg.window_col0, msg.window_rows, msg.window_cols,
                          msg.compaction), (o.pred_row, o.pred_col), centroid_mean(o, msg),
                         float(msg.alpha), chosen=0 if msg.count else -1)
        ev.outcomes[-1] = None                                         # memory: the frame's here
        if prior == "tp":
            rf.chosen = -1
            if ev.withheld(o.k):
                rf.track = {"skipped": True}
            elif o.command is not None:
                i = int(o.command.object_index)
                rf.chosen = i if 0 <= i < msg.count else -1
                rf.track = track_state(o.command)
            rf.prediction = (ev.feedback.predicted_row, ev.feedback.predicted_col)
        out.append(rf)
    return out


def score_top1(event: FrameSequence, frames: list, radius_px: float) -> np.ndarray:
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
