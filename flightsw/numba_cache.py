"""Numba's on-disk cache made safe for the several processes that compile at once here.

``uvisi`` compiles in two processes on a cold cache (the command, and the warm-up process on the
other core); the test suite does the same (``tests/compile_ahead.py``); campaigns run Dask workers.
Numba 0.68's cache (``numba.core.caching.IndexDataCacheFile.save``) reads a function's index,
picks the first unused data-file number and writes the index, then the data, with no lock: two
processes saving different signatures of one function at the same moment can both pick number 1,
so that the index names one signature's file while it holds the other's machine code. A later
process then runs code compiled for C-contiguous arrays on strided views, or the reverse (seen as
wrong opportunity-track states on a cold cache, 2026-11-28). :func:`serialise_cache_writes` wraps
``save`` in an exclusive ``fcntl.flock`` on a lock file beside the index, so each save reads the
index as the previous one left it and never reuses a number. Loading needs no lock: a data file is
written to a temporary name and renamed, and a number once in an index is never given to another
signature.
"""
from __future__ import annotations

import fcntl
import functools

__all__ = ["serialise_cache_writes"]


def serialise_cache_writes() -> None:
    """Install the locked ``save``: now if numba's cache module is loaded, else when it is (a
    package that imports this does not import numba by itself: ``uvisi scenarios`` never loads
    it). Idempotent."""
    import sys
    mod = sys.modules.get("numba.core.caching")
    if mod is not None:
        _lock_saves(mod)
    elif not any(isinstance(f, _PatchOnImport) for f in sys.meta_path):
        sys.meta_path.insert(0, _PatchOnImport())


class _PatchOnImport:
    """A meta-path finder that lets ``numba.core.caching`` load as usual, then locks its saves."""

    def find_spec(self, name, path=None, target=None):
        if name != "numba.core.caching":
            return None
        import importlib.util
        import sys
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        run = spec.loader.exec_module

        def exec_module(module):
            run(module)
            _lock_saves(module)
        spec.loader.exec_module = exec_module
        return spec


def _lock_saves(caching) -> None:
    cls = caching.IndexDataCacheFile
    if getattr(cls.save, "uvisi_locked", False):
        return
    unlocked = cls.save

    @functools.wraps(unlocked)
    def save(self, key, data):
        with open(self._index_path + ".lock", "a") as fh:
            fcntl.flock(fh, fcntl.LOCK_EX)
            try:
                return unlocked(self, key, data)
            finally:
                fcntl.flock(fh, fcntl.LOCK_UN)

    save.uvisi_locked = True
    cls.save = save
