"""Test-session set-up: compile ahead on the second core (:mod:`tests.compile_ahead`), and run the
benchmark smoke test last.

A session that collects at least :data:`COMPILE_AHEAD_MIN_TESTS` tests (the whole suite, not one
file) starts ``python -m tests.compile_ahead`` beside it, and stops it when the session ends if it
is still running. On a warm cache the process only loads the cache (a few seconds on the other
core). Only with ``UVISI_WARMUP=1``; without it the commands the tests run start no warm-up
process either (``uvisi``'s own, on by default outside the tests). A cold suite with it took 722 s
on 2026-11-30 against 757 s without it the session before, on the same slow host; no controlled
comparison shows it paying for a second process by default.

tests/test_bench_smoke.py runs every benchmark once in a process of its own, which loads from the
cache whatever the suite has compiled before it: run last, it compiles almost nothing (on a cold
cache ~20 s instead of ~60-90 s in alphabetical place).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil_harness.warmup import WARMUP_ENV

ROOT = Path(__file__).resolve().parents[1]
# the commands the tests run (in this process and in subprocesses) start no warm-up process of
# their own: the suite compiles everything anyway, and its own helper is the compile-ahead
# process below; a test of the warm-up sets the variable itself
os.environ.setdefault("UVISI_WARMUP", "0")
# the tests live in folders by package (tests/ip, tests/tp, ...); their shared helpers
# (ip_reference, quat_oracle) stay here, importable from every folder
sys.path.insert(0, str(Path(__file__).resolve().parent))
#: fewer collected tests than this (a file, a -k selection): no compile-ahead process
COMPILE_AHEAD_MIN_TESTS = 300
_PROCESS = pytest.StashKey[subprocess.Popen]()
#: the test files run after all the others, in this order
LAST = ("tests/test_bench_smoke.py",)


def pytest_collection_modifyitems(session, config, items):
    def rank(item):
        path = item.nodeid.split("::", 1)[0]
        return LAST.index(path) + 1 if path in LAST else 0
    items.sort(key=rank)                    # stable: the others keep their order


def pytest_collection_finish(session):
    if len(session.items) < COMPILE_AHEAD_MIN_TESTS or os.environ.get(WARMUP_ENV) \
            or os.environ.get("UVISI_WARMUP", "0") != "1" or session.config.option.collectonly:
        return
    env = dict(os.environ, **{WARMUP_ENV: "1"})
    try:
        session.config.stash[_PROCESS] = subprocess.Popen(
            [sys.executable, "-m", "tests.compile_ahead"], cwd=ROOT, env=env,
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True)
    except OSError:
        pass


def pytest_unconfigure(config):
    proc = config.stash.get(_PROCESS, None)
    if proc is not None and proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
