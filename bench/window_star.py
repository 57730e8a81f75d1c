"""Is a bright source in the IP's window what hides a tracked satellite? (docs/validation.md "Why
`mid_offset_ahead`"): ``python -m bench.window_star SCENARIO [SCENARIO...] --seeds 211,212,213``.

Runs each closed-loop event (:class:`hil_harness.event.Event`, the defaults unless
``--sequence``) and re-runs the IP (:func:`flightsw.ip.process_frame`) on each processed frame with
the target in the field, with the same frame, window, prior and alpha and its stage images. Each
such frame is ``before`` (up to the first lock), ``miss`` (after it, no candidate at the target in
the message: within 1.5 processed px of the true pixel) or ``found`` (after it, a candidate there).
On the image that enters the threshold step (the window in processed pixels; truth is read only to
measure):

* ``peak``: the target's value there (the largest of the 3x3 processed pixels about its true
  position); ``thr``: the paper's threshold, mean + alpha std of the window (host float: a
  diagnostic, not the flight's word); ``std`` the window's std;
* ``src``: the brightest value outside the 5x5 about the target, and the catalogue star nearest
  to it (the frame's truth); ``thr_wo``: mean + alpha std of the window without the 9x9 about that
  source;
* ``pred_err``: the distance between the TP's prediction in force and the true pixel (processed
  px; NaN before the first prediction, left out of the medians); ``off_centre``: the target's
  distance from the field centre (imager px); ``corner``: its distance from the nearest corner of
  the processed-pixel grid (processed px; 0 = the flux split evenly over four pixels, 0.71 = one
  pixel's centre).

Prints per event and per scenario, for each group: its frames, of them ``below`` (peak <= thr),
``bright`` (below with a source over 100 counts), ``wo_pass`` (bright, and peak > thr_wo), the
medians (and ranges) of the figures above, and the stars found as ``src`` (HIP: frames).
"""
from __future__ import annotations

import argparse
import math
from collections import Counter

import numpy as np

from flightsw.ip import process_frame
from hil_harness.event.metrics import held_after_lock

from .satellite_misses import run_keeping_frames

__all__ = ["window_statistics", "event_window_frames", "main"]


def window_statistics(d, alpha: float, trow: float, tcol: float) -> dict:
    """The figures of the module docstring for one window.

    ``d``: [rows, cols] the image entering the threshold step (processed px, counts); ``alpha``
    the frame's alpha; ``trow``, ``tcol``: the target in window coordinates (processed px, pixel
    centres at +0.5). Returns a dict: ``peak``, ``thr``, ``src``, ``src_rc`` (row, col of the
    source, window px, pixel centre), ``thr_wo``, ``std`` (floats)."""
    d = np.asarray(d, float)
    r, c = int(math.floor(trow)), int(math.floor(tcol))
    peak = d[max(r - 1, 0):r + 2, max(c - 1, 0):c + 2].max()
    masked = d.copy()
    masked[max(r - 2, 0):r + 3, max(c - 2, 0):c + 3] = -np.inf
    sr, sc = np.unravel_index(int(np.argmax(masked)), d.shape)
    keep = np.ones(d.shape, bool)
    keep[max(sr - 4, 0):sr + 5, max(sc - 4, 0):sc + 5] = False
    return {"peak": float(peak), "thr": float(d.mean() + alpha * d.std()),
            "src": float(d[sr, sc]), "src_rc": (sr + 0.5, sc + 0.5), "std": float(d.std()),
            "thr_wo": float(d[keep].mean() + alpha * d[keep].std())}


def _threshold_input(res, sequence):
    """The stage image entering the threshold step (the window itself when it is the first)."""
    names = [s.stage for s in sequence.steps]
    i = names.index("threshold")
    stages = dict((s.name, s.image) for s in res.stages)
    return stages[names[i - 1]] if i > 0 else res.subimage.image


def _star_at(stars, row: float, col: float) -> int:
    """HIP number of the catalogue star nearest (row, col) in imager px (-1 none within 6 px)."""
    if stars is None or len(stars) == 0:
        return -1
    dist = np.hypot(stars["row"] - row, stars["col"] - col)
    j = int(np.argmin(dist))
    return int(stars["hip"][j]) if dist[j] <= 6.0 else -1


