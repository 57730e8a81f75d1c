"""A record for the all-sky job that weighs only a few features, chosen by the exact count
(docs/validation.md, "Aurora on real all-sky imagery", "Measured and not kept"):
``python -m bench.allsky_sparse_choice [--workers N] [--max-size N]`` (~13 min wall on 2 cores).

Why: the record that ranks the label first on the most training frames (62 of 70, with every
feature weighed) does so on at most 43 of the 75 scored frames, and fitted to one training block
it carries poorly to the other. A record with fewer free coefficients has less to fit to one
phase of the night. Chosen on the training frames of THEMIS Gillam 2008 only (frames 0-69, two
blocks), with the shipped ``aurora_allsky`` sequence and field; the scored frames 75-149, the
2014 night and the WIC night are run once, after the choice:

1. **Screen**: every set of one to ``--max-size`` features among the ten that are not the
   centroids (:func:`subsets`; a record that does not weigh the centroids ranks the same wherever
   the TP's prior puts them), each scored by block cross-validation: the exact best record of
   those features (:func:`hil_harness.tuning.record_ceiling.best_record` with the others unused)
   fitted to one training block, run as ``uvisi detect`` on the other; the two counts summed.
2. **Choice**: the highest cross-validated count (on a tie, fewer features, then the screen's
   order).
3. **Score**: that set's best record fitted to all 70 training frames, run as ``uvisi detect``
   and ``uvisi track`` on each scored night.

The labels are read only to fit and to score (as ``python -m hil_harness.tuning.label_scores``).
"""
from __future__ import annotations

import argparse
import itertools
import os
import sys

from bench.allsky_exact_choice import CENTROIDS, fit_and_score, print_scored, rate_text, run_all

__all__ = ["subsets", "main"]


def subsets(max_size: int = 3) -> list[tuple[str, ...]]:
    """Every set of 1 to ``max_size`` feature names (:data:`flightsw.messages.FEATURE_NAMES`
    order) among the features that are not the centroids, smaller sets first."""
    from flightsw.messages import FEATURE_NAMES
    free = [f for f in FEATURE_NAMES if f not in CENTROIDS]
    return [s for n in range(1, max_size + 1) for s in itertools.combinations(free, n)]


def _unused(chosen) -> tuple[str, ...]:
    from flightsw.messages import FEATURE_NAMES
    return tuple(f for f in FEATURE_NAMES if f not in chosen)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--max-size", type=int, default=3, help="most features a record weighs")
    args = ap.parse_args(argv)
    if args.workers < 1 or not 1 <= args.max_size <= 10:
        ap.error("--workers: at least 1; --max-size: 1 to 10")
    sets = subsets(args.max_size)
    cv = run_all([(None, False, _unused(s)) for s in sets], args.workers, "screen",
                 "feature sets")
    order = sorted(range(len(sets)), key=lambda i: (-sum(cv[i]), len(sets[i]), i))
    print("| features weighed | A on B | B on A | of 70 |\n| --- | ---: | ---: | ---: |")
    for i in order[:10]:
        print(f"| {', '.join(sets[i])} | {cv[i][0]} | {cv[i][1]} | {sum(cv[i])} |")
    print("\n| features | sets | best cross-validated: of 70 |\n| ---: | ---: | ---: |")
    for n in range(1, args.max_size + 1):
        mine = [sum(cv[i]) for i in range(len(sets)) if len(sets[i]) == n]
        print(f"| {n} | {len(mine)} | {max(mine)} |")
    k = order[0]
    print(f"\nchosen: {', '.join(sets[k])}: {rate_text(sum(cv[k]), 70)} cross-validated")
    got = fit_and_score(None, _unused(sets[k]), widest=False)
    print_scored(got)
    return 0


if __name__ == "__main__":
    sys.exit(main())
