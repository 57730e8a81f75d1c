"""``uvisi demo [--out DIR] [--arith]``: the product's main job on its built-in default.

Runs ``uvisi event satellite_over_stars`` (a satellite crossing a star field in the wide-FOV visible
imager, 90 s at 2 Hz, closed loop) into DIR (default ``./events/satellite_over_stars``) and prints
where the recording, summary and figures are. The flight code is the paper's system; ``--with``
switches on proposals (``uvisi proposals``). ``--arith`` prints instead the flight-arithmetic
self-report: the cases the processors' documents pin down, each checked against its reference, and
the emulated cycle budget of the image processor's heaviest vector step.
"""
from __future__ import annotations

import time
from fractions import Fraction

import numpy as np

from hil_harness.cli.options import add_with_option


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the product's main job on the built-in default",
                       description=__doc__)
    p.add_argument("-o", "--out", default=None,
                   help="output directory (default: ./events/satellite_over_stars, replaced on each "
                        "run; another run in a given one is refused unless --force)")
    p.add_argument("--force", action="store_true", help="replace another run found in --out")
    p.add_argument("--arith", action="store_true", help="flight-arithmetic self-report instead")
    add_with_option(p)
    p.set_defaults(func=run, outputs={"out": "folder"})


def _adsp_report() -> list[tuple[str, str, bool]]:
    from flightsw.arith import adsp2100 as dsp

    rows = []
    mr, mv = dsp.mac(0, 0x8000, 0x8000, op="=")
    rows.append(("ADSP MAC (-1)*(-1) -> 00_8000_0000, MV=1 (manual)", f"{mr:010X}, MV={mv}",
                 (mr, mv) == (0x0080000000, 1)))
    rows.append(("ADSP IF MV SAT MR", f"{dsp.sat_mr(mr):010X}", dsp.sat_mr(mr) == 0x007FFFFFFF))
    r = dsp.rnd_mr(0x0000028000)
    rows.append(("ADSP RND 2.5 -> 2 (half to even)", f"MR1={r >> 16 & 0xFFFF:#06x}", r >> 16 == 2))
    ar, ac, av = dsp.alu_add(0x7FFF, 0x0001, ar_sat=True)
    rows.append(("ADSP AR_SAT 0x7FFF+1", f"{ar:#06x} AC={ac} AV={av}", (ar, av) == (0x7FFF, 1)))
    q, _ = dsp.divide_signed(0x2000, 0x0000, 0x4000)
    rows.append(("ADSP DIVS/DIVQ 0.25/0.5", f"{Fraction(q, 1 << 15)}", q == 0x4000))
    return rows


def _m1750_report() -> list[tuple[str, str, bool]]:
    try:
        from flightsw.arith import m1750
    except ImportError:
        return []
    rows = []
    for value, words in ((10.0, 0x50000004), (-1.0, 0x80000000), (0.25, 0x400000FF)):
        enc = m1750.encode32(value)
        rows.append((f"1750A encode32({value})", f"{enc >> 16:04X} {enc & 0xFFFF:04X}", enc == words))
    s, flags = m1750.fa32(m1750.encode32(1.0), m1750.encode32(0.5))
    rows.append(("1750A FA 1.0 + 0.5", f"{m1750.decode32(s)} flags={flags}", m1750.decode32(s) == 1.5))
    return rows


def event_args(args):
    """The arguments of ``uvisi event satellite_over_stars [--out OUT] [--force]``, parsed by the
    event command's own parser (so every option it has takes its default)."""
    from hil_harness.cli import build_parser
    argv = ["event", "satellite_over_stars"]
    if args.out is not None:
        argv += ["--out", str(args.out)]
    if getattr(args, "force", False):
        argv.append("--force")
    if getattr(args, "with_", None) is not None:
        argv += ["--with", str(args.with_)]
    return build_parser().parse_args(argv)


def run(args) -> int:
    if not getattr(args, "arith", False):
        from hil_harness.cli.event import run as run_event
        return run_event(event_args(args))
    return _arith_report()


def _arith_report() -> int:
    from flightsw.arith.adsp2100 import correlate_cycles, correlate_valid_q15
    from flightsw.budget import ADSP2100, FRAME_PERIOD_S

    print("uvisi demo --arith: flight arithmetic self-report\n")
    rows = _adsp_report() + _m1750_report()
    width = max(len(r[0]) for r in rows)
    for name, got, ok in rows:
        print(f"  {'ok ' if ok else 'BAD'}  {name:<{width}}  {got}")

    rng = np.random.default_rng(0)
    img = rng.integers(0, 4096, (70, 70)).astype(np.int16)
    g = np.exp(-0.5 * ((np.arange(7) - 3) / 1.5) ** 2)
    kern = np.round(np.outer(g, g) / np.outer(g, g).sum() * 32768).astype(np.int16)
    correlate_valid_q15(img, kern)                               # compile / load from cache
    t0 = time.perf_counter()
    n = 200
    for _ in range(n):
        correlate_valid_q15(img, kern)
    host_us = (time.perf_counter() - t0) / n * 1e6
    cyc = correlate_cycles(64, 64, 7)
    print(f"\n  7x7 Q15 correlation of a 64x64 window: {cyc:,d} ADSP-2100 cycles = "
          f"{1e3 * ADSP2100.seconds(cyc):.2f} ms of the {1e3 * FRAME_PERIOD_S:.0f} ms frame "
          f"({100 * ADSP2100.seconds(cyc) / FRAME_PERIOD_S:.1f} %); host {host_us:.1f} us")
    bad = [r for r in rows if not r[2]]
    print(f"\n{len(rows) - len(bad)}/{len(rows)} checks agree with the manuals.")
    return 1 if bad else 0
