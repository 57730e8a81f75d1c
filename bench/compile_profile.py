"""Where a first run's compile time goes (issue 45, item 2): one command of ``uvisi`` run in this
process on an empty numba cache, with numba's compile events and LLVM's three stages timed.

    python -m bench.compile_profile [--top N] -- event satellite_over_stars --frames 20 --no-figures

Prints the wall time of the command; the compile events (one per kernel and argument types
numba compiles) and the extra seconds the repeated ones cost (each kernel's own time beyond its
cheapest compile); the seconds in numba's passes (``native_lowering`` holds LLVM's work and the
building of its IR); LLVM's three stages over every library: the per-function optimisation, the
whole-module optimisation after a kernel's callees are linked in, and the machine code; and how
many functions the optimised modules still define (a callee that is not inlined is optimised and
compiled again in every kernel that links it). Then the ``--top`` kernels by their own LLVM time.

It times numba's ``CPUCodeLibrary`` methods by wrapping them (numba's internals: a measuring
script, not product code) and sets ``NUMBA_CACHE_DIR`` to a fresh folder before numba loads, and
``UVISI_WARMUP=0``: the command compiles everything in this process, as it does without the
first run's warm-up process (which would compile the image processor beside it).
"""
from __future__ import annotations

import argparse
import collections
import os
import sys
import tempfile
import time


def _time_stages(totals, per_library, defined):
    """Wrap numba's code-library stages: seconds into ``totals[stage]`` and
    ``per_library[name][stage]``; functions defined by each finalised module into ``defined``."""
    import numba.core.codegen as cg

    def wrap(cls, method, stage):
        orig = getattr(cls, method)

        def timed(self, *a, **k):
            t0 = time.perf_counter()
            try:
                return orig(self, *a, **k)
            finally:
                dt = time.perf_counter() - t0
                totals[stage] += dt
                per_library[self.name][stage] += dt
        setattr(cls, method, timed)

    wrap(cg.CPUCodeLibrary, "_optimize_functions", "function passes")
    wrap(cg.CPUCodeLibrary, "_optimize_final_module", "module passes")
    wrap(cg.JITCodeLibrary, "_finalize_specific", "machine code")
    orig_final = cg.CPUCodeLibrary._finalize_final_module

    def count(self):
        defined[self.name] = sum(1 for f in self._final_module.functions if not f.is_declaration)
        return orig_final(self)
    cg.CPUCodeLibrary._finalize_final_module = count


def _listen(kind, on_end):
    """Register a numba event listener for ``kind`` that times each event less its nested ones
    and calls ``on_end(event, seconds, own seconds)``."""
    from numba.core import event as ev
    stack = []

    class Listener(ev.Listener):
        def on_start(self, e):
            stack.append([time.perf_counter(), 0.0])

        def on_end(self, e):
            t0, nested = stack.pop()
            dt = time.perf_counter() - t0
            if stack:
                stack[-1][1] += dt
            on_end(e, dt, dt - nested)
    ev.register(kind, Listener())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--top", type=int, default=10, help="kernels listed by their LLVM time")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the uvisi command")
    args = ap.parse_args(argv)
    cmd = [a for a in args.command if a != "--"] or ["event", "satellite_over_stars", "--frames",
                                                     "20", "--no-figures"]
    if "numba" in sys.modules:
        sys.exit("bench.compile_profile: numba was imported before the cache folder was set")
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="uvisi-compile-profile-")
    os.environ["UVISI_WARMUP"] = "0"        # every kernel compiled here, none by a second process
    stages = collections.defaultdict(float)
    per_lib = collections.defaultdict(lambda: collections.defaultdict(float))
    defined: dict = {}
    _time_stages(stages, per_lib, defined)
    kernels = collections.defaultdict(list)
    passes = collections.defaultdict(float)

    def compiled(e, dt, own):
        f = getattr(e.data["dispatcher"], "py_func", None)
        kernels[f"{f.__module__}.{f.__qualname__}" if f else "?"].append(own)

    def ran_pass(e, dt, own):
        name = e.data.get("name", "?") if isinstance(e.data, dict) else str(e.data)
        passes[name.split(" [")[0]] += own
    _listen("numba:compile", compiled)
    _listen("numba:run_pass", ran_pass)
    from hil_harness.cli import main as uvisi
    with tempfile.TemporaryDirectory() as scratch:
        if cmd[0] == "event" and "--out" not in cmd:
            cmd = [*cmd, "--out", os.path.join(scratch, "run")]
        t0 = time.perf_counter()
        try:
            uvisi(["-q", *cmd])
        except SystemExit:
            pass
        wall = time.perf_counter() - t0
    events = sum(len(v) for v in kernels.values())
    repeats = sum(sum(sorted(v)[1:]) for v in kernels.values())
    print(f"uvisi {' '.join(cmd)}: {wall:.1f} s wall on an empty cache")
    print(f"compile events {events} ({len(kernels)} kernels); the repeated ones' own time "
          f"{repeats:.1f} s")
    print("numba passes (own s): " + ", ".join(
        f"{k} {v:.1f}" for k, v in sorted(passes.items(), key=lambda t: -t[1])[:4]))
    print("LLVM (s): " + ", ".join(f"{k} {v:.1f}" for k, v in stages.items())
          + f"; {len(defined)} libraries define {sum(defined.values())} functions")
    for name, d in sorted(per_lib.items(), key=lambda kv: -sum(kv[1].values()))[:args.top]:
        print(f"  {sum(d.values()):5.2f} s  {defined.get(name, 0):3d} functions  {name[:80]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
