"""``uvisi replay RECORDING``: re-run the flight code (IP + TP) on a recording's frames and attitude data
and report any difference from the recorded candidate messages and track commands (bit-identical
expected). Exit status 1 when they differ."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("replay", help="re-run the flight code on a recording and compare",
                       description=__doc__)
    p.add_argument("recording", help="recording.h5 written by uvisi event")
    p.set_defaults(func=run)


def run(args) -> int:
    from .event_io import replay
    r = replay(args.recording)
    if r["identical"]:
        print(f"{r['recording']}: {r['frames']} frames, {r['compared']} messages re-computed, all "
              f"bit-identical")
        return 0
    print(f"{r['recording']}: {len(r['mismatches'])} of {r['compared']} messages differ")
    for m in r["mismatches"][:20]:
        print(f"  frame {m['k']}: {m['what']} differs from word {m['first_word']}")
    return 1
