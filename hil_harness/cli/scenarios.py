"""``uvisi scenarios``: list the scenarios shipped with the ground simulator."""
from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("scenarios", help="list the shipped scenarios", description=__doc__)
    p.set_defaults(func=run, compiles=False)


def run(args) -> int:
    from groundsim.scenario import Scenario
    names = Scenario.shipped()
    w = max(len(n) for n in names)
    for n in names:
        s = Scenario.load(n)
        print(f"{n:<{w}}  {s.imager:<8} c{s.compaction}  {s.duration:5.0f} s  "
              f"{s.target_type or 'no target':<9}  {s.description}")
    return 0
