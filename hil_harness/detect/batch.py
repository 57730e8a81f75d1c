"""Many frames spread over the machine's cores: the per-frame work of ``uvisi detect`` (bad-frame
flags, the 12-bit mapping, the noise estimate, the full-frame detection) in forked worker
processes, results back in input order.

Each frame is independent, so processes scale with the cores (the flight kernels are
single-threaded; numba ``prange`` inside a frame would not help the NumPy parts, which take most of
a frame's time: on a 244x256 frame the flags 3.6-5.6 ms, the noise estimate 2.2-3 ms, the
detection ~0.25 ms). Forked workers inherit the compiled kernels and the frames already read, so a frame
costs its own work plus the return of its result. Below :data:`MIN_FRAMES` frames the pool's
start-up is not won back and the frames run in this process.

Measured 2026-11-24 on the shared 2-core host under a load average of 5-10 (other jobs on both
cores): 200 frames of 244x256, the per-frame loop 3.9 s (min of 4) in one process and 5.8 s with
two workers; 32 frames of 768x1024, 9.4 and 9.2 s. With both cores busy a second worker cannot
win, so ``uvisi detect`` runs one process unless ``--workers`` asks for more (0: one per core).

Public: :func:`map_ordered`, :func:`workers_for`, :data:`MIN_FRAMES`.
"""
from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

__all__ = ["map_ordered", "workers_for", "MIN_FRAMES"]

#: fewer frames than this run in this process (``workers_for`` with the automatic choice)
MIN_FRAMES = 16

_WORK: tuple | None = None            # (function, items): set before the workers fork


def _call(i: int):
    fn, items = _WORK
    return fn(items[i])


def workers_for(n_items: int, requested: int = 1) -> int:
    """Worker processes for ``n_items`` frames: ``requested`` if >= 1, else (0, automatic) one per
    core this process may run on when there are at least :data:`MIN_FRAMES` frames, 1 below."""
    if requested < 0:
        raise ValueError(f"--workers {requested} must be >= 0 (0: automatic)")
    if requested >= 1:
        return int(requested)
    if n_items < MIN_FRAMES:
        return 1
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:                    # not Linux
        cores = os.cpu_count() or 1
    return max(1, cores)


def map_ordered(fn, items, workers: int):
    """Yield ``fn(item)`` for each of ``items`` (a sequence) in order, computed on ``workers``
    forked processes (``workers <= 1`` or a single item: in this process, one at a time). ``fn``
    and ``items`` reach the workers by fork (nothing is pickled on the way in; each result is
    pickled back). An exception in ``fn`` is raised here, at its item, and the pending items are
    cancelled."""
    global _WORK
    if workers <= 1 or len(items) < 2 or "fork" not in multiprocessing.get_all_start_methods():
        for it in items:
            yield fn(it)
        return
    workers = min(workers, len(items))
    _WORK = (fn, items)
    ex = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))
    try:
        chunk = max(1, min(8, len(items) // (4 * workers)))
        yield from ex.map(_call, range(len(items)), chunksize=chunk)
    finally:
        ex.shutdown(wait=True, cancel_futures=True)
        _WORK = None
