"""One frame through the image processor, as a convenience over the compiled pipeline
(:mod:`flightsw.ip.pipeline`): :func:`process_frame` for a frame, :func:`process_window` for a
window the caller cut. The flight module is :class:`flightsw.ip.ImageProcessor`; the back end alone
is :func:`flightsw.ip.backend.backend`.

Every way of running a frame runs the same two kernels on a plan's frame header
(:data:`flightsw.ip.frame_header.FRAME_HEADER`): :func:`flightsw.ip.pipeline.place_window_k`
places the window about the prediction and :func:`flightsw.ip.pipeline.ip_frame_into_k` runs the
pipeline. :meth:`flightsw.ip.ImageProcessor.step` calls them inside its one compiled step (with the
command read, the message and the alpha logic); :func:`process_frame` through
:meth:`flightsw.ip.pipeline.FramePlan.run` on a kept plan (:func:`flightsw.ip.pipeline.plan_for`:
no processor is built per call); :func:`process_window` skips the placement (the caller cut the
window). The ground's full-frame detector (:mod:`hil_harness.detect`) takes its header and the
back end's parameters from the same plan and runs the same stage kernels, the window union its
one added step.
"""
from __future__ import annotations

import math

import numpy as np

from flightsw.budget import Ledger
from flightsw.ip.backend import BackendResult, backend
from flightsw.ip.pipeline import FrameResult, plan_for
from flightsw.ip.preprocess import Subimage
from flightsw.ip.sequence import ProcessingSequence
from flightsw.messages import Feedback
from flightsw.records import Record

__all__ = ["backend", "BackendResult", "process_frame", "process_window", "FrameResult",
           "check_inputs", "frame_parts"]


def frame_parts(frame):
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


def _check_objects(sequence, record):
    if not isinstance(sequence, ProcessingSequence):
        raise ValueError(f"sequence must be a ProcessingSequence, got {type(sequence).__name__}")
    if not isinstance(record, Record):
        raise ValueError(f"record must be a flightsw.records.Record, got {type(record).__name__}")


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

    Its keyword-only options are the reason for its 11 parameters (the message header's values
    and the ground's overrides; the compiled pipeline takes its inputs as records).

    Returns
    -------
    FrameResult (iterates as ``message, stages, ledger``)
    """
    _check_objects(sequence, record)
    if feedback is not None and not isinstance(feedback, Feedback):
        raise ValueError(f"feedback must be a flightsw.messages.Feedback, got "
                         f"{type(feedback).__name__}")
    img, meta = frame_parts(frame)
    imager = imager if imager is not None else str(meta.get("imager", "wfov_vis"))
    frame_count = int(frame_count if frame_count is not None else meta.get("frame_count", 0)) & 0xFFFF
    time_tag = float(time_tag if time_tag is not None else meta.get("time_tag", 0.0))
    check_inputs(alpha_q12, time_tag)
    img = sequence.checked_frame(img, check)
    pred = None
    if feedback is not None and feedback.has_prediction:
        pred = (float(feedback.predicted_row), float(feedback.predicted_col))
    return plan_for(sequence, record, imager).run(
        img, pred, alpha_q12=alpha_q12, ledger=ledger, frame_count=frame_count, time_tag=time_tag,
        want_stages=want_stages)


def process_window(sub: Subimage, sequence, record, centroid_mean=None, *,
                   imager: str = "wfov_vis", **options) -> FrameResult:
    """The part of :func:`process_frame` after the preprocessor, on a given ``Subimage`` ``sub``
    (the ground's full-frame mode cuts its own windows). ``centroid_mean`` (full-res (row, col))
    replaces the record's centroid means; None: the window centre. ``options``: the keywords of
    :meth:`flightsw.ip.pipeline.FramePlan.run_window` (``alpha_q12``, ``ledger``,
    ``frame_count``, ``time_tag``, ``want_stages`` (default True here), ``max_candidates``)."""
    _check_objects(sequence, record)
    check_inputs(options.get("alpha_q12"), float(options.get("time_tag", 0.0)))
    if not isinstance(sub, Subimage):
        raise ValueError(f"sub must be a flightsw.ip.preprocess.Subimage, got {type(sub).__name__}")
    options.setdefault("want_stages", True)
    return plan_for(sequence, record, imager).run_window(sub, centroid_mean, **options)
