"""``uvisi compare SPEC.toml [--json OUT] [--plot PNG] [--workers N] [--scheduler ADDRESS]``

Weigh flight-software arms side by side (``hil_harness.compare``): every arm of the spec (the
paper's system, or it with proposals, another record or sequence) runs the closed loop on the same
events (scenarios x seeds, or a campaign events file's), each rendering its own frames from the same
seeds; every frame and track command is hashed to prove the inputs were the same up to the first
command that differs. Per arm: frames held after lock, decisions correct, closed-loop top-1, median
track error (processed px) and the emulated budget, each rate k/n with a Wilson 95 % interval on
frames and an interval over events; per event each arm's difference from the first arm; and a
paired test (Wilcoxon signed-rank, or an exact sign test when no event differs) of each arm against
the first. One Dask task per (arm, event) on a local cluster of ``--workers`` processes, or on the
scheduler at ``--scheduler``; ``--workers 1`` runs in this process.
"""
from __future__ import annotations

import json
from pathlib import Path


def register(sub) -> None:
    """Add the ``compare`` subcommand to the ``uvisi`` subparsers ``sub``."""
    p = sub.add_parser("compare", help="weigh flight-software arms (proposals) side by side on the "
                                       "same events", description=__doc__.split("\n\n")[1])
    p.add_argument("spec", help="comparison spec (TOML): [events] and [[arms]]")
    p.add_argument("--json", default=None, metavar="OUT",
                   help="write the comparison (JSON: spec, events, arms, paired, per_event)")
    p.add_argument("--plot", default=None, metavar="PNG",
                   help="write a figure of each arm's held-after-lock rate, intervals and "
                        "per-event points")
    p.add_argument("--workers", type=int, default=2,
                   help="worker processes of the local Dask cluster (default 2; 1: in this "
                        "process, no Dask)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of an existing Dask scheduler, e.g. tcp://host:8786")
    p.set_defaults(func=run, outputs={"json": "file", "plot": "file"})


def run(args) -> int:
    """Run the comparison of ``args.spec``; print the table, write ``--json`` / ``--plot``;
    0 when done (a ``ValueError`` naming the spec's file and field is a bad input: exit 2)."""
    from hil_harness import console
    from hil_harness.compare import (compare_plot, compare_table, jsonable, load_spec,
                                     run_compare)
    if args.scheduler is None and args.workers < 1:
        raise ValueError(f"--workers {args.workers} must be >= 1")
    for opt in ("json", "plot"):
        out = getattr(args, opt)
        if out is not None and (Path(out).is_dir() or not Path(out).resolve().parent.is_dir()):
            raise ValueError(f"--{opt} {out}: not a writable file path (is a folder, or its "
                             f"folder does not exist)")
    spec = load_spec(args.spec)
    console.note(f"[compare] {args.spec}: {len(spec.arms)} arms x {len(spec.events)} events = "
                 f"{len(spec.arms) * len(spec.events)} closed-loop runs")
    res = run_compare(spec, workers=args.workers, scheduler=args.scheduler,
                      progress=console.progress_enabled(), log=console.note)
    print(compare_table(res))
    if args.json:
        Path(args.json).write_text(json.dumps(jsonable(res), indent=1, allow_nan=False))
        console.note(f"[compare] wrote {args.json}")
    if args.plot:
        console.note(f"[compare] wrote {compare_plot(res, args.plot)}")
    return 0
