"""``uvisi replay RECORDING``: verify a recording's checksums, then re-run the flight code (IP + TP) on
its frames and attitude data and report any difference from the recorded candidate messages and track
commands (bit-identical expected). Exit status 1 when they differ, 2 when the recording is damaged
(one line naming the dataset and rows; ``--ignore-checksums`` replays it as stored and says what it
ignored). A partial recording (``recording.partial.h5``, left by an interrupted event) is replayed
over the frames it holds, and said to be incomplete.

The proposals, record and sequence come from the recording (``--with`` is refused: a replay
re-runs what was recorded). A recording made before proposals existed ran today's configuration
at that time: it is replayed with all eight proposals, and the report says so in one line.

``uvisi replay --clear-flags RECORDING``: clear the open-for-write flags a killed ``uvisi event``
leaves in its ``recording.partial.h5`` (as ``h5clear -s`` does), so that HDF5 tools older than 2.0
(``h5dump`` 1.10, h5py on HDF5 1.14) open it; nothing else in the file changes and nothing is
replayed. Refused while a ``uvisi event`` still writes to the folder.

The root attributes that describe the run (scenario, seed, config, summary, ``complete``, ...) are
sealed by a digest (``attrs_sha256``); a file of the current format whose attributes changed, or
that lacks the digest or its checksums, is refused. A recording of an older format is replayed with
a one-line "not verified", and its verdict fails unless ``--accept-unverified``."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def register(sub) -> None:
    from hil_harness.cli.checks import add_ignore_checksums
    p = sub.add_parser("replay", help="re-run the flight code on a recording and compare",
                       description=__doc__)
    p.add_argument("recording", help="recording.h5 written by uvisi event")
    p.add_argument("--with", dest="with_", default=None, help=argparse.SUPPRESS)
    p.add_argument("--clear-flags", action="store_true",
                   help="only clear the open-for-write flags a killed event left in the file "
                        "(for HDF5 tools before 2.0), then stop")
    add_ignore_checksums(p)
    p.add_argument("--accept-unverified", action="store_true",
                   help="a recording of an older format (not sealed, or without checksums) is "
                        "replayed and passes when bit-identical (default: a failed verdict, exit 1)")
    p.set_defaults(func=run)


def _clear_flags(path: Path) -> int:
    from groundsim.assess.h5open import clear_write_flags
    from hil_harness.event.run_folder import writer_pid
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such recording")
    pid = writer_pid(path.parent)
    if pid is not None:
        raise ValueError(f"{path}: a uvisi event (pid {pid}) still writes to {path.parent}; "
                         f"clear the flags once it has ended")
    flags = clear_write_flags(path)
    if flags:
        print(f"{path}: open-for-write flags cleared (were 0x{flags:02x}); HDF5 1.10+ tools "
              f"open it")
    else:
        print(f"{path}: no open-for-write flags set; nothing to clear")
    return 0


def _flags_tail(r: dict) -> str:
    """The end of a partial recording's line: how to clear the flags a killed writer left."""
    from groundsim.assess.h5open import write_flags
    if r["complete"] or not write_flags(r["recording"]):
        return ""
    return (f"; still flagged open-for-write (the writer was killed): HDF5 tools before 2.0 open "
            f"it after uvisi replay --clear-flags {r['recording']}")


def run(args) -> int:
    import sys

    from hil_harness.event.io import replay
    if args.with_ is not None:
        raise ValueError("--with: replay takes the proposals from the recording "
                         "(config.flight.with); run `uvisi event --with ...` for another set")
    if args.clear_flags:
        return _clear_flags(Path(args.recording))
    r = replay(args.recording, ignore_checksums=args.ignore_checksums)
    if r["note"]:
        print(f"uvisi replay: {r['note']}", file=sys.stderr)
    if r.get("predates_proposals"):
        print(f"{r['recording']}: made before proposals existed: replayed with today's "
              f"configuration (all eight proposals)")
    head = f"{r['recording']}: {r['verified']} frames verified (checksums)"
    if not r["checksums"]:
        head = f"{r['recording']}: recorded without checksums, not verified"
    if not r["complete"]:
        head = (f"{r['recording']}: incomplete recording (complete = False: the event was "
                f"interrupted), holds {r['frames']} of {r['planned']} frames; {r['verified']} "
                f"frames verified (checksums)")
    if r["identical"]:
        print(f"{head}, {r['compared']} messages re-computed, all bit-identical{_flags_tail(r)}")
        if r.get("unverified") and not args.accept_unverified:
            print(f"uvisi replay: {r['recording']}: {r['unverified']}: a failed verdict "
                  f"(--accept-unverified accepts it)", file=sys.stderr)
            return 1
        return 0
    print(f"{head}; {len(r['mismatches'])} of {r['compared']} messages differ{_flags_tail(r)}")
    for m in r["mismatches"][:20]:
        print(f"  frame {m['k']}: {m['what']} differs from word {m['first_word']}")
    return 1
