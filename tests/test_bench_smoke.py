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
