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
           "stand_in_attitude", "track_state", "ON_RADIUS", "on_label", "blob_at"]


@dataclass
class ReplayFrame:
    """One frame of a replay.

    ``candidates`` (CANDIDATE_DTYPE, best first, full-resolution pixels) and ``feature_words``
    ([n_blobs, 12] int64, every blob) are the IP's answer; ``prior`` the (row, col) feedback it got
    (NaN: none: window and record centroid at the image centre); ``centroid_mean`` the record
    centroid means it used; ``track`` the TP's state after the frame (:func:`track_state`; empty
    for the ``"centre"``/``"truth"`` priors, where the TP does not run); ``chosen`` the index of the
    candidate the TP used as the object (-1 none; the rank-1 candidate without a TP);
    ``prediction`` the (row, col) the TP predicts for the next frame. With ``replay(...,
    keep_blobs=True)`` (else None) the IP's blob images of the window, int32 [rows, cols] processed
    pixels (the window's top-left is ``window[0], window[1]`` in full-resolution pixels):
    ``ranks``, each reported blob's pixels numbered by its rank (1 = best), and ``colours``, every
    blob's pixels numbered by its colour (blob ``c`` is row ``c - 1`` of ``feature_words``); 0
    elsewhere."""

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
    ranks: np.ndarray | None = None
    colours: np.ndarray | None = None


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
           proposals=(), keep_blobs: bool = False) -> list:
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
    keep_blobs : bool
        Keep each frame's rank and colour images (``ReplayFrame.ranks``, ``.colours``; the IP then
        forms its stage images, which changes none of its outputs).
    """
    ev = SequenceEvent(event, sequence, record, prior, withheld=skip, proposals=proposals,
                       keep_features=True)
    ev.all_stages = bool(keep_blobs)
    out = []
    while not ev.done:
        o = ev.step()
        msg = CandidateMessage.from_words(o.message_words)          # what crossed the bus
        rf = ReplayFrame(o.k, float(o.t), msg.candidates, o.feature_words,
                         (msg.window_row0, msg.window_col0, msg.window_rows, msg.window_cols,
                          msg.compaction), (o.pred_row, o.pred_col), centroid_mean(o, msg),
                         float(msg.alpha), chosen=0 if msg.count else -1)
        if keep_blobs and o.stages:
            st = dict(o.stages)
            rf.ranks = np.asarray(st["rank"], np.int32)
            rf.colours = np.asarray(st["colour"], np.int32)
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


#: processed (compacted) pixels between a candidate's centroid and the label that still count
ON_RADIUS = 3.0


def on_label(row: float, col: float, rank: int, ranks, origin, f: int, label,
             radius: float = ON_RADIUS) -> bool:
    """Is a candidate on the labelled pixel (issue 43's rule)?

    ``row``, ``col``: the candidate's centroid (full-resolution pixels, centres at +0.5);
    ``rank``: its rank in ``ranks`` (1 = best); ``ranks``: int32 [h, w] rank image of the window
    in processed pixels, or None (then only the distance counts); ``origin``: the window's top-left
    (row, col) in full-resolution pixels; ``f``: compaction; ``label``: (row, col), full-resolution
    pixels. True when the centroid is within ``radius`` processed pixels of the label or the
    labelled pixel belongs to the candidate's blob."""
    lr, lc = label
    if math.hypot(row - lr, col - lc) <= radius * f:
        return True
    return blob_at(ranks, origin, f, label) == rank


def blob_at(image, origin, f: int, label) -> int:
    """The value of a window's blob image (rank or colour, int [h, w] processed pixels, or None)
    under the full-resolution pixel ``label`` (row, col); 0 when none or off the window."""
    if image is None:
        return 0
    i = int(math.floor((label[0] - origin[0]) / f))
    j = int(math.floor((label[1] - origin[1]) / f))
    ok = 0 <= i < image.shape[0] and 0 <= j < image.shape[1]
    return int(image[i, j]) if ok else 0


def score_top1(event: FrameSequence, frames: list, radius_px: float) -> np.ndarray:
    """bool [F]: the IP's rank-1 candidate lies within ``radius_px`` of the true object position,
    or -- when the replay kept its blob images (``keep_blobs``) -- its blob holds that pixel
    (False where nothing is reported or the object is absent). The only reader of truth."""
    hit = np.zeros(event.n_frames, bool)
    for k, rf in enumerate(frames):
        if rf.candidates.size and event.has_object[k]:
            c, f = rf.candidates[0], int(rf.window[4])
            hit[k] = on_label(float(c["row"]), float(c["col"]), 1, rf.ranks, rf.window[:2], f,
                              (event.truth_row[k], event.truth_col[k]), radius_px / f)
    return hit
