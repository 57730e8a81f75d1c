"""``uvisi detect``: the flight image processor on real image files.

``uvisi detect IMAGE... [--record NAME|FILE] [--compaction N] [--sequence FILE] [--window full|64]
[--scale-to-12bit] [--max-candidates K] --json OUT [--plot PNG]``

Reads FITS (astropy), TIFF (tifffile), PNG/JPEG (pillow) and NPY/NPZ (one frame or a stack
``[n, H, W]``; in an ``.npz`` the key ``img`` if present, else every array), runs the flight IP
(``flightsw.ip``: compaction, the sequence's front end, blob colouring, the 12 features, ranking
against the a priori record) and writes per image the candidates with full-resolution centroids
(0-based ``[row, col]``, pixel centres at +0.5), distance, GOF and the 12 normalised features::

    {"images": [{"path", "frame", "shape", "compaction", "mode", "windows", "record",
                 "candidates": [{"rank", "row", "col", "distance", "gof", "features": {...}}]}]}

Pixels must be 12-bit counts (integers 0..4095). ``--scale-to-12bit`` makes them so: float data is
scaled linearly so that its maximum is 4095 (NaN -> 0), integer data above 4095 is shifted right by
the fewest bits that fit (a 12-bit reading stored shifted left by 4, like the tetra3 TIFFs, comes
back exactly).

Modes (said in the output's ``mode``):

* ``--window 64``: the flight window, 64 x 64 compacted pixels about the image centre (the IP with
  no TP prediction);
* ``--window full`` (default): the whole compacted image. When it has at most 128 x 128 pixels
  (the threshold's statistics limit) it is processed as one large window; otherwise it is tiled into
  128 x 128 windows overlapping by 16 pixels, each processed as the flight code processes a window
  (its own adaptive threshold), each blob kept by the tile whose centre is nearest its centroid,
  and all blobs ranked together against the record with the centroid means at the image centre.

Default sequence (no ``--sequence``): the shipped ``aurora`` sequence for an aurora record, else a
point-source sequence (high-pass detrend, 3x3 matched filter, threshold at 4 sigma, clipped).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

TILE = 128
OVERLAP = 16


def register(sub) -> None:
    p = sub.add_parser("detect", help="run the flight image processor on image files",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("images", nargs="+", help="FITS, TIFF, PNG, NPY or NPZ files")
    p.add_argument("--record", default="star",
                   help="a priori record: shipped name (aurora, star, satellite, plume) or a .toml "
                        "file (default: star)")
    p.add_argument("--compaction", type=int, default=None, choices=(1, 2, 4),
                   help="compaction factor (default: the sequence's)")
    p.add_argument("--sequence", default=None,
                   help="processing sequence TOML (default: shipped 'satellite' sequence)")
    p.add_argument("--window", default="full", choices=("full", "64"),
                   help="full-frame mode or the 64x64 flight window (default: full)")
    p.add_argument("--scale-to-12bit", action="store_true",
                   help="scale floats / shift wide integers to 12-bit counts")
    p.add_argument("--max-candidates", type=int, default=23,
                   help="candidates reported per image (default 23, the flight limit)")
    p.add_argument("--json", required=True, help="output JSON file")
    p.add_argument("--plot", default=None,
                   help="PNG with candidates marked and numbered by rank (one per image: "
                        "_<i> is added when there are several)")
    p.set_defaults(func=run)


# ------------------------------------------------------------------------------------------------
# reading
# ------------------------------------------------------------------------------------------------
def read_frames(path) -> list:
    """``[(label, 2-D array)]`` from one image file."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    suf = p.suffix.lower()
    if suf in (".fits", ".fit", ".fts") or p.name.lower().endswith(".fits.gz"):
        from astropy.io import fits
        with fits.open(p) as hdul:
            arrays = [(f"hdu{i}", np.asarray(h.data)) for i, h in enumerate(hdul)
                      if h.data is not None and np.asarray(h.data).ndim >= 2]
        if not arrays:
            raise ValueError(f"{p}: no image HDU")
        out = []
        for name, a in arrays[:1]:
            out += _split(a, str(p))
        return out
    if suf in (".tif", ".tiff"):
        import tifffile
        return _split(np.asarray(tifffile.imread(p)), str(p))
    if suf in (".png", ".jpg", ".jpeg", ".bmp", ".gif"):
        from PIL import Image
        with Image.open(p) as im:
            if im.mode not in ("L", "I", "I;16", "I;16B", "F"):
                im = im.convert("L")
            return _split(np.asarray(im), str(p))
    if suf == ".npy":
        return _split(np.load(p, allow_pickle=False), str(p))
    if suf == ".npz":
        with np.load(p, allow_pickle=False) as z:
            keys = ["img"] if "img" in z.files else list(z.files)
            out = []
            for k in keys:
                a = np.asarray(z[k])
                if a.ndim in (2, 3) and np.issubdtype(a.dtype, np.number):
                    out += _split(a, f"{p}[{k}]")
        if not out:
            raise ValueError(f"{p}: no 2-D or 3-D numeric array")
        return out
    raise ValueError(f"{p}: unsupported format {suf!r} (FITS, TIFF, PNG, NPY, NPZ)")


