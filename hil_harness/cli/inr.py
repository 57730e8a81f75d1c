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
import sys

from hil_harness.cli.options import MAX_SEED, number


def _report_options(p) -> None:
    """The assessment options every ``inr`` subcommand takes (defaults: ``REPORT_DEFAULTS``)."""
    p.add_argument("--theta-nav", default=None, metavar="URAD",
                   help="NAV threshold theta in urad (default 65)")
    p.add_argument("--theta-ffr", action="append", default=None, metavar="SPACING:URAD",
                   help="FFR threshold per frame spacing, e.g. 900:36 (repeatable), or one value for "
                        "every spacing (default 900:36, 5400:49, others 36)")
    p.add_argument("--veto-sigma", default=None,
                   help="Kalman veto n-sigma (a positive number), or 'none' (default none)")
    p.add_argument("--reference", default=None, help="reference imager for coregistration")
    p.add_argument("--moment", choices=("sample", "core"), default="sample",
                   help="inconsistency second moment M: the paper's sample moment or the robust core")
    p.add_argument("--coreg-period", default=None, metavar="S",
                   help="harmonic period of the EW coregistration model in seconds (default 86400)")


def register(sub) -> None:
    p = sub.add_parser("inr", help="3-sigma INR verification with platinum landmarks (reports)",
                       description="3-sigma INR verification with platinum landmarks (Carr & Madani). "
                                   "Every report starts from the same settings and prints them; the "
                                   "exit status is 1 when a verdict fails.")
    isub = p.add_subparsers(dest="inr_command", metavar="INR_COMMAND")
    pr = isub.add_parser("report", help="assess a landmark-measurement CSV")
    pr.add_argument("csv", help="landmark CSV (schema uvisi-inr-landmarks/1)")
    pr.set_defaults(outputs={"out": "folder"})
    pr.add_argument("-o", "--out", default="inr_report",
                    help="output directory (default ./inr_report)")
    _report_options(pr)
    pe = isub.add_parser("event", help="assess the star landmarks of an event recording")
    pe.add_argument("recording", help="recording.h5 written by uvisi event")
    pe.set_defaults(outputs={"out": "folder"})
    pe.add_argument("-o", "--out", default="inr_event",
                    help="output directory (default ./inr_event)")
    pe.add_argument("--imager", default=None, help="imager id (default: the most used one)")
    pe.add_argument("--gate", type=number(0, lo_open=True), default=3.0, help="star association gate [px] (default 3)")
    pe.add_argument("--csv", action="store_true", help="also write the landmark table as CSV")
    from hil_harness.cli.checks import add_ignore_checksums
    add_ignore_checksums(pe)
    _report_options(pe)
    ps = isub.add_parser("synthetic", help="the paper-scale synthetic population, reported")
    ps.set_defaults(outputs={"out": "folder"})
    ps.add_argument("-o", "--out", default="inr_synthetic",
                    help="output directory (default ./inr_synthetic)")
    ps.add_argument("--seed", type=number(0, MAX_SEED, integer=True), default=0)
    ps.add_argument("--excursion", type=number(), default=0.0,
                    help="inject a real system excursion of this many urad (EW) for one hour")
    ps.add_argument("--outliers", type=int, default=6, metavar="N",
                    help="invalid (type-II) absolute measurements injected into the population "
                         "(default 6: the paper's GOES-13 case; its '5 of 1781' follows from this input)")
    ps.add_argument("--csv", action="store_true", help="also write the synthetic table as CSV")
    _report_options(ps)
    p.set_defaults(func=run, _inr_parser=p)


