"""``uvisi event SCENARIO [--seed N] [--frames N] [--out DIR [--force]] [--no-frames]``: run one
closed-loop tracking event.

The ground simulator renders each 2 Hz frame of the scenario; the flight image processor turns it into
a candidate message, the track processor into a pointing command, which the spacecraft follows. Writes
``recording.h5``, the figures (processing stages, centroid track, track error, gates, budget, an animated
GIF) and ``summary.json`` to DIR, and prints a short table. SCENARIO is a shipped name (``uvisi
scenarios`` lists them) or a TOML file. The flight code is the paper's system; ``--with`` switches on
candidate changes (``uvisi proposals`` lists them). The files a scenario's ``[[uplinks]]`` name are
read inside the scenario file's folder (or ``--uplink-dir DIR``): the uplink path rule.

The recording is written in blocks of 20 frames as ``recording.partial.h5`` and renamed
``recording.h5`` at the end; an interrupted event (Ctrl-C, SIGTERM, kill -9) leaves the partial file
readable up to its last block. A DIR given with ``--out`` that holds another run is refused unless
``--force``; the default folder ``./events/<scenario>`` is simply replaced. One event at a time
writes to a folder.
"""
from __future__ import annotations

import json
import signal
import sys
import threading
from pathlib import Path

from hil_harness.cli.options import add_with_option
from hil_harness.console import progress_enabled


def register(sub) -> None:
    p = sub.add_parser("event", help="run a closed-loop tracking event on a scenario",
                       description=__doc__)
    p.add_argument("scenario", nargs="?", default="satellite_over_stars",
                   help="shipped scenario name or TOML file (default: satellite_over_stars)")
    p.add_argument("--seed", type=int, default=None, help="seed (default: the scenario's)")
    p.add_argument("--frames", type=int, default=None, help="stop after N frames")
    p.add_argument("-o", "--out", default=None,
                   help="output directory (default: ./events/<scenario>, replaced on each run)")
    p.add_argument("--force", action="store_true",
                   help="replace another run found in --out (removed first)")
    p.add_argument("--no-frames", action="store_true",
                   help="do not store the frames in the recording (smaller; no replay)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    p.add_argument("--sequence", default=None, help="processing sequence: shipped name or TOML file")
    p.add_argument("--record", default=None, help="a priori record: shipped name or TOML file")
    p.add_argument("--handover", action="store_true",
                   help="enable the wide -> narrow FOV hand-over once locked")
    p.add_argument("--hypothesis", default=None, metavar="NAME",
                   help="price every frame under a budget hypothesis (uvisi budget --explain lists "
                        "them), overruns included; default: today's cycle model")
    p.add_argument("--uplink-dir", default=None, metavar="DIR",
                   help="read the scenario's [[uplinks]] files inside DIR instead of the scenario "
                        "file's folder (the uplink path rule, docs/formats.md)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON instead of a table")
    add_with_option(p)
    from hil_harness.cli.checks import add_no_size_check
    add_no_size_check(p)
    p.set_defaults(func=run, outputs={"out": "folder"})


_TERMINATED = []


def check_event_size(name: str, args, out: Path) -> None:
    """Before anything runs: ``--frames`` no longer than the scenario, and the event's frames,
    recording and figures within the caps and the free memory and disk (:mod:`hil_harness.sizes`;
    one line, exit 2)."""
    from groundsim.scenario import Scenario
    from hil_harness.sizes import check, event_cost
    scn = Scenario.load(name, seed=args.seed,
                        uplink_dir=getattr(args, "uplink_dir", None))
    n = scn.n_frames
    if args.frames is not None and args.frames > n:
        raise ValueError(f"--frames {args.frames:,}: scenario {scn.name} has {n:,} frames "
                         f"({scn.duration:g} s at 2 Hz); give at most {n:,}")
    n = n if args.frames is None else args.frames
    what = f"scenario {scn.name}" + ("" if name == scn.name else f" ({name})") + \
        ("" if args.frames is not None else f", duration = {scn.duration:g} s at 2 Hz")
    check(event_cost(what, n, out, not args.no_frames, not args.no_figures),
          lift_cap=bool(getattr(args, "no_size_check", False)))


def _terminate(signum, frame):
    """SIGTERM ends the event as Ctrl-C does (what was recorded is kept)."""
    _TERMINATED.append(signum)
    raise KeyboardInterrupt


def run(args) -> int:
    from groundsim.scenario import MAX_SEED, Scenario
    from hil_harness.event.io import (EventInterrupted, FiguresInterrupted, run_event,
                                      summary_table)
    from hil_harness.event.selection import SelectionParams
    name = args.scenario
    if name not in Scenario.shipped() and not Path(name).exists():
        raise ValueError(f"scenario {name!r}: not a shipped scenario nor a file"
                         f"{Scenario.nearest(name)} (uvisi scenarios lists them)")
    if args.frames is not None and args.frames < 1:
        raise ValueError(f"--frames {args.frames}: must be >= 1")
    if args.seed is not None and not 0 <= args.seed <= MAX_SEED:
        raise ValueError(f"--seed {args.seed}: must be in 0..{MAX_SEED}")
    if args.hypothesis is not None:
        from hil_harness.cli.budget import check_hypothesis
        check_hypothesis(args.hypothesis)
    out = Path(args.out) if args.out else Path("events") / Path(name).stem
    scenario = name
    if args.uplink_dir is not None:
        if not Path(args.uplink_dir).is_dir():
            raise ValueError(f"--uplink-dir {args.uplink_dir}: not a folder")
        scenario = Scenario.load(name, seed=args.seed, uplink_dir=args.uplink_dir)
    check_event_size(name, args, out)
    record = args.record
    if record is not None and Path(record).is_file() and Path(record).suffix.lower() != ".toml":
        from hil_harness.tuning.export import record_from
        record = record_from(record)                   # an uplink image (words file)
    replace = bool(getattr(args, "force", False)) or not args.out
    _TERMINATED.clear()
    main_thread = threading.current_thread() is threading.main_thread()
    prev = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    try:
        s = run_event(scenario, seed=args.seed, frames=args.frames, out=out,
                      record_frames=not args.no_frames, figures=not args.no_figures,
                      progress=progress_enabled(), sequence=args.sequence, record=record,
                      selection=SelectionParams(handover=args.handover), force=replace,
                      hypothesis=args.hypothesis, proposals=args.with_,
                      proposals_where="--with")
    except FiguresInterrupted as exc:
        print(f"uvisi event: interrupted while writing the figures: the recording and summary.json "
              f"in {exc.out} are complete; the figures are missing (uvisi view "
              f"{exc.out}/recording.h5 writes the viewer page)", file=sys.stderr)
        return 130
    except EventInterrupted as exc:
        how = "terminated (SIGTERM)" if _TERMINATED else "interrupted"
        print(f"uvisi event: {how}: partial recording kept: {exc.recording} ({exc.frames} frames, "
              f"complete = False)", file=sys.stderr)
        return 143 if _TERMINATED else 130
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, prev)
    if args.json:
        print(json.dumps(s, indent=2, default=str))
    else:
        print(summary_table(s))
        print(f"recording: {s['recording']}")
        print(f"summary:   {out / 'summary.json'}")
        if s.get("figures"):
            print("figures:   " + ", ".join(s["figures"]))
    return 0
