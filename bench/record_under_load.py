"""A recorded frame's host cost under load: ``python -m bench.record_under_load [options]``.

Runs ``uvisi event satellite_over_stars --no-figures`` (frames recorded, 20-frame blocks: the
command's defaults) ROUNDS times in fresh processes, each beside BUSY busy loops (``while 1:
pass``, started before the event and ended by their process id after it, at the niceness of this
command), and prints, per run, the figures of the run's ``summary.json`` ``host``:

- ``median``: ``median_frame_us``, the closed loop's median frame (render + IP + TP + spacecraft);
- ``record``: ``mean_record_us``, the mean host time a frame the recorder took on the loop's
  thread (the event writer's call for each frame and its drains: the rows and the block writes,
  the closing drain included; not the recorder's opening, nor its closing: the last part-block's
  write, the seal, the rename). The recorder runs no other thread: this is all it costs the run
  between its opening and its closing;
- ``sum``: their sum, the figure issue #45 holds to (<= 500 us on a quiet machine, <= 700 us at
  load 2);
- ``loop mean``: the loop's mean frame (``loop_s`` / frames): preemption and stalls the median
  leaves out;
- ``load``: the 1-minute load average before and after the run (the machine's other users
  included).

``--bare`` adds, to each run, the same event without a recorder in another fresh process beside
the same number of busy loops (``run_event`` with no output folder): ``bare``, its
``median_frame_us``, the loop alone, the floor under ``sum`` whatever the recorder does.

``--cpu`` measures the recorder's CPU instead, less sensitive to the machine's other users: the
event's frames are stepped in one process with the event writer called after each, as ``uvisi
event`` calls it, and the thread CPU time (``time.thread_time``) of the writer's calls and of the
loop's steps is summed over one event after a warm-up one (the figures of that process: ``record
cpu``, ``loop cpu``, us a frame; ``record`` and ``median`` as above, from the wall clock).

``--pair COMMIT`` compares this tree's recorder with COMMIT's in one process (thread CPU):
COMMIT's ``hil_harness/event/io.py`` and ``recording.py`` (``git show``) are loaded as a package
of their own beside this tree's other event modules, and the two recorders record the same
event's frames in turn (ROUNDS events each, in the order ABBA..., after a warm-up pair), so that
the host's changes of speed fall on both alike; it prints each one's median thread CPU a frame
(the writer's calls; of which the block writes, ``Recorder.flush``) and the paired ratios.

With several ``--tree`` checkouts (``--tree /path/to/a --tree /path/to/b``, each one's root on
``PYTHONPATH`` for its runs) the trees take turns within each round, so that an A/B sees the same
load; the last lines give each tree's median of each figure. On a 2-core machine ``--busy 2``
gives load ~2 (plus whatever else runs), ``--busy 1`` load ~1. Run it niced like anything else on a
shared machine (``nice -n 5 python -m bench.record_under_load``): the busy loops get the same
niceness, so the event competes with them as with equals. ``--json``: one JSON object per run.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUSY = "while 1: pass"
FIGURES = ("median_frame_us", "mean_record_us", "sum_us", "loop_mean_us")


def _busy(n: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(n)]


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        p.kill()                  # this command's own children, by their process id
    for p in procs:
        p.wait()


def _beside_busy(args: list, cwd: Path, env: dict, busy: int, settle_s: float, what: str):
    """Run ``args`` (a Python command line after the interpreter) in ``cwd`` with ``env`` beside
    ``busy`` busy loops (started ``settle_s`` before it) -> (completed process, load average
    before, after); SystemExit naming ``what`` when it fails."""
    procs = _busy(busy)
    try:
        time.sleep(settle_s if busy else 0.0)
        load0 = os.getloadavg()[0]
        p = subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                           text=True)
        load1 = os.getloadavg()[0]
    finally:
        _stop(procs)
    if p.returncode != 0:
        raise SystemExit(f"{what} failed:\n{p.stderr[-2000:]}")
    return p, load0, load1


def _last_json(p, load0: float, load1: float, busy: int) -> dict:
    """The JSON object a child printed last, with the busy loops and the load around it."""
    return dict(json.loads(p.stdout.strip().splitlines()[-1]), busy=busy, load_before=load0,
                load_after=load1)


#: the ``--bare`` run: the event without a recorder, in a fresh process; prints one JSON object
BARE_CHILD = """
import json
from hil_harness.event.io import run_event
print(json.dumps(run_event("satellite_over_stars", figures=False)["host"]))
"""


def bare_run(tree: Path, busy: int, settle_s: float = 2.0) -> float:
    """:data:`BARE_CHILD` of ``tree``'s code beside ``busy`` busy loops: the loop's median frame
    without a recorder (us)."""
    p, _, _ = _beside_busy(["-c", BARE_CHILD], tree, dict(os.environ, PYTHONPATH=str(tree)), busy,
                           settle_s, f"{tree}: the event without a recorder")
    return json.loads(p.stdout.strip().splitlines()[-1])["median_frame_us"]


def one_run(tree: Path, busy: int, out: Path, settle_s: float = 2.0, bare: bool = False) -> dict:
    """One event of ``tree``'s code in a fresh process beside ``busy`` busy loops: its
    ``summary.json`` figures (us a frame) and the load average before and after; ``bare``: and
    ``bare_median_us``, the same event's median frame without a recorder (:func:`bare_run`)."""
    _, load0, load1 = _beside_busy(
        ["-m", "hil_harness.cli", "-q", "event", "satellite_over_stars", "--no-figures", "--out",
         str(out), "--force"], tree, dict(os.environ, PYTHONPATH=str(tree)), busy, settle_s,
        f"{tree}: the event")
    s = json.loads((out / "summary.json").read_text())
    h, n = s["host"], s["frames"]
    row = {"busy": busy, "load_before": load0, "load_after": load1, "frames": n,
           "median_frame_us": h["median_frame_us"], "mean_record_us": h["mean_record_us"],
           "sum_us": h["median_frame_us"] + h["mean_record_us"],
           "loop_mean_us": 1e6 * h["loop_s"] / n}
    if bare:
        row["bare_median_us"] = bare_run(tree, busy, settle_s)
    return row


