"""Numba's on-disk cache written by several processes at once (flightsw.numba_cache).

Oracle: the index and data files themselves. Two processes save 60 different keys each into one
cache file at the same time; afterwards every key is in the index and its data file holds that
key's payload (numba 0.68's unlocked save lets two processes pick the same data-file number, so a
key can name the other process's machine code).
"""
from __future__ import annotations

import multiprocessing as mp

from numba.core.caching import IndexDataCacheFile

import flightsw  # noqa: F401  (installs the locked save)

N = 60


def _writer(path: str, tag: str, go) -> None:
    import flightsw  # noqa: F401
    f = IndexDataCacheFile(path, "kernel-1.py311", ("stamp", 1))
    go.wait()
    for i in range(N):
        f.save((tag, i), {"payload": (tag, i), "pad": b"x" * 2048})


def test_concurrent_saves_keep_every_key_with_its_own_data(tmp_path):
    ctx = mp.get_context("fork")
    go = ctx.Event()
    procs = [ctx.Process(target=_writer, args=(str(tmp_path), tag, go)) for tag in "ab"]
    for p in procs:
        p.start()
    go.set()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    f = IndexDataCacheFile(str(tmp_path), "kernel-1.py311", ("stamp", 1))
    for key in [(tag, i) for tag in "ab" for i in range(N)]:       # numba's own reader
        got = f.load(key)
        assert got is not None and got["payload"] == key, key
