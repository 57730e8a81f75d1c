"""``uvisi scenarios [--all | --family NAME]``: list the scenarios shipped with the ground simulator.

By default the product's scenarios (the satellite over stars, the launch in the narrow field, the
auroral surge, the star-rich slews, the bus-fault and uplink demonstrations) and one line per
evaluation or training family (its name and how many scenarios it holds); ``--family NAME`` lists a
family's scenarios, ``--all`` every scenario.
"""
from __future__ import annotations

import re

#: a family's scenarios: <aurora|satellite>_<eval|train>[N]_<place or case>
FAMILY = re.compile(r"^((?:aurora|satellite)_(?:eval|train)\d*)_")


def register(sub) -> None:
    p = sub.add_parser("scenarios", help="list the shipped scenarios", description=__doc__)
    g = p.add_mutually_exclusive_group()
    g.add_argument("--all", action="store_true", help="every shipped scenario, families included")
    g.add_argument("--family", default=None, metavar="NAME",
                   help="the scenarios of one family, e.g. satellite_eval12")
    p.set_defaults(func=run, compiles=False)


def family_of(name: str) -> str | None:
    """The evaluation or training family a shipped scenario belongs to (None: a product one)."""
    m = FAMILY.match(name)
    return m.group(1) if m else None


def _line(name: str, w: int) -> str:
    from groundsim.scenario import Scenario
    s = Scenario.load(name)
    return (f"{name:<{w}}  {s.imager:<8} c{s.compaction}  {s.duration:5.0f} s  "
            f"{s.target_type or 'no target':<9}  {s.description}")


def run(args) -> int:
    from groundsim.scenario import Scenario
    names = Scenario.shipped()
    families: dict[str, list] = {}
    for n in names:
        f = family_of(n)
        if f is not None:
            families.setdefault(f, []).append(n)
    if args.family is not None and args.family not in families:
        raise ValueError(f"--family {args.family}: no such family; known: "
                         f"{', '.join(sorted(families))}")
    show = names if args.all else families[args.family] if args.family else \
        [n for n in names if family_of(n) is None]
    w = max(len(n) for n in show)
    for n in show:
        print(_line(n, w))
    if not args.all and args.family is None:
        import textwrap
        print(textwrap.fill(
            f"evaluation and training families ({len(families)}, "
            f"{sum(map(len, families.values()))} scenarios; uvisi scenarios --family NAME or "
            f"--all): " + ", ".join(f"{f} ({len(v)})" for f, v in sorted(families.items())),
            100, subsequent_indent="  "))
    return 0
