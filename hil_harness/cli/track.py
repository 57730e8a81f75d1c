"""``uvisi track``: the flight IP and TP over a real image sequence.

``uvisi track IMAGES... --record R [--sequence S] --json OUT [--plot PNG] [--frame-dt S]
[--fov DEG] [--no-scale]``

The frames (every frame of every file, in order: single images, or a multi-frame NPZ / FITS / TIFF
cube) are read and turned into the flight's 12-bit counts by :mod:`hil_harness.images` (counts pass
unchanged, wide integers by a known shift, anything else by a robust map from the background and
the noise; ``--no-scale`` insists on counts), then replayed exactly as in the closed loop
(:mod:`hil_harness.tuning.closed_loop`), without a spacecraft: each frame's window is placed and the
record's centroid means are set from the TP's prediction of the previous frame (the first frame
from the image centre); the TP runs in target-of-opportunity mode with a stand-in attitude (fixed
pointing), imager pixel scale from ``--fov`` (degrees across the columns) or the UVISI wide field
of view (13.1 deg across 256 columns, scaled to the frame width), and a nominal 0.5 s per input
frame unless ``--frame-dt`` is given (real sequences can be minutes apart, beyond the TP's coast
limit). Real time tags, where the input has them, are written beside each frame. Frames whose
compacted image is smaller than the sequence's window both ways are processed in one window of the
whole compacted frame, as ``uvisi detect --window 64`` does (a note says so).

The instrument's field (``--mask FILE``, ``--field-circle ROW,COL,RADIUS``, else found on the
median of up to 16 frames: :mod:`hil_harness.field`) is one for the whole sequence; pixels outside
it take part in no statistic, flag or detection (:func:`hil_harness.images.to_counts` sets them to
the field's background before the 12-bit mapping). ``--channel`` picks what a colour frame becomes.

Bad frames (:func:`hil_harness.images.frame_flags`, measured inside the field) are reported in the
JSON and on stderr (one line for each kind of flagged frame, naming its frames:
:func:`hil_harness.cli.flag_report.flag_lines`). An *unusable* one (blank, constant, nan, missing)
still gets the IP's answer, but its candidate message does not reach the TP: it does not move the
track. A *warning* (saturated) is reported and the frame is used.

Output (``--json``)::

    {"record", "sequence", "frame_dt", "fov_deg", "scale_rad_per_px", "field",
     "frames": [{"index", "input", "time_utc", "t", "shape", "flags", "scale",
                 "window": {"row0", "col0", "rows", "cols", "compaction"},
                 "prior": {"row", "col"} | null,
                 "candidates": [{"rank", "row", "col", "distance", "gof", "features": {...}}],
                 "chosen": rank of the candidate the TP used (1-based) | null,
                 "track": {"locked", "decided", "coasting", "status", "object_index",
                           "object_type", "predicted_row", "predicted_col", "mode"}
                          | {"skipped": true, "reason": "flagged: ..."}}]}

Candidates are best first, centroids in full-resolution pixels (0-based, pixel centres at +0.5),
as ``uvisi detect`` writes them.
"""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from hil_harness.cli.flag_report import flag_lines
from hil_harness.cli.options import add_with_option, with_names
from hil_harness.console import note
from hil_harness.fileio import temp_beside
from hil_harness.real_track import (NOMINAL_DT, default_track_sequence, fit_sequence_to_frames,
                                     read_sequence, track_sequence)


