"""Every benchmark runs once (timing disabled) so that the suites cannot rot between `make bench`s.

The benchmark bodies also check that our result equals the peer's, so this is a correctness test
of the comparisons, not only an import check.
"""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_benchmark_runs_once():
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    res = subprocess.run([sys.executable, "-m", "pytest", "bench", "-q", "-x", "--benchmark-disable",
                          "-p", "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True,
                         timeout=900, env=env)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-2000:]


def test_report_renders_from_results(tmp_path):
    from bench import report
    groups = {"demo group": {"doc": "A group.", "module": "bench/x.py", "rows": [
        {"name": "test_ours_x", "median_s": 2e-6, "rounds": 10},
        {"name": "test_peer", "median_s": 8e-6, "rounds": 10}]}}
    text = report.render(groups, "a machine", "2026-01-01")
    assert "| **ours x** | 2.0 us | 1.00 |" in text and "| peer | 8.0 us | 4.00 |" in text


def test_regenerating_the_report_keeps_the_dated_ab_records():
    """make bench rewrites BENCHMARKS.md from the suites; the hand-measured A/B sections (their
    heading says "(A/B with COMMIT)") are kept, in order, above the suites' tables."""
    from bench.report import ab_sections
    text = ("# Benchmarks\n\nintro\n\n## 2026-01-02: x (A/B with abc1234)\n\nrow 1\n\n"
            "## IP back end\n\ntable\n\n## 2026-01-01: y (A/B with def5678)\n\nrow 2\n")
    kept = ab_sections(text)
    assert [k.split("\n")[1] for k in kept] == ["## 2026-01-02: x (A/B with abc1234)",
                                                "## 2026-01-01: y (A/B with def5678)"]
    assert "row 1" in kept[0] and "table" not in "".join(kept)


def test_every_dated_record_in_benchmarks_md_survives_a_regeneration():
    """Each dated section of the committed BENCHMARKS.md (``## YYYY-MM-DD: ...``, measured by hand)
    is one a regeneration keeps: its heading names what it was measured against with "(A/B with
    ...)". A dated heading without it would be dropped by the next ``make bench``."""
    import re
    from bench.report import ab_sections
    text = (ROOT / "BENCHMARKS.md").read_text(encoding="utf-8")
    dated = re.findall(r"^## (\d{4}-\d{2}-\d{2}:.*)$", text, flags=re.M)
    kept = [k.split("\n")[1][3:] for k in ab_sections(text)]
    assert dated and [d for d in dated if d not in kept] == []


def test_each_group_says_when_where_and_at_what_load(monkeypatch):
    """A group's figures carry the date, machine and load of the run that took them, so that a
    ``-k`` run's groups and the ones kept from an older run are told apart; the peers' versions
    are the installed ones, and a peer that is not installed is said so."""
    from bench import report
    taken = {"date": "2026-01-02", "machine": "box", "load": report.load_range([1.31, 0.52, 0.9])}
    rows = [{"name": "test_ours_x", "median_s": 2e-6, "rounds": 10}]
    groups = {"new": {"doc": "", "module": "bench/x.py", "rows": rows, "taken": taken},
              "old": {"doc": "", "module": "bench/y.py", "rows": rows}}
    text = report.render(groups, "box", "2026-01-02", "OpenCV 9")
    assert ("Taken 2026-01-02 on this machine; 1-min load average 0.52-1.31 during the run, the "
            "run's own process counting up to 1 of it.") in text
    assert "Taken 2026-01-02 on box;" in report.render(groups, "other box", "2026-01-03")
    old = text.split("## old")[1].split("|")[0]
    assert old.count("When, where and at what load these figures were taken: not recorded.") == 1
    assert "Peers: OpenCV 9." in text and report.load_range([]) == "n/a"
    import cv2
    assert f"OpenCV {cv2.__version__}" in report.peer_versions()
    monkeypatch.setattr(report, "PEERS", (("Nothing", "no-such-distribution-uvisi"),))
    assert report.peer_versions() == "Nothing not installed (no-such-distribution-uvisi)"
