"""A sequence and record for the all-sky job chosen by the exact count instead of the closed-loop
tuner (docs/validation.md, "Aurora on real all-sky imagery", "Measured and not kept"):
``python -m bench.allsky_exact_choice [--workers N] [--top N]`` (~20 min wall on 2 cores).

Chosen on the training frames of THEMIS Gillam 2008 only (frames 0-69, two blocks); the scored
frames 75-149, the 2014 night and the WIC night are run once, after the choice:

1. **Screen**: 210 compaction-4 sequences (:func:`grid`), each scored by block cross-validation:
   the exact best record (:func:`hil_harness.tuning.record_ceiling.best_record`) fitted to one
   training block, run as ``uvisi detect`` on the other; the two counts summed (of 70).
2. **Refine**: the ``--top`` best again, with each best record replaced by its widest-lead record
   (:func:`hil_harness.tuning.record_ceiling.widest_record`), with and without the centroid rows
   weighed (a record that does not weigh them ranks the same wherever the TP's prior is).
3. **Choice**: the highest cross-validated count of step 2 (the first in the screen's order on a
   tie).
4. **Score**: that sequence's widest-lead record fitted to all 70 training frames, run as
   ``uvisi detect`` and ``uvisi track`` on each scored night, beside the shipped
   ``aurora_allsky`` job.

The labels are read only to fit and to score (as ``python -m hil_harness.tuning.label_scores``).
"""
from __future__ import annotations

import argparse
import itertools
import os
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TRAIN_BLOCKS = ("gill2008_train_a", "gill2008_train_b")
SCORED = ("gill2008_test", "gill2014", "wic")
CENTROIDS = ("row", "col")

__all__ = ["CENTROIDS", "grid", "sequence_toml", "label", "block_cv", "run_all", "fit_and_score",
           "rate_text", "print_scored", "main"]


def grid():
    """The screened sequences: ``(compaction, detrend, sigma, filter, alpha, mode)`` tuples
    (the high-pass at sigma 1.0-3.0, the polynomial detrend or none; no filter, 3x3 smoothing or
    the 3x3 matched filter; alpha 1.0-3.0; clip or binarise), 210 in all."""
    detrends = [("highpass", s) for s in (1.0, 1.5, 2.0, 2.5, 3.0)]
    detrends += [("polynomial", None), ("none", None)]
    return [(4, d, s, f, a, m) for (d, s), f, a, m in itertools.product(
        detrends, ("none", "smooth", "matched"), (1.0, 1.5, 2.0, 2.5, 3.0),
        ("clip", "binarize"))]


def sequence_toml(spec) -> str:
    """A sequence file's text for one :func:`grid` tuple."""
    comp, detrend, sigma, filt, alpha, mode = spec
    text = (f'name = "screen"\ndescription = "{label(spec)}"\n\n[preprocess]\n'
            f"compaction = {comp}\nwindow = 64\n")
    if detrend != "none":
        text += f'\n[[steps]]\nop = "detrend"\nmethod = "{detrend}"\n'
        if sigma is not None:
            text += f"sigma = {sigma}\n"
    if filt != "none":
        text += f'\n[[steps]]\nop = "filter"\nkernel = "{filt}"\nsize = 3\n'
    return text + f'\n[[steps]]\nop = "threshold"\nalpha = {alpha}\nmode = "{mode}"\n'


def label(spec) -> str:
    """One :func:`grid` tuple in words, as the tables print it."""
    comp, detrend, sigma, filt, alpha, mode = spec
    d = f"highpass {sigma}" if detrend == "highpass" else detrend
    return f"c{comp}, {d}, filter {filt}, alpha {alpha} {mode}"


def _fit(sequence, frames, widest: bool, unused=()):
    """The best (or widest-lead) record of the aurora_allsky job's blobs on ``frames``."""
    from flightsw.messages import FEATURE_NAMES
    from hil_harness.tuning.export import record_from
    from hil_harness.tuning.label_scores import NIGHTS, blob_tables
    from hil_harness.tuning.record_ceiling import best_record, widest_record
    base = record_from("aurora_allsky")
    images, labels, _ = NIGHTS["gill2008_train"]
    table, fixed = blob_tables(ROOT / images, ROOT / labels, base, frames, sequence=sequence)
    off = [FEATURE_NAMES.index(name) for name in unused]
    best = best_record(table, fixed, unused=off)
    if widest:
        best = widest_record(table, best, fixed, unused=off)
    return best.record(base), best.hits


