"""``uvisi tune``: tune an a priori feature record on labelled frames (``hil_harness.tuning``).

Where a set spec names no ``sequence`` (or no ``field_scale``), optimise and validate run it as the
record's job does (``--base``, ``--record``): ``aurora_allsky`` runs its own sequence and field.

``uvisi tune set SPEC.toml -o SET.npz [--workers N]``
    build a labelled training set (every blob's flight features) and save it; every other command
    takes either a set spec (TOML, built on the fly) or a saved ``.npz`` set.

``uvisi tune fit SET -o FIT.toml [--base aurora] [--name N] [--id K] [--version V]``
    feature means and sigmas from the object's candidates, quantisation thresholds from the object
    and non-object distributions; weights, flag and GOF threshold from ``--base``.

``uvisi tune optimise SPEC.toml -o TUNED.toml [--words TUNED.words] [--base aurora|FILE]
[--frr 0.005] [--quantize auto|on|off] [--folds 3] [--seed 0] [--maxiter 15] [--popsize 4]
[--centroid-penalty 0.25] [--events DIR] [--json OUT.json] [--workers N]``
    every event of the spec rendered once, then replayed through the flight IP + TP for each
    candidate record: fit on the blobs the base record saw in closed loop, weights maximising the
    closed-loop top-1 rate (SciPy differential evolution) with a penalty that stops them leaning
    on the position prior alone, GOF threshold for the stated false-rejection rate; the
    cross-validation groups by event (``hil_harness.tuning.closed``). The weight searches (per
    fold and quantisation choice) run at once on N processes (default: one per core), the same
    record on any N.

``uvisi tune validate SPEC.toml --record TUNED.toml [--compare aurora ...] --report DIR
[--require-top1 0.95] [--events DIR]``
    the flight protocol: ``top1_closed_loop`` (the IP's prior from the TP), beside it
    ``top1_no_prior`` and ``top1_truth_prior`` (an upper bound), each k/n with a Wilson 95 %
    interval; top-3, false lock, rank over time, confusion summary on the closed-loop frames;
    ``DIR/report.md`` + ``metrics.json`` + PNG plots. ``--require-top1``: exit status 1 when the
    record's closed-loop top-1 rate is below it.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from hil_harness.cli.options import add_with_option, number, with_names
from hil_harness.console import progress_enabled


def register(sub) -> None:
    p = sub.add_parser("tune", help="fit, optimise and validate a priori feature records",
                       description=__doc__.split("\n\n")[0])
    ts = p.add_subparsers(dest="tune_command", metavar="TUNE_COMMAND")

    def common(q):
        q.add_argument("set", help="set spec (.toml) or saved set (.npz)")
        q.add_argument("--workers", type=number(1, integer=True), default=None,
                       help="processes that render a set spec's events (default: the spec's "
                            "workers) and run optimise's independent weight searches (default: "
                            "one per core this process may run on); results do not depend on it")
        q.add_argument("--no-progress", action="store_true", help="no progress bar")
        from hil_harness.cli.checks import add_no_size_check
        add_no_size_check(q)
        q.add_argument("--channel", default=None, choices=("l", "r", "g", "b"),
                       help="what a colour image of a [[real]] entry becomes when the entry names "
                            "no channel: l = BT.601 luma (the default), or the r, g or b channel")

    q = ts.add_parser("set", help="build and save a labelled training set")
    common(q)
    q.add_argument("-o", "--out", required=True, help="output .npz")
    q.set_defaults(func=_set, outputs={"out": "file"})

    q = ts.add_parser("fit", help="means, sigmas and quantisation thresholds from a set")
    common(q)
    q.add_argument("-o", "--out", required=True, help="output record TOML")
    q.add_argument("--base", default="aurora",
                   help="record giving weights, type, id (shipped name or TOML; default aurora)")
    _naming(q)
    q.add_argument("--save-set", default=None, help="also save the built set (.npz)")
    q.set_defaults(func=_fit, outputs={"out": "file"})

    q = ts.add_parser("optimise", aliases=["optimize"],
                      help="fit + optimise weights (cross-validated) + GOF threshold")
    common(q)
    q.add_argument("-o", "--out", required=True, help="output record TOML")
    q.add_argument("--words", default=None,
                   help="also write the uplink image (.words hex text, .bin big-endian binary)")
    q.add_argument("--base", default="aurora",
                   help="starting weights, type, id (shipped name or TOML; default aurora)")
    q.add_argument("--frr", type=float, default=0.005,
                   help="false-rejection rate for the GOF threshold (default 0.005)")
    q.add_argument("--quantize", default="auto", choices=("auto", "on", "off"),
                   help="quantisation flag: both searched, the better closed-loop training "
                        "rate wins (auto), or forced")
    q.add_argument("--folds", type=int, default=3,
                   help="cross-validation folds, grouped by event (one night: blocks of >= 4 "
                        "frames); default 3, 1 = none")
    q.add_argument("--cv-groups", choices=("event", "scenario"), default="event",
                   help="what a cross-validation fold holds out: events (default) or whole "
                        "scenarios (every seed of a set entry in one fold)")
    q.add_argument("--seed", type=int, default=0, help="optimiser seed")
    q.add_argument("--maxiter", type=int, default=15, help="differential-evolution generations")
    q.add_argument("--popsize", type=int, default=4, help="population per weight")
    q.add_argument("--centroid-penalty", type=float, default=0.25,
                   help="weight of the rate with the centroid weights zeroed in the objective "
                        "(keeps the record from leaning on the position prior alone; default "
                        "0.25)")
    q.add_argument("--events", default=None,
                   help="directory keeping the rendered events (read back when present; keyed "
                        "by scenario entry and seed: empty it when the renderer changes)")
    q.add_argument("--json", default=None, help="write the optimisation summary (JSON)")
    _naming(q)
    add_with_option(q)
    q.set_defaults(func=_optimise, outputs={"out": "file", "words": "file", "json": "file"})

    q = ts.add_parser("validate", help="identification rates and report on a held-out set")
    common(q)
    q.add_argument("--record", required=True, help="record to validate (TOML or shipped name)")
    q.add_argument("--compare", nargs="*", default=["aurora"],
                   help="records reported beside it on the same frames (default: aurora, Table 1)")
    q.add_argument("--report", required=True, help="output directory")
    q.add_argument("--title", default=None)
    q.add_argument("--require-top1", type=number(0, 1), default=None,
                   help="exit status 1 if the record's closed-loop top-1 rate is below this")
    q.add_argument("--events", default=None,
                   help="directory keeping the rendered events (read back when present; keyed "
                        "by scenario entry and seed: empty it when the renderer changes)")
    add_with_option(q)
    q.set_defaults(func=_validate, outputs={"report": "folder"})
    p.set_defaults(func=lambda a: (p.print_help(), 0)[1])


def _naming(q):
    q.add_argument("--name", default=None, help="record name (default: <base>_tuned)")
    q.add_argument("--id", type=int, default=None, help="record id (default: the base's)")
    q.add_argument("--version", type=int, default=None,
                   help="record version (default: the base's + 1)")


def _get_set(args):
    from hil_harness.tuning.data import build_set
    p = Path(args.set)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such set spec or set")
    if p.suffix == ".toml":
        from hil_harness.tuning.data import SetSpec
        check_render_size(SetSpec.load(p), args)
    t0 = time.perf_counter()
    ts = build_set(_with_channel(p, args.channel), workers=args.workers,
                   progress=progress_enabled() and not args.no_progress)
    print(f"[tune] set {ts.meta.get('name', p.stem)}: {ts.summary()} "
          f"({time.perf_counter() - t0:.1f} s)")
    return ts


def check_render_size(spec, args) -> None:
    """Before anything is rendered: the frames every scenario entry and seed of the set spec
    renders (each entry's ``start``, ``every`` and ``frames`` over the scenario's length, overrides
    applied), within the frame cap and the free memory (a rendered frame and its rows each, the
    closed-loop commands keep them) and the free disk of ``--events`` (:mod:`hil_harness.sizes`)."""
    from hil_harness.sizes import FRAME_BYTES, RECORD_BYTES_PER_FRAME, MAX_FRAMES, Cost, check
    from hil_harness.tuning.data import scenario_from_entry
    n = 0
    for e in spec.scenarios:
        scn = scenario_from_entry(e["name"], e.get("override"), None, spec.base_dir)
        per_seed = max(0, -(-(scn.n_frames - e.get("start", 0)) // e.get("every", 1)))
        if e.get("frames") is not None:
            per_seed = min(per_seed, e["frames"])
        n += per_seed * len(e["seeds"])
    cache = getattr(args, "events", None)
    check(Cost(f"set spec {spec.name}", n, "frames",
               n * FRAME_BYTES if cache else 0.0, n * (FRAME_BYTES + RECORD_BYTES_PER_FRAME),
               MAX_FRAMES, Path(cache) if cache else None), lift_cap=args.no_size_check)


def _with_channel(p: Path, channel):
    """The set spec at ``p`` with ``channel`` given to its ``[[real]]`` entries that name none
    (``p`` itself when there is no channel to give or it is a saved set)."""
    from hil_harness.tuning.data import SetSpec
    if channel is None or p.suffix != ".toml":
        return p
    spec = SetSpec.load(p)
    for e in spec.reals:
        e["channel"] = e.get("channel") or channel
    return spec


def _names(args):
    from hil_harness.tuning.export import record_from as load_record
    base = load_record(args.base)
    name = args.name or f"{base.name}_tuned"
    rid = base.record_id if args.id is None else args.id
    ver = min(base.version + 1, 0xFFFF) if args.version is None else args.version
    return base, name, rid, ver


def _set(args) -> int:
    ts = _get_set(args)
    ts.save(args.out)
    print(f"wrote {args.out}")
    return 0


def _fit(args) -> int:
    from hil_harness.tuning.export import export_record
    from hil_harness.tuning.fit import fit_record, top1_rate
    ts = _get_set(args)
    if args.save_set:
        ts.save(args.save_set)
    base, name, rid, ver = _names(args)
    rec = fit_record(ts, base=base, name=name, record_id=rid, version=ver)
    export_record(rec, args.out, comment=f"uvisi tune fit {args.set} (base {base.name})")
    print(f"[tune] fitted {name}: ranking top-1 with the base weights on the set's own windows "
          f"{top1_rate(ts, rec):.4f} (prior '{ts.meta.get('predict')}'; not a flight figure: "
          f"uvisi tune validate gives the closed-loop rate)")
    print(f"wrote {args.out}")
    return 0


def _replayer(args, record=None):
    """Render (or read back from ``--events``) every event of the spec once -> Replayer; with
    ``record``, the spec as that record's job runs it (:meth:`SetSpec.for_record`)."""
    from hil_harness.tuning.closed import Replayer
    from hil_harness.tuning.data import SetSpec
    from hil_harness.tuning.events import build_events, event_radius
    p = Path(args.set)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such set spec")
    if p.suffix != ".toml":
        raise ValueError(f"{p}: closed-loop tuning replays frames: give the set spec (.toml), "
                         f"not a saved feature set")
    spec = _with_channel(p, args.channel) if args.channel else SetSpec.load(p)
    if record is not None:
        spec = spec.for_record(record)
    check_render_size(spec, args)
    t0 = time.perf_counter()
    evs = build_events(spec, cache_dir=args.events, workers=args.workers,
                       progress=progress_enabled() and not args.no_progress)
    nobj = sum(int(e.has_object.sum()) for e in evs)
    print(f"[tune] set {spec.name}: {len(evs)} events, {sum(e.n_frames for e in evs)} frames "
          f"({nobj} with the object) ({time.perf_counter() - t0:.1f} s)")
    # the closed-loop replays run the TP in target-of-opportunity mode (no velocity filter)
    from hil_harness.cli.options import available_cores
    return Replayer(evs, spec.sequence, event_radius(spec), spec.base_dir, spec.name,
                    proposals=with_names(args, "opportunity") or (),
                    workers=args.workers or available_cores(), object_rule=spec.object_rule)


