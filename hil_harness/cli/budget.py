"""``uvisi budget [SCENARIO] [--sequence FILE] [--window N ...] [--compaction N]
[--hypothesis NAME] [--explain] [--plot PNG] [--sensitivity PNG] [--json OUT]``: the emulated 2 Hz
budget of a processing sequence on a scenario's first frame.

Prints, per window size, the emulated time per processor and the DSP data memory at the sequence's
compaction (today's event model, ``hil_harness.budget``); then, at compaction 1, the 64x64 window's
time per stage and processor under ``--hypothesis`` (default ``today``) with its share of 500 ms and
the margin, and the largest window each hypothesis for the paper's 64x64 limit allows
(``hil_harness.budget.hypotheses``). ``--explain`` adds what would make 64 the limit under each
hypothesis and every parameter's source. ``--plot`` draws that window's stages against the 500 ms
line; ``--sensitivity`` the largest window vs the code overhead factor and the DSP clock.
``--recording REC.h5`` re-prices a recorded event's frames under the hypotheses instead (the
opt-in: recordings keep today's model) and counts the frames that would overrun, k/n with a 95 %
interval."""
from __future__ import annotations

import json
from pathlib import Path



def register(sub) -> None:
    p = sub.add_parser("budget", description=__doc__,
                       help="emulated 2 Hz budget of a processing sequence by window size")
    p.add_argument("scenario", nargs="?", default="satellite_over_stars",
                   help="scenario whose first frame is processed (default: satellite_over_stars)")
    p.add_argument("--sequence", default=None,
                   help="processing sequence: shipped name or TOML file (default: the scenario's)")
    p.add_argument("--window", type=int, nargs="+", default=None,
                   help="window sides to evaluate (default 16..max in steps of 8)")
    p.add_argument("--compaction", type=int, choices=(1, 2, 4), default=None,
                   help="compaction factor (default: the sequence's)")
    p.add_argument("--hypothesis", default="today", metavar="NAME",
                   help="budget hypothesis of the per-stage table and --plot (default: today, the "
                        "model event recordings use; --explain lists them)")
    p.add_argument("--explain", action="store_true",
                   help="the hypotheses for the paper's 64x64 limit with their sources and what "
                        "would make 64 the limit")
    p.add_argument("--recording", default=None,
                   help="an event recording (recording.h5): re-price every frame's ledger under "
                        "each hypothesis and count the frames that would overrun (the recording "
                        "itself keeps today's model)")
    from hil_harness.cli.checks import add_ignore_checksums
    add_ignore_checksums(p)
    p.add_argument("--plot", default=None, help="bar chart PNG of the stages")
    p.add_argument("--sensitivity", default=None,
                   help="PNG: largest window vs code overhead factor and DSP clock")
    p.add_argument("--json", default=None, help="write the numbers as JSON")
    p.set_defaults(func=run, outputs={"json": "file", "plot": "file"})


def _sources(results) -> str:
    out = ["", "parameters and sources (fixed before evaluation):"]
    for r in results:
        h = r.hypothesis
        out.append(f"  {h.name}: {h.question}")
        for param, value, src in h.sources:
            out.append(f"      {param} = {value}  [{src}]")
    return "\n".join(out)


def _run_recording(args) -> int:
    from hil_harness.budget import hypotheses as bh
    from hil_harness.cli.checks import verify_recording
    names = [args.hypothesis] if args.hypothesis != "today" else [h.name for h in bh.HYPOTHESES]
    verify_recording(args.recording, args, "budget")
    how = "ignore" if args.ignore_checksums else "verify"
    rows = [bh.rescore_recording(args.recording, bh.hypothesis(n), how) for n in names]
    rec = rows[0]["overruns_recorded"]
    print(f"{args.recording}: {rows[0]['frames']} processed frames, "
          f"{'?' if rec is None else rec} overran as recorded (today's model)")
    print(f"{'hypothesis':<24} {'overruns':>9} {'95 % interval':>15} {'worst dsp ms':>13} "
          f"{'worst ip1750 ms':>16}")
    for r in rows:
        lo, hi = r["overrun_ci95"] or (0.0, 0.0)
        print(f"{r['hypothesis']:<24} {r['overruns']:>4}/{r['frames']:<4} "
              f"{100 * lo:6.1f}-{100 * hi:5.1f} % {r['worst_ms']['dsp']:13.2f} "
              f"{r['worst_ms']['ip1750']:16.2f}")
    if args.json:
        _write_json(args.json, {"recording": str(args.recording), "rescored": rows})
    return 0


