"""A real image sequence through the flight IP and TP, as ``uvisi track`` runs it: read and map
the frames (one field for the sequence, the record's job field), choose the sequence, replay the
closed loop.

Library functions (``uvisi track``, :mod:`hil_harness.tuning.label_scores`); the command's options
and output are :mod:`hil_harness.cli.track`'s.

Public: :func:`read_sequence`, :func:`default_track_sequence`, :func:`track_sequence`,
:data:`NOMINAL_DT`, :data:`WFOV_DEG`.
"""
from __future__ import annotations

import math
import sys

import numpy as np

__all__ = ["read_sequence", "default_track_sequence", "fit_sequence_to_frames", "track_sequence",
           "NOMINAL_DT", "WFOV_DEG"]

#: UVISI wide field of view across the 256 columns (groundsim's wfov imagers), degrees
WFOV_DEG = 13.1
#: the TP's nominal frame interval, s (the IP's 2 Hz)
NOMINAL_DT = 0.5


def read_sequence(paths, no_scale: bool = False, channel: str = "l", mask=None, circle=None,
                  field_scale: float = 1.0):
    """Read and map every frame -> (names, counts uint16 [F, H, W], scales, flags, time tags,
    field). ``channel``, ``mask``, ``circle``: as ``uvisi detect`` takes them; ``field_scale``:
    the part of a found fisheye circle kept (the record's job,
    :func:`hil_harness.detect.jobs.field_scale`)."""
    from tqdm import tqdm

    from hil_harness.field import sequence_field
    from hil_harness.images import frame_flags, read_images, scale_note, to_counts
    frames = read_images(paths, channel)
    if not frames:
        raise ValueError(f"{paths[0]}: no frames")
    shape = frames[0].data.shape
    for fr in frames:
        if fr.data.shape != shape:
            raise ValueError(f"{fr.name}: frame shape {fr.data.shape} differs from the first "
                             f"frame's {shape} (one sequence, one imager)")
    try:
        field = sequence_field(frames, mask, circle)
        if mask is None and circle is None:
            field = field.scaled(field_scale)
    except ValueError as exc:
        raise ValueError(f"{frames[0].name}: {'--mask' if mask is not None else '--field-circle'}"
                         f": {exc}") from None
    counts, scales, flags = [], [], []
    for fr in tqdm(frames, desc="[track] read", unit="frame", disable=len(frames) < 50,
                   file=sys.stderr):
        c, m = to_counts(fr.data, no_scale=no_scale, bits=fr.bits, field=field.mask)
        note = scale_note(fr.name, m)
        if note:
            print(f"uvisi track: note: {note}", file=sys.stderr)
        counts.append(c)
        scales.append(m)
        flags.append(frame_flags(fr.data, field.mask))
    return ([f.name for f in frames], np.array(counts, np.uint16), scales, flags,
            [f.time_utc for f in frames], field)


def default_track_sequence(record, shape, name=None):
    """The sequence ``uvisi track`` runs: ``name`` (shipped name or .toml) when given; else a job
    record's own sequence (:data:`hil_harness.detect.jobs.JOBS`: ``aurora_allsky`` runs
    ``aurora_allsky``, as in ``uvisi detect``); else by object type: aurora -> ``aurora``,
    anything else -> ``satellite``. Set for frames of ``shape`` (H, W) by
    :func:`fit_sequence_to_frames`."""
    from hil_harness.detect.jobs import job_sequence_name
    from hil_harness.tuning.data import load_sequence
    if name is None:
        name = job_sequence_name(record) or ("aurora" if record.object_type == "aurora"
                                             else "satellite")
    return fit_sequence_to_frames(load_sequence(name), shape)


def fit_sequence_to_frames(seq, shape):
    """``seq`` set for frames of ``shape`` (H, W).

    Interpretation (frames that are not UVISI's): where the compacted frame is smaller than the
    sequence's window in both directions, the window is the whole compacted frame, as ``uvisi
    detect --window 64`` places it (the flight's 256 x 244 frames always hold the window in one
    direction at least; :func:`flightsw.ip.preprocess.window_shape` cuts the other)."""
    from hil_harness.tuning.data import reshape_sequence
    pre = seq.preprocess
    whole = max(shape[0] // pre.compaction, shape[1] // pre.compaction)
    return reshape_sequence(seq, tuple(shape), min(pre.window, whole))


def track_sequence(counts, record, sequence, frame_dt=NOMINAL_DT, fov_deg=None, skip=None,
                   proposals=(), keep_blobs=False):
    """IP + TP over ``counts`` (uint16 [F, H, W]) -> (list of ReplayFrame, ImagerGeometry).

    ``skip`` (bool [F]): frames whose message does not reach the TP (flagged frames);
    ``proposals``: those in force (default none: the paper's system); ``keep_blobs``: keep each
    frame's rank and colour images (``ReplayFrame.ranks``, ``.colours``)."""
    from hil_harness.tuning.closed_loop import FrameSequence, replay
    from hil_harness.tuning.events import imager_geometry
    if not (isinstance(frame_dt, (int, float)) and math.isfinite(frame_dt) and frame_dt > 0):
        raise ValueError(f"--frame-dt {frame_dt!r} must be a positive number of seconds")
    w = counts.shape[2]
    fov = fov_deg if fov_deg is not None else math.degrees(
        2 * math.atan(w / 256.0 * math.tan(math.radians(WFOV_DEG) / 2)))
    geom = imager_geometry("real", fov, counts.shape[1:])
    ev = FrameSequence(counts, frame_dt * np.arange(counts.shape[0]), "real", geom,
                     name="input", object_type=record.object_type)
    return (replay(ev, sequence, record, "tp", skip=skip, proposals=proposals,
                   keep_blobs=keep_blobs), geom, fov)
