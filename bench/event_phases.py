"""Where the wall time of one ``uvisi event`` goes: ``python -m bench.event_phases [CLI ARGS...]``.

Runs the CLI's ``main(["event", ...])`` in this process and attributes every moment of it to one
phase (each moment to exactly one: the innermost phase running), then prints one JSON object:

- ``imports``: importing the CLI and the event modules (numpy, numba, h5py, the flight code);
- ``cache_load``: numba dispatchers loading compiled kernels from the cache (or compiling them on
  a cold cache) wherever that happens, inside the other phases included;
- ``simulate``: :meth:`hil_harness.event.Event.step`, the closed loop's frames;
- ``record``: the recorder: its opening, every frame's :class:`~hil_harness.event.io.EventWriter`
  call, the writer's drains (the rows of the frames it holds, and block writes), its closing;
- ``figures``: after the recording is closed: figures, the viewer page, ``summary.json``;
- ``other``: the rest of the command (scenario and catalogue set-up, run folder, summary);
- ``frames``, ``loop_median_frame_us`` and ``mean_record_us`` from the run's ``summary.json``.

The parent (:mod:`bench.bench_event`) adds the interpreter's start-up and exit from the process's
total wall time (the process leaves as the ``uvisi`` console script does: the heap frozen first). Wall-clock seconds; run it on a quiet machine.
"""
from __future__ import annotations

import gc
import json
import sys
import time

_T0 = time.perf_counter()


class Phases:
    """Exclusive wall time per phase: a stack of phases, the time between two switches goes to
    the phase on top."""

    def __init__(self, first: str):
        self.seconds: dict[str, float] = {}
        self.stack = [first]
        self.t = time.perf_counter()

    def _switch(self) -> None:
        now = time.perf_counter()
        top = self.stack[-1]
        self.seconds[top] = self.seconds.get(top, 0.0) + now - self.t
        self.t = now

    def push(self, name: str) -> None:
        self._switch()
        self.stack.append(name)

    def pop(self) -> None:
        self._switch()
        self.stack.pop()

    def rename_base(self, name: str) -> None:
        """From now on, time outside every pushed phase goes to ``name``."""
        self._switch()
        self.stack[0] = name

    def wrap(self, owner, attr: str, name: str, after=None) -> None:
        """Make ``owner.attr`` (a function or method) run as phase ``name``; ``after()`` once it
        returns."""
        fn = getattr(owner, attr)

        def timed(*a, **k):
            self.push(name)
            try:
                return fn(*a, **k)
            finally:
                self.pop()
                if after is not None:
                    after()

        setattr(owner, attr, timed)


def measure(argv: list[str]) -> dict:
    """Run ``uvisi event ARGV`` with the phases attributed; returns the JSON object (seconds)."""
    ph = Phases("imports")
    ph.seconds["imports"] = time.perf_counter() - _T0       # this module's own start
    from numba.core.dispatcher import Dispatcher
    ph.wrap(Dispatcher, "compile", "cache_load")
    from hil_harness.cli import main
    from hil_harness.event import io, loop, recording
    ph.rename_base("other")
    ph.wrap(loop.Event, "step", "simulate")
    ph.wrap(io.EventWriter, "__call__", "record")
    ph.wrap(io.EventWriter, "drain", "record")           # also the event's last, after its loop
    ph.wrap(recording.Recorder, "__init__", "record")
    ph.wrap(recording.Recorder, "close", "record", after=lambda: ph.rename_base("figures"))
    rc = main(["event", *argv])
    ph.rename_base("other")
    out = {k: round(v, 6) for k, v in ph.seconds.items()}
    out["rc"] = rc
    out["total_in_process"] = round(time.perf_counter() - _T0, 6)
    if "--out" in argv:
        from pathlib import Path
        s = json.loads((Path(argv[argv.index("--out") + 1]) / "summary.json").read_text())
        out["frames"] = s.get("frames") or s.get("n_frames")
        out["loop_median_frame_us"] = s["host"]["median_frame_us"]
        out["mean_record_us"] = s["host"]["mean_record_us"]
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = measure(argv)
    print(json.dumps(out))
    return 0 if out["rc"] == 0 else 1


if __name__ == "__main__":
    rc = main()
    gc.freeze()                 # as the uvisi console script leaves (hil_harness.cli.run)
    sys.exit(rc)