def _write_json(path, d) -> None:
    tmp = Path(path + ".tmp")
    tmp.write_text(json.dumps(d, indent=2))
    tmp.replace(path)
    print(f"json: {path}")


def check_hypothesis(name) -> None:
    """``--hypothesis NAME`` (uvisi budget and uvisi event): ValueError listing the known names
    unless NAME is one (checked when the command runs, so building the parser loads no flight
    code)."""
    from hil_harness.budget.hypotheses import HYPOTHESES
    names = [h.name for h in HYPOTHESES]
    if name not in names:
        raise ValueError(f"--hypothesis {name!r}: not one of {', '.join(names)}")


def run(args) -> int:
    check_hypothesis(args.hypothesis)
    if args.recording:
        return _run_recording(args)
    from flightsw.budget import PACE1750A
    from flightsw.ip import load_default_sequence
    from flightsw.records import load_record
    from groundsim.scenario import Scenario
    from hil_harness.budget import budget_report
    from hil_harness.budget import hypotheses as bh
    from hil_harness.event.selection import record_name_for
    from hil_harness.sequences import resolve_sequence
    scn = Scenario.load(args.scenario)
    frame, truth = scn.world().render()
    tt = scn.target_type
    seq = resolve_sequence(args.sequence) if args.sequence else \
        load_default_sequence("aurora" if tt == "aurora" else "satellite")
    tg = truth["target"]
    centre = (tg["row"], tg["col"]) if tg.get("in_field") else None
    comp = args.compaction if args.compaction else (None if args.sequence else scn.compaction)
    record = load_record(record_name_for(tt))
    rep = budget_report(seq, frame, record, args.window, compaction=comp, centre=centre,
                        scene=f"{scn.name} frame 0")
    print(rep.table())
    scenes = bh.measure_scene(seq, frame, record, centre)
    results = [bh.evaluate(h, scenes) for h in bh.HYPOTHESES]
    edges = [bh.break_even(h, scenes) for h in bh.HYPOTHESES] if args.explain else None
    chosen = bh.hypothesis(args.hypothesis)
    ws = next(s for s in scenes if s.side == 64)
    print()
    print(bh.stage_table(chosen, ws))
    print()
    print(bh.explain_table(results, edges))
    if args.explain:
        print(_sources(results))
    if args.plot:
        from hil_harness.figures import budget_bars
        cost = bh.window_cost(chosen, ws)
        clock = {"dsp": chosen.dsp_clock_hz, "ip1750": PACE1750A.clock_hz}
        stage_ms = {f"{p}/{s}": 1e3 * c / clock[p] for p in clock for s, c in cost[p].items()}
        path = budget_bars(stage_ms, args.plot, title=f"{rep.sequence_name}: 64x64 window, "
                                                      f"hypothesis {chosen.name}")
        print(f"plot: {path}")
    if args.sensitivity:
        print(f"sensitivity: {bh.sensitivity_figure(args.sensitivity, seq)}")
    if args.json:
        d = rep.as_dict()
        d["hypotheses"] = [{"name": r.hypothesis.name, "resource": r.hypothesis.resource,
                            "largest_window": r.largest, "largest_side_exact": r.exact,
                            "reproduces_64": r.reproduces_64, "verdict": r.verdict,
                            "stops": r.stops} for r in results]
        _write_json(args.json, d)
    return 0
