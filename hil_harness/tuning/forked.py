"""Independent jobs of a tuning run (weight searches) on forked worker processes.

A job is ``(cost, fn, args)``: ``fn(*args, tick=tick)`` is called in a worker, ``tick()`` once
per unit of progress (a generation of a search). The workers are forked when the jobs start, so
``args`` (events, rankers) reach them without pickling; only the results come back. Jobs go out
largest ``cost`` first, so the workers finish together; the results come back in job order, and a
job's result does not depend on where it ran, so every output is the same on any number of
workers. Progress: the ticks of every job, counted in shared memory and shown by this process (a
bar when ``progress``, else a heartbeat line every few seconds: :class:`hil_harness.console.
Heartbeat`).
"""
from __future__ import annotations

import multiprocessing
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

__all__ = ["run_jobs"]

#: (jobs, tick counters) the workers fork with
_FORKED: list = []


def _run(j: int):
    jobs, counts = _FORKED
    _, fn, args = jobs[j]

    def tick() -> None:
        counts[j] += 1
    return fn(*args, tick=tick)


class _Progress:
    def __init__(self, total: int, desc: str, unit: str, bar: bool):
        self.n = 0
        if bar:
            from tqdm import tqdm
            self.bar, self.beat = tqdm(total=total, desc=desc, unit=unit, leave=False), None
        else:
            from hil_harness.console import Heartbeat
            self.bar, self.beat = None, Heartbeat(total, desc, unit)

    def to(self, n: int) -> None:
        k, self.n = n - self.n, n
        if self.bar is not None:
            self.bar.update(k)
        else:
            self.beat.update(k)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        else:
            self.beat.close()


def run_jobs(jobs: list, workers: int, total_ticks: int, desc: str, unit: str,
             progress: bool = False) -> list:
    """Run ``jobs`` (module docstring) on up to ``workers`` forked processes (in this process
    when 1, or with a single job). Returns, per job in order, its result or the exception it
    raised (returned, for the caller to raise where it would have)."""
    prog = _Progress(total_ticks, desc, unit, progress)
    try:
        if workers <= 1 or len(jobs) < 2 or "fork" not in multiprocessing.get_all_start_methods():
            return _serial(jobs, prog)
        return _parallel(jobs, workers, prog)
    finally:
        prog.close()


def _serial(jobs: list, prog: _Progress) -> list:
    out = []

    def tick() -> None:
        prog.to(prog.n + 1)
    for _, fn, args in jobs:
        try:
            out.append(fn(*args, tick=tick))
        except Exception as exc:            # noqa: BLE001 - handed back, raised by the caller
            out.append(exc)
    return out


def _parallel(jobs: list, workers: int, prog: _Progress) -> list:
    ctx = multiprocessing.get_context("fork")
    counts = ctx.RawArray("q", len(jobs))   # shared with the workers: each writes its own slot
    _FORKED[:] = [jobs, counts]
    order = sorted(range(len(jobs)), key=lambda j: -jobs[j][0])
    try:
        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=ctx) as ex:
            futs = {ex.submit(_run, j): j for j in order}
            pending = set(futs)
            while pending:
                _, pending = wait(pending, timeout=0.5, return_when=FIRST_COMPLETED)
                prog.to(sum(counts))
            out = [None] * len(jobs)
            for f, j in futs.items():
                exc = f.exception()
                out[j] = exc if exc is not None else f.result()
        return out
    finally:
        _FORKED.clear()