#: the ``--cpu`` run, in a fresh process of the tree's code: prints one JSON object
CPU_CHILD = """
import json, sys, tempfile, time
from pathlib import Path
import numpy as np
from hil_harness.event import Event, EventConfig
from hil_harness.event.io import EventWriter
from hil_harness.event.recording import Recorder
ev = Event(EventConfig("satellite_over_stars"), keep_frames=False)
with tempfile.TemporaryDirectory() as tmp:
    for rep in range(2):                    # a warm-up event, then the measured one
        ev.reset()
        rec = Recorder(Path(tmp) / str(rep) / "recording.h5")
        w = EventWriter(rec, ev, True)
        rc = rw = lc = 0.0
        loop = []
        while not ev.done:
            c0, t0 = time.thread_time(), time.perf_counter()
            o = ev.step()
            c1, t1 = time.thread_time(), time.perf_counter()
            w(o)
            if ev.done:
                w.drain()
            o.frame = None
            c2, t2 = time.thread_time(), time.perf_counter()
            lc += c1 - c0; rc += c2 - c1; rw += t2 - t1; loop.append(t1 - t0)
        rec.close()
n = len(loop)
print(json.dumps({"record_cpu_us": 1e6 * rc / n, "loop_cpu_us": 1e6 * lc / n,
                  "mean_record_us": 1e6 * rw / n, "median_frame_us": 1e6 * float(np.median(loop))}))
"""


def cpu_run(tree: Path, busy: int, settle_s: float = 2.0) -> dict:
    """:data:`CPU_CHILD` of ``tree``'s code beside ``busy`` busy loops: its figures and the load."""
    ran = _beside_busy(["-c", CPU_CHILD], tree, dict(os.environ, PYTHONPATH=str(tree)), busy,
                       settle_s, f"{tree}: the run")
    return _last_json(*ran, busy)


