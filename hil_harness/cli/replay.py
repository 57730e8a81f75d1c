"""``uvisi replay RECORDING``: verify a recording's checksums, then re-run the flight code (IP + TP) on
its frames and attitude data and report any difference from the recorded candidate messages and track
commands (bit-identical expected). Exit status 1 when they differ, 2 when the recording is damaged
(one line naming the dataset and frame). A partial recording (``recording.partial.h5``, left by an
interrupted event) is replayed over the frames it holds, and said to be incomplete.

The proposals, record and sequence come from the recording (``--with`` is refused: a replay
re-runs what was recorded). A recording made before proposals existed ran today's configuration
at that time: it is replayed with all eight proposals, and the report says so in one line."""
from __future__ import annotations

import argparse


def register(sub) -> None:
    p = sub.add_parser("replay", help="re-run the flight code on a recording and compare",
                       description=__doc__)
    p.add_argument("recording", help="recording.h5 written by uvisi event")
    p.add_argument("--with", dest="with_", default=None, help=argparse.SUPPRESS)
    p.set_defaults(func=run)


def run(args) -> int:
    from hil_harness.event.io import replay
    if args.with_ is not None:
        raise ValueError("--with: replay takes the proposals from the recording "
                         "(config.flight.with); run `uvisi event --with ...` for another set")
    r = replay(args.recording)
    if r.get("predates_proposals"):
        print(f"{r['recording']}: made before proposals existed: replayed with today's "
              f"configuration (all eight proposals)")
    head = f"{r['recording']}: {r['verified']} frames verified (checksums)"
    if not r["checksums"]:
        head = f"{r['recording']}: recorded without checksums, not verified"
    if not r["complete"]:
        head = (f"{r['recording']}: incomplete recording (complete = False: the event was "
                f"interrupted), holds {r['frames']} of {r['planned']} frames; {r['verified']} frames "
                f"verified (checksums)")
    if r["identical"]:
        print(f"{head}, {r['compared']} messages re-computed, all bit-identical")
        return 0
    print(f"{head}; {len(r['mismatches'])} of {r['compared']} messages differ")
    for m in r["mismatches"][:20]:
        print(f"  frame {m['k']}: {m['what']} differs from word {m['first_word']}")
    return 1
