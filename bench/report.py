"""Run the benchmark suites and regenerate ``BENCHMARKS.md``.

Usage::

    python -m bench.report                 # every suite under bench/ (what `make bench` runs)
    python -m bench.report -k frontend     # only some (pytest -k expression); other groups are
                                           # kept from the previous BENCHMARKS.md data file
    python -m bench.report --from-json F   # re-render from a saved pytest-benchmark JSON

Conventions the suites follow: each job is one pytest-benchmark *group*; our contender's test name
contains ``ours``; peers are the other tests of the group. A group's description is the docstring of
its bench module (first paragraph). Ratios are peer median / our median from the same run.
The flight-budget tables come from the cost models in the flight code (cycles are not measured, they
are emulated), through the providers listed in :data:`BUDGET_PROVIDERS`.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import importlib
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "BENCHMARKS.md"
DATA = ROOT / "bench" / "results.json"      # the last full set of results, merged per group

#: (module, function) returning Markdown for the emulated-budget section; missing ones are skipped
BUDGET_PROVIDERS = (
    ("bench.budget_tables", "frontend_cycle_markdown"),
    ("hil_harness.budget", "budget_markdown"),
)


def _machine() -> str:
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba
    import numpy
    return (f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}, "
            f"numba {numba.__version__}, numpy {numpy.__version__}, {platform.system()}")


#: the peers' distributions (import name in the suites: distribution on PyPI)
PEERS = (("OpenCV", "opencv-python-headless"), ("SEP", "sep"), ("SciPy", "scipy"),
         ("scikit-image", "scikit-image"), ("filterpy", "filterpy"), ("apytypes", "apytypes"),
         ("fxpmath", "fxpmath"))


def peer_versions() -> str:
    """The installed version of each peer the suites time, e.g. ``OpenCV 5.0.0 (opencv-python-
    headless), SEP 1.4.1, ...``; a peer not installed is said so (its benchmarks are skipped)."""
    from importlib import metadata
    out = []
    for name, dist in PEERS:
        try:
            v = metadata.version(dist)
        except metadata.PackageNotFoundError:
            v = "not installed"
        out.append(f"{name} {v}" + (f" ({dist})" if dist.lower() != name.lower() else ""))
    return ", ".join(out)


def load_range(samples: list[float]) -> str:
    """``"0.52-1.31"``: the lowest and highest 1-min load average sampled (``"n/a"``: none)."""
    return f"{min(samples):.2f}-{max(samples):.2f}" if samples else "n/a"


def stamp_line(taken: dict | None, machine: str) -> str:
    """The line under a group's command: when, where (when not ``machine``, the report's) and at
    what load its figures were taken."""
    if not taken:
        return "When, where and at what load these figures were taken: not recorded."
    where = "this machine" if taken["machine"] == machine else taken["machine"]
    return (f"Taken {taken['date']} on {where}; 1-min load average {taken['load']} during the "
            f"run, the run's own process counting up to 1 of it.")


def run_suites(k: str | None, json_path: Path, loads: list) -> int:
    """Run the suites into ``json_path`` (pytest's exit code); the 1-min load average sampled
    every 5 s meanwhile is appended to ``loads``."""
    cmd = [sys.executable, "-m", "pytest", str(ROOT / "bench"), "-q", "--benchmark-enable",
           "--benchmark-only", f"--benchmark-json={json_path}", "-p", "no:cacheprovider"]
    if k:
        cmd += ["-k", k]
    print("running:", " ".join(cmd), flush=True)
    # one core for the contenders, as the targets are stated (numba kernels are single-threaded)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1",
               NUMBA_NUM_THREADS="1", OPENCV_FOR_THREADS_NUM="1")
    proc = subprocess.Popen(cmd, cwd=ROOT, env=env)
    while True:                              # the machine's load, every 5 s while the suites run
        loads.append(os.getloadavg()[0])
        try:
            return proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            continue


def _group_doc(fullname: str, group: str | None = None) -> str:
    """The group's description: the suite module's ``GROUP_DOCS[group]`` if it has one (targets and
    notes per group), else the first paragraph of the module docstring."""
    module = fullname.split("::")[0].replace("/", ".").removesuffix(".py")
    if module.startswith("bench.") is False and "bench." in module:
        module = module[module.index("bench."):]
    try:
        mod = importlib.import_module(module)
    except Exception:  # a broken suite must not stop the report
        return ""
    notes = getattr(mod, "GROUP_DOCS", {})
    if group in notes:
        return " ".join(notes[group].split())
    doc = mod.__doc__ or ""
    return doc.strip().split("\n\n")[0].replace("\n", " ")


def collect(json_file: Path, taken: dict | None = None) -> dict:
    """The groups of a pytest-benchmark JSON, each with its rows and ``taken`` (date, machine,
    load: :func:`stamp_line`; None when rendered from a saved JSON of unknown origin)."""
    raw = json.loads(json_file.read_text())
    groups: dict[str, dict] = {}
    for b in raw["benchmarks"]:
        g = b.get("group") or b["fullname"].split("::")[0]
        entry = groups.setdefault(g, {"doc": _group_doc(b["fullname"], g), "rows": [],
                                      "module": b["fullname"].split("::")[0], "taken": taken})
        entry["rows"].append({"name": b["name"], "median_s": b["stats"]["median"],
                              "mean_s": b["stats"]["mean"], "rounds": b["stats"]["rounds"],
                              "extra": b.get("extra_info") or {}})
    return groups


def _fmt(seconds: float) -> str:
    us = seconds * 1e6
    if us < 1000:
        return f"{us:.1f} us"
    if us < 1e6:
        return f"{us / 1000:.2f} ms"
    return f"{us / 1e6:.2f} s"


def _fmt_ratio(x: float) -> str:
    """Two decimals, or two significant digits below 0.1 (a floor 200x faster: 0.005, not 0.00)."""
    return f"{x:.2g}" if x < 0.1 else f"{x:.2f}"


#: the heading of a dated A/B record (measured by hand against another commit, alternated)
AB_HEADING = "(A/B with "


def ab_sections(text: str) -> list[str]:
    """The ``## ...(A/B with COMMIT)`` sections of a BENCHMARKS.md, each with its trailing blank
    line, in order: a regeneration keeps them above the suites' tables."""
    parts = text.split("\n## ")
    return [f"\n## {p.rstrip()}\n" for p in parts[1:] if AB_HEADING in p.split("\n", 1)[0]]


def render(groups: dict, machine: str, when: str, peers: str = "") -> str:
    out = ["# Benchmarks", "",
           "Generated by `make bench` (`python -m bench.report`); do not edit by hand. Every figure is",
           "a median from pytest-benchmark on one core; the peers of a group ran in the same run on the",
           "same input, and each was checked to find the same result as ours before it was timed.",
           "Ratio = peer median / our median (> 1: we are faster).", "",
           f"Machine: {machine}. Taken {when}.", "",
           "Each group says when, where and at what load its figures were taken (`python -m",
           "bench.report -k` re-runs some groups and keeps the others).",
           ""]
    if peers:
        out += [f"Peers: {peers}.", ""]
    for g in sorted(groups):
        if g.startswith(EVENT_PREFIX):
            continue                          # rendered by event_markdown, below
        entry = groups[g]
        rows = sorted(entry["rows"], key=lambda r: r["median_s"])
        ours = [r for r in rows if "ours" in r["name"]]
        base = ours[0]["median_s"] if ours else None
        out += [f"## {g}", ""]
        if entry["doc"]:
            out += [entry["doc"], ""]
        out += [f"Command: `.venv/bin/python -m pytest {entry['module']} --benchmark-enable`", "",
                stamp_line(entry.get("taken"), machine), "",
                "| contender | median | ratio to ours |", "| --- | ---: | ---: |"]
        for r in rows:
            name = r["name"].removeprefix("test_").replace("_", " ")
            if "ours" in r["name"]:
                name = f"**{name}**"
            ratio = _fmt_ratio(r["median_s"] / base) if base else "n/a"
            out.append(f"| {name} | {_fmt(r['median_s'])} | {ratio} |")
        out.append("")
    out += event_markdown(groups, machine)
    budget = []
    for module, func in BUDGET_PROVIDERS:
        try:
            budget.append(getattr(importlib.import_module(module), func)())
        except (ImportError, AttributeError):
            continue
    if budget:
        out += ["## Emulated flight budget", "",
                "Cycles from the flight code's documented cost models, not host timings.", ""]
        out += [b.rstrip() + "\n" for b in budget]
    return "\n".join(out).rstrip() + "\n"


#: groups of bench/bench_event.py, rendered as the event section (mean per frame, phases)
EVENT_PREFIX = "event: "
#: (phase key of bench.event_phases, row label) of the event wall-time table
EVENT_PHASES = (("python_start", "Python start-up and exit"), ("imports", "imports"),
                ("cache_load", "numba cache load"), ("simulate", "simulate (the closed loop)"),
                ("record", "record (open, every frame, close)"),
                ("figures", "figures, viewer page, summary.json"),
                ("other", "other (scenario and catalogue set-up, run folder, summary)"))


def _row(entry: dict, name: str) -> dict | None:
    return next((r for r in entry["rows"] if r["name"].startswith(name)), None)


def event_markdown(groups: dict, machine: str = "") -> list[str]:
    """The event section: the recorded frame's mean beside the loop's median, and the wall-time
    table of a warm ``uvisi event`` (rows' ``extra`` from bench/bench_event.py)."""
    frame = groups.get(EVENT_PREFIX + "recorded closed-loop frame")
    wall = groups.get(EVENT_PREFIX + "wall time of a warm uvisi event")
    if not frame and not wall:
        return []
    out = ["## Event: a recorded frame, and the wall time of a warm `uvisi event`", ""]
    doc = (frame or wall)["doc"]
    if doc:
        out += [doc, ""]
    out += ["Command: `.venv/bin/python -m pytest bench/bench_event.py --benchmark-enable`", "",
            stamp_line((frame or wall).get("taken"), machine), ""]
    ours = _row(frame, "test_ours_recorded_frame") if frame else None
    loop = _row(frame, "test_loop_frame_unrecorded") if frame else None
    if ours:
        x = ours["extra"]
        out += ["| satellite_over_stars, one core | mean | median | real time (mean) |",
                "| --- | ---: | ---: | ---: |",
                f"| **recorded frame (loop + recorder)** | {_fmt(ours['mean_s'])} | "
                f"{_fmt(ours['median_s'])} | {0.5 / ours['mean_s']:.0f}x |"]
        if "loop_mean_us" in x:
            out.append(f"| of which the loop | {_fmt(x['loop_mean_us'] * 1e-6)} | | |")
            out.append(f"| of which the recorder | {_fmt(x['record_mean_us'] * 1e-6)} | | |")
        if loop:
            out.append(f"| loop alone, nothing recorded | {_fmt(loop['mean_s'])} | "
                       f"{_fmt(loop['median_s'])} | {0.5 / loop['median_s']:.0f}x (median) |")
        out.append("")
    runs = {}
    for r in (wall or {"rows": []})["rows"]:
        runs["--no-figures" if "no_figures" in r["name"] else "with figures"] = r["extra"]
    if runs:
        cols = [c for c in ("with figures", "--no-figures") if c in runs]
        out += ["Warm `uvisi event satellite_over_stars` in a fresh process, median of the timed "
                "runs, seconds of wall time per phase (each moment counted once: cache loads inside "
                "the other phases go to the cache-load row):", "",
                "| phase | " + " | ".join(cols) + " |", "| --- |" + " ---: |" * len(cols)]
        for key, label in EVENT_PHASES:
            out.append(f"| {label} | " + " | ".join(f"{runs[c].get(key, 0.0):.3f}" for c in cols)
                       + " |")
        out.append("| **total wall** | " + " | ".join(f"**{runs[c].get('wall', 0.0):.3f}**"
                                                     for c in cols) + " |")
        x = runs[cols[0]]
        if "loop_median_frame_us" in x:
            out += ["", f"The timed runs' own `summary.json` (`host`, {cols[0]}): loop median "
                        f"{x['loop_median_frame_us']:.0f} us a frame, recorder mean "
                        f"{x['mean_record_us']:.0f} us a frame."]
        out.append("")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.report", description=__doc__.split("\n\n")[0])
    ap.add_argument("-k", help="pytest -k expression selecting suites; other groups keep old results")
    ap.add_argument("--from-json", type=Path, help="render from this pytest-benchmark JSON")
    args = ap.parse_args(argv)

    machine = _machine()
    when = _dt.date.today().isoformat()
    if args.from_json:
        fresh = collect(args.from_json)
    else:
        loads: list[float] = []
        with tempfile.TemporaryDirectory() as tmp:
            jf = Path(tmp) / "bench.json"
            rc = run_suites(args.k, jf, loads)
            if not jf.exists():
                print(f"benchmarks failed (pytest exit {rc}); BENCHMARKS.md left unchanged",
                      file=sys.stderr)
                return rc or 1
            fresh = collect(jf, {"date": when, "machine": machine, "load": load_range(loads)})
            if rc not in (0, 5):
                print(f"warning: pytest exit {rc}; rendering the groups that ran", file=sys.stderr)

    stored = json.loads(DATA.read_text()) if DATA.exists() else {"groups": {}}
    groups = dict(stored["groups"]) if args.k else {}
    groups.update(fresh)
    peers = peer_versions()
    text = render(groups, machine, when, peers)
    kept = ab_sections(OUT.read_text()) if OUT.exists() else []
    if kept:                          # the dated A/B records, not produced by the suites: kept
        head, sep, rest = text.partition("\n## ")
        text = head + "".join(kept) + sep + rest
    tmp_md, tmp_js = OUT.with_suffix(".md.tmp"), DATA.with_suffix(".json.tmp")
    tmp_md.write_text(text)
    tmp_js.write_text(json.dumps({"machine": machine, "date": when, "peers": peers,
                                  "groups": groups}, indent=1))
    os.replace(tmp_md, OUT)           # atomic: never a half-written report
    os.replace(tmp_js, DATA)
    print(f"wrote {OUT.relative_to(ROOT)} ({len(groups)} groups)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