def _split(a, label):
    a = np.asarray(a)
    if a.ndim == 2:
        return [(label, a)]
    if a.ndim == 3 and a.shape[-1] in (3, 4) and a.shape[0] > 4:      # colour image: luminance
        return [(label, a[..., :3].astype(np.float64) @ np.array([0.299, 0.587, 0.114]))]
    if a.ndim == 3:
        return [(f"{label}[{i}]", a[i]) for i in range(a.shape[0])]
    raise ValueError(f"{label}: expected a 2-D image or a [n, H, W] stack, got shape {a.shape}")


def to_12bit(a, scale: bool, label: str = "image") -> np.ndarray:
    """12-bit counts (uint16) from an image; see the module docstring."""
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
            k = max(0, mx.bit_length() - 12)
            a = a.astype(np.int64) >> k
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
# processing
# ------------------------------------------------------------------------------------------------
#: default sequence for point sources (no --sequence, record other than aurora): the shipped
#: satellite sequence's high-pass detrend and matched filter, but a *clipped* threshold so that the
#: brightness features see the filtered intensities
POINT_SOURCE_SEQUENCE = {
    "name": "detect_point", "description": "high-pass detrend, 3x3 matched filter, clip at 4 sigma",
    "preprocess": {"compaction": 1, "window": 64},
    "steps": [{"op": "detrend", "method": "highpass", "sigma": 1.5},
              {"op": "filter", "kernel": "matched", "size": 3, "sigma": 1.0},
              {"op": "threshold", "alpha": 4.0, "mode": "clip"}],
}


def _sequence(args, record):
    from flightsw.ip.sequence import ProcessingSequence, load_default_sequence
    if args.sequence:
        return ProcessingSequence.from_toml(Path(args.sequence))
    if record.object_type == "aurora":
        return load_default_sequence("aurora")
    return ProcessingSequence.from_dict(POINT_SOURCE_SEQUENCE)


def _with_window(seq, compaction, window, shape):
    from flightsw.ip.sequence import ProcessingSequence, Preprocess
    steps = [dict(s.raw) for s in seq.steps]
    pre = Preprocess(compaction, window, frame_shape=tuple(shape))
    return ProcessingSequence(steps, pre, seq.name, seq.description)