def block_cv(sequence, widest=False, unused=()) -> tuple:
    """Block cross-validation on the training frames -> ``(held-out hits of block A's record on
    B, of B's on A)``: each block's record run as ``uvisi detect`` on the other."""
    from hil_harness.tuning.label_scores import NIGHTS, detect_hits
    out = []
    for fit_on, score_on in (TRAIN_BLOCKS, TRAIN_BLOCKS[::-1]):
        rec, _ = _fit(sequence, NIGHTS[fit_on][2], widest, unused)
        images, labels, frames = NIGHTS[score_on]
        out.append(sum(detect_hits(ROOT / images, ROOT / labels, rec, frames,
                                   sequence=sequence).values()))
    return tuple(out)


def _screen_one(args):
    return block_cv(*args)


def run_all(jobs, workers: int, desc: str, unit: str = "sequences") -> list:
    """:func:`block_cv` of each job (a tuple of its arguments) on ``workers`` processes (the
    workers quiet: the searches' own progress would interleave), with a bar on a terminal or a
    heartbeat line in a log counting ``unit``."""
    from hil_harness.console import QUIET, Heartbeat, progress_enabled, set_level
    if progress_enabled():
        from tqdm import tqdm
        shown = tqdm(total=len(jobs), desc=desc, unit=unit.rstrip("s"), file=sys.stderr)
    else:
        shown = Heartbeat(len(jobs), desc, unit)
    out = []
    with ProcessPoolExecutor(workers, initializer=set_level, initargs=(QUIET,)) as pool:
        for r in pool.map(_screen_one, jobs):
            out.append(r)
            shown.update(1)
    shown.close()
    return out


def fit_and_score(sequence, unused=(), widest=True) -> dict:
    """The widest-lead record (``widest=False``: the best record) fitted to training frames 0-69
    -> ``{"train": hits, night: (detect hits, frames, locked, track frames, on the label when
    locked)}`` for :data:`SCORED`."""
    from hil_harness.tuning.label_scores import NIGHTS, detect_hits, track_hits
    rec, hits = _fit(sequence, NIGHTS["gill2008_train"][2], widest, unused)
    out = {"train": hits}
    for night in SCORED:
        images, labels, frames = NIGHTS[night]
        h = detect_hits(ROOT / images, ROOT / labels, rec, frames, sequence=sequence)
        t = track_hits(ROOT / images, ROOT / labels, rec, frames, sequence=sequence)
        locked = [f for f, (lk, _) in t.items() if lk]
        out[night] = (sum(h.values()), len(h), len(locked), len(t),
                      sum(t[f][1] for f in locked))
    return out


def rate_text(k, n) -> str:
    """``k`` of ``n`` as the tables print a rate: percent, k/n and the Wilson 95 % interval."""
    from hil_harness.rates import rate
    from hil_harness.tuning.label_scores import rate_cell
    return rate_cell(rate(k, n))


def print_scored(got: dict) -> None:
    """:func:`fit_and_score`'s result as the training count and a table of the scored nights."""
    print(f"fitted to training frames 0-69: {rate_text(got['train'], 70)}\n")
    print("| night | `uvisi detect`: rank 1 on the label | `uvisi track`: locked | on the label "
          "when locked |\n| --- | --- | --- | --- |")
    for night in SCORED:
        d, n, lk, nt, on = got[night]
        print(f"| {night} | {rate_text(d, n)} | {rate_text(lk, nt)} | {rate_text(on, lk)} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--top", type=int, default=20, help="sequences refined in step 2")
    args = ap.parse_args(argv)
    if args.workers < 1 or args.top < 1:
        ap.error("--workers and --top: at least 1")
    specs = grid()
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for i, spec in enumerate(specs):
            p = Path(tmp) / f"screen_{i:03d}.toml"
            p.write_text(sequence_toml(spec))
            paths.append(str(p))
        cv = run_all([(p, False, ()) for p in paths], args.workers, "screen")
        order = sorted(range(len(specs)), key=lambda i: -sum(cv[i]))[:args.top]
        print("| sequence | A on B | B on A | of 70 |\n| --- | ---: | ---: | ---: |")
        for i in order:
            print(f"| {label(specs[i])} | {cv[i][0]} | {cv[i][1]} | {sum(cv[i])} |")
        jobs = [(paths[i], True, u) for i in order for u in ((), CENTROIDS)]
        refined = run_all(jobs, args.workers, "refine")
        print("\n| sequence | centroids weighed | widest lead: of 70 |\n| --- | --- | ---: |")
        for (p, _, u), r in zip(jobs, refined):
            print(f"| {label(specs[paths.index(p)])} | {'no' if u else 'yes'} | {sum(r)} |")
        k = max(range(len(jobs)), key=lambda j: (sum(refined[j]), -j))
        path, _, unused = jobs[k]
        spec = specs[paths.index(path)]
        print(f"\nchosen: {label(spec)}, centroids {'not ' if unused else ''}weighed: "
              f"{rate_text(sum(refined[k]), 70)} cross-validated")
        got = fit_and_score(path, unused)
    print_scored(got)
    return 0


if __name__ == "__main__":
    sys.exit(main())
