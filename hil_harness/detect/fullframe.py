"""Full-frame detection on the ground: a large image seen through overlapping flight windows, in
one compiled call built from the flight IP's stage kernels.

Why overlapping windows and a union: the flight threshold is ``mean + alpha * std`` of its window,
so a bright source inflates the threshold of every window it is in. Windows of ``tile`` pixels
every ``tile / 4`` put every point in up to 16 windows; a faint source is kept if *any* window that
holds it passes it, so a bright star hides faint ones only where every covering window holds both.
Measured (faint stars of peak SNR 15-25 at 20-90 px from a saturated star, 10 fields): 128-pixel
tiles every 32 find 35/80, 64-pixel tiles every 16 find 80/80. Extended jobs (streaks, aurora) use
128-pixel tiles so that one object stays in one window.

What it computes exactly (:func:`detect_frame`, ``window_mode="full"``, an image larger than one
tile; :mod:`hil_harness.detect.frame_k`):

1. the flight compaction of the whole frame (``compact_k``);
2. each front-end step of the sequence before the threshold (``flightsw.ip.pipeline.front_step_k``:
   the spatial filters and the high-pass detrender) once on the whole compacted frame;
3. for every window, the flight threshold words ``T4`` of that window of the step-2 image (the same
   integer formula, block shift and rounding as ``flightsw.ip.threshold``; from running sums,
   :func:`hil_harness.detect.union.window_t4_k`), and each pixel kept (clip) or set to 1
   (binarise) where ``16 x > T4`` for at least one window that covers it;
4. the flight back end once on that image (``flightsw.ip.backend.backend_k``: blob colouring, the
   twelve features in 1750A float, normalisation, ranking against the record with the centroid
   means at the image centre, at most ``max_candidates``).

How it relates to the flight window: a window of the flight IP runs the same kernels on the window
cut out, so its front end sees the window's edges (replicated) where this mode sees the
neighbouring pixels, and the high-pass detrender's block headroom is that of the whole frame; the
threshold words of a window are those of the flight on the step-2 image's window. A blob cut by a
window edge is one blob here (labelled once on the whole frame), so no duplicate merge is needed.
The flight algorithm per window stays bit for bit in :mod:`flightsw.ip`; this is a ground tool.
A sequence with the polynomial detrender (a fit per window, not translation invariant) or a
frequency-domain filter (its FFT tiles and kernel tables are sized for the flight window) still
runs window by window through ``process_window`` with duplicates merged
(:func:`merge_duplicates`).

On a 244x256 star field at compaction 1 (169 windows) the compiled call takes ~0.20-0.23 ms; the
same 169 windows through ``process_window`` one by one took ~7.8 ms (``bench/bench_fullframe.py``).
On a 2800x2800 field (29,584 windows, 7414 blobs) it takes ~90 ms (``bench/bench_largeframe.py``).

Public: :func:`detect_frame`, :func:`tile_starts`, :func:`merge_duplicates`, :data:`MAX_TILE`,
:data:`DEFAULT_TILE`, :data:`MERGE_RADIUS`.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["detect_frame", "tile_starts", "merge_duplicates", "MAX_TILE", "DEFAULT_TILE",
           "MERGE_RADIUS"]

#: largest window (compacted pixels): the threshold's statistics limit (its 40-bit sum of squares)
MAX_TILE = 128
#: default tile (compacted pixels) for point sources; the step is a quarter tile
DEFAULT_TILE = 64
#: duplicates: the smallest ellipse axis (full-resolution pixels) a kept blob covers
MERGE_RADIUS = 2.0


def tile_starts(n: int, tile: int, step: int) -> list[int]:
    """Start offsets of tiles of ``tile`` pixels every ``step`` covering ``0..n`` (the last tile
    flush with the end). ``n <= tile`` gives ``[0]``."""
    if n <= tile:
        return [0]
    starts = list(range(0, n - tile + 1, step))
    if starts[-1] + tile < n:
        starts.append(n - tile)
    return starts


def merge_duplicates(feats, margin, radius=MERGE_RADIUS) -> np.ndarray:
    """Indices of the detections kept after merging duplicates and pieces.

    ``feats``: structured [k] (FEATURE_DTYPE, normalised: full-resolution centroids and axes,
    orientation in degrees from +column toward +row); ``margin``: float [k], the distance of each
    centroid from its window's nearest inner edge (larger = less truncated; ``inf`` at the image
    border). Greedy, largest blob first (ties: larger margin): a detection is dropped when its
    centroid lies inside the ellipse of a kept one, widened to at least ``radius`` pixels on each
    axis (the same star seen by two windows, or a piece of a trail cut by a window edge); a faint
    star beside a bright one lies outside the bright one's ellipse and is kept. Returns int64 [m]
    indices in keeping order.
    """
    rows = np.asarray(feats["row"], float)
    cols = np.asarray(feats["col"], float)
    th = np.radians(np.asarray(feats["orientation"], float))
    ur, uc = np.sin(th), np.cos(th)
    a = np.maximum(radius, np.asarray(feats["semimajor"], float))
    b = np.maximum(radius, np.asarray(feats["semiminor"], float))
    order = np.lexsort((-np.asarray(margin, float), -np.asarray(feats["size"], float)))
    cell = 16.0                          # spatial hash: a kept blob is listed in every cell its
    grid: dict = {}                      # ellipse's bounding square touches
    kept: list[int] = []
    for i in order:
        key = (int(rows[i] // cell), int(cols[i] // cell))
        inside = False
        for k in grid.get(key, ()):
            dr, dc = rows[i] - rows[k], cols[i] - cols[k]
            along, across = dr * ur[k] + dc * uc[k], dr * uc[k] - dc * ur[k]
            if (along / a[k]) ** 2 + (across / b[k]) ** 2 < 1.0:
                inside = True
                break
        if inside:
            continue
        kept.append(int(i))
        r0, r1 = int((rows[i] - a[i]) // cell), int((rows[i] + a[i]) // cell)
        c0, c1 = int((cols[i] - a[i]) // cell), int((cols[i] + a[i]) // cell)
        for gr in range(r0, r1 + 1):
            for gc in range(c0, c1 + 1):
                grid.setdefault((gr, gc), []).append(int(i))
    return np.asarray(kept, np.int64)


def _with_window(seq, compaction, window, shape):
    from flightsw.ip.sequence import Preprocess, ProcessingSequence
    steps = [dict(s.raw) for s in seq.steps]
    return ProcessingSequence(steps, Preprocess(compaction, window, frame_shape=tuple(shape)),
                              seq.name, seq.description)


def _single(img12, seq, record, f, size, max_candidates, mode_text):
    from flightsw.ip.features import words_to_struct
    from flightsw.ip.frame import process_window
    s = _with_window(seq, f, size, img12.shape)
    res = process_window(s.window(img12, None), s, record, ledger=None,
                         max_candidates=max_candidates, want_stages=True)
    feats = words_to_struct(res.backend.feature_words[res.backend.order])
    sub = res.subimage
    means = ((sub.origin[0] + sub.size[0] / 2.0) * f, (sub.origin[1] + sub.size[1] / 2.0) * f)
    return dict(mode=mode_text(sub), windows=1, feats=feats, centroid_means=means,
                distance=res.message.candidates["distance"], gof=res.message.candidates["gof"],
                thresholded=_threshold_canvas(res, img12.shape, f),
                ranks=_rank_canvas(res, img12.shape, f))


def _threshold_canvas(res, shape, f):
    """The threshold stage's window image placed in a zero compacted frame (int16 [H // f,
    W // f]), or None when the sequence has no threshold step."""
    stage = [st for st in res.stages if st.data is not None and st.name != "colour"
             and st.name != "rank"]
    if not stage:
        return None
    return _canvas(res.subimage, np.asarray(stage[-1].image), shape, f, np.int16)


