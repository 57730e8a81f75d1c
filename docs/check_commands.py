"""Run every command and Python example the README and docs/*.md show, and check what they print.

``make docs-check`` runs this (outside ``make test``: some commands take minutes). For each fenced
code block:

* a block of ``uvisi ...`` / ``python -m ...`` / ``make ...`` lines (a line ending in ``\\``
  continues): the commands of one document run in order in one scratch folder holding copies of
  the repository's data files (so nothing is written into the repository), with ``uvisi`` as
  ``python -m hil_harness.cli``; it must exit with 0, or with the status a trailing
  ``# exit N`` comment states, and print no traceback. ``make`` lines are listed, not run (they
  set up a virtual environment of their own). The file commands a reader runs beside them
  (``mkdir``, ``cp``, ``sed``) run too, without a shell, in the same folder.
* a ``python`` block: run the same way; when the next block is its output (a plain fenced block),
  every line of that output must be printed, in order (a line ending in ``...`` matches any line
  that starts with the text before it).

Each command run prints its wall time, the CPU time (user + system) it and its worker processes
used, and the host's load average while it ran: on a shared machine the CPU seconds are the figure
that does not move with the load.

Exit status 0 when everything passes, 1 otherwise (each failure on one line).

``python docs/check_commands.py README.md`` (or ``make docs-check DOCS=README.md``) checks one
document; ``--list`` prints the commands without running them.
"""
from __future__ import annotations

import argparse
import os
import re
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))
#: copied into the scratch folder (commands write beside these files, never into the repository)
COPIED = ("data", "campaigns", "flightsw/data", "groundsim/scenarios", "tests/data")
FENCE = re.compile(r"^```(\w*)\s*$")
#: the lines of a command block that are run: uvisi, python -m and make (listed only), and the file
#: commands a reader types beside them
FILE_COMMANDS = ("mkdir ", "cp ", "sed ", "cmp ")
RUN_PREFIXES = ("uvisi ", "make ", "python -m ") + FILE_COMMANDS


def blocks(path: Path) -> list[tuple[str, list[str], int]]:
    """(language, lines, first line number) of every fenced block in a Markdown file."""
    out, lang, buf, start = [], None, [], 0
    for n, line in enumerate(path.read_text().splitlines(), 1):
        m = FENCE.match(line.strip())
        if m and lang is None:
            lang, buf, start = m.group(1), [], n + 1
        elif line.strip() == "```" and lang is not None:
            out.append((lang, buf, start))
            lang = None
        elif lang is not None:
            buf.append(line)
    return out


def commands(lines: list[str]) -> list[tuple[str, int]]:
    """The shell commands of a block (continuations joined), each with its expected exit status."""
    out, cur = [], ""
    for raw in lines:
        line = raw.rstrip()
        cur = (cur + " " + line.rstrip("\\").strip()) if cur else line.rstrip("\\").strip()
        if line.endswith("\\"):
            continue
        words = cur.split()
        if cur.startswith(RUN_PREFIXES) and len(words) > 1 and not words[1].endswith(":"):
            m = re.search(r"#\s*exit\s+(\d+)", cur)
            out.append((cur.split("#")[0].strip(), int(m.group(1)) if m else 0))
        cur = ""
    return out


def scratch() -> Path:
    """A folder holding copies of the repository's data files, where a document's commands run in
    order (a later command may read what an earlier one wrote)."""
    import shutil
    d = Path(tempfile.mkdtemp(prefix="uvisi-docs-"))
    for name in COPIED:
        if (ROOT / name).exists():
            shutil.copytree(ROOT / name, d / name)
    return d


def run(argv: list[str], cwd: Path, timeout: int) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(ROOT), UVISI_PROGRESS="0")
    return subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def timed(argv: list[str], cwd: Path, timeout: int) -> tuple[subprocess.CompletedProcess, str]:
    """:func:`run` and a line saying what it cost: wall seconds, CPU seconds (user + system, the
    command and every process it waited for) and the 1-minute load average at its end."""
    import resource
    import time
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = run(argv, cwd, timeout)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return res, f"{wall:.1f} s wall, {cpu:.1f} s CPU, load {os.getloadavg()[0]:.1f}"


