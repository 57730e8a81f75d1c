"""``uvisi detect``: the flight image processor on real image files.

``uvisi detect IMAGE... [--record NAME|FILE] [--sequence NAME|FILE] [--compaction N]
[--window full|64] [--no-scale] [--channel l|r|g|b] [--mask FILE | --field-circle ROW,COL,RADIUS]
[--max-candidates K] [--workers N] [--json OUT] [--plot PNG]``

Reads FITS, TIFF, PNG/JPEG, NPY/NPZ (every plane of a cube, in order: :mod:`hil_harness.images`),
turns each frame into the flight's 12-bit counts (:func:`hil_harness.images.to_counts`: counts pass
unchanged, wide integers with zero low bits are shifted, anything else is mapped from its sky level
and noise -- not stretched to its maximum), flags bad frames, runs the flight IP (compaction, the
sequence's front end, blob colouring, the 12 features, ranking against the record) and reports per
image the candidates with full-resolution centroids (0-based ``[row, col]``, pixel centres at
+0.5)::

    {"images": [{"path", "time_utc", "shape", "flags", "scale", "field", "compaction", "mode",
                 "windows", "record", "sequence", "gate",
                 "candidates": [{"rank", "row", "col", "distance", "gof", "features": {...}}]}]}

Without ``--json`` a table goes to stdout. The instrument's field (:mod:`hil_harness.field`) is
found in each frame or given by ``--mask`` / ``--field-circle``; pixels outside it take part in no
statistic, flag or detection. A flagged frame (unusable: blank, constant, nan, missing; warning:
saturated; :func:`hil_harness.images.frame_flags`, inside the field) is warned of on stderr, once
the frames are done, in one line for each kind of flagged frame
(:func:`hil_harness.cli.flag_report.flag_lines`); the IP's answer for it is still given. The jobs
(star, streak, aurora: :mod:`hil_harness.detect.jobs`) and the full-frame tiling
(:mod:`hil_harness.detect.fullframe`) are described in :data:`HELP_TEXT`, the ``--help`` text.
"""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from hil_harness.cli.flag_report import flag_lines
from hil_harness.cli.options import number
from hil_harness.detect.jobs import FIELD_SPARE          # re-exported: it was defined here
from hil_harness.images import (CHANNELS, ImageError, frame_flags, read_images, scale_note,
                                to_counts, unusable)

__all__ = ["register", "run", "detect_one", "add_trails", "add_input_options", "add_channel_option", "read_mask", "read_frames", "to_12bit", "HELP_TEXT", "FIELD_SPARE"]

HELP_TEXT = """\
Run the flight image processor on image files. Every plane of every file (FITS, TIFF, PNG/JPEG,
NPY/NPZ) becomes 12-bit counts: counts pass unchanged, wide integers whose low bits are always zero
are shifted (a 12-bit reading stored << 4), anything else is mapped linearly from its sky level and
pixel noise (sky -> 200 counts, noise -> 8 counts or more; never the maximum stretch). The mapping
is in the JSON as "scale". A colour image becomes its BT.601 luma (0.299 R + 0.587 G + 0.114 B) or
the --channel asked for.

Field: the instrument's field is found in each frame (a fisheye disc with dark corners; else the
whole frame) or given by --mask FILE or --field-circle ROW,COL,RADIUS (JSON "field"). Pixels
outside it are set to the field's median before the 12-bit mapping and take part in no statistic,
flag or detection; candidate coordinates stay in the input image's pixels.

Bad frames, measured inside the field on the pixel noise (JSON "flags"; on stderr one line for
each kind, naming its frames): unusable (blank, constant, nan, missing: kept from the TP by track)
or a warning (saturated: >= 5 % of the field at the maximum). The IP's answer is still given.

Jobs (--record; the job's sequence follows unless --sequence is given):
  star     (default) point sources: stars, distant satellites, any unresolved spot. Sequence
           'star': compaction 1, high-pass detrend, 5x5 smoothing, clipped threshold at 3 sigma.
           Candidates pass a significance gate (peak in the smoothed image >= 4.5 pixel-noise
           sigmas, the noise measured on the frame). Ordering (a ground ordering; the flight
           ranking is in "flight_rank"): gated candidates by aperture flux, brightest first, then
           free slots filled with candidates below the gate whose S/N in a 2-px aperture is >= 5
           ("gate": false). On a fisheye frame the field is the sky above 15 deg elevation (75/90
           of the circle found).
  streak   satellite or meteor trails 80 px and longer that stand out of the sky (a trail of a
           few noise sigmas per pixel on a banded or graded sky is below the job's threshold).
           Sequence 'streak': compaction 4, one candidate per trail with its orientation (degrees
           from +column toward +row) and "trail": its ends, length and direction as traced on
           the frame.
  aurora   extended UV glow, auroral arcs and surges. Sequence 'aurora': compaction 2, no
           detrend, clipped threshold at 1.5 sigma.
  aurora_allsky
           the brightest auroral structure in a ground all-sky (fisheye) frame, tuned on real
           THEMIS frames. Sequence 'aurora_allsky': compaction 4 (a 256 x 256 sky in one 64 x 64
           window), high-pass detrend (sigma 3 compacted pixels), 3x3 smoothing, clipped
           threshold at 1.5 sigma. The field is 0.7 of the fisheye circle found (elevations above
           ~27 deg). Rank 1 is on the labelled form on 43 % of the scored Gillam 2008 frames
           (docs/validation.md): where several forms are about as bright it often picks another.

Modes: --window full (default) processes the whole compacted image as one window when it fits in
one tile, else through overlapping flight windows (64 x 64 compacted pixels every 16 for point
sources, so that a bright star does not raise the threshold over faint ones beside it; 128 x 128
every 32 for the streak and aurora sequences, so that one trail or arc stays in one window): the
flight front end runs once on the whole frame, a pixel is kept where the flight threshold of any
window covering it passes it, and the flight back end labels and ranks the blobs once;
--window 64 is the flight window about the image centre (no track prediction).
"""