def _rate_text(r) -> str:
    return f"{r['k']}/{r['n']} = {r['rate']:.4f} (95 % CI {r['ci95'][0]:.4f}-{r['ci95'][1]:.4f})"


def _optimise(args) -> int:
    from hil_harness.tuning.closed import cross_validate_closed, optimise_closed_loop
    from hil_harness.tuning.export import export_record
    from hil_harness.tuning.validate import atomic_text
    if not 0.0 <= args.frr < 1.0:
        raise ValueError(f"--frr {args.frr} must be in [0, 1)")
    if args.folds < 1 or args.maxiter < 1 or args.popsize < 1:
        raise ValueError("--folds, --maxiter and --popsize must be >= 1")
    if not args.centroid_penalty >= 0.0:
        raise ValueError(f"--centroid-penalty {args.centroid_penalty} must be >= 0")
    base, name, rid, ver = _names(args)
    rp = _replayer(args, base)
    kw = dict(base=base, frr=args.frr, quantize=args.quantize, maxiter=args.maxiter,
              popsize=args.popsize, centroid_penalty=args.centroid_penalty)
    t0 = time.perf_counter()
    kw["progress"] = progress_enabled() and not args.no_progress
    cv = (cross_validate_closed(rp, args.folds, seed=args.seed, by=args.cv_groups, **kw)
          if args.folds > 1 else {})
    res = optimise_closed_loop(rp, seed=args.seed, name=name, record_id=rid, version=ver,
                               kappa=cv.get("kappa", 1.0) if cv else 1.0, **kw)
    res.cv = cv
    dt = time.perf_counter() - t0
    tr = res.train
    lines = [f"uvisi tune optimise {args.set} (base {base.name}, frr {args.frr:g}, quantize "
             f"{args.quantize}, {args.folds} folds by {args.cv_groups}, seed {args.seed}, "
             f"centroid penalty {args.centroid_penalty:g})",
             f"closed-loop training top-1 {_rate_text(tr['top1_closed_loop'])}"]
    if cv:
        lines += [f"cross-validated by {cv['how']}: closed loop "
                  f"{_rate_text(cv['top1_closed_loop'])}; no prior "
                  f"{_rate_text(cv['top1_no_prior'])}; truth prior (upper bound) "
                  f"{_rate_text(cv['top1_truth_prior'])}",
                  "GOF threshold calibrated on the held-out folds in closed loop: "
                  + ("none (--frr 0)" if args.frr == 0
                     else "none (no widening kept the loss within --frr)" if cv["kappa"] is None
                     else f"kappa {cv['kappa']:g} x the --frr quantile distance")]
    out = export_record(res.record, args.out, args.words, "\n".join(lines))
    print(f"[tune] optimised in {dt:.1f} s; " + "; ".join(lines[1:]) +
          f"; n = {res.record.n_weighted}, uplink CRC {out['crc']}")
    print("wrote " + ", ".join(v for k, v in out.items() if k != "crc"))
    if args.json:
        atomic_text(args.json, json.dumps(res.as_dict(), indent=1, default=str))
    return 0


def _validate(args) -> int:
    from hil_harness.tuning.export import record_from as load_record
    from hil_harness.tuning.closed import validate_closed_loop
    rec = load_record(args.record)
    records = {rec.name: rec}
    for c in args.compare or []:
        r = load_record(c)
        if any(r == x for x in records.values()):
            continue                                  # the same record twice: report it once
        label = r.name if r.name not in records else f"{r.name} ({c})"
        records[label] = r
    rp = _replayer(args, rec)
    m = validate_closed_loop(rp, records, args.report,
                             title=args.title or f"Validation of record {rec.name} on "
                                                 f"{Path(args.set).name}")
    print(f"wrote {Path(args.report) / 'report.md'}")
    r = m[rec.name]["top1_closed_loop"]
    if args.require_top1 is not None and not r["rate"] >= args.require_top1:
        print(f"[tune] closed-loop top-1 {_rate_text(r)} is below the required "
              f"{args.require_top1}")
        return 1
    return 0