#: the ``--pair`` run: both recorders in one process, events alternated; prints one JSON object
PAIR_CHILD = """
import importlib, json, statistics, sys, tempfile, time
from pathlib import Path
import numpy as np
sys.path.insert(0, {pkg_dir!r})
from hil_harness.event import Event, EventConfig
from hil_harness.event import io as new_io, recording as new_rec
old_io = importlib.import_module({pkg!r} + ".io")
old_rec = importlib.import_module({pkg!r} + ".recording")
V = {{"old": (old_rec.Recorder, old_io.EventWriter), "new": (new_rec.Recorder, new_io.EventWriter)}}
flush = {{v: [0.0] for v in V}}
for v, (R, _) in V.items():
    def timed(self, _f=R.flush, _acc=flush[v]):
        c = time.thread_time()
        try:
            return _f(self)
        finally:
            _acc[0] += time.thread_time() - c
    R.flush = timed
ev = Event(EventConfig("satellite_over_stars"), keep_frames=False)
ev.run()
out = {{v: {{"record_cpu_us": [], "flush_cpu_us": [], "loop_cpu_us": []}} for v in V}}
order = []
for i in range({rounds} + 1):
    order += ["old", "new"] if i % 2 == 0 else ["new", "old"]
with tempfile.TemporaryDirectory() as tmp:
    for j, v in enumerate(order):
        R, W = V[v]
        f0 = flush[v][0]
        ev.reset()
        rec = R(Path(tmp) / str(j) / "recording.h5")
        w = W(rec, ev, True)
        rc = lc = 0.0
        n = 0
        while not ev.done:
            c0 = time.thread_time()
            o = ev.step()
            c1 = time.thread_time()
            w(o)
            if ev.done:
                w.drain()
            o.frame = None
            lc += c1 - c0
            rc += time.thread_time() - c1
            n += 1
        rec.close()
        if j >= 2:
            out[v]["record_cpu_us"].append(1e6 * rc / n)
            out[v]["flush_cpu_us"].append(1e6 * (flush[v][0] - f0) / n)
            out[v]["loop_cpu_us"].append(1e6 * lc / n)
ratios = [b / a for a, b in zip(out["old"]["record_cpu_us"], out["new"]["record_cpu_us"])]
print(json.dumps(dict(out, ratio=ratios)))
"""


def pair_run(commit: str, rounds: int, busy: int, settle_s: float = 2.0) -> dict:
    """:data:`PAIR_CHILD`: this tree's recorder and ``commit``'s in one process, beside ``busy``
    busy loops; the per-event figures of each, the paired ratios and the load."""
    import tempfile as _tf
    with _tf.TemporaryDirectory() as tmp:
        pkg = "recorder_at_" + "".join(c for c in commit if c.isalnum())
        d = Path(tmp) / pkg
        d.mkdir()
        (d / "__init__.py").write_text("")
        for m in sorted((ROOT / "hil_harness" / "event").glob("*.py")):
            if m.stem in ("__init__", "io", "recording"):
                continue
            (d / m.name).write_text(                  # this tree's module, every name of it
                f"import importlib\n_m = importlib.import_module('hil_harness.event.{m.stem}')\n"
                "globals().update({k: getattr(_m, k) for k in dir(_m) if k[:2] != '__'})\n")
        for m in ("io", "recording"):
            (d / f"{m}.py").write_text(subprocess.run(
                ["git", "show", f"{commit}:hil_harness/event/{m}.py"], cwd=ROOT, check=True,
                capture_output=True, text=True).stdout)
        ran = _beside_busy(["-c", PAIR_CHILD.format(pkg_dir=tmp, pkg=pkg, rounds=rounds)], ROOT,
                           dict(os.environ, PYTHONPATH=str(ROOT)), busy, settle_s,
                           "the paired run")
    return _last_json(*ran, busy)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.record_under_load",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3, help="runs of each tree (default 3)")
    ap.add_argument("--busy", type=int, default=0, help="busy loops beside each run (default 0)")
    ap.add_argument("--tree", type=Path, action="append",
                    help="a checkout whose code runs (repeat for an A/B; default: this one)")
    ap.add_argument("--cpu", action="store_true",
                    help="the recorder's and the loop's thread CPU time, in one process")
    ap.add_argument("--pair", metavar="COMMIT",
                    help="this tree's recorder against COMMIT's, in one process (thread CPU)")
    ap.add_argument("--bare", action="store_true",
                    help="and the same event without a recorder each run (the loop alone)")
    ap.add_argument("--json", action="store_true", help="one JSON object per run")
    a = ap.parse_args(argv)
    if a.bare and (a.cpu or a.pair):
        ap.error("--bare goes with the default runs, not with --cpu or --pair")
    if a.pair:
        return _pair_main(a)
    trees = [t.resolve() for t in (a.tree or [ROOT])]
    names = {t: t.name for t in trees}
    if a.cpu:
        return _cpu_main(a, trees, names)
    if not a.json:
        print(f"uvisi event satellite_over_stars --no-figures; {a.busy} busy loops; "
              f"{os.cpu_count()} cores; " + ", ".join(str(t) for t in trees))
        print(f"{'tree':>12} {'load':>9} {'median':>7} {'record':>7} {'sum':>6} {'loop mean':>9}"
              + (f" {'bare':>6}" if a.bare else "") + "   (us a frame)")
    cols = list(zip(FIGURES, (7, 7, 6, 9))) + ([("bare_median_us", 6)] if a.bare else [])
    with tempfile.TemporaryDirectory() as tmp:
        return _rounds(a, trees, names,
                       lambda t, i: one_run(t, a.busy, Path(tmp) / f"run{i}-{names[t]}",
                                            bare=a.bare), cols)


