"""A warm ``uvisi`` command with one of the flight code's numba start-up changes undone, against
the command as it runs: ``python -m bench.startup_ab --change {blas,refresh} [--rounds N] [CLI
ARGS...]`` (default command ``event satellite_over_stars --no-figures``).

The changes (:mod:`flightsw.numba_cache`):

- ``blas``: numba's BLAS check as numba ships it (importing ``scipy.linalg``) against the check
  :func:`~flightsw.numba_cache.defer_blas_check` defers: the first way's process imports
  ``numba.np.arraymath`` before the flight code, so numba checks as it ships;
- ``refresh``: numba's cache load as it ships (a refresh of numba's typing and target contexts
  before every load) against :func:`~flightsw.numba_cache.load_without_refresh`: the first way's
  process puts numba's ``Cache.load_overload`` back after importing the flight code.

Each round runs the command once each way, in turn, in fresh processes on the same cached kernels,
then the ``uvisi`` console script's entry point. Prints each run's wall time and CPU time (user +
sys of the child), then the medians and their difference. Run it on a quiet machine, after one
warm-up run of the command (the first compiles).
"""
from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

RUN = "from hil_harness.cli import run\nrun()\n"
#: change -> {way: the code of its process}, numba as it ships first
CHANGES = {
    "blas": {"numba's check": "import numba.np.arraymath\n" + RUN,
             "deferred": RUN},
    "refresh": {"numba's refresh": ("import numba.core.caching as caching\n"
                                    "shipped = caching.Cache.load_overload\n"
                                    "import flightsw\n"
                                    "caching.Cache.load_overload = shipped\n" + RUN),
                "runtime only": RUN},
}
DEFAULT = ["event", "satellite_over_stars", "--no-figures"]


def run_once(code: str, argv: list[str]) -> tuple[float, float]:
    """Wall and CPU seconds (user + sys) of one process running ``code`` with ``argv``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", code, "-q", *argv], capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"startup_ab: {' '.join(argv)} failed: {done.stderr.strip()[-300:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(args=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.startup_ab", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--change", required=True, choices=sorted(CHANGES),
                    help="the start-up change to undo in the first way")
    ap.add_argument("--rounds", type=int, default=6, help="runs each way (default 6)")
    ap.add_argument("command", nargs="*", help="the uvisi command and its arguments")
    a = ap.parse_args(args)
    if a.rounds < 1:
        ap.error(f"--rounds {a.rounds}: at least 1")
    ways = CHANGES[a.change]
    argv = a.command or DEFAULT
    runs = {w: [] for w in ways}
    with tempfile.TemporaryDirectory() as tmp:
        if argv[0] == "event" and "-o" not in argv and "--out" not in argv:
            argv = [*argv, "--force", "-o", str(Path(tmp) / "event")]
        for r in range(a.rounds):
            for way, code in ways.items():
                wall, cpu = run_once(code, argv)
                runs[way].append((wall, cpu))
                print(f"round {r + 1}/{a.rounds}  {way:16s} wall {wall:.2f} s  cpu {cpu:.2f} s",
                      flush=True)
    med = {w: (statistics.median(x[0] for x in v), statistics.median(x[1] for x in v))
           for w, v in runs.items()}
    for w, (wall, cpu) in med.items():
        print(f"median  {w:16s} wall {wall:.2f} s  cpu {cpu:.2f} s")
    (shipped, (w0, c0)), (ours, (w1, c1)) = med.items()
    print(f"{ours} - {shipped}: wall {w1 - w0:+.2f} s ({w1 / w0 - 1:+.0%}), "
          f"cpu {c1 - c0:+.2f} s ({c1 / c0 - 1:+.0%})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
