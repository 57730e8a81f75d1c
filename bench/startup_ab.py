"""A warm ``uvisi event`` with numba's BLAS check as numba ships it and as the flight code defers
it (:func:`flightsw.numba_cache.defer_blas_check`): ``python -m bench.blas_check_ab [--rounds N]
[CLI ARGS...]`` (default ``event satellite_over_stars --no-figures``).

Each round runs the command once each way, in turn, in fresh processes on the same cached kernels:

- ``numba's check``: a process that imports ``numba.np.arraymath`` before the flight code, so
  numba checks for BLAS as it ships (importing ``scipy.linalg``), then runs the ``uvisi`` console
  script's entry point;
- ``deferred``: the same entry point alone, as ``uvisi`` runs.

Prints each run's wall time and CPU time (user + sys of the child), then the medians and their
difference. Run it on a quiet machine, after one warm-up run of the command (the first compiles).
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

WAYS = {
    "numba's check": "import numba.np.arraymath\nfrom hil_harness.cli import run\nrun()\n",
    "deferred": "from hil_harness.cli import run\nrun()\n",
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
        raise SystemExit(f"blas_check_ab: {' '.join(argv)} failed: {done.stderr.strip()[-300:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main(args=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.blas_check_ab", description=__doc__)
    ap.add_argument("--rounds", type=int, default=6, help="runs each way (default 6)")
    ap.add_argument("command", nargs="*", help="the uvisi command and its arguments")
    a = ap.parse_args(args)
    if a.rounds < 1:
        ap.error(f"--rounds {a.rounds}: at least 1")
    argv = a.command or DEFAULT
    runs = {w: [] for w in WAYS}
    with tempfile.TemporaryDirectory() as tmp:
        if argv[0] == "event" and "-o" not in argv and "--out" not in argv:
            argv = [*argv, "--force", "-o", str(Path(tmp) / "event")]
        for r in range(a.rounds):
            for way, code in WAYS.items():
                wall, cpu = run_once(code, argv)
                runs[way].append((wall, cpu))
                print(f"round {r + 1}/{a.rounds}  {way:14s} wall {wall:.2f} s  cpu {cpu:.2f} s",
                      flush=True)
    med = {w: (statistics.median(x[0] for x in v), statistics.median(x[1] for x in v))
           for w, v in runs.items()}
    for w, (wall, cpu) in med.items():
        print(f"median  {w:14s} wall {wall:.2f} s  cpu {cpu:.2f} s")
    (w0, c0), (w1, c1) = med["numba's check"], med["deferred"]
    print(f"deferred - numba's check: wall {w1 - w0:+.2f} s ({w1 / w0 - 1:+.0%}), "
          f"cpu {c1 - c0:+.2f} s ({c1 / c0 - 1:+.0%})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