def expected_output_found(expected: list[str], printed: str) -> str | None:
    """None when every expected line appears in order; else the first one missing."""
    got = printed.splitlines()
    i = 0
    for want in (w.rstrip() for w in expected if w.strip()):
        prefix = want[:-3].rstrip() if want.endswith("...") else None
        while i < len(got) and not (got[i].rstrip() == want or
                                    (prefix is not None and got[i].startswith(prefix))):
            i += 1
        if i == len(got):
            return want
        i += 1
    return None


def check(path: Path, timeout: int, dry: bool, keep: bool = False) -> list[str]:
    """Run (or with ``dry`` list) one document's blocks; the scratch folder is removed afterwards
    unless ``keep`` (then its path is printed)."""
    import shutil
    work = None if dry else scratch()
    try:
        return _check(path, timeout, dry, work)
    finally:
        if work is not None:
            if keep:
                print(f"{path.relative_to(ROOT)}: scratch folder kept: {work}")
            else:
                shutil.rmtree(work, ignore_errors=True)


def _check(path: Path, timeout: int, dry: bool, work: Path | None) -> list[str]:
    fails = []
    bl = blocks(path)
    for j, (lang, lines, start) in enumerate(bl):
        where = f"{path.relative_to(ROOT)}:{start}"
        if lang == "python":
            print(f"{where}: python example ({len(lines)} lines)", flush=True)
            if dry:
                continue
            res, cost = timed([sys.executable, "-c", "\n".join(lines)], work, timeout)
            print(f"    {cost}", flush=True)
            if res.returncode != 0:
                fails.append(f"{where}: python example exit {res.returncode}: "
                             f"{(res.stderr.strip().splitlines() or [''])[-1]}")
            elif j + 1 < len(bl) and bl[j + 1][0] == "":
                missing = expected_output_found(bl[j + 1][1], res.stdout)
                if missing is not None:
                    fails.append(f"{where}: python example did not print {missing!r}")
            continue
        for cmd, want in commands(lines):
            if dry or cmd.startswith("make "):
                print(f"{where}: {cmd}" + ("" if want == 0 else f"  (exit {want})"))
                continue
            argv = shlex.split(cmd)
            if cmd.startswith(FILE_COMMANDS):
                pass                                    # run as written, in the scratch folder
            else:
                argv = [sys.executable] + (argv[1:] if argv[0] == "python" else
                                           ["-m", "hil_harness.cli"] + argv[1:])
            print(f"{where}: {cmd}", flush=True)
            try:
                res, cost = timed(argv, work, timeout)
            except subprocess.TimeoutExpired:
                fails.append(f"{where}: {cmd}: no answer within {timeout} s")
                continue
            print(f"    {cost}", flush=True)
            if res.returncode != want or "Traceback" in res.stderr:
                last = (res.stderr.strip().splitlines() or [""])[-1]
                fails.append(f"{where}: {cmd}: exit {res.returncode} (expected {want}): {last}")
    return fails


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--list", action="store_true", help="list the commands, run nothing")
    ap.add_argument("--timeout", type=int, default=1800, help="seconds per command")
    ap.add_argument("--keep", action="store_true",
                    help="keep each document's scratch folder (its path is printed)")
    ap.add_argument("docs", nargs="*", metavar="FILE",
                    help="check only these documents (README.md, docs/api.md or api.md); "
                         "default: README.md and every docs/*.md")
    ap.add_argument("--only", nargs="*", default=None, metavar="FILE",
                    help="the same as naming the documents (kept for old scripts)")
    args = ap.parse_args(argv)
    wanted = set(Path(d).name for d in (args.docs or []) + (args.only or []))
    unknown = wanted - {p.name for p in DOCS}
    if unknown:
        ap.error(f"no such document: {', '.join(sorted(unknown))} "
                 f"(known: {', '.join(p.name for p in DOCS)})")
    fails = []
    for path in DOCS:
        if wanted and path.name not in wanted:
            continue
        fails += check(path, args.timeout, args.list, args.keep)
    for f in fails:
        print(f"FAIL {f}", file=sys.stderr)
    if not args.list:
        print(f"docs-check: {len(fails)} failure(s)")
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
