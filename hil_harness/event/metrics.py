"""Event-level tracking figures computed from a closed-loop event's frame outcomes.

``held_after_lock`` is the figure behind ``summary.json``'s ``held_fraction_after_lock`` (issue 20):
the share of frames after lock on which the track processor is locked and its prediction lies within
3 processed pixels of the truth.
"""
from __future__ import annotations

import math

import numpy as np

from hil_harness.rates import wilson_interval

__all__ = ["HELD_RADIUS_PX", "held_after_lock", "processed_pixel_urad"]

#: a frame is "held" when the prediction is within this many processed pixels of the truth
HELD_RADIUS_PX = 3.0


def processed_pixel_urad(geometry_entry, compaction: int) -> float:
    """One processed pixel as an angle (urad): ``compaction`` x the imager pixel, the imager pixel being
    the RMS of its column and row scales, ``hypot(scale_col, scale_row) / sqrt(2)`` (rad/px).
    ``geometry_entry``: ``(scale_col, scale_row, q_imager_to_body)`` as in ``Event.geometry``."""
    sc, sr = float(geometry_entry[0]), float(geometry_entry[1])
    return 1e6 * math.hypot(sc, sr) / math.sqrt(2) * int(compaction)


def held_after_lock(outcomes, geometry: dict, compaction: int, radius_px: float = HELD_RADIUS_PX) -> dict:
    """Share of frames after lock on which the track holds the object.

    Definitions (frame k is the k-th outcome, 2 Hz; dropped and skipped frames included):

    * lock frame L: the first frame whose track-processor command reports ``locked``;
    * frames counted: every frame k > L, i.e. from the first frame whose prediction was made by a
      locked TP to the end of the event (n = N - 1 - L; n = 0 if the TP never locked or locked on the
      last frame);
    * frame k is **held** when (a) the TP command in force for frame k -- the last command issued on
      a frame before k, whose prediction placed frame k's window -- reports ``locked``, (b) the object
      is in the field (truth), and (c) that prediction (``outcome.pred_row/pred_col``) lies within
      ``radius_px`` processed pixels of the true object pixel, as an angle:
      ``outcome.error_urad <= radius_px * compaction * imager pixel`` with the imager pixel of frame
      k's imager (:func:`processed_pixel_urad`). A frame with the object out of the field, or with no
      prediction, is not held.

    Truth is read only here, to score.

    Parameters
    ----------
    outcomes : sequence of FrameOutcome-like objects
        Each with ``command`` (None or an object with a bool ``locked``), ``imager`` (str),
        ``error_urad`` (float, urad, NaN when not scoreable) and ``truth`` (dict).
    geometry : dict
        imager id -> ``(scale_col, scale_row, q)`` (rad/px).
    compaction : int
        Processed pixel = compaction x imager pixel.
    radius_px : float
        Hold radius in processed pixels (default 3).

    Returns
    -------
    dict: ``lock_frame`` (int or None), ``k`` (held frames), ``n`` (frames counted), ``rate`` (k / n;
    0.0 when n = 0), ``ci95`` ([lo, hi], Wilson), ``radius_px``, and ``error_px`` (float64[n], the
    prediction error of each counted frame in processed pixels, NaN where not scoreable).
    """
    locked_cmd = np.array([bool(o.command.locked) if o.command is not None else False for o in outcomes])
    issued = np.array([o.command is not None for o in outcomes])
    lock_frame = int(np.argmax(locked_cmd)) if locked_cmd.any() else None
    held = []
    err_px = []
    in_force = False                 # lock state of the last command issued before frame k
    for k, o in enumerate(outcomes):
        if lock_frame is not None and k > lock_frame:
            tg = (o.truth or {}).get("target") or {}
            px = processed_pixel_urad(geometry[o.imager], compaction)
            e = float(o.error_urad) / px if tg.get("in_field") else float("nan")
            err_px.append(e)
            held.append(bool(in_force and np.isfinite(e) and e <= radius_px))
        if issued[k]:
            in_force = bool(locked_cmd[k])
    n = len(held)
    k_held = int(sum(held))
    lo, hi = wilson_interval(k_held, n)
    return {"lock_frame": lock_frame, "k": k_held, "n": n, "rate": (k_held / n) if n else 0.0,
            "ci95": [lo, hi], "radius_px": float(radius_px), "error_px": np.asarray(err_px, float)}
