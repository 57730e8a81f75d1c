"""A recorded closed-loop frame and the wall time of a whole ``uvisi event`` (issue 23).

- Recorded frame: one frame of ``satellite_over_stars`` (render + IP + TP + spacecraft) followed by
  the recorder's call for it (the TP's snapshot row; every 20th frame the block's rows and their
  write), frames recorded, over two 181-frame events. Target: <= 450 us MEAN per frame (>= 1100x real time); the mean is what counts,
  the block writes make the median unrepresentative. Beside it, the loop alone (median, target
  <= 250 us) in the same run.
- Event wall time: a warm ``uvisi event satellite_over_stars`` (with figures, and ``--no-figures``:
  target <= 1.5 s) in a fresh process, split into phases by :mod:`bench.event_phases`.

Run: ``.venv/bin/python -m pytest bench/bench_event.py --benchmark-enable -q``.
"""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from hil_harness.event import Event, EventConfig
from hil_harness.event.io import EventWriter
from hil_harness.event.recording import Recorder, Recording

ROOT = Path(__file__).resolve().parents[1]
GROUP_FRAME = "event: recorded closed-loop frame"
GROUP_WALL = "event: wall time of a warm uvisi event"
#: events the recorded-frame bench runs through
EVENTS = 2
#: timed runs of the whole command (after one untimed warm-up run)
WALL_ROUNDS = 3


class _RecordedLoop:
    """An event stepped frame by frame with its recorder, reopened when the event ends."""

    def __init__(self, tmp: Path):
        self.ev = Event(EventConfig("satellite_over_stars", frames=181), keep_frames=False)
        self.ev.run()                         # compile / warm every kernel once
        self.tmp, self.n_rec, self.rec = tmp, 0, None
        self.loop_s, self.record_s, self.frames = 0.0, 0.0, 0
        self.paths = []

    def setup(self):
        if self.rec is None or self.ev.done:
            if self.rec is not None:
                self.paths.append(self.rec.close())
            self.ev.reset()
            self.n_rec += 1
            self.rec = Recorder(self.tmp / f"r{self.n_rec}" / "recording.h5",
                                attrs={"scenario": self.ev.scenario.name})
            self.writer = EventWriter(self.rec, self.ev, True)

    def frame(self):
        t0 = time.perf_counter()
        o = self.ev.step()
        t1 = time.perf_counter()
        self.writer(o)
        if self.ev.done:                      # the last frames' rows, as run_event does
            self.writer.drain()
        o.frame = None                        # keep_frames=False, as Event.run does
        self.loop_s += t1 - t0
        self.record_s += time.perf_counter() - t1
        self.frames += 1


def test_ours_recorded_frame(benchmark, tmp_path):
    benchmark.group = GROUP_FRAME
    lp = _RecordedLoop(tmp_path)
    benchmark.pedantic(lp.frame, setup=lp.setup, rounds=EVENTS * 181, warmup_rounds=0,
                       iterations=1)
    n = lp.frames
    while lp.frames < 181:                    # timing disabled (one round): finish the event
        lp.setup()
        lp.frame()
    lp.setup()                                # closes the event's recording
    with Recording(lp.paths[0]) as r:         # what was timed is a whole, valid recording
        assert r.complete and r.n_frames == 181 and r.verify()["frames"] == 181
    if benchmark.stats is not None:
        benchmark.extra_info.update(
            frames=n, mean_frame_us=1e6 * benchmark.stats.stats.mean,
            loop_mean_us=1e6 * lp.loop_s / lp.frames, record_mean_us=1e6 * lp.record_s / lp.frames)


def test_loop_frame_unrecorded(benchmark):
    """The loop alone in the same run (Event.step, nothing recorded)."""
    benchmark.group = GROUP_FRAME
    ev = Event(EventConfig("satellite_over_stars", frames=181), keep_frames=False)
    ev.run()

    def setup():
        if ev.done:
            ev.reset()
        if ev.outcomes:
            ev.outcomes[-1].frame = None

    ev.reset()
    benchmark.pedantic(ev.step, setup=setup, rounds=EVENTS * 181, warmup_rounds=20, iterations=1)
    assert all(o.k == i for i, o in enumerate(ev.outcomes))
    if benchmark.stats is not None:
        benchmark.extra_info.update(mean_frame_us=1e6 * benchmark.stats.stats.mean)


def _event_phases(out: Path, figures: bool, frames: int | None = None) -> dict:
    """One ``uvisi event satellite_over_stars`` in a fresh process, split into phases (s)."""
    args = ["satellite_over_stars", "--out", str(out), "--force"] + ([] if figures else
                                                                      ["--no-figures"])
    args += [] if frames is None else ["--frames", str(frames)]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    # a user's Python keeps the modules' bytecode; a shell that says not to (as some sandboxes
    # do) would time compiling every module from source, ~0.6 s a run on the development host
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "bench.event_phases", *args], cwd=ROOT, env=env,
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    assert p.returncode == 0, p.stderr[-2000:]
    ph = json.loads(p.stdout.strip().splitlines()[-1])
    ph["wall"] = wall
    ph["python_start"] = wall - ph["total_in_process"]
    return ph


@pytest.mark.parametrize("figures", [True, False], ids=["with_figures", "no_figures"])
def test_ours_event_wall(benchmark, tmp_path, figures):
    benchmark.group = GROUP_WALL
    # timing disabled (the test suite's smoke run): one short event checks the plumbing
    frames = 6 if benchmark.disabled else None
    if not benchmark.disabled:
        _event_phases(tmp_path / "warm", figures)          # warm caches, not timed
    runs = []

    def once():
        runs.append(_event_phases(tmp_path / f"run{len(runs)}", figures, frames))

    benchmark.pedantic(once, rounds=WALL_ROUNDS, iterations=1)
    assert runs and all(r["frames"] == (frames or 181) for r in runs)
    phases = ("imports", "cache_load", "simulate", "record", "figures", "other")
    assert all(0 <= r.get(k, 0.0) <= r["total_in_process"] for r in runs for k in phases)
    assert all(abs(sum(r.get(k, 0.0) for k in phases) - r["total_in_process"]) < 0.05 for r in runs)
    keys = [k for k in runs[0] if isinstance(runs[0][k], (int, float)) and k != "rc"]
    benchmark.extra_info.update({k: float(np.median([r.get(k, 0.0) for r in runs])) for k in keys})
