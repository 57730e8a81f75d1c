"""``uvisi rde``: the recursive distortion estimator (Arnold et al. 1982) on the ground.

``uvisi rde study [--out DIR] [--realisations N] [--quick] [--workers W]``
    the Monte Carlo study of section V: writes ``rde_figure2.png`` (epsilon_90 vs measurement error,
    five-scene interval), ``rde_figure3.png`` (control-point density needed for epsilon_90 < 4.9 m at
    6.7 m vs interval length) and ``rde_study.json`` to DIR, prints the numbers. The realisations
    run on W processes (default: one per core this process may run on), the same numbers on any W.

``uvisi rde study --sensitivity [--out DIR] [--realisations N] [--quick] [--workers W]``
    the same study with one input of the a priori error model scaled at a time (the calibrated
    random walks sigma1 and sigma_align_rate0, the a priori sigmas sigma_att0, sigma_align0,
    sigma_pos0; x0.25, 0.5, 1, 2, 4; 60 realisations by default): writes
    ``rde_sensitivity.csv``/``.md``/``.json`` and ``rde_sensitivity.png`` to DIR, prints the table
    (``groundsim.assess.rde_sensitivity``).

``uvisi rde reconstruct CONTROL_POINTS.npz|RECORDING.h5 [--out DIR] [--iterations K]
[--min-significance S] [--flight-centroids] [--keep-blends]``
    imager alignment + attitude-knowledge reconstruction from matched star control points (schema
    ``uvisi-rde-cp/1``, documented in ``groundsim.assess.rde_reconstruct``); prints the star
    residuals before/after, the consistency of the fit (normalised innovations, 2 per star
    expected), the correction and about which imager axes it was applied (only where at least S
    sigma from zero, default 3: roll about the boresight is often not), and, when the file carries
    ground truth, the RMS pointing-knowledge error before/after. A ``uvisi event`` recording is turned
    into control points first (its candidates matched to Hipparcos stars, blends left out and, when
    the recording holds the frames, the centroids re-measured on the full-resolution frames unless
    ``--flight-centroids``; ``groundsim.assess.recording_stars``); writes ``rde_reconstruct.json``
    (and the per-epoch correction, ``.npz``) to DIR.

``uvisi rde synth OUT.npz [--seed S] [--duration T]``
    writes a synthetic control-point file (star field, injected alignment + attitude-knowledge error,
    truth included) for trying ``reconstruct`` until event recordings exist.
"""
from __future__ import annotations

import json
import os

from hil_harness.cli.options import MAX_SEED, available_cores, number
from hil_harness.console import Heartbeat


def register(sub) -> None:
    p = sub.add_parser("rde", help="recursive distortion estimator: Landsat study, pointing reconstruction",
                       description=__doc__)
    rsub = p.add_subparsers(dest="rde_command", metavar="RDE_COMMAND")
    ps = rsub.add_parser("study", help="reproduce the paper's Figures 2 and 3")
    ps.set_defaults(outputs={"out": "folder"})
    ps.add_argument("-o", "--out", default=None,
                    help="output directory (default: ./rde_study; ./rde_sensitivity with --sensitivity)")
    ps.add_argument("--realisations", type=int, default=None,
                    help="Monte Carlo realisations per point (default 100; 60 with --sensitivity)")
    ps.add_argument("--quick", action="store_true", help="reduced grid (smoke runs, tests)")
    ps.add_argument("--sensitivity", action="store_true",
                    help="rerun the study with each error-model input scaled x0.25..x4, one at a time")
    ps.add_argument("--workers", type=int, default=None,
                    help="worker processes (default: one per core this process may run on; "
                    "1 = serial); the numbers do not depend on it")
    from hil_harness.cli.checks import add_no_size_check
    add_no_size_check(ps)
    pr = rsub.add_parser("reconstruct", help="pointing reconstruction from a control-point .npz")
    pr.add_argument("control_points", help="control-point file (.npz, schema uvisi-rde-cp/1) or an "
                    "event recording (.h5)")
    pr.set_defaults(outputs={"out": "folder"})
    pr.add_argument("-o", "--out", default=None, help="directory for rde_reconstruct.json/.npz")
    pr.add_argument("--iterations", type=number(1, integer=True), default=3, help="linearisation passes (default 3)")
    pr.add_argument("--min-significance", type=number(0), default=3.0,
                    help="apply the correction about an imager axis only if its mean is at least this "
                    "many sigma from zero (default 3; 0 applies it everywhere)")
    pr.add_argument("--flight-centroids", action="store_true",
                    help="recording: use the IP's centroids, not ones re-measured on the frames")
    pr.add_argument("--keep-blends", action="store_true",
                    help="recording: keep stars with a catalogue neighbour within 4 px")
    from hil_harness.cli.checks import add_ignore_checksums
    add_ignore_checksums(pr)
    pn = rsub.add_parser("synth", help="write a synthetic control-point file")
    pn.add_argument("output", help="output .npz")
    pn.add_argument("--seed", type=number(0, MAX_SEED, integer=True), default=0)
    pn.add_argument("--duration", type=number(0, lo_open=True), default=90.0, help="event length [s]")
    p.set_defaults(func=run, _rde_parser=p)