def register(sub) -> None:
    from hil_harness.detect.jobs import JOBS
    jobs = "; ".join(f"{k}: {v[2]}" for k, v in JOBS.items())
    import argparse
    p = sub.add_parser("detect", help="run the flight image processor on image files",
                       description=HELP_TEXT, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("images", nargs="+", help="FITS, TIFF, PNG/JPEG, NPY or NPZ files (cubes: "
                                             "every plane)")
    p.add_argument("--record", default="star",
                   help=f"a priori record: shipped name or a .toml file (default: star). Jobs -- "
                        f"{jobs}")
    p.add_argument("--sequence", default=None,
                   help="processing sequence: shipped name (star, streak, aurora, satellite, "
                        "satellite_c2, aurora_allsky) or a .toml file (default: the record's job "
                        "sequence)")
    p.add_argument("--compaction", type=int, default=None, choices=(1, 2, 4),
                   help="compaction factor (default: the sequence's)")
    p.add_argument("--window", default="full", choices=("full", "64"),
                   help="full-frame mode or the 64x64 flight window (default: full)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--scale-to-12bit", action="store_true",
                   help="map the pixels to 12-bit counts (the default; kept for old scripts)")
    g.add_argument("--no-scale", action="store_true",
                   help="insist that the pixels already are 12-bit counts (integers 0..4095)")
    add_input_options(p)
    p.add_argument("--max-candidates", type=int, default=23,
                   help="candidates reported per image, 1..1000 (default 23, the flight limit)")
    p.add_argument("--workers", type=number(1, integer=True), default=1,
                   help="processes for the frames (default 1; 0: one per core when there are 16 "
                        "frames or more)")
    p.add_argument("--json", default=None, help="output JSON file (default: a table on stdout)")
    p.add_argument("--plot", default=None,
                   help="PNG with candidates marked and numbered by rank (one per image: "
                        "_<i> is added when there are several)")
    p.set_defaults(func=run, outputs={"json": "file", "plot": "file"})


def add_input_options(p) -> None:
    """The input options ``detect``, ``track`` and the tuning commands share: ``--channel``,
    ``--mask``, ``--field-circle`` (the field's mutually exclusive pair)."""
    from hil_harness.field import parse_circle
    add_channel_option(p)
    g = p.add_mutually_exclusive_group()
    g.add_argument("--mask", default=None, metavar="FILE",
                   help="the instrument's field: an image the size of the frames (any format read "
                        "here), non-zero inside (default: found in each frame: a fisheye disc with "
                        "dark corners, else the whole frame)")
    g.add_argument("--field-circle", default=None, type=_circle_arg(parse_circle),
                   metavar="ROW,COL,RADIUS",
                   help="the field as a circle in full-resolution pixels (pixel centres at +0.5)")


def add_channel_option(p) -> None:
    """``--channel l|r|g|b``: what a colour image becomes (:func:`hil_harness.images.read_images`);
    part of :func:`add_input_options`, alone for ``uvisi label``, which has no field."""
    p.add_argument("--channel", default="l", choices=CHANNELS,
                   help="what a colour image becomes: l = luma by ITU-R BT.601 (0.299 R + 0.587 G "
                        "+ 0.114 B; the default), or the r, g or b channel (auroral green 557.7 nm:"
                        " g); greyscale images are read as they are")


def _circle_arg(parse):
    import argparse

    def conv(text):
        try:
            return parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1]) from None
    conv.__name__ = "ROW,COL,RADIUS"
    return conv


