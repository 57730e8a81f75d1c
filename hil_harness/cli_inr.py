"""``uvisi inr``: 3-sigma INR verification with platinum measurements (Carr & Madani; issue 11).

``uvisi inr report CSV [--out DIR] [--theta-nav U] [--theta-ffr SPACING:U ...] [--veto-sigma N|none]
[--reference IMAGER] [--moment sample|core] [--coreg-period S]``
    assess a landmark CSV (schema ``uvisi-inr-landmarks/1``, documented in
    ``groundsim.assess.inr_table``): writes ``inr_report.md``, the PNG figures and ``summary.json``.

``uvisi inr event RECORDING.h5 [--out DIR] [--imager ID] [--gate PX] [--csv] [report options]``
    the landmark measurements of a ``uvisi event`` recording: the candidates the flight IP reported,
    matched to Hipparcos stars predicted from the attitude data (NAV), with frame-to-frame
    correlation of star chips when the recording holds the frames (FFR); assessed and reported
    like ``report`` (``groundsim.assess.recording_stars``).

``uvisi inr synthetic [--out DIR] [--seed S] [--excursion U] [--csv]``
    the paper-scale synthetic population (1781 valid VIS landmarks with a few type-II invalid ones,
    a simultaneous IR channel) assessed and reported the same way; ``--csv`` also writes the table.
"""
from __future__ import annotations

import os


def register(sub) -> None:
    p = sub.add_parser("inr", help="3-sigma INR verification with platinum landmarks (reports)",
                       description=__doc__)
    isub = p.add_subparsers(dest="inr_command", metavar="INR_COMMAND")
    pr = isub.add_parser("report", help="assess a landmark-measurement CSV")
    pr.add_argument("csv", help="landmark CSV (schema uvisi-inr-landmarks/1)")
    pr.add_argument("--out", default="inr_report", help="output directory (default ./inr_report)")
    pr.add_argument("--theta-nav", type=float, default=None, help="NAV threshold theta [urad] (default 65)")
    pr.add_argument("--theta-ffr", action="append", default=None, metavar="SPACING:UR",
                    help="FFR threshold per frame spacing, e.g. 900:36 (repeatable) or one value for all")
    pr.add_argument("--veto-sigma", default=None, help="Kalman veto n-sigma, or 'none' (default 4)")
    pr.add_argument("--reference", default=None, help="reference imager for coregistration")
    pr.add_argument("--moment", choices=("sample", "core"), default="sample",
                    help="inconsistency second moment M: the paper's sample moment or the robust core")
    pr.add_argument("--coreg-period", type=float, default=None, help="harmonic period of the EW "
                    "coregistration model [s] (default 86400)")
    pe = isub.add_parser("event", help="assess the star landmarks of an event recording")
    pe.add_argument("recording", help="recording.h5 written by uvisi event")
    pe.add_argument("--out", default="inr_event", help="output directory (default ./inr_event)")
    pe.add_argument("--imager", default=None, help="imager id (default: the most used one)")
    pe.add_argument("--gate", type=float, default=3.0, help="star association gate [px] (default 3)")
    pe.add_argument("--csv", action="store_true", help="also write the landmark table as CSV")
    for a in ("--theta-nav", "--coreg-period"):
        pe.add_argument(a, type=float, default=None)
    pe.add_argument("--theta-ffr", action="append", default=None, metavar="SPACING:UR")
    pe.add_argument("--veto-sigma", default=None)
    pe.add_argument("--reference", default=None)
    pe.add_argument("--moment", choices=("sample", "core"), default="sample")
    ps = isub.add_parser("synthetic", help="the paper-scale synthetic population, reported")
    ps.add_argument("--out", default="inr_synthetic", help="output directory (default ./inr_synthetic)")
    ps.add_argument("--seed", type=int, default=0)
    ps.add_argument("--excursion", type=float, default=0.0,
                    help="inject a real system excursion of this many urad (EW) for one hour")
    ps.add_argument("--csv", action="store_true", help="also write the synthetic table as CSV")
    p.set_defaults(func=run, _inr_parser=p)


def _theta_ffr(values):
    if not values:
        return None
    if len(values) == 1 and ":" not in values[0]:
        return float(values[0])
    out = {}
    for v in values:
        if ":" not in v:
            raise ValueError(f"--theta-ffr {v!r}: expected SPACING_S:THETA_URAD")
        s, th = v.split(":", 1)
        out[float(s)] = float(th)
    return out