def _with_progress(base_map):
    """``base_map`` (a map-like callable) with a progress bar over its tasks (stderr, when progress
    is on: a terminal, or UVISI_PROGRESS=1)."""
    from hil_harness.console import progress_enabled

    def mapped(fn, tasks):
        tasks = list(tasks)
        if not progress_enabled():
            return _with_heartbeat(base_map(fn, tasks), len(tasks))
        from tqdm import tqdm
        return tqdm(base_map(fn, tasks), total=len(tasks), desc="rde study", unit="task",
                    leave=False)
    return mapped


def _pool(workers: int):
    """A process pool whose workers fork from this process where the system can (they inherit
    the kernels :func:`groundsim.assess.rde_study.load_kernels` loaded)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    ctx = (multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods()
           else None)
    return ProcessPoolExecutor(workers, mp_context=ctx)


def _check_study_args(args) -> None:
    if args.out is None:
        args.out = "rde_sensitivity" if args.sensitivity else "rde_study"
    if args.realisations is None:
        args.realisations = 60 if args.sensitivity else 100
    if args.realisations < 2:
        raise ValueError(f"--realisations {args.realisations}: must be at least 2")
    from hil_harness.sizes import MAX_RUNS, Cost, check
    # realisations are reduced to their mean chunk by chunk: nothing grows with their number
    check(Cost(f"rde study --realisations {args.realisations:,}", args.realisations,
               "realisations per grid point", 0.0, 0.0, MAX_RUNS), lift_cap=args.no_size_check)
    if args.workers is None:
        args.workers = available_cores()
    if args.workers < 1:
        raise ValueError(f"--workers {args.workers}: must be >= 1")
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        raise NotADirectoryError(f"{args.out}: --out exists and is not a directory")


def _sensitivity(args) -> int:
    """``rde study --sensitivity``: the error-model sensitivity table, figure and files."""
    from groundsim.assess.rde_sensitivity import markdown_table, run_sensitivity
    from hil_harness.console import progress_enabled
    kw = {}
    if args.quick:
        kw = dict(scales=(0.5, 1.0, 2.0), lengths=(5, 10),
                  densities=(1, 1.5, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64))
    bar = {}

    def progress(done, total):
        if not progress_enabled():
            if "beat" not in bar:
                bar["beat"] = Heartbeat(total, "uvisi rde: sensitivity", "models")
            bar["beat"].update(done - bar["beat"].n)
            return
        if "bar" not in bar:
            from tqdm import tqdm
            bar["bar"] = tqdm(total=total, desc="rde sensitivity", unit="model", leave=False)
        bar["bar"].update(done - bar["bar"].n)

    try:
        if args.workers > 1:
            with _pool(args.workers) as ex:
                res = run_sensitivity(args.out, realisations=args.realisations, map=ex.map,
                                      progress=progress, **kw)
        else:
            res = run_sensitivity(args.out, realisations=args.realisations, progress=progress, **kw)
    finally:
        if "bar" in bar:
            bar["bar"].close()
    print("RDE study vs its a priori error model (one input scaled at a time; sigma1 and "
          "sigma_align_rate0 are the calibrated random walks)")
    print(markdown_table(res), end="")
    print(f"wrote {os.path.join(args.out, 'rde_sensitivity.md')}, rde_sensitivity.csv, "
          "rde_sensitivity.json, rde_sensitivity.png")
    return 0


def _with_heartbeat(results, total: int):
    """``results`` passed through, a heartbeat line every few seconds (no terminal: no bar)."""
    beat = Heartbeat(total, "uvisi rde: study", "tasks")
    for r in results:
        beat.update(1)
        yield r
    beat.close()


def _study(args) -> int:
    from groundsim.assess.rde_study import CALIBRATION_NOTE, load_kernels, run_study
    _check_study_args(args)
    if args.workers > 1:
        load_kernels()          # once, here: the forked workers inherit them
    if args.sensitivity:
        return _sensitivity(args)
    if args.workers > 1:
        with _pool(args.workers) as ex:
            res = run_study(args.out, realisations=args.realisations, quick=args.quick,
                            map=_with_progress(ex.map))
    else:
        res = run_study(args.out, realisations=args.realisations, quick=args.quick,
                        map=_with_progress(map))
    f2, f3 = res["figure2"], res["figure3"]
    print(f"Figure 2: epsilon_90 [m], {f2['n_scenes'][0]:g}-scene interval, "
          f"{f2['realisations']} realisations")
    print("  sigma [m]      " + " ".join(f"{s:7.1f}" for s in f2["sigmas"]))
    for di, d in enumerate(f2["densities"]):
        for ei, ns in enumerate(f2["n_states"]):
            print(f"  {d:4g} CP/sc {ns:2d}s " + " ".join(f"{v:7.2f}" for v in f2["eps90_mean"][di, :, ei]))
    print("Figure 3: density needed for epsilon_90 < 4.9 m at 6.7 m [CP/scene] (paper: ~3 beyond 10 scenes)")
    for li, L in enumerate(f3["n_scenes"]):
        vals = "  ".join(f"{ns}s {f3['density_needed'][li, ei]:6.2f}" for ei, ns in enumerate(f3["n_states"]))
        print(f"  {L:5g} scenes  {vals}")
    print("  note: " + CALIBRATION_NOTE.replace("\n", " "))
    print(f"wrote {os.path.join(args.out, 'rde_figure2.png')}, rde_figure3.png, rde_study.json")
    return 0


def _reconstruct(args) -> int:
    import numpy as np
    from groundsim.assess.rde_reconstruct import load_control_points, reconstruct_from_npz
    if not os.path.exists(args.control_points):
        raise FileNotFoundError(f"no such control-point file: {args.control_points}")
    if args.control_points.endswith((".h5", ".hdf5")):
        from groundsim.assess.recording_stars import (BLEND_PX, control_points_from_recording,
                                                      recording_status)
        from hil_harness.cli.checks import verify_recording
        verify_recording(args.control_points, args, "rde reconstruct")
        complete, held, planned = recording_status(args.control_points)
        if not complete:
            print(f"{args.control_points}: incomplete recording (complete = False: the event was "
                  f"interrupted); using the {held} of {planned} frames it holds")
        cp = control_points_from_recording(args.control_points,
                                           refine=False if args.flight_centroids else None,
                                           blend_px=None if args.keep_blends else BLEND_PX)
    else:
        cp = load_control_points(args.control_points)
    res, rep = reconstruct_from_npz(cp, n_iter=args.iterations, min_significance=args.min_significance)
    extra = ""
    if "refined" in cp:
        extra = (f" ({int(np.sum(cp['refined']))} centroids re-measured on the frames, "
                 f"{int(cp.get('n_blends_dropped', 0))} blended stars left out)")
    print(f"control points {rep['n_cp']} over {rep['n_epochs']} epochs{extra}")
    print(f"RMS star residual: {rep['rms_star_residual_px_before']:.3f} px before, "
          f"{rep['rms_star_residual_px_after']:.3f} px after; {rep['n_rejected']} gated out")
    nis = f"normalised innovations {rep['nis_per_star']:.2f} per star (2 expected"
    if "nis_per_star_frame" in rep:
        nis += f"; {rep['nis_per_star_frame']:.2f} with single-frame centroid sigmas"
    print(nis + ")")
    print("estimated correction (imager x = boresight roll, y, z) [urad]: "
          + ", ".join(f"{v:.1f} +- {s:.1f}" for v, s in zip(rep["theta_estimated_mean_urad"],
                                                              rep["theta_sigma_median_urad"]))
          + "; applied about " + (", ".join(a for a, ok in zip("xyz", rep["theta_applied"]) if ok)
                                  or "no axis")
          + f" (>= {args.min_significance:g} sigma)")
    if "improvement_factor" in rep:
        print(f"RMS pointing-knowledge error vs truth: {rep['rms_pointing_error_urad_before']:.1f} urad "
              f"before, {rep['rms_pointing_error_urad_after']:.1f} urad after "
              f"(x{rep['improvement_factor']:.1f}); boresight LOS {rep['rms_los_error_urad_before']:.1f}"
              f" -> {rep['rms_los_error_urad_after']:.1f} urad (x{rep['los_improvement_factor']:.1f})")
    if "target_los_eci" in rep:
        print(f"corrected target LOS for {len(rep['target_los_eci'])} target centroids (in the report)")
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "rde_reconstruct.json"), "w") as fh:
            json.dump(rep, fh, indent=1)
        np.savez(os.path.join(args.out, "rde_reconstruct.npz"), t=res.t, x=res.x, theta=res.theta,
                 theta_sigma=res.theta_sigma, C_ii_est=res.C_ii_est)
        print(f"wrote {os.path.join(args.out, 'rde_reconstruct.json')} and rde_reconstruct.npz")
    return 0


def _synth(args) -> int:
    from groundsim.assess.rde_reconstruct import save_control_points, synthetic_control_points
    cp = synthetic_control_points(args.seed, duration=args.duration)
    save_control_points(args.output, cp)
    print(f"wrote {args.output}: {cp['t'].size} control points over {cp['frame_t'].size} frames")
    return 0


def run(args) -> int:
    cmd = getattr(args, "rde_command", None)
    if cmd == "study":
        return _study(args)
    if cmd == "reconstruct":
        return _reconstruct(args)
    if cmd == "synth":
        return _synth(args)
    args._rde_parser.print_help()
    return 0