def event_window_frames(scenario: str, seed: int, sequence=None) -> dict | None:
    """Per processed frame with the target in the field: :func:`window_statistics` plus
    ``group``, ``pred_err``, ``off_centre``, ``corner``, ``hip`` (None when the TP never
    locked)."""
    ev, kept = run_keeping_frames(scenario, seed, sequence)
    f = ev.scenario.compaction
    lock = held_after_lock(ev.outcomes, ev.geometry, f)["lock_frame"]
    if lock is None:
        return None
    im = ev.scenario.imagers[ev.scenario.imager]
    rows = []
    for o in ev.outcomes:
        tg = (o.truth or {}).get("target") or {}
        if o.k not in kept or not tg.get("in_field"):
            continue
        cand = o.message.candidates
        at = any(math.hypot(x["row"] - tg["row"], x["col"] - tg["col"]) <= 1.5 * f for x in cand)
        frame, fb, _ = kept[o.k]
        res = process_frame(frame, ev.ip.sequence, ev.ip.record, fb, imager=o.imager,
                            alpha_q12=int(round(o.alpha * 4096)), want_stages=True)
        sub = res.subimage
        trow, tcol = tg["row"] / f - sub.origin[0], tg["col"] / f - sub.origin[1]
        w = window_statistics(_threshold_input(res, ev.ip.sequence), o.alpha, trow, tcol)
        fr, fc = tg["row"] / f % 1.0, tg["col"] / f % 1.0
        w["group"] = "before" if o.k <= lock else ("found" if at else "miss")
        w["corner"] = math.hypot(min(fr, 1 - fr), min(fc, 1 - fc))
        w["off_centre"] = math.hypot(tg["row"] - im.n_rows / 2, tg["col"] - im.n_cols / 2)
        w["pred_err"] = math.hypot(o.pred_row - tg["row"], o.pred_col - tg["col"]) / f
        w["hip"] = _star_at(o.truth.get("stars"), *sub.to_imager(*w["src_rc"]))
        rows.append(w)
    return {"lock": lock, "rows": rows}


_FIGURES = ("peak", "thr", "thr_wo", "src", "std", "pred_err", "off_centre", "corner")


def _line(name: str, rows: list) -> str:
    if not rows:
        return f"{name}: 0 frames"
    g = {k: np.array([r[k] for r in rows], float) for k in _FIGURES}
    below = g["peak"] <= g["thr"]
    bright = below & (g["src"] > 100)
    wo = bright & (g["peak"] > g["thr_wo"])
    med = " ".join(f"{k} {np.nanmedian(v):.2f} ({np.nanmin(v):.2f}-{np.nanmax(v):.2f})"
                    for k, v in g.items() if np.isfinite(v).any())
    stars = Counter(r["hip"] for r in rows).most_common(3)
    return (f"{name}: {len(rows)} frames, below {int(below.sum())} bright {int(bright.sum())} "
            f"wo_pass {int(wo.sum())}; medians (ranges) {med}; src stars "
            + ", ".join(f"HIP {h}: {n}" for h, n in stars))


def _print_groups(name: str, rows: list) -> None:
    for grp in ("before", "miss", "found"):
        print(_line(f"{name} {grp}", [r for r in rows if r["group"] == grp]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.window_star",
                                 description=__doc__.split("\n")[0])
    ap.add_argument("scenarios", nargs="+")
    ap.add_argument("--seeds", default="211,212,213", help="comma-separated seeds")
    ap.add_argument("--sequence", default=None,
                    help="shipped name or TOML file (default: the event's)")
    args = ap.parse_args(argv)
    for scn in args.scenarios:
        rows = []
        for seed in (int(x) for x in args.seeds.split(",")):
            d = event_window_frames(scn, seed, args.sequence)
            if d is None:
                print(f"{scn} {seed}: never locked")
                continue
            print(f"{scn} {seed}: first lock at frame {d['lock']}")
            _print_groups(f"{scn} {seed}", d["rows"])
            rows += d["rows"]
        _print_groups(f"{scn} all", rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
