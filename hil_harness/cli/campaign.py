"""``uvisi campaign SPEC.toml [--out DIR] [--workers N] [--scheduler ADDRESS] [--resume]
[--serial] [--job module:function] [--no-progress]`` or ``uvisi campaign --show DIR``

Run a Monte Carlo campaign (``hil_harness.campaign``): every run of the spec (seeds x axes) executes
the spec's job (default ``hil_harness.campaign.jobs:identification``) on a Dask cluster -- a local
one of ``--workers`` processes (default 2), or the existing scheduler at ``--scheduler`` -- and the
results land in ``DIR/results.parquet`` (one row per run). Each finished run is committed at once
(``DIR/parts/``); after an interruption ``--resume`` runs only what is missing. ``--serial`` runs in
this process without Dask (the single-process baseline for throughput). The closed-loop event job
runs the paper's system unless the spec's ``[flight] with = [...]`` or ``--with`` (which replaces
it) names proposals; each result row carries ``flight.profile`` and ``flight.with``.
"""
from __future__ import annotations

import json
from pathlib import Path

from hil_harness.cli.options import add_with_option, with_names


def register(sub) -> None:
    p = sub.add_parser("campaign", help="Monte Carlo sweeps on Dask (results in Parquet, resumable)",
                       description=__doc__.split("\n\n")[1])
    p.add_argument("spec", nargs="?", default=None, help="campaign spec (TOML)")
    p.add_argument("--show", default=None, metavar="DIR",
                   help="print the summary of a campaign folder (runs, failures by reason, "
                        "results per axis combination) and exit")
    p.add_argument("-o", "--out", default=None, help="output directory (default: campaign_<name>)")
    p.add_argument("--workers", type=int, default=2,
                   help="worker processes of the local cluster (default 2)")
    p.add_argument("--scheduler", default=None,
                   help="address of an existing Dask scheduler, e.g. tcp://host:8786")
    p.add_argument("--resume", action="store_true",
                   help="continue the campaign in --out, skipping finished runs")
    p.add_argument("--serial", action="store_true", help="run in this process, no Dask")
    p.add_argument("--job", default=None, help="job 'module:function' (overrides the spec)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--json", default=None, help="write the run summary (JSON)")
    add_with_option(p)
    from hil_harness.cli.checks import add_no_size_check
    add_no_size_check(p)
    p.set_defaults(func=run, outputs={"out": "folder", "json": "file"})


def run(args) -> int:
    from hil_harness.campaign import CampaignSpec, campaign_report, failure_reasons, run_campaign
    if args.show:
        if args.spec:
            raise ValueError("give either a spec to run or --show DIR, not both")
        print(campaign_report(args.show))
        return 1 if failure_reasons(args.show) else 0
    if not args.spec:
        raise ValueError("a campaign spec (TOML) is required (or --show DIR)")
    if args.serial and args.scheduler:
        raise ValueError("--serial and --scheduler exclude each other")
    if not args.serial and not args.scheduler and args.workers < 1:
        raise ValueError(f"--workers {args.workers} must be >= 1")
    from hil_harness.sizes import campaign_cost, check
    spec = CampaignSpec.load(args.spec, lift_cap=args.no_size_check)
    if args.job or args.with_ is not None:
        raw = dict(spec.raw)
        if args.with_ is not None:                    # --with replaces the spec's [flight] with
            with_names(args)                          # unknown names refused here, by --with
            raw["flight"] = {"with": [n.strip() for n in args.with_.split(",") if n.strip()]}
        spec = CampaignSpec.from_dict(raw, spec.source, args.job, args.no_size_check)
    spec.validate_inputs()
    out = Path(args.out or f"campaign_{spec.name}")
    check(campaign_cost(f"campaign {spec.source}", len(spec.runs), out), args.no_size_check)
    print(f"[campaign] {spec.name}: {len(spec.runs)} runs of {spec.job} -> {out}")
    s = run_campaign(spec, out, scheduler=args.scheduler, workers=args.workers,
                     resume=args.resume, progress=not args.no_progress, serial=args.serial)
    if args.json:
        Path(args.json).write_text(json.dumps(s, indent=1, default=str))
    return 1 if s["failed"] else 0