def register(sub) -> None:
    p = sub.add_parser("track", help="the flight IP + TP over a real image sequence",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("images", nargs="+",
                   help="image files in order (FITS, TIFF, PNG, NPY, NPZ; a cube gives one frame "
                        "per plane)")
    p.add_argument("--record", required=True,
                   help="a priori record: shipped name (aurora, aurora_allsky, aurora_surge, star, "
                        "streak, satellite, plume) or .toml")
    p.add_argument("--sequence", default=None,
                   help="processing sequence: shipped name or .toml (default: a job record's own "
                        "sequence, as in uvisi detect; else 'aurora' for an aurora record, "
                        "'satellite' for the others)")
    p.add_argument("--json", required=True, help="output JSON file")
    p.add_argument("--plot", default=None, help="PNG: the track over the last good frame")
    p.add_argument("--frame-dt", type=float, default=NOMINAL_DT,
                   help="seconds between input frames on the TP's clock (default 0.5)")
    p.add_argument("--fov", type=float, default=None,
                   help="field of view across the columns, degrees (default: the UVISI wide "
                        "field, 13.1 deg over 256 columns, scaled to the frame width)")
    p.add_argument("--no-scale", action="store_true",
                   help="the pixels must already be 12-bit counts (no mapping)")
    add_with_option(p)
    from hil_harness.cli.detect import add_input_options
    add_input_options(p)
    p.set_defaults(func=run, outputs={"json": "file", "plot": "file"})


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _candidates(cands) -> list:
    from flightsw.messages import FEATURE_NAMES
    return [{"rank": i + 1, "row": float(c["row"]), "col": float(c["col"]),
             "distance": _num(c["distance"]), "gof": _num(c["gof"]),
             "features": {n: _num(c[n]) for n in FEATURE_NAMES}} for i, c in enumerate(cands)]


def _frame_entry(k, name, tag, rf, scale, flags) -> dict:
    from hil_harness.images import UNUSABLE
    r0, c0, rows, cols, f = rf.window
    prior = None if not math.isfinite(rf.prior[0]) else {"row": rf.prior[0], "col": rf.prior[1]}
    track = dict(rf.track)
    if track.get("skipped"):
        track["reason"] = "flagged: " + ", ".join(f for f in flags if f in UNUSABLE)
    return {"index": k, "input": name, "time_utc": tag, "t": rf.t,
            "flags": list(flags), "scale": scale,
            "window": {"row0": int(r0), "col0": int(c0), "rows": int(rows), "cols": int(cols),
                       "compaction": int(f)},
            "prior": prior, "candidates": _candidates(rf.candidates),
            "chosen": rf.chosen + 1 if rf.chosen >= 0 else None, "track": track}


def _write_json(path, obj):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = temp_beside(path, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(obj, fh, indent=1, allow_nan=False)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _sequence_for_frames(seq, shape, first):
    """``seq`` (the track's sequence at the flight frame's shape) set for frames of ``shape``
    (H, W). A note when the frames are too small for its window (the window is then the whole
    compacted frame: :func:`hil_harness.real_track.fit_sequence_to_frames`); an error names the
    first input."""
    try:
        out = fit_sequence_to_frames(seq, shape)
    except ValueError as exc:
        raise ValueError(f"{first}: frames of {shape[0]}x{shape[1]} pixels: {exc}") from None
    c, w = seq.preprocess.compaction, seq.preprocess.window
    if out.preprocess.window != w:
        note(f"uvisi track: note: frames of {shape[0]}x{shape[1]} pixels are "
             f"{shape[0] // c}x{shape[1] // c} at the sequence {seq.name}'s compaction {c}, "
             f"smaller than its {w}x{w} window: the window is the whole compacted frame (as in "
             f"uvisi detect --window 64)")
    return out


def _why(unusable: bool, several: bool) -> str:
    if unusable:
        return ("unusable: the IP still answers; the track does not move on "
                + ("them" if several else "it"))
    return "a warning: the frames are used" if several else "a warning: the frame is used"


def run(args) -> int:
    from hil_harness.tuning.export import record_from
    record = record_from(args.record)
    if args.fov is not None and not 0.0 < args.fov < 90.0:
        raise ValueError(f"--fov {args.fov} must be in (0, 90) degrees")
    if not (math.isfinite(args.frame_dt) and args.frame_dt > 0):    # before the frames are read
        raise ValueError(f"--frame-dt {args.frame_dt} must be a positive number of seconds")
    from flightsw.ip.preprocess import FRAME_SHAPE
    from hil_harness.cli.detect import read_mask
    from hil_harness.detect.jobs import field_scale
    from hil_harness.images import unusable
    seq = default_track_sequence(record, FRAME_SHAPE, args.sequence)     # its own errors first
    names, counts, scales, flags, tags, field = read_sequence(
        args.images, args.no_scale, args.channel, read_mask(args.mask), args.field_circle,
        field_scale(record))
    seq = _sequence_for_frames(seq, counts.shape[1:], args.images[0])
    skip = np.array([unusable(f) for f in flags])
    for line in flag_lines(names, flags, skip, _why):
        print(f"uvisi track: warning: {line}", file=sys.stderr)
    from flightsw.proposals import flight_profile
    proposals = with_names(args, "opportunity") or ()     # uvisi track: no velocity filter
    frames, geom, fov = track_sequence(counts, record, seq, args.frame_dt, args.fov, skip,
                                       proposals)
    out = {"record": record.name, "sequence": seq.name, "flight": flight_profile(proposals),
           "frame_dt": args.frame_dt,
           "fov_deg": fov, "scale_rad_per_px": geom.scale_col, "field": field.to_json(),
           "frames": [_frame_entry(k, names[k], tags[k], rf, scales[k], flags[k])
                      for k, rf in enumerate(frames)]}
    _write_json(args.json, out)
    locked = sum(1 for e in out["frames"] if e["track"].get("locked"))
    n = len(frames)
    print(f"{n} frame{'' if n == 1 else 's'} ({int(skip.sum())} unusable), record {record.name}, "
          f"sequence {seq.name}: the TP locked on {locked}; wrote {args.json}")
    if args.plot:
        _plot(args.plot, counts, out["frames"], skip)
    return 0


def _plot(path, counts, frames, skip):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    good = np.flatnonzero(~skip)
    img = counts[good[-1] if good.size else -1]
    H, W = img.shape
    fig, ax = plt.subplots(figsize=(7, 7 * H / W + 0.4), dpi=110)
    lo, hi = np.percentile(img, [1, 99.7])
    ax.imshow(img, cmap="gray", vmin=lo, vmax=max(hi, lo + 1), extent=(0, W, H, 0))
    pts = [(e["candidates"][e["chosen"] - 1]["col"], e["candidates"][e["chosen"] - 1]["row"])
           for e in frames if e["chosen"]]
    if pts:
        ax.plot(*zip(*pts), "-o", color="#ff4040", ms=3, lw=1, label="TP's object")
    pr = [(e["prior"]["col"], e["prior"]["row"]) for e in frames if e["prior"]]
    if pr:
        ax.plot(*zip(*pr), "x", color="#33ddff", ms=4, label="prediction (window centre)")
    if pts or pr:
        ax.legend(fontsize=7, loc="lower right")
    n_flagged = sum(1 for e in frames if e["flags"])
    n = len(frames)
    ax.set_title(f"{n} frame{'' if n == 1 else 's'} ({n_flagged} flagged, {int(np.sum(skip))} of "
                 f"them unusable); the last usable frame shown", fontsize=9)
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p)
    plt.close(fig)
