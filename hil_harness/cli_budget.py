"""``uvisi budget [SCENARIO] [--sequence FILE] [--window N ...] [--compaction N] [--plot PNG]``:
the emulated 2 Hz budget of a processing sequence on a scenario's first frame: time per stage and
processor, DSP data memory, the margin against 500 ms, and the largest window that fits (time and
memory; see ``hil_harness.budget``). Prints a table; ``--plot`` draws the per-stage bars of the 64x64
(or first) window against the 500 ms line; ``--json`` writes the numbers."""
from __future__ import annotations

import json
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("budget", help="emulated 2 Hz budget of a processing sequence by window size",
                       description=__doc__)
    p.add_argument("scenario", nargs="?", default="satellite_over_stars",
                   help="scenario whose first frame is processed (default: satellite_over_stars)")
    p.add_argument("--sequence", default=None,
                   help="processing sequence: shipped name or TOML file (default: the scenario's)")
    p.add_argument("--window", type=int, nargs="+", default=None,
                   help="window sides to evaluate (default 16..max in steps of 8)")
    p.add_argument("--compaction", type=int, choices=(1, 2, 4), default=None,
                   help="compaction factor (default: the sequence's)")
    p.add_argument("--plot", default=None, help="bar chart PNG of the stages")
    p.add_argument("--json", default=None, help="write the numbers as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from flightsw.ip import load_default_sequence
    from flightsw.records import load_record
    from groundsim.scenario import Scenario
    from .budget import budget_report
    from .event import _shipped_sequence
    from .selection import record_name_for
    scn = Scenario.load(args.scenario)
    world = scn.world()
    frame, truth = world.render()
    tt = scn.target_type
    seq = _shipped_sequence(args.sequence) if args.sequence else \
        load_default_sequence("aurora" if tt == "aurora" else "satellite")
    tg = truth["target"]
    centre = (tg["row"], tg["col"]) if tg.get("in_field") else None
    comp = args.compaction if args.compaction else (None if args.sequence else scn.compaction)
    rep = budget_report(seq, frame, load_record(record_name_for(tt)), args.window,
                        compaction=comp, centre=centre, scene=f"{scn.name} frame 0")
    print(rep.table())
    if args.plot:
        from .figures import budget_bars
        row = rep.row(64) or rep.rows[0]
        path = budget_bars(row.stages_ms, args.plot,
                           title=f"{rep.sequence_name}: {row.shape[0]}x{row.shape[1]} window")
        print(f"plot: {path}")
    if args.json:
        tmp = Path(args.json + ".tmp")
        tmp.write_text(json.dumps(rep.as_dict(), indent=2))
        tmp.replace(args.json)
        print(f"json: {args.json}")
    return 0
