"""Test-session set-up: the commands the tests run start no warm-up process, the benchmark smoke
test runs last, and no command's closing note follows the report.

``make test`` runs the suite in two worker processes (pytest-xdist, ``-n 2``): on a cold numba
cache each worker compiles the kernels its tests reach, and numba's compile lock
(:mod:`flightsw.numba_cache`) has a worker that reaches a kernel the other is compiling wait and
load it. ``python -m pytest`` alone runs the suite in one process.

tests/test_bench_smoke.py runs every benchmark once in a process of its own, which loads from the
cache whatever the suite has compiled before it: run last, it compiles almost nothing (on a cold
cache ~20 s instead of ~60-90 s in alphabetical place). tests/bench/test_record_under_load.py
runs whole events in processes of their own, and goes just before it for the same reason.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

# the commands the tests run (in this process and in subprocesses) start no warm-up process of
# their own: the suite compiles everything anyway; a test of the warm-up sets the variable itself
os.environ.setdefault("UVISI_WARMUP", "0")
# the tests live in folders by package (tests/ip, tests/tp, ...); their shared helpers
# (ip_reference, quat_oracle) stay here, importable from every folder
sys.path.insert(0, str(Path(__file__).resolve().parent))
#: the test files run after all the others, in this order
LAST = ("tests/bench/test_record_under_load.py", "tests/test_bench_smoke.py")


def pytest_collection_modifyitems(session, config, items):
    def rank(item):
        path = item.nodeid.split("::", 1)[0]
        return LAST.index(path) + 1 if path in LAST else 0
    items.sort(key=rank)                    # stable: the others keep their order


def pytest_sessionfinish(session, exitstatus):
    """Quiet the console at the session's end: the commands the tests ran in this process set up
    the first-run compile notice, whose closing line ("compiling: N/M kernels done") a process
    prints as it exits, after pytest's capture has ended: a note for a user's command, which in
    the suite landed on the report's progress line."""
    from hil_harness import console
    console.set_level(console.QUIET)