def read_mask(path):
    """The ``--mask`` file as a 2-D array (its first frame), or None without one. Raises
    :class:`ImageError` naming the file when it holds more than one frame."""
    if path is None:
        return None
    frames = read_images([path])
    if len(frames) != 1:
        raise ImageError(f"{path}: --mask: the mask file holds {len(frames)} frames; give one "
                         f"image")
    return frames[0].data


# ------------------------------------------------------------------------------------------------
# kept for callers of the old interface
# ------------------------------------------------------------------------------------------------
def read_frames(path) -> list:
    """``[(name, 2-D array)]`` of one file (:func:`hil_harness.images.read_images`)."""
    return [(f.name, f.data) for f in read_images([path])]


def to_12bit(a, scale: bool, label: str = "image") -> np.ndarray:
    """The old maximum-stretch conversion, unchanged for the tuning code that still calls it:
    integers above 4095 are shifted right by the fewest bits that fit, floats scaled so that their
    maximum is 4095 (NaN -> 0). ``uvisi detect`` itself uses
    :func:`hil_harness.images.to_counts`."""
    a = np.asarray(a)
    if np.issubdtype(a.dtype, np.bool_):
        a = a.astype(np.uint16)
    if np.issubdtype(a.dtype, np.integer):
        if a.size and a.min() < 0:
            if not scale:
                raise ValueError(f"{label}: negative pixel values (use --scale-to-12bit)")
            a = a.astype(np.int64) - int(a.min())
        mx = int(a.max()) if a.size else 0
        if mx > 4095:
            if not scale:
                raise ValueError(f"{label}: values up to {mx} are not 12-bit counts "
                                 f"(use --scale-to-12bit)")
            a = a.astype(np.int64) >> max(0, mx.bit_length() - 12)
        return a.astype(np.uint16)
    if np.issubdtype(a.dtype, np.floating):
        if not scale:
            raise ValueError(f"{label}: floating-point pixels (use --scale-to-12bit)")
        a = np.nan_to_num(a.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        a = a - min(0.0, float(a.min()))
        mx = float(a.max())
        return np.clip(np.rint(a * (4095.0 / mx if mx > 0 else 1.0)), 0, 4095).astype(np.uint16)
    raise ValueError(f"{label}: unsupported pixel type {a.dtype}")


# ------------------------------------------------------------------------------------------------
# one image
# ------------------------------------------------------------------------------------------------
def detect_one(img12, seq, record, compaction, window_mode="full", max_candidates=23,
               gate_sigma=None, tile=None, field=None, trails=False) -> dict:
    """The flight IP on one 12-bit image (uint16 [H, W]) -> the JSON entry's processing part:
    ``mode``, ``windows``, ``gate`` (None, or the star gate's ``sigma``, ``noise_counts``,
    ``cut_counts``), ``candidates`` (list of dicts, best first).

    ``gate_sigma``: the star job: apply its peak gate (:func:`hil_harness.detect.jobs.
    peak_gate_record`) at this many sigmas of the frame's pixel noise, then order the candidates
    by aperture flux (:func:`hil_harness.detect.photometry.order_stars`: a ground ordering; the
    flight ranking is unchanged and each candidate keeps its ``flight_rank``). ``tile``: full-frame
    tile (default: the sequence's, :func:`hil_harness.detect.jobs.tile_for`). ``field``: optional
    bool [H, W], the instrument's field (:mod:`hil_harness.field`): the noise is measured inside
    it and candidates whose centroid falls outside it are dropped (a ground filter after the
    flight ranking; the IP is asked for up to :data:`FIELD_SPARE` more candidates so that
    ``max_candidates`` remain). ``trails``: the streak job: each candidate gets ``"trail"``
    (:func:`add_trails`)."""
    from flightsw.ip.preprocess import compact
    from hil_harness.detect.noise import frame_noise
    from hil_harness.field import compact_mask
    whole = field is None or bool(np.all(field))
    mask = None if whole else np.asarray(field, bool)
    tile = tile_for_seq(seq) if tile is None else tile
    if not gate_sigma:
        out, cands = _ip_candidates(img12, seq, record, compaction, window_mode, max_candidates,
                                    tile, mask)
        if trails:
            add_trails(cands, img12, out.get("thresholded"), compaction, mask)
        return {"mode": out["mode"], "windows": out["windows"], "gate": None,
                "candidates": cands}
    from hil_harness.detect.jobs import GATE_TOP, peak_gate_record
    from hil_harness.detect.photometry import FILL_PEAK_SIGMA, order_stars
    comp = compact(img12, compaction) if compaction > 1 else img12
    # the pixel noise (hil_harness.images.noise_sigma, compiled: the same number)
    raw_noise = frame_noise(comp, None if mask is None else compact_mask(mask, compaction))
    noise = raw_noise if math.isfinite(raw_noise) and raw_noise > 0.5 else 0.5  # noiseless: 1/2
    # a high-contrast frame (a 1-bit image, a checkerboard) has no sky noise to speak of: its
    # pixel-to-pixel "noise" would put the gate above full scale; cap it just below
    noise = min(noise, 0.999 * GATE_TOP / gate_sigma)
    gate = {"feature": "max_brightness", "sigma": float(gate_sigma), "noise_counts": float(noise),
            "cut_counts": float(gate_sigma * noise)}
    out, gated = _ip_candidates(img12, seq, peak_gate_record(record, noise, gate_sigma),
                                compaction, window_mode, 1000, tile, mask)
    below = []
    if len(gated) < max_candidates:
        below = _ip_candidates(img12, seq, peak_gate_record(record, noise, FILL_PEAK_SIGMA),
                               compaction, window_mode, 1000, tile, mask)[1]
    pix_noise = raw_noise if compaction == 1 else frame_noise(img12, mask)
    cands = order_stars(img12, gated, below, pix_noise if pix_noise > 0 else 0.5,
                        max_candidates, mask)
    return {"mode": out["mode"], "windows": out["windows"], "gate": gate, "candidates": cands}


def add_trails(cands, img12, thresholded, f, mask=None) -> None:
    """The streak job's ground measurement, in place: each candidate dict gets ``"trail"``:
    ``{"ends", "length", "orientation"}`` (full-resolution pixels, degrees from +column toward
    +row), the ends of its blob in ``thresholded`` (int16 [H // f, W // f], the image the back
    end labelled; :func:`hil_harness.detect.trails.trail_ends`) followed outward on ``img12``
    (uint16 [H, W]) while the trail stands out of the noise
    (:func:`hil_harness.detect.trails.trace_trail`); None when the mode gives no thresholded
    image (``--window 64``) or no blob lies under the centroid."""
    from scipy.ndimage import label

    from hil_harness.detect.trails import trace_trail, trail_ends
    from hil_harness.images import noise_sigma
    if thresholded is None:
        for c in cands:
            c["trail"] = None
        return
    labels = label(np.asarray(thresholded) != 0, structure=np.ones((3, 3), int))[0]
    noise = noise_sigma(img12, mask)
    for c in cands:
        te = trail_ends(thresholded, f, c["row"], c["col"], labels)
        c["trail"] = None if te is None else trace_trail(img12, te["ends"], noise, mask)


def tile_for_seq(seq) -> int:
    """The full-frame tile of a sequence (:func:`hil_harness.detect.jobs.tile_for`)."""
    from hil_harness.detect.jobs import tile_for
    return tile_for(seq)


def _ip_candidates(img12, seq, record, compaction, window_mode, max_candidates, tile, mask):
    """One run of the IP -> (detect_frame's dict, candidate dicts inside ``mask``, at most
    ``max_candidates``, ranks 1.. in the IP's order)."""
    from flightsw.messages import FEATURE_NAMES
    from hil_harness.detect.fullframe import detect_frame
    from hil_harness.field import inside
    ask = max_candidates if mask is None else min(1000, max_candidates + FIELD_SPARE)
    out = detect_frame(img12, seq, record, compaction, window_mode, ask, tile)
    keep = np.arange(len(out["feats"]))
    if mask is not None and keep.size:
        keep = keep[inside(mask, out["feats"]["row"], out["feats"]["col"])]
    keep = keep[:max_candidates]
    ft = out["feats"][keep]
    # Python floats column by column (tolist), not a NumPy scalar per feature and candidate
    cols = [ft[n].astype(float).tolist() for n in FEATURE_NAMES]
    dist = np.asarray(out["distance"], float)[keep].tolist()
    gof = np.asarray(out["gof"], float)[keep].tolist()
    row, col = ft["row"].astype(float).tolist(), ft["col"].astype(float).tolist()
    cands = [{"rank": k + 1, "row": row[k], "col": col[k], "distance": dist[k], "gof": gof[k],
              "features": dict(zip(FEATURE_NAMES, vals))}
             for k, vals in enumerate(zip(*cols))]
    return out, cands


# ------------------------------------------------------------------------------------------------
# output
# ------------------------------------------------------------------------------------------------
def _plot(path, img, cands, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    H, W = img.shape
    fig, ax = plt.subplots(figsize=(8, 8 * H / W + 0.4), dpi=110)
    lo, hi = np.percentile(img, [1, 99.7])
    ax.imshow(img, cmap="gray", vmin=lo, vmax=max(hi, lo + 1), origin="upper",
              extent=(0, W, H, 0), interpolation="nearest")
    for c in cands:
        # marker radius from the blob's semimajor axis, capped so an extended blob (a sunlit limb)
        # does not hide the picture; the label sits on the marker and is clipped to the axes
        r = min(max(4.0, 2.5 * c["features"]["semimajor"]), 0.06 * max(H, W))
        ax.add_patch(plt.Circle((c["col"], c["row"]), r, fill=False, color="#ff4040", lw=1.0))
        ax.text(c["col"] + r * 0.8, c["row"] - r * 0.8, str(c["rank"]), color="#ffdd33",
                fontsize=8, fontweight="bold", clip_on=True)
    ax.set_title(title, fontsize=9)
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _scale_text(m: dict) -> str:
    if m["method"] == "shift":
        full = m.get("full_scale_pixels")
        return f"shift >> {m['shift']}" + (f", {full} full-scale pixels -> 4095" if full else "")
    if m["method"] == "robust" and m.get("noise") is not None:
        return f"robust: gain {m['gain']:.4g}, noise {m['noise_counts']:.1f} counts"
    return m["method"]


def _table(entry) -> str:
    """A readable block for one image (stdout when there is no --json)."""
    flags = ", ".join(entry["flags"]) or "-"
    lines = [f"{entry['path']}: {entry['shape'][0]}x{entry['shape'][1]}, scale "
             f"{_scale_text(entry['scale'])}, flags {flags}, record {entry['record']}, sequence "
             f"{entry['sequence']}, {len(entry['candidates'])} candidates",
             f"  {entry['mode']}"]
    if entry["candidates"]:
        lines.append(f"  {'rank':>4} {'row':>9} {'col':>9} {'gof':>8} {'size':>7} "
                     f"{'peak':>7} {'orient':>7}")
        for c in entry["candidates"]:
            f = c["features"]
            lines.append(f"  {c['rank']:>4} {c['row']:>9.2f} {c['col']:>9.2f} {c['gof']:>8.4f} "
                         f"{f['size']:>7.0f} {f['max_brightness']:>7.0f} "
                         f"{f['orientation']:>7.1f}")
    return "\n".join(lines)


def _finite(o):
    """JSON-safe copy: non-finite floats -> None, NumPy scalars -> Python numbers."""
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_finite(v) for v in o]
    if isinstance(o, np.generic):
        o = o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return o


def _write_json(path, entries):
    """Write the JSON whole or not at all (a temporary file renamed into place)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")
    try:
        with open(tmp, "w") as fh:
            json.dump({"images": _finite(entries)}, fh, indent=1, allow_nan=False)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


# ------------------------------------------------------------------------------------------------
# the command
# ------------------------------------------------------------------------------------------------
def _setup(args):
    from hil_harness.detect.jobs import default_sequence_name, resolve_sequence
    from hil_harness.tuning.export import record_from
    record = record_from(args.record)
    seq = resolve_sequence(args.sequence or default_sequence_name(record))
    f = args.compaction if args.compaction is not None else seq.preprocess.compaction
    if not 1 <= args.max_candidates <= 1000:
        raise ValueError("--max-candidates must be in 1..1000")
    gate = None
    if record.name == "star" and args.record == "star":
        from hil_harness.detect.jobs import GATE_SIGMA
        gate = GATE_SIGMA
    return record, seq, f, gate


def _frame_job(args, record, seq, f, gate, user_mask=None):
    """The work of one frame, as a function of the frame alone (run here or in a worker):
    ``InputFrame -> (entry, counts or None (no --plot), messages for stderr)``."""
    from hil_harness.detect.jobs import field_scale
    from hil_harness.detect.noise import frame_noise
    from hil_harness.field import find_field, resolve_field
    scale = field_scale(record)

    def field_of(data):
        if user_mask is None and args.field_circle is None:    # found in the frame: its noise
            return find_field(data, frame_noise(data)).scaled(scale)   # compiled, same number
        return resolve_field(data, user_mask, args.field_circle)

    def one(fr):
        try:
            field = field_of(fr.data)
        except ValueError as exc:
            opt = f"--mask {args.mask}" if args.mask else "--field-circle"
            raise ImageError(f"{fr.name}: {opt}: {exc}") from None
        flags = frame_flags(fr.data, field.mask)
        try:
            img, scale = to_counts(fr.data, no_scale=args.no_scale, bits=fr.bits,
                                   field=field.mask)
        except ImageError as exc:
            raise ImageError(f"{fr.name}: {exc}") from None
        note = scale_note(fr.name, scale)
        msgs = [f"uvisi detect: note: {note}"] if note else []
        try:
            out = detect_one(img, seq, record, f, args.window, args.max_candidates, gate,
                             field=field.mask, trails=record.name == "streak")
        except ValueError as exc:           # e.g. a frame too small for the compaction
            raise ImageError(f"{fr.name}: {exc}") from None
        entry = {"path": fr.name, "time_utc": fr.time_utc, "shape": list(img.shape),
                 "flags": flags, "scale": scale, "field": field.to_json(), "compaction": f,
                 "mode": out["mode"],
                 "windows": out["windows"], "record": record.name, "sequence": seq.name,
                 "gate": out["gate"], "candidates": out["candidates"]}
        return entry, (img if args.plot else None), msgs

    return one


def _why(unusable_: bool, several: bool) -> str:
    return ("unusable" if unusable_ else "warning only") + "; the IP's answer is still given"


def run(args) -> int:
    from tqdm import tqdm

    from hil_harness.detect.batch import map_ordered, workers_for
    record, seq, f, gate = _setup(args)
    frames = read_images(args.images, args.channel)
    user_mask = read_mask(args.mask)
    workers = workers_for(len(frames), args.workers)
    entries, plots = [], []
    bar = tqdm(total=len(frames), desc="detect", unit="frame", file=sys.stderr,
               disable=len(frames) < 4 or None)
    for entry, img, msgs in map_ordered(_frame_job(args, record, seq, f, gate, user_mask), frames,
                                       workers):
        bar.update()
        for m in msgs:
            tqdm.write(m, file=sys.stderr)
        entries.append(entry)
        flags = entry["flags"]
        plots.append((img, entry["candidates"], f"{Path(entry['path']).name}: "
                      f"{len(entry['candidates'])} candidates, record {record.name}"
                      + (f" [{', '.join(flags)}]" if flags else "")))
    bar.close()
    for line in flag_lines([e["path"] for e in entries], [e["flags"] for e in entries],
                           [unusable(e["flags"]) for e in entries], _why):
        print(f"uvisi detect: warning: {line}", file=sys.stderr)
    if args.json:
        _write_json(args.json, entries)
        for e in entries:
            top = e["candidates"][0] if e["candidates"] else None
            print(f"{e['path']}: {e['shape'][0]}x{e['shape'][1]}, {len(e['candidates'])} "
                  f"candidates" + (f", best at row {top['row']:.2f} col {top['col']:.2f}"
                                   if top else "") + (f" [{', '.join(e['flags'])}]"
                                                      if e["flags"] else ""))
    else:
        print("\n\n".join(_table(e) for e in entries))
    if args.plot:
        base = Path(args.plot)
        base.parent.mkdir(parents=True, exist_ok=True)
        for i, (img, cands, title) in enumerate(plots):
            p = base if len(plots) == 1 else base.with_name(f"{base.stem}_{i}{base.suffix}")
            _plot(p, img, cands, title)
        first, last = (base.with_name(f"{base.stem}_{i}{base.suffix}") for i in (0, len(plots) - 1))
        print(f"plot: {base}" if len(plots) == 1 else
              f"plots: {len(plots)} files, one per image, {first} .. {last}")
    return 0
