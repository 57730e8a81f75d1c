"""The event recorder's cost alone: ``python -m bench.recorder_cost [REPEATS]``.

Runs the 181 frames of ``satellite_over_stars`` once, keeping every frame's outcome in memory, then
writes them REPEATS times (default 4) through :class:`hil_harness.event.io.EventWriter` into a fresh
recording (open, every frame, close) and prints the mean wall and CPU time per frame, the median
per-frame call (appends only; every 20th call also writes a block) and the file size; then the same
without the frames (as ``uvisi event --no-frames`` records: the tables' Python and HDF5 work alone,
without the frames' 125 kB page-cache writes, the part of the cost that varies most with the
machine's load). CPU time is given beside wall time because on a shared machine the wall time
mostly measures the neighbours; the last line gives each pass's least CPU time per frame.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hil_harness.event import Event, EventConfig
from hil_harness.event.io import EventWriter
from hil_harness.event.recording import Recorder


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    repeats = int(argv[0]) if argv else 4
    ev = Event(EventConfig("satellite_over_stars"), keep_frames=True)
    ev.run()
    n = len(ev.outcomes)
    print(f"recorder alone, {n} frames of satellite_over_stars, {repeats} runs")
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        for frames in (True, False):
            for rep in range(repeats):
                path = Path(tmp) / f"r{rep}{frames}" / "recording.h5"
                t0, c0 = time.perf_counter(), time.process_time()
                rec = Recorder(path, attrs={"scenario": ev.scenario.name})
                w = EventWriter(rec, ev, frames)
                per = []
                for o in ev.outcomes:
                    t = time.perf_counter()
                    w(o)
                    per.append(time.perf_counter() - t)
                rec.close()
                wall, cpu = time.perf_counter() - t0, time.process_time() - c0
                what = "frames" if frames else "no frames"
                best[what] = min(best.get(what, cpu), cpu)
                print(f"  {what} run {rep}: {1e6 * wall / n:.0f} us wall, "
                      f"{1e6 * cpu / n:.0f} us CPU a frame (open to close); median call {1e6 * np.median(per):.0f} us; "
                      f"{path.stat().st_size / 1e6:.1f} MB")
                path.unlink()
    print("  least CPU a frame: " + ", ".join(f"{k} {1e6 * v / n:.0f} us" for k, v in best.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