def detect_image(img12, seq, record, compaction, window_mode, max_candidates=23):
    """Run the flight IP on one 12-bit image -> dict (the JSON entry without path/frame)."""
    from flightsw.ip.features import words_to_struct
    from flightsw.ip.frame import process_window
    from flightsw.ip.preprocess import Subimage, compact
    from flightsw.ip.rank import rank_words
    f = compaction
    H, W = img12.shape
    ch, cw = H // f, W // f
    if ch < 8 or cw < 8:
        raise ValueError(f"image {H}x{W} is too small for compaction {f}")
    if window_mode == "64":
        size = 64
        if size > ch and size > cw:
            size = max(ch, cw)
        s = _with_window(seq, f, size, (H, W))
        res = process_window(s.window(img12, None), s, record, ledger=None,
                             max_candidates=max_candidates, want_stages=False)
        sub = res.subimage
        mode = (f"flight window: {sub.size[0]}x{sub.size[1]} compacted pixels at "
                f"({sub.origin[0]}, {sub.origin[1]}) (compacted), compaction {f}")
        feats = words_to_struct(res.backend.feature_words[res.backend.order])
        dist = res.message.candidates["distance"]
        gof = res.message.candidates["gof"]
        return dict(mode=mode, windows=1, feats=feats, distance=dist, gof=gof,
                    cycles=res.ledger.as_dict())
    comp = compact(img12, f)
    if ch <= TILE and cw <= TILE:
        s = _with_window(seq, f, max(ch, cw), (H, W))
        res = process_window(s.window(img12, None), s, record, ledger=None,
                             max_candidates=max_candidates, want_stages=False)
        feats = words_to_struct(res.backend.feature_words[res.backend.order])
        return dict(mode=f"full frame: one {ch}x{cw} window (compaction {f})", windows=1,
                    feats=feats, distance=res.message.candidates["distance"],
                    gof=res.message.candidates["gof"], cycles=res.ledger.as_dict())
    # ---- tiled full frame ----
    s = _with_window(seq, f, TILE, (H, W))
    step = TILE - OVERLAP
    rows = list(range(0, max(ch - TILE, 0) + 1, step))
    cols = list(range(0, max(cw - TILE, 0) + 1, step))
    if rows[-1] + TILE < ch:
        rows.append(ch - TILE)
    if cols[-1] + TILE < cw:
        cols.append(cw - TILE)
    th, tw = min(TILE, ch), min(TILE, cw)
    kept = []

    def core(starts, size, n):
        """[lo, hi) per tile: boundaries half way between neighbouring tile centres."""
        mids = [(a + b + size) / 2.0 for a, b in zip(starts[:-1], starts[1:])]
        lo = [-math.inf] + mids
        hi = mids + [math.inf]
        return dict(zip(starts, zip(lo, hi)))

    rcore, ccore = core(rows, th, ch), core(cols, tw, cw)
    for r0 in rows:
        for c0 in cols:
            tile = np.ascontiguousarray(comp[r0:r0 + th, c0:c0 + tw]).astype(np.int16)
            sub = Subimage(tile, (r0, c0), f, (th, tw))
            res = process_window(sub, s, record, ledger=None, max_candidates=1000,
                                 want_stages=False)
            words = res.backend.feature_words
            if not len(words):
                continue
            st = words_to_struct(words)
            rr, cc = st["row"] / f, st["col"] / f            # compacted coordinates
            (lo_r, hi_r), (lo_c, hi_c) = rcore[r0], ccore[c0]
            inside = (rr >= lo_r) & (rr < hi_r) & (cc >= lo_c) & (cc < hi_c)
            kept.append(words[inside])
    words = np.concatenate(kept) if kept else np.zeros((0, 12), np.int64)
    centre = (H / 2.0, W / 2.0)
    rk = rank_words(words, record, centre, None, max_candidates=max(1, min(max_candidates, 1000)))
    feats = words_to_struct(words[rk.order]) if len(words) else words_to_struct(words)
    return dict(mode=(f"full frame tiled: {len(rows) * len(cols)} windows of {th}x{tw} compacted "
                      f"pixels overlapping by {OVERLAP} (compaction {f}), ranked together with the "
                      f"centroid means at the image centre"),
                windows=len(rows) * len(cols), feats=feats, distance=rk.distance[rk.order],
                gof=rk.gof, cycles=None)


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


def run(args) -> int:
    from flightsw.messages import FEATURE_NAMES
    from flightsw.records import load_record
    record = load_record(args.record)
    seq = _sequence(args, record)
    f = args.compaction if args.compaction is not None else seq.preprocess.compaction
    if not 1 <= args.max_candidates <= 1000:
        raise ValueError("--max-candidates must be in 1..1000")
    entries, plots = [], []
    for path in args.images:
        for label, a in read_frames(path):
            img = to_12bit(a, args.scale_to_12bit, label)
            out = detect_image(img, seq, record, f, args.window, args.max_candidates)
            cands = []
            for i, ft in enumerate(out["feats"]):
                cands.append({"rank": i + 1, "row": float(ft["row"]), "col": float(ft["col"]),
                              "distance": float(out["distance"][i]), "gof": float(out["gof"][i]),
                              "features": {n: float(ft[n]) for n in FEATURE_NAMES}})
            entries.append({"path": label, "shape": list(img.shape), "compaction": f,
                            "mode": out["mode"], "windows": out["windows"],
                            "record": record.name, "sequence": seq.name,
                            "candidates": cands})
            plots.append((img, cands, f"{Path(label).name}: {len(cands)} candidates, record "
                                      f"{record.name}"))
            top = cands[0] if cands else None
            print(f"{label}: {img.shape[0]}x{img.shape[1]}, {out['mode']}; {len(cands)} candidates"
                  + (f", best at row {top['row']:.2f} col {top['col']:.2f} (GOF {top['gof']:.3g})"
                     if top else ""))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    with open(args.json, "w") as fh:
        json.dump({"images": entries}, fh, indent=1, allow_nan=False,
                  default=lambda o: None if isinstance(o, float) and not math.isfinite(o) else o)
    if args.plot:
        base = Path(args.plot)
        base.parent.mkdir(parents=True, exist_ok=True)
        for i, (img, cands, title) in enumerate(plots):
            p = base if len(plots) == 1 else base.with_name(f"{base.stem}_{i}{base.suffix}")
            _plot(p, img, cands, title)
    return 0