def _rank_canvas(res, shape, f):
    """The rank stage (each reported blob's pixels numbered by its rank, 1 = best) placed in a
    zero compacted frame (int32 [H // f, W // f])."""
    stage = [st for st in res.stages if st.name == "rank"]
    return _canvas(res.subimage, np.asarray(stage[0].image), shape, f, np.int32) if stage else None


def _canvas(sub, img, shape, f, dtype):
    """``img`` (a window's stage image) at the window's compacted origin in a zero frame."""
    out = np.zeros((shape[0] // f, shape[1] // f), dtype)
    r0, c0 = sub.origin
    h, w = min(img.shape[0], out.shape[0] - r0), min(img.shape[1], out.shape[1] - c0)
    out[r0:r0 + h, c0:c0 + w] = img[:h, :w]
    return out


def detect_frame(img12, seq, record, compaction, window_mode="full", max_candidates=23,
                 tile=DEFAULT_TILE) -> dict:
    """The flight IP on one 12-bit image; returns the candidates and how they were found.

    ``img12``: uint16 [H, W] counts 0..4095; ``seq``: ProcessingSequence (its steps are used, its
    window replaced); ``record``: flightsw Record; ``compaction``: 1, 2 or 4; ``window_mode``:
    ``"64"`` (one flight window about the image centre, no TP prediction) or ``"full"`` (the whole
    compacted image as one window when it fits in ``tile`` x ``tile`` pixels, else the union of
    overlapping windows of ``tile`` (16..128) compacted pixels every ``tile // 4`` in one compiled
    call, see the module docstring, ranked together with the centroid means at the image
    centre). Returns a dict: ``mode`` (text),
    ``windows`` (int), ``feats`` (structured [m], FEATURE_DTYPE, best first), ``distance`` and
    ``gof`` (float [m]), ``centroid_means`` ((row, col), full-resolution pixels: the record's
    centroid means the ranking used), and in the compiled full-frame mode ``thresholded`` (int16
    [H // f, W // f], the image the back end labelled; absent in the other modes); in the
    one-window modes ``ranks`` (int32 [H // f, W // f]: the rank stage, each reported blob's
    pixels numbered by its rank in ``feats``, 1 = best; 0 elsewhere).
    """
    f = compaction
    H, W = img12.shape
    ch, cw = H // f, W // f
    if ch < 8 or cw < 8:
        raise ValueError(f"image {H}x{W} is too small for compaction {f}")
    if not 16 <= tile <= MAX_TILE:
        raise ValueError(f"tile {tile} must be in 16..{MAX_TILE}")
    if window_mode == "64":
        size = 64 if (64 <= ch or 64 <= cw) else max(ch, cw)
        return _single(img12, seq, record, f, size, max_candidates,
                       lambda sub: (f"flight window: {sub.size[0]}x{sub.size[1]} compacted pixels "
                                    f"at ({sub.origin[0]}, {sub.origin[1]}) (compacted), "
                                    f"compaction {f}"))
    if ch <= tile and cw <= tile:
        return _single(img12, seq, record, f, max(ch, cw), max_candidates,
                       lambda sub: f"full frame: one {ch}x{cw} window (compaction {f})")
    step = max(tile // 4, 1)
    plan = _frame_plan(seq, record, f)
    if plan.uses_poly or plan.ffts is not None:       # per-window fits and FFT tiles: one by one
        return _tiled(img12, seq, record, f, max_candidates, tile, step)
    return _compiled(img12, seq, record, f, max_candidates, tile, step)


_PLANS: dict = {}


def _frame_plan(seq, record, f):
    """The flight ``FramePlan`` of a sequence at compaction ``f`` (its front end; kept: the star
    job's gate makes a new record every frame, and the plan's front end does not depend on it; a
    kept entry holds its sequence, so its key always names the same object). The ranking record
    is chosen per call (:func:`_ranking_record`)."""
    from flightsw.ip.pipeline import FramePlan
    key = (id(seq), f)
    hit = _PLANS.get(key)
    if hit is None or hit[1] is not seq:
        if len(_PLANS) >= 32:
            _PLANS.clear()
        win = _with_window(seq, f, DEFAULT_TILE, (DEFAULT_TILE * f, DEFAULT_TILE * f))
        hit = _PLANS[key] = (FramePlan(win, record), seq)
    return hit[0]


def _ranking_record(plan, record):
    """The record the back end ranks against: the one the sequence's rank step names, else
    ``record`` (as :class:`flightsw.ip.pipeline.FramePlan` chooses)."""
    return record if plan.rank_record is plan.record else plan.rank_record


@lru_cache(maxsize=32)
def _geometry(ch, cw, th, tw, step):
    """Window starts (int64 [nr], [nc]) and each row's and column's covering windows."""
    from hil_harness.detect.union import cover_ranges
    rows = np.asarray(tile_starts(ch, th, step), np.int64)
    cols = np.asarray(tile_starts(cw, tw, step), np.int64)
    return rows, cols, cover_ranges(rows, th, ch), cover_ranges(cols, tw, cw)


def _compiled(img12, seq, record, f, max_candidates, tile, step):
    from flightsw.ip.backend import backend_params, result_from_head
    from flightsw.ip.features import words_to_struct
    from hil_harness.detect.frame_k import fullframe_k
    plan = _frame_plan(seq, record, f)
    rec = _ranking_record(plan, record)
    H, W = img12.shape
    ch, cw = H // f, W // f
    th, tw = min(tile, ch), min(tile, cw)
    rows, cols, rcover, ccover = _geometry(ch, cw, th, tw, step)
    params = backend_params(rec, *plan.flags, False, f, plan.imager,
                            max(1, min(max_candidates, 1000)))
    header, _ = plan.window_header(f, (0, 0), (ch, cw), (H / 2.0, W / 2.0), cut=f)
    pack, kept = fullframe_k(np.ascontiguousarray(img12), header, plan.front, None, None, params,
                             rows, cols, th, tw, rcover, ccover)
    be = result_from_head(_NO_LABELS, pack, header)
    cand = be.candidates()
    n_tiles = len(rows) * len(cols)
    return dict(mode=(f"full frame: {n_tiles} overlapping windows of {th}x{tw} compacted pixels "
                      f"every {step} (compaction {f}): the front end once on the whole frame, a "
                      f"pixel kept where any window's threshold passes it, blobs labelled once, "
                      f"ranked together with the centroid means at the image centre"),
                windows=n_tiles, feats=words_to_struct(be.feature_words[be.order]),
                centroid_means=(H / 2.0, W / 2.0),
                distance=np.asarray(cand["distance"], float), gof=np.asarray(cand["gof"], float),
                thresholded=kept)


_NO_LABELS = np.zeros((0, 0), np.int32)


#: a frame of more windows than this shows a progress bar on stderr (about 2 s of work)
PROGRESS_WINDOWS = 4000


def _progress(n):
    import sys

    from tqdm import tqdm
    return tqdm(total=n, desc="windows", unit="win", file=sys.stderr, leave=False,
                disable=n <= PROGRESS_WINDOWS or None)


def _tiled(img12, seq, record, f, max_candidates, tile, step):
    from flightsw.ip.features import words_to_struct
    from flightsw.ip.frame import process_window
    from flightsw.ip.preprocess import Subimage, compact
    from flightsw.ip.rank import rank_words
    H, W = img12.shape
    comp = compact(img12, f)
    ch, cw = comp.shape
    th, tw = min(tile, ch), min(tile, cw)
    s = _with_window(seq, f, tile, (H, W))
    rows, cols = tile_starts(ch, th, step), tile_starts(cw, tw, step)
    words, margin = [], []
    bar = _progress(len(rows) * len(cols))
    for r0 in rows:
        for c0 in cols:
            bar.update()
            win = np.ascontiguousarray(comp[r0:r0 + th, c0:c0 + tw]).astype(np.int16)
            res = process_window(Subimage(win, (r0, c0), f, (th, tw)), s, record, ledger=None,
                                 max_candidates=1000, want_stages=False)
            w = res.backend.feature_words
            if not len(w):
                continue
            st = words_to_struct(w)
            rr, cc = st["row"] / f - r0, st["col"] / f - c0          # in the tile, compacted
            inf = np.inf
            m = np.minimum.reduce([rr if r0 > 0 else np.full_like(rr, inf),
                                   th - rr if r0 + th < ch else np.full_like(rr, inf),
                                   cc if c0 > 0 else np.full_like(cc, inf),
                                   tw - cc if c0 + tw < cw else np.full_like(cc, inf)])
            words.append(w)
            margin.append(m)
    bar.close()
    if words:
        words = np.concatenate(words)
        st = words_to_struct(words)
        keep = merge_duplicates(st, np.concatenate(margin))
        words = words[np.sort(keep)]
    else:
        words = np.zeros((0, 12), np.int64)
    rk = rank_words(words, record, (H / 2.0, W / 2.0), None,
                    max_candidates=max(1, min(max_candidates, 1000)))
    n_tiles = len(rows) * len(cols)
    return dict(mode=(f"full frame tiled: {n_tiles} windows of {th}x{tw} compacted pixels every "
                      f"{step} (compaction {f}), duplicates merged, ranked together with the "
                      f"centroid means at the image centre"),
                windows=n_tiles, feats=words_to_struct(words[rk.order]),
                centroid_means=(H / 2.0, W / 2.0),
                distance=rk.distance[rk.order], gof=rk.gof)