def _print(a, paths) -> None:
    c = a.summary["counts"]
    print(f"{c['rows']} rows: {c['qm_valid']} QM-valid, {c['gold']} gold, {c['vetoed']} vetoed, "
          f"{c['inconsistency_pairs']} inconsistency pairs, {c['platinum']} platinum, "
          f"{c['tarnished']} tarnished")
    for im, d in a.summary["inconsistency"].items():
        print(f"  {im}: {100 * d['fraction_inside']:.1f} % inside the 2-sigma ellipse "
              f"(2-D normal {100 * d['expected_fraction_inside']:.1f} %)")
    blocks = [("NAV", a.compliance["nav"])] + [(f"FFR {k}", v) for k, v in a.compliance["ffr"].items()]
    for name, block in blocks:
        for sname in ("valid", "gold", "platinum"):
            for scope, x in block[sname].items():
                if x["n"]:
                    print(f"  {name:9s} {sname:8s} {scope:5s} {x['n_noncompliant']:4d} of {x['n']:5d} "
                          f"noncompliant, {x['compliance_pct']:.3f} % ({'meets' if x['meets'] else 'FAILS'};"
                          f" 99.7th pct {x['p997']['value']:.1f} urad, theta {x['theta_urad']:g})")
    print(f"wrote {paths['report']}, {paths['summary']} and {len(paths) - 2} figures")


def _report(args, table=None, title=None) -> int:
    from groundsim.assess.inr import InrConfig, assess, read_csv
    from groundsim.assess.inr_report import write_report
    if table is None:
        table = read_csv(args.csv)
    kw = {"inconsistency_moment": args.moment}
    if args.theta_nav is not None:
        kw["theta_nav_urad"] = args.theta_nav
    th = _theta_ffr(args.theta_ffr)
    if th is not None:
        kw["theta_ffr_urad"] = th
        if isinstance(th, dict):
            kw["ffr_spacings_s"] = tuple(sorted(th))
    if args.veto_sigma is not None:
        kw["kf_veto_sigma"] = None if args.veto_sigma.lower() == "none" else float(args.veto_sigma)
    if args.reference:
        kw["reference_imager"] = args.reference
    if args.coreg_period:
        kw["coreg_period_s"] = args.coreg_period
    a = assess(table, InrConfig(**kw))
    paths = write_report(a, args.out, title=title or
                         f"INR 3-sigma assessment of {os.path.basename(args.csv)}")
    _print(a, paths)
    return 0


def _synthetic(args) -> int:
    from groundsim.assess.inr import assess, synthetic_config, synthetic_population, write_csv
    from groundsim.assess.inr_report import write_report
    table, _ = synthetic_population(seed=args.seed, excursion_urad=args.excursion)
    a = assess(table, synthetic_config())
    paths = write_report(a, args.out, title="INR 3-sigma assessment: paper-scale synthetic population")
    if args.csv:
        print(f"wrote {write_csv(table, os.path.join(args.out, 'inr_synthetic.csv'))}")
    _print(a, paths)
    return 0


def _event(args) -> int:
    from groundsim.assess.inr import write_csv
    from groundsim.assess.recording_stars import inr_table_from_recording, recording_status
    complete, held, planned = recording_status(args.recording)
    table = inr_table_from_recording(args.recording, args.imager, args.gate)
    if not complete:
        print(f"{args.recording}: incomplete recording (complete = False: the event was "
              f"interrupted); assessing the {held} of {planned} frames it holds")
    print(f"{args.recording}: {len(table.time)} star landmark measurements")
    if args.csv:
        os.makedirs(args.out, exist_ok=True)
        print(f"wrote {write_csv(table, os.path.join(args.out, 'inr_event.csv'))}")
    return _report(args, table, f"INR 3-sigma assessment of {os.path.basename(args.recording)}")


def run(args) -> int:
    cmd = getattr(args, "inr_command", None)
    if cmd == "report":
        return _report(args)
    if cmd == "event":
        return _event(args)
    if cmd == "synthetic":
        return _synthetic(args)
    args._inr_parser.print_help()
    return 0
