"""Independent tuning jobs on forked workers (hil_harness.tuning.forked): results in job order
whatever order they ran in, a job's exception handed back at its place, every tick counted."""
from __future__ import annotations

import os

import pytest

from hil_harness import console
from hil_harness.tuning.forked import run_jobs


def _job(k, fail=False, tick=None):
    for _ in range(k):
        tick()
    if fail:
        raise ValueError(f"job {k} failed")
    return k, os.getpid()


@pytest.mark.parametrize("workers", [1, 2])
def test_results_in_job_order_exceptions_returned_ticks_counted(workers, capsys, monkeypatch):
    monkeypatch.setattr(console.Heartbeat, "HEARTBEAT_S", 0.0)
    jobs = [(1, _job, (1,)), (5, _job, (3,)), (2, _job, (2, True)), (9, _job, (4,))]
    out = run_jobs(jobs, workers, 10, "[tune] test", "tick")
    assert [r[0] for r in (out[0], out[1], out[3])] == [1, 3, 4]
    assert isinstance(out[2], ValueError) and "job 2 failed" in str(out[2])
    pids = {r[1] for r in (out[0], out[1], out[3])}
    assert (os.getpid() in pids) == (workers == 1)
    assert "[tune] test: 10/10 tick done" in capsys.readouterr().err
