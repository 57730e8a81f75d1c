"""``uvisi proposals [--json]``: the candidate flight-software changes the emulator offers.

The flight code runs the MSX paper's system by default. Each proposal is a behaviour the paper's
system did not have, kept as a named change that is off until switched on with ``--with NAME`` (or
``--with all``) on ``event``, ``track``, ``tune``, ``campaign`` and ``demo``, or ``with = [...]``
under ``[flight]`` in a scenario or campaign file, and weighed against the paper's system with
``uvisi compare``. For each: what it changes, the uplink word or configuration key that carries
it, and the evidence it was chosen on (``docs/fidelity.md`` has the measured tables).
"""
from __future__ import annotations

import json
import textwrap


def register(sub) -> None:
    p = sub.add_parser("proposals", help="list the candidate flight-software changes (--with)",
                       description=__doc__)
    p.add_argument("--json", action="store_true",
                   help="print a JSON list of objects (name, summary, evidence, carrier, ...)")
    p.set_defaults(func=run, compiles=False)


def run(args) -> int:
    from flightsw.proposals import ALL, PROPOSALS
    items = [PROPOSALS[n].as_dict() for n in ALL]
    if args.json:
        print(json.dumps(items, indent=2))
        return 0
    for d in items:
        modes = "/".join(d["modes"])
        print(f"{d['name']}  ({d['processor'].upper()}, {modes} events)")
        for label, key in (("changes", "summary"), ("carried by", "carrier"),
                           ("evidence", "evidence")):
            print(textwrap.fill(d[key], 96, initial_indent=f"  {label}: ",
                                subsequent_indent=" " * (len(label) + 4)))
    print(f"\n{len(items)} proposals, all off by default (the paper's system). Switch on with "
          f"--with NAME[,NAME...] or --with all; weigh them with uvisi compare.")
    return 0