def _positive(option, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{option} {value!r}: expected a number") from None
    if not (x > 0 and x < float("inf")):
        raise ValueError(f"{option} {value!r}: must be a positive number")
    return x


def _theta_ffr(values):
    if not values:
        return None
    if len(values) == 1 and ":" not in values[0]:
        return _positive("--theta-ffr", values[0])
    out = {}
    for v in values:
        if ":" not in v:
            raise ValueError(f"--theta-ffr {v!r}: expected SPACING_S:THETA_URAD (e.g. 900:36)")
        sp, th = v.split(":", 1)
        out[_positive("--theta-ffr spacing", sp)] = _positive("--theta-ffr threshold", th)
    return out


def config_from_args(args, synthetic: bool = False):
    """The :class:`groundsim.assess.inr.InrConfig` for these options: ``REPORT_DEFAULTS`` (with the
    synthetic population's spacings for ``synthetic``) and each option given on top."""
    from groundsim.assess.inr import report_config, synthetic_config
    kw = {"inconsistency_moment": args.moment}
    if args.theta_nav is not None:
        kw["theta_nav_urad"] = _positive("--theta-nav", args.theta_nav)
    th = _theta_ffr(args.theta_ffr)
    if th is not None:
        kw["theta_ffr_urad"] = th
        if isinstance(th, dict):
            kw["ffr_spacings_s"] = tuple(sorted(th))
    if args.veto_sigma is not None:
        kw["kf_veto_sigma"] = None if str(args.veto_sigma).lower() == "none" else \
            _positive("--veto-sigma", args.veto_sigma)
    if args.reference:
        kw["reference_imager"] = args.reference
    if args.coreg_period is not None:
        kw["coreg_period_s"] = _positive("--coreg-period", args.coreg_period)
    return synthetic_config(**kw) if synthetic else report_config(**kw)


def failed_verdicts(a) -> int:
    """How many (set, scope) verdicts of an assessment fail."""
    blocks = [a.compliance["nav"]] + list(a.compliance["ffr"].values())
    return sum(1 for block in blocks for sname in ("valid", "gold", "platinum")
               for x in block[sname].values() if x["n"] and not x["meets"])


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


def _report(args, table=None, title=None, cfg=None) -> int:
    from groundsim.assess.inr import assess, describe_config, read_csv
    from groundsim.assess.inr_report import write_report
    cfg = cfg or config_from_args(args)
    if table is None:
        if not os.path.exists(args.csv):             # a folder: read_csv names it
            raise ValueError(f"{args.csv}: no such file")
        table = read_csv(args.csv)
        usable_rows(table, args.csv)
    a = assess(table, cfg)
    paths = write_report(a, args.out, title=title or
                         f"INR 3-sigma assessment of {os.path.basename(args.csv)}")
    print(f"settings: {describe_config(cfg)}")
    _print(a, paths)
    bad = failed_verdicts(a)
    if bad:
        print(f"{bad} verdict(s) FAIL", file=sys.stderr)
        return 1
    return 0


def usable_rows(table, path) -> int:
    """The rows with an absolute measurement (both ``ew_err_urad`` and ``ns_err_urad``); the rows
    with only one of the two are said (they are not used as absolute measurements); none at all
    is an error naming the file (a report of nothing would read as "meets")."""
    import numpy as np
    fin = np.isfinite(table.abs_err)
    both, one = int(np.sum(fin.all(axis=1))), int(np.sum(fin.any(axis=1) & ~fin.all(axis=1)))
    if both == 0:
        raise ValueError(f"{path}: no row has both ew_err_urad and ns_err_urad: nothing to assess")
    if one:
        print(f"uvisi inr: note: {path}: {one} of {len(table)} rows have only one of ew_err_urad / "
              f"ns_err_urad: not used as absolute measurements", file=sys.stderr)
    return both


def _synthetic(args) -> int:
    from groundsim.assess.inr import synthetic_population, write_csv
    if args.outliers < 0:
        raise ValueError(f"--outliers {args.outliers}: must be >= 0")
    cfg = config_from_args(args, synthetic=True)
    try:
        table, _ = synthetic_population(seed=args.seed, excursion_urad=args.excursion,
                                        n_invalid_abs=args.outliers)
    except ValueError as exc:
        if "n_invalid_abs" not in str(exc):
            raise
        raise ValueError(f"--outliers {args.outliers}: {str(exc).split(': ', 1)[1]}") from None
    if args.csv:
        os.makedirs(args.out, exist_ok=True)
        print(f"wrote {write_csv(table, os.path.join(args.out, 'inr_synthetic.csv'))}")
    print(f"synthetic population: {args.outliers} invalid absolute measurements injected (an input, "
          f"not a result)")
    return _report(args, table, "INR 3-sigma assessment: paper-scale synthetic population", cfg)


def _event(args) -> int:
    from groundsim.assess.inr import write_csv
    from groundsim.assess.recording_stars import inr_table_from_recording, recording_status
    from hil_harness.cli.checks import verify_recording
    cfg = config_from_args(args)
    verify_recording(args.recording, args, "inr event")
    complete, held, planned = recording_status(args.recording)
    table = inr_table_from_recording(args.recording, args.imager, args.gate)
    if not complete:
        print(f"{args.recording}: incomplete recording (complete = False: the event was "
              f"interrupted); assessing the {held} of {planned} frames it holds")
    print(f"{args.recording}: {len(table.time)} star landmark measurements")
    if args.csv:
        os.makedirs(args.out, exist_ok=True)
        print(f"wrote {write_csv(table, os.path.join(args.out, 'inr_event.csv'))}")
    rc = _report(args, table, f"INR 3-sigma assessment of {os.path.basename(args.recording)}", cfg)
    if rc:
        print(resolution_note(table, cfg), file=sys.stderr)
    return rc


def resolution_note(table, cfg) -> str:
    """Why star landmarks from an event fail the verdicts: their 99.7th-percentile errors against
    the imager pixel and the IP's processed pixel, beside the NAV threshold."""
    import numpy as np
    res = getattr(table, "resolution", None) or {}
    px = res.get("pixel_urad", [float("nan")] * 2)
    comp = res.get("compaction", 1)
    err = np.abs(table.abs_err[np.all(np.isfinite(table.abs_err), axis=1)])
    p_ns, p_ew = (float(np.percentile(err[:, i], 99.7)) if len(err) else float("nan")
                  for i in (1, 0))
    return (f"uvisi inr: why: these landmarks are the flight IP's star centroids, quantised to "
            f"processed pixels of {comp} x {px[1]:.0f} urad (EW) by {comp} x {px[0]:.0f} urad (NS); "
            f"their 99.7th-percentile errors are {p_ew:.0f} urad EW, {p_ns:.0f} urad NS, against a "
            f"NAV threshold of {cfg.theta_nav_urad:.0f} urad made for sub-pixel landmark "
            f"measurements: the verdicts measure the centroids' resolution, not the pointing")


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