def _rounds(a, trees: list, names: dict, run, cols: list) -> int:
    """``a.rounds`` rounds of ``run(tree, round)`` (-> a run's dict) over ``trees``: one JSON
    object per run (``--json``), or a row per run and each tree's medians of ``cols`` (``(key,
    width)``, us a frame) under the caller's header."""
    def row(name, load, values):
        return f"{name[-12:]:>12} {load:>9} " + " ".join(
            f"{v:{w}.0f}" for v, (_, w) in zip(values, cols))
    runs: dict[Path, list] = {t: [] for t in trees}
    for i in range(a.rounds):
        for t in trees:
            r = run(t, i)
            runs[t].append(r)
            if a.json:
                print(json.dumps(dict(r, round=i, tree=str(t))), flush=True)
            else:
                print(row(names[t], f"{r['load_before']:4.1f}-{r['load_after']:<4.1f}",
                          [r[k] for k, _ in cols]), flush=True)
    if not a.json:
        for t in trees:
            print(row(names[t], "median", [statistics.median(r[k] for r in runs[t])
                                           for k, _ in cols]))
    return 0


def _cpu_main(a, trees: list, names: dict) -> int:
    cols = ("record_cpu_us", "loop_cpu_us", "mean_record_us", "median_frame_us")
    if not a.json:
        print(f"satellite_over_stars in one process, frames recorded; {a.busy} busy loops; "
              f"{os.cpu_count()} cores; " + ", ".join(str(t) for t in trees))
        print(f"{'tree':>12} {'load':>9} {'record cpu':>10} {'loop cpu':>8} {'record':>7} "
              f"{'median':>7}   (us a frame)")
    return _rounds(a, trees, names, lambda t, i: cpu_run(t, a.busy),
                   list(zip(cols, (10, 8, 7, 7))))


def _pair_main(a) -> int:
    r = pair_run(a.pair, a.rounds, a.busy)
    if a.json:
        print(json.dumps(r))
        return 0
    med = statistics.median
    print(f"satellite_over_stars, {a.pair}'s recorder and this tree's in one process, "
          f"{a.rounds} events each; {a.busy} busy loops; load {r['load_before']:.2f}-"
          f"{r['load_after']:.2f}; us a frame (thread CPU), median")
    for v, name in (("old", a.pair), ("new", "this tree")):
        x = r[v]
        print(f"{name[-12:]:>12}: recorder {med(x['record_cpu_us']):5.0f} (block writes "
              f"{med(x['flush_cpu_us']):5.0f}), loop {med(x['loop_cpu_us']):5.0f}")
    print(f"this tree / {a.pair}, paired: {med(r['ratio']):.2f} "
          f"({min(r['ratio']):.2f}-{max(r['ratio']):.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
